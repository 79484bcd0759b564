"""Writing and reading the HDF5 file of a record (the layout of :mod:`inscal.io.records`).

A record is written chunk by chunk (:func:`write_stream`) or whole (:func:`write_record`), atomically;
it is read whole (:func:`read_record`, :func:`load_record` for a command) or as its metadata
(:func:`record_info`).  Every read opens the file with its header checked (:func:`open_checked`) and
turns the errors of a damaged file into one :class:`~inscal.io.records.DataFileError` naming it
(:func:`reading`); :mod:`inscal.io.streaming` reads a record piece by piece on the same checks.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import math
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import h5py
import numpy as np

from inscal import SCHEMA_VERSION, __version__
from inscal.core.cancel import check_cancel
from inscal.io.files import atomic_path, check_input
from inscal.io.records import (
    KIND,
    UNITS,
    DataFileError,
    Record,
    RecordInfo,
    Temperature,
    Truth,
    validate_arrays,
    validate_temperature,
)

if TYPE_CHECKING:  # imported on first use: they pull in scipy and numba (seconds), which reading a record does not need
    from inscal.core.earth import Site
    from inscal.core.thermal import ThermalModel
    from inscal.core.turntable import RotationPath


# ----------------------------------------------------------------------------- writing
def _write_dataclass(group, obj) -> None:
    for f in dataclasses.fields(obj):
        group.create_dataset(f.name, data=np.asarray(getattr(obj, f.name), dtype=float))


def _create_layout(h5, scenario_name, rate_hz, site, path, n, has_gimbal=True, created: str | None = None):
    h5.attrs["kind"] = KIND
    h5.attrs["schema_version"] = SCHEMA_VERSION
    h5.attrs["inscal_version"] = __version__
    h5.attrs["created"] = created or _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    h5.attrs["scenario"] = scenario_name
    h5.attrs["rate_hz"] = float(rate_hz)
    h5.attrs["units"] = json.dumps(UNITS)
    h5.attrs["path"] = path.to_json() if path is not None else ""
    s = h5.create_group("site")
    s.attrs["latitude_rad"] = site.latitude
    s.attrs["longitude_rad"] = site.longitude
    s.attrs["height_m"] = site.height
    s.attrs["gravity_model"] = json.dumps(site.gravity_model.to_json())
    ch = min(max(n, 1), 1 << 16)
    h5.create_dataset("time", shape=(n,), dtype="f8", chunks=(ch,))
    h5.create_dataset("dtheta", shape=(n, 3), dtype="f8", chunks=(ch, 3))
    h5.create_dataset("dvel", shape=(n, 3), dtype="f8", chunks=(ch, 3))
    if has_gimbal:
        h5.create_dataset("gimbal", shape=(n, 2), dtype="f8", chunks=(ch, 2))


def write_stream(path, info: "RecordInfo", chunks, overwrite: bool = False, extra_attrs: dict | None = None,
                 temperature: Temperature | None = None) -> int:
    """Write a record chunk by chunk, atomically, holding one chunk in memory.

    Parameters
    ----------
    path : str or pathlib.Path
        The HDF5 file to write.
    info : RecordInfo
        The metadata: size, rate, site, path, truth (written under ``/truth``), scenario.
    chunks : iterable of tuple
        ``(time, dtheta, dvel, gimbal)`` slices in order, together ``info.n_samples`` long
        (``gimbal`` None when ``info.has_gimbal`` is false).
    overwrite : bool
        Replace an existing file; otherwise one is refused.
    extra_attrs : dict, optional
        More root attributes (``created`` replaces the time of writing).
    temperature : Temperature, optional
        Temperature readings (default ``info.temperature``).

    Returns
    -------
    int
        The number of samples written.

    Raises
    ------
    DataFileError
        Chunks that do not add up to ``info.n_samples``, or arrays that fail :func:`validate_arrays`.
    FileExistsError
        ``path`` exists and ``overwrite`` is false.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.earth import Site
    >>> from inscal.io import RecordInfo, read_record, write_stream
    >>> info = RecordInfo(200, 100.0, Site(0.7), None, None, "still", has_gimbal=False)
    >>> t = np.arange(1, 201) / 100.0
    >>> chunks = [(t[k:k + 100], np.zeros((100, 3)), np.zeros((100, 3)), None) for k in (0, 100)]
    >>> write_stream("streamed.h5", info, chunks)
    200
    >>> read_record("streamed.h5").scenario
    'still'
    """
    temperature = temperature if temperature is not None else info.temperature
    k = 0
    with atomic_path(path, overwrite) as tmp:
        with h5py.File(tmp, "w") as h5:
            extra = dict(extra_attrs or {})  # "created" written once (a value overwritten stays in the file's heap)
            _create_layout(h5, info.scenario, info.rate_hz, info.site, info.path, info.n_samples, info.has_gimbal,
                           extra.pop("created", None))
            for key, val in extra.items():
                h5.attrs[key] = val
            for t, dth, dv, g in chunks:
                check_cancel()
                sl = slice(k, k + t.shape[0])
                h5["time"][sl] = t
                h5["dtheta"][sl] = dth
                h5["dvel"][sl] = dv
                if info.has_gimbal:
                    h5["gimbal"][sl] = g
                k = sl.stop
            if k != info.n_samples:
                raise DataFileError(f"wrote {k} samples, expected {info.n_samples}")
            if info.truth is not None:
                t = h5.create_group("truth")
                _write_dataclass(t.create_group("imu"), info.truth.imu)
                _write_dataclass(t.create_group("gimbal"), info.truth.gimbal)
                _write_dataclass(t.create_group("noise"), info.truth.noise)
                if info.truth.thermal is not None:
                    _write_thermal(t.create_group("thermal"), info.truth.thermal)
            if temperature is not None:
                _write_temperature(h5, temperature, h5["time"] if info.n_samples else None)
    return k


def _write_thermal(group, model) -> None:
    from inscal.core.thermal import THERMAL_TERMS

    for key in ("t_ref", "t_min", "t_max"):
        group.attrs[key] = float(getattr(model, key))
    group.attrs["out_of_range"] = model.out_of_range
    group.attrs["sensor"] = model.sensor
    for name in (*THERMAL_TERMS, "gyro_bias_rate"):
        group.create_dataset(name, data=np.asarray(getattr(model, name), dtype=float))


def _write_temperature(h5, temp: Temperature, time_ds) -> None:
    """/temperature, and /temperature_time unless the readings are on the record's own time grid."""
    h5.create_dataset("temperature", data=np.asarray(temp.values, dtype=float))
    h5["temperature"].attrs["sensors"] = json.dumps(list(temp.sensors))
    n = temp.time.shape[0]
    same = time_ds is not None and time_ds.shape[0] == n and np.array_equal(time_ds[()], temp.time)
    if not same:
        h5.create_dataset("temperature_time", data=np.asarray(temp.time, dtype=float))


