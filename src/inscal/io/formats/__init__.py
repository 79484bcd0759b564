"""The formats ``inscal import`` reads and ``inscal export`` writes, in one table (:data:`REGISTRY`).

Each format is a module of this package (``inscal.io.formats.<module>``) with a reader
``read(src, options: ReadOptions) -> Raw`` (:mod:`inscal.io.formats.base`): the columns of the source
converted to SI, not yet checked (the importer checks them, :mod:`inscal.io.importers`).  A format that
``inscal export`` writes has a writer ``write(tmp, chunks, info, rows)`` (the record's ``(t, dtheta, dvel,
gimbal)`` chunks into the file ``tmp``; ``rows``: the csv's temperature rows).  A module may also define
``source_hash(src)`` (the record's provenance hash; default the file's SHA-256).  One row of
:data:`REGISTRY` registers it: the command line's ``--format`` choices and help, the importer's checks
(which options a format takes, what its mapping may hold, where its site comes from) and the formats
page of the documentation all read the table.

This module is the table only (no NumPy, no h5py): the command line reads it when it starts.  The
readers are imported when a source is read (:func:`reader`).  The modules shared by the readers:
:mod:`~inscal.io.formats.base` (``Raw``, the options), :mod:`~inscal.io.formats.table` (delimited text),
:mod:`~inscal.io.formats.rates` (rates at their stamps integrated onto a grid) and
:mod:`~inscal.io.formats.sidecars` (the temperature and gimbal files beside any source).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass


@dataclass(frozen=True)
class Format:
    """One format of ``inscal import`` (and of ``inscal export``, with ``exports``).

    ``options``: the ``inscal import`` options its reader takes (parameter names: ``dtype``, ``variable``,
    ``rates``, ``topic``, ``stamps``, ``temperature_topic``, ``config``); any other of these is refused
    with it.  ``mapping``: what its
    mapping TOML holds, ``"columns"`` (the columns, units, axes: ``[columns]`` and ``[units]`` are
    required) or ``"site"`` (its rows are fixed: only a ``[site]`` table).  ``delimiter``: a columns
    mapping's default delimiter.  ``site_in_file``: the source names its site (no ``--lat`` needed).
    ``units``: the units its rows hold by definition, (gyro, accel), when no mapping says them;
    ``declared``: the gyro unit its messages declare (a magnitude that contradicts it is a warning, not a
    refusal; None: assumed).  ``folder``: a folder that may be given as the source, (what it is, the
    file it must hold)."""

    name: str
    module: str  # the plugin module under inscal.io.formats: read(src, options) -> Raw
    source: str  # the file, as the --format help and the documentation name it
    rows: str  # what its rows hold (the documentation's table)
    options: tuple[str, ...] = ()
    mapping: str = "site"
    delimiter: str | None = None
    exports: bool = False
    site_in_file: bool = False
    units: tuple[str, str] | None = None
    declared: str | None = None
    folder: tuple[str, str] | None = None

    def takes(self, option: str) -> bool:
        """Whether ``inscal import --format NAME`` takes ``option`` (a parameter name)."""
        return option in self.options


#: every format, by its ``--format`` name (the order of the help and of the messages)
REGISTRY: dict[str, Format] = {f.name: f for f in (
    Format("psins", "psins", "PSINS .bin", "`[dθx dθy dθz dvx dvy dvz t]` (rad, m/s, s), little-endian float64 (or "
           "`--dtype float32`); with `--rates`, `[wx wy wz fx fy fz t]` (rad/s, m/s², s)",
           options=("dtype", "variable", "rates"), exports=True),
    Format("psins-imu", "psins_imu", "PSINS .imu", "a header (initial attitude, site, start time, interval, g, scale "
           "factors), then integer counts", site_in_file=True),
    Format("csv", "text", "csv", "as its mapping says, or the header that `inscal export` writes", mapping="columns",
           delimiter=",", exports=True),
    Format("txt", "text", "whitespace text", "as its mapping says", mapping="columns", delimiter="whitespace"),
    Format("mat", "mat", "MATLAB .mat", "the same 7 columns as psins; `--variable NAME` or the first N×7 variable",
           options=("variable", "rates"), exports=True),
    Format("rosbag", "rosbag", "ROS 1 .bag, ROS 2 bag folder or .mcap", "`sensor_msgs/Imu` messages of `--topic`: rates at "
           "their header stamps (`--stamps receive`: the bag's receive times), integrated onto a uniform grid (the "
           "import reports the error bound); `--temperature-topic` for `sensor_msgs/Temperature`",
           options=("topic", "stamps", "temperature_topic"), units=("rad/s", "m/s^2"),
           declared="rad/s (sensor_msgs/Imu, REP 145)", folder=("ROS 2 bag", "metadata.yaml")),
    Format("kf-gins", "kfgins", "KF-GINS text", "`t dθx dθy dθz dvx dvy dvz` (s, rad, m/s; blanks or commas; extra "
           "columns ignored); `--config kf-gins.yaml` for its settings", options=("config",),
           exports=True),
)}


class UnknownFormat(ValueError):
    """A ``--format`` that is not in :data:`REGISTRY` (the message lists the known ones)."""


def format_spec(name: str, export: bool = False) -> Format:
    """The row of ``name`` (an export format with ``export``); :class:`UnknownFormat` names the choices."""
    spec = REGISTRY.get(name)
    if spec is None or (export and not spec.exports):
        known = export_formats() if export else tuple(REGISTRY)
        raise UnknownFormat(f"unknown {'export ' if export else ''}format {name!r}; choose one of: {', '.join(known)}")
    return spec


def export_formats() -> tuple[str, ...]:
    """The formats ``inscal export`` writes a record in."""
    return tuple(n for n, f in REGISTRY.items() if f.exports)


def taking(option: str) -> tuple[str, ...]:
    """The formats whose reader takes ``option`` (the ones a message names)."""
    return tuple(n for n, f in REGISTRY.items() if option in f.options)


def with_mapping(kind: str) -> tuple[str, ...]:
    """The formats whose mapping holds ``kind`` (``"columns"`` or ``"site"``)."""
    return tuple(n for n, f in REGISTRY.items() if f.mapping == kind)


def reader(spec: Format):
    """The plugin module of ``spec`` (its ``read`` and, where it has one, ``source_hash``)."""
    return importlib.import_module(f"{__name__}.{spec.module}")


def import_help() -> str:
    """The ``--format`` help of ``inscal import``: the names, in the table's order."""
    return " | ".join(REGISTRY)


def source_help() -> str:
    """What ``inscal import`` reads, for its source argument's help."""
    return ", ".join(dict.fromkeys(f.source for f in REGISTRY.values()))


#: names this package gave when it held the readers itself, and the modules that hold them now
MOVED = {"ImportFileError": "inscal.io.mapping", "Raw": "inscal.io.formats.base",
         "RawTemperature": "inscal.io.formats.base", "check_angles": "inscal.io.formats.base",
         "write_rows": "inscal.io.formats.base", "read_psins_bin": "inscal.io.formats.psins",
         "read_psins_imu": "inscal.io.formats.psins_imu", "read_mat": "inscal.io.formats.mat",
         "read_text": "inscal.io.formats.text", "read_temperature_file": "inscal.io.formats.sidecars",
         "read_gimbal_file": "inscal.io.formats.sidecars"}


def __getattr__(name: str):
    """A name of :data:`MOVED`, from its module (imported then: this module stays free of NumPy)."""
    if name in MOVED:
        return getattr(importlib.import_module(MOVED[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