def write_record(path, rec: Record, overwrite: bool = False) -> None:
    """Write an in-memory :class:`Record` (imported or edited data) to an HDF5 file, atomically.

    Parameters
    ----------
    path : str or pathlib.Path
        The HDF5 file to write.
    rec : Record
        The record; its arrays are checked first (:func:`validate_arrays`).
    overwrite : bool
        Replace an existing file; otherwise one is refused.

    Raises
    ------
    DataFileError
        Arrays of the wrong shape, NaN/inf or a time grid that is not uniform at ``rate_hz``.
    FileExistsError
        ``path`` exists and ``overwrite`` is false.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.earth import Site
    >>> from inscal.io import Record, read_record, write_record
    >>> t = np.arange(1, 201) / 100.0
    >>> write_record("still.h5", Record(t, np.zeros((200, 3)), np.zeros((200, 3)), None, 100.0, Site(0.7)))
    >>> read_record("still.h5").duration
    2.0
    """
    validate_arrays(rec.time, rec.dtheta, rec.dvel, rec.gimbal, rec.rate_hz)
    info = RecordInfo(rec.n_samples, rec.rate_hz, rec.site, rec.path, rec.truth, rec.scenario, rec.gimbal is not None,
                      rec.temperature)
    write_stream(path, info, [(rec.time, rec.dtheta, rec.dvel, rec.gimbal)], overwrite)


# ----------------------------------------------------------------------------- reading
def read_rate(h5, path) -> float:
    """The sample rate [Hz] of an open record (root attribute ``rate_hz``), or a :class:`DataFileError`
    naming ``path`` when it is missing or not a number."""
    if "rate_hz" not in h5.attrs:
        raise DataFileError(f"{path}: missing attribute rate_hz (not an inscal record, or a damaged one)")
    try:
        return float(h5.attrs["rate_hz"])
    except (TypeError, ValueError):
        raise DataFileError(f"{path}: attribute rate_hz is not a number") from None


#: what HDF5 and the decoding of a damaged file raise (h5py: OSError, RuntimeError, KeyError, ...)
_DAMAGE = (OSError, RuntimeError, KeyError, ValueError, TypeError, IndexError, AttributeError, UnicodeDecodeError,
           OverflowError)


@contextmanager
def reading(path):
    """Turn the errors of a damaged file (HDF5 metadata, attributes that do not decode) into one
    :class:`DataFileError` that names the file."""
    try:
        yield
    except DataFileError:
        raise
    except _DAMAGE as exc:
        msg = " ".join(str(exc).split())
        raise DataFileError(f"{path}: damaged or not an inscal record ({type(exc).__name__}: "
                            f"{msg[:200] + '...' if len(msg) > 200 else msg})") from None


def open_checked(path) -> h5py.File:
    """The record at ``path`` open for reading, its header checked (kind, schema version, units, the
    datasets every record has); the caller closes it.  Anything else is one :class:`DataFileError`."""
    p = Path(path)
    check_input(p, "file", DataFileError)  # a FIFO would block h5py forever
    try:
        h5 = h5py.File(p, "r")
    except OSError as exc:
        raise DataFileError(f"{p}: not a readable HDF5 file (truncated or not HDF5?): {exc}") from None
    try:
        with reading(p):
            _check_header(h5, p)
    except BaseException:
        h5.close()
        raise
    return h5


def _check_header(h5, p) -> None:
    kind = h5.attrs.get("kind", "")
    if kind != KIND:
        raise DataFileError(f"{p}: not an inscal record (kind={kind!r})")
    ver = int(h5.attrs.get("schema_version", -1))
    if ver != SCHEMA_VERSION:
        raise DataFileError(f"{p}: schema version {ver}, this inscal ({__version__}) reads version {SCHEMA_VERSION}")
    units = json.loads(h5.attrs.get("units", "{}"))
    if not isinstance(units, dict):
        raise DataFileError(f"{p}: attribute units is not a JSON table")
    for k, u in UNITS.items():
        if k in h5 and units.get(k) != u:
            raise DataFileError(f"{p}: dataset {k} is in {units.get(k)!r}, expected {u!r}")
    for k in ("time", "dtheta", "dvel", "site"):
        if k not in h5:
            raise DataFileError(f"{p}: missing /{k}")


#: the groups of /truth and the dataclass each holds (every field required, see :func:`_read_truth`)
def truth_groups() -> dict:
    """The dataclass each group of a record's ``/truth`` holds.

    Returns
    -------
    dict
        ``{"imu": ImuErrors, "gimbal": GimbalErrors, "noise": ImuNoise}``.

    Examples
    --------
    >>> from inscal.io import truth_groups
    >>> sorted(truth_groups())
    ['gimbal', 'imu', 'noise']
    """
    from inscal.core.error_model import GimbalErrors, ImuErrors, ImuNoise

    return {"imu": ImuErrors, "gimbal": GimbalErrors, "noise": ImuNoise}


def _read_dataclass(group, cls, where: str = ""):
    """Every field of ``cls`` from the datasets of ``group``.  A missing field is an error that
    names it: the truth is optional as a whole (measured records have none), but a partial
    truth is never completed with silent zeros."""
    names = [f.name for f in dataclasses.fields(cls)]
    keys = set(group.keys())
    unknown = keys - set(names)
    if unknown:
        raise DataFileError(f"{where}truth{group.name.removeprefix('/truth')}: unknown parameters {sorted(unknown)} "
                            "(file from another version?)")
    missing = [n for n in names if n not in keys]
    if missing:
        raise DataFileError(f"{where}partial truth: {group.name} lacks {', '.join(missing)} (a record's truth is "
                            "complete or absent; delete /truth to use it as a measured record)")
    kw = {}
    for k in names:
        ds = group[k]
        if not isinstance(ds, h5py.Dataset) or not np.issubdtype(ds.dtype, np.number):
            raise DataFileError(f"{where}truth {group.name}/{k} is not a numeric dataset (SI units)")
        v = ds[()]
        kw[k] = float(v) if np.ndim(v) == 0 else np.asarray(v, dtype=float)
    try:
        return cls(**kw)
    except (TypeError, ValueError) as exc:
        raise DataFileError(f"{where}truth {group.name}: {exc}") from None


def _read_truth(h5, p) -> "Truth | None":
    """The /truth group (None when absent); an incomplete one is a :class:`DataFileError`."""
    if "truth" not in h5:
        return None
    t = h5["truth"]
    missing = []
    for g, cls in truth_groups().items():
        if g not in t or not isinstance(t[g], h5py.Group):
            missing.append(f"{g}/ (all of it)")
        else:
            missing += [f"{g}/{f.name}" for f in dataclasses.fields(cls) if f.name not in t[g]]
    if missing:
        raise DataFileError(f"{p}: partial truth: /truth lacks {', '.join(missing)} (a record's truth is complete "
                            "or absent; delete /truth to use it as a measured record)")
    parts = {g: _read_dataclass(t[g], cls, where=f"{p}: ") for g, cls in truth_groups().items()}
    thermal = _read_thermal(t["thermal"], p) if "thermal" in t else None
    return Truth(parts["imu"], parts["gimbal"], parts["noise"], thermal)


def _read_thermal(group, p) -> "ThermalModel":
    from inscal.core.thermal import THERMAL_TERMS, ThermalModel

    if not isinstance(group, h5py.Group):
        raise DataFileError(f"{p}: /truth/thermal is not a group")
    names = (*THERMAL_TERMS, "gyro_bias_rate")
    unknown = set(group.keys()) - set(names)
    if unknown:
        raise DataFileError(f"{p}: truth/thermal: unknown terms {sorted(unknown)} (file from another version?)")
    kw = {k: np.asarray(group[k][()], dtype=float) for k in names if k in group}
    try:
        return ThermalModel(t_ref=float(group.attrs["t_ref"]), t_min=float(group.attrs.get("t_min", -math.inf)),
                            t_max=float(group.attrs.get("t_max", math.inf)),
                            out_of_range=str(group.attrs.get("out_of_range", "warn")),
                            sensor=str(group.attrs.get("sensor", "")), **kw)
    except (KeyError, TypeError, ValueError) as exc:
        raise DataFileError(f"{p}: truth/thermal: {exc}") from None


def read_temperature(h5, p) -> Temperature | None:
    """The ``/temperature`` readings of an open record, validated.

    Parameters
    ----------
    h5 : h5py.File
        The open record.
    p : str or pathlib.Path
        Its path, for the messages.

    Returns
    -------
    Temperature or None
        The readings, None when the record has none.

    Raises
    ------
    DataFileError
        A dataset that is not numeric, sensor names that are not a JSON list, readings that do not
        match their times, or readings that fail :func:`validate_temperature`.

    Examples
    --------
    >>> import h5py
    >>> import numpy as np
    >>> from inscal.core.earth import Site
    >>> from inscal.io import Record, Temperature, read_temperature, write_record
    >>> t = np.arange(1, 201) / 100.0
    >>> temp = Temperature(t[::100], np.array([[20.0], [20.1]]), ("case",))
    >>> write_record("warm.h5", Record(t, np.zeros((200, 3)), np.zeros((200, 3)), None, 100.0, Site(0.7),
    ...                                temperature=temp))
    >>> with h5py.File("warm.h5", "r") as h5:
    ...     read_temperature(h5, "warm.h5").sensors
    ('case',)
    """
    if "temperature" not in h5:
        return None
    ds = h5["temperature"]
    if not isinstance(ds, h5py.Dataset) or not np.issubdtype(ds.dtype, np.number):
        raise DataFileError(f"{p}: /temperature is not a numeric dataset (degC)")
    v = np.asarray(ds[()], dtype=float)
    v = v[:, None] if v.ndim == 1 else v
    try:
        raw = ds.attrs.get("sensors")
        sensors = json.loads(raw) if raw else [f"T{i}" for i in range(v.shape[1] if v.ndim == 2 else 1)]
    except (TypeError, ValueError):
        raise DataFileError(f"{p}: /temperature attribute sensors is not a JSON list of names") from None
    if not isinstance(sensors, list):
        raise DataFileError(f"{p}: /temperature attribute sensors is not a JSON list of names")
    if "temperature_time" in h5:
        t = np.asarray(h5["temperature_time"][()], dtype=float)
    else:
        t = np.asarray(h5["time"][()], dtype=float)
        if v.shape[0] != t.shape[0]:
            raise DataFileError(f"{p}: /temperature has {v.shape[0]} readings and no /temperature_time, but the record "
                                f"has {t.shape[0]} samples")
    validate_temperature(t, v, sensors, where=f"{p}: temperature")
    return Temperature(t, v, tuple(sensors))


def read_meta(h5, p) -> tuple[Site, RotationPath | None, Truth | None]:
    """The site, the rotation path (None when not stored) and the truth (None for a measured record) of
    an open record; a stored value that does not decode is a :class:`DataFileError` naming ``p``."""
    from inscal.core.earth import GravityModel, Site
    from inscal.core.turntable import PathError, RotationPath

    s = h5["site"].attrs
    try:
        gm = s.get("gravity_model")
        gravity = GravityModel.from_json(json.loads(gm) if gm else None)
    except (ValueError, TypeError) as exc:
        raise DataFileError(f"{p}: stored gravity model is invalid: {exc}") from None
    site = Site(float(s["latitude_rad"]), float(s["longitude_rad"]), float(s["height_m"]), gravity)
    pj = h5.attrs.get("path", "")
    try:
        path = RotationPath.from_json(pj) if pj else None
    except (PathError, json.JSONDecodeError) as exc:
        raise DataFileError(f"{p}: stored rotation path is invalid: {exc}") from None
    return site, path, _read_truth(h5, p)


def read_record(path) -> Record:
    """Read a whole record into memory, validated (schema version, shapes, NaN, uniform time).

    Parameters
    ----------
    path : str or pathlib.Path
        An inscal HDF5 record.

    Returns
    -------
    Record
        Its samples and metadata (SI).

    Raises
    ------
    DataFileError
        A file that is missing, not an inscal record, of another schema version, damaged or truncated,
        or whose samples fail :func:`validate_arrays`.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.earth import Site
    >>> from inscal.io import Record, read_record, write_record
    >>> t = np.arange(1, 201) / 100.0
    >>> write_record("still.h5", Record(t, np.zeros((200, 3)), np.zeros((200, 3)), None, 100.0, Site(0.7)))
    >>> rec = read_record("still.h5")
    >>> rec.n_samples, rec.rate_hz, rec.gimbal is None
    (200, 100.0, True)
    """
    with open_checked(path) as h5, reading(path):
        try:
            time = h5["time"][()]
            dth = h5["dtheta"][()]
            dv = h5["dvel"][()]
            gim = h5["gimbal"][()] if "gimbal" in h5 else None
        except OSError as exc:
            raise DataFileError(f"{path}: cannot read data (truncated file?): {exc}") from None
        rate = read_rate(h5, path)
        site, p, truth = read_meta(h5, path)
        scen = str(h5.attrs.get("scenario", ""))
        temp = read_temperature(h5, path)
    validate_arrays(time, dth, dv, gim, rate, where=str(path))
    return Record(time, dth, dv, gim, rate, site, p, truth, scen, str(path), temp)


def load_record(path, name=str) -> Record:
    """:func:`read_record` for a command: every failure of a malformed record is one line.

    Parameters
    ----------
    path : str or Path
        The HDF5 record.
    name : callable
        Writes the path and an exception's text into the message (``str``; the command line cuts long
        ones).

    Returns
    -------
    Record
        The record, its increments floating point.

    Raises
    ------
    DataFileError
        A malformed record (a missing attribute, a non-numeric dataset) or increments that are not
        floating point (rad, m/s), in one line.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.earth import Site
    >>> from inscal.io import Record, load_record, write_record
    >>> t = np.arange(1, 101) / 100.0
    >>> write_record("r.h5", Record(t, np.zeros((100, 3)), np.zeros((100, 3)), None, 100.0, Site(0.7)))
    >>> load_record("r.h5").n_samples
    100
    >>> load_record("missing.h5")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    inscal.io.records.DataFileError: ...missing.h5...
    """
    try:
        rec = read_record(path)
    except DataFileError:
        raise
    except (KeyError, TypeError, ValueError) as exc:
        raise DataFileError(f"{name(path)}: not a valid inscal record ({type(exc).__name__}: {name(exc)})") from None
    bad = [n for n in ("dtheta", "dvel") if not np.issubdtype(np.asarray(getattr(rec, n)).dtype, np.floating)]
    if bad:
        raise DataFileError(f"{name(path)}: {', '.join(bad)} must be floating point (rad, m/s), got "
                            f"{np.asarray(getattr(rec, bad[0])).dtype}")
    return rec


def record_info(path) -> RecordInfo:
    """A record's metadata without reading its samples.

    Parameters
    ----------
    path : str or pathlib.Path
        An inscal HDF5 record.

    Returns
    -------
    RecordInfo
        Size, rate, site, path, truth, scenario, gimbal and temperature of the record.

    Raises
    ------
    DataFileError
        A file that is not a readable inscal record, or datasets of the wrong shape or type.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.earth import Site
    >>> from inscal.io import Record, record_info, write_record
    >>> t = np.arange(1, 201) / 100.0
    >>> write_record("still.h5", Record(t, np.zeros((200, 3)), np.zeros((200, 3)), None, 100.0, Site(0.7)))
    >>> info = record_info("still.h5")
    >>> info.n_samples, info.has_gimbal
    (200, False)
    """
    with open_checked(path) as h5, reading(path):
        check_datasets(h5, path)
        site, p, truth = read_meta(h5, path)
        return RecordInfo(int(h5["time"].shape[0]), read_rate(h5, path), site, p, truth,
                          str(h5.attrs.get("scenario", "")), "gimbal" in h5, read_temperature(h5, path), str(path))


#: columns of the sample datasets (None: 1-D)
_COLUMNS = {"time": None, "dtheta": 3, "dvel": 3, "gimbal": 2}


def check_datasets(h5, path) -> int:
    """Check the shapes and types of a record's sample datasets without reading them.

    Parameters
    ----------
    h5 : h5py.File
        The open record.
    path : str or pathlib.Path
        Its path, for the messages.

    Returns
    -------
    int
        The number of samples N (``/time`` is (N,), ``/dtheta`` and ``/dvel`` (N, 3), ``/gimbal`` (N, 2)).

    Raises
    ------
    DataFileError
        A dataset that is not floating point or whose shape does not match ``/time``.

    Examples
    --------
    >>> import h5py
    >>> import numpy as np
    >>> from inscal.io import check_datasets
    >>> with h5py.File("bare.h5", "w") as h5:
    ...     _ = h5.create_dataset("time", data=np.arange(5.0))
    ...     _ = h5.create_dataset("dtheta", data=np.zeros((5, 3)))
    ...     check_datasets(h5, "bare.h5")
    5
    """
    n = None
    for name, cols in _COLUMNS.items():
        if name not in h5:
            continue
        ds = h5[name]
        if not isinstance(ds, h5py.Dataset):
            raise DataFileError(f"{path}: /{name} is not a dataset")
        if not np.issubdtype(ds.dtype, np.floating):
            raise DataFileError(f"{path}: {name} must be floating point (SI units: {UNITS[name]}), got {ds.dtype}")
        if n is None:
            n = int(ds.shape[0]) if len(ds.shape) == 1 else -1
            if n < 0:
                raise DataFileError(f"{path}: time must be a 1-D array, got shape {ds.shape}")
        elif ds.shape != (n, cols):
            raise DataFileError(f"{path}: {name} has shape {ds.shape}, expected ({n}, {cols}) to match time")
    return int(n)

