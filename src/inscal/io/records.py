"""Data files: IMU records in HDF5 (simulated or recorded).

Layout (schema version :data:`inscal.SCHEMA_VERSION`)::

    /                attrs: kind="inscal-record", schema_version, inscal_version, created,
                            scenario, rate_hz, units (JSON: dataset -> unit), path (JSON or "")
    /time            (N,)   s       end time of each increment interval
    /dtheta          (N, 3) rad     angular increments, IMU s-frame
    /dvel            (N, 3) m/s     velocity increments, IMU s-frame
    /gimbal          (N, 2) rad     recorded gimbal angles (outer, inner) at /time (optional)
    /site            attrs: latitude_rad, longitude_rad, height_m, gravity_model (JSON
                            {"kind": "wgs84"|"psins"|"measured", "value": m/s^2 or null};
                            absent: wgs84)
    /truth           (simulated data only) groups imu/, gimbal/, noise/ with SI datasets, and
                     thermal/ (optional: the thermal model, :mod:`inscal.core.thermal`; attrs t_ref,
                     t_min, t_max; one (order, size) dataset per term, SI per degC^k)
    /temperature     (M, S) degC  optional: S temperature sensors; attrs sensors (JSON list of names)
    /temperature_time (M,)  s     the sensors' own times (absent: /time, then M = N)

Files are written to a temporary name in the same folder and renamed when complete,
so a crash never leaves a half-written file under the requested name, and an existing
file is never overwritten unless asked.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import math
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Iterator

import h5py
import numpy as np

from inscal import SCHEMA_VERSION, __version__

if TYPE_CHECKING:  # imported on first use: they pull in scipy and numba (seconds), which reading a record does not need
    from inscal.core.earth import Site
    from inscal.core.error_model import GimbalErrors, ImuErrors, ImuNoise
    from inscal.core.thermal import ThermalModel
    from inscal.core.turntable import RotationPath


import bisect

from inscal.core.cancel import check_cancel
from inscal.io.files import atomic_path, check_input

#: names this module re-exports from the domain modules, imported on first use (PEP 562)
KIND = "inscal-record"
UNITS = {"time": "s", "dtheta": "rad", "dvel": "m/s", "gimbal": "rad", "temperature": "degC", "temperature_time": "s"}
#: temperatures (degC) outside this span are refused as implausible (kelvin or a raw sensor count?)
TEMPERATURE_SPAN = (-100.0, 200.0)


class DataFileError(ValueError):
    """A data file that cannot be used, with the reason (a ``ValueError``: one line naming the file).

    Examples
    --------
    >>> from inscal.io import DataFileError, read_record
    >>> try:
    ...     read_record("no-such-record.h5")
    ... except DataFileError as exc:
    ...     print("refused")
    refused
    """


@dataclass(frozen=True)
class Truth:
    """What a simulated record was made with (SI): the ``/truth`` group of the record.

    Parameters
    ----------
    imu : ImuErrors
        The IMU errors (at the thermal model's reference temperature when there is one).
    gimbal : GimbalErrors
        The gimbal errors (non-orthogonality, mount attitude).
    noise : ImuNoise
        The sensor noise the samples were drawn with.
    thermal : ThermalModel or None
        The thermal model the IMU errors follow, if any.

    Examples
    --------
    >>> from inscal.core.error_model import GimbalErrors, ImuErrors, ImuNoise
    >>> from inscal.io import Truth
    >>> truth = Truth(ImuErrors(), GimbalErrors(), ImuNoise())
    >>> truth.thermal is None
    True
    """
    imu: ImuErrors
    gimbal: GimbalErrors
    noise: ImuNoise
    thermal: ThermalModel | None = None  # the IMU errors follow the temperature (``imu`` = at T_ref)


@dataclass(frozen=True)
class Temperature:
    """Temperature sensor readings of a record, one column per sensor.

    Parameters
    ----------
    time : numpy.ndarray
        (M,) times of the readings [s] on the record's clock, increasing.
    values : numpy.ndarray
        (M, S) readings [degC] (a 1-D array is one sensor).
    sensors : tuple of str
        The S sensor names, distinct.

    Raises
    ------
    DataFileError
        Shapes that do not match, NaN/inf, time that does not increase, or readings outside
        -100 .. 200 degC (kelvin?).

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.io import Temperature
    >>> temp = Temperature(np.array([0.0, 10.0]), np.array([[20.0, 22.0], [21.0, 23.0]]), ("a", "b"))
    >>> temp.series("b").tolist(), temp.series().tolist()
    ([22.0, 23.0], [21.0, 22.0])
    """

    time: np.ndarray
    values: np.ndarray
    sensors: tuple[str, ...]

    def __post_init__(self):
        object.__setattr__(self, "sensors", tuple(str(x) for x in self.sensors))
        v = np.asarray(self.values, dtype=float)
        object.__setattr__(self, "values", v[:, None] if v.ndim == 1 else v)
        object.__setattr__(self, "time", np.asarray(self.time, dtype=float))
        validate_temperature(self.time, self.values, self.sensors)

    def series(self, sensor: str = "") -> np.ndarray:
        """The readings of ``sensor`` (M,), or the mean of the sensors when ``sensor`` is empty."""
        if sensor:
            if sensor not in self.sensors:
                raise DataFileError(f"no temperature sensor {sensor!r} in the record (it has {', '.join(self.sensors)})")
            return self.values[:, self.sensors.index(sensor)]
        return self.values.mean(axis=1)


def validate_temperature(time, values, sensors, where: str = "temperature") -> None:
    """Check temperature readings: shapes, finiteness, increasing time and a plausible Celsius range.

    Parameters
    ----------
    time : array_like
        (M,) times of the readings [s].
    values : array_like
        (M, S) readings [degC].
    sensors : sequence of str
        The S sensor names.
    where : str
        What the message names as the place of a fault.

    Raises
    ------
    DataFileError
        One line saying what is wrong and where (the first faulty reading).

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.io import DataFileError, validate_temperature
    >>> validate_temperature(np.array([0.0, 1.0]), np.array([[20.0], [20.5]]), ["case"])
    >>> try:
    ...     validate_temperature(np.array([0.0, 1.0]), np.array([[293.1], [293.2]]), ["case"])
    ... except DataFileError as exc:
    ...     print(exc)
    temperature: readings 293.1 .. 293.2 degC lie outside the plausible -100 .. 200 degC (kelvin? give the column's unit as K)
    """
    t = np.asarray(time)
    v = np.asarray(values)
    if t.ndim != 1 or t.shape[0] < 1:
        raise DataFileError(f"{where}: time must be a non-empty 1-D array, got shape {t.shape}")
    if v.ndim != 2 or v.shape[0] != t.shape[0] or v.shape[1] < 1:
        raise DataFileError(f"{where}: values have shape {v.shape}, expected ({t.shape[0]}, sensors) to match its time")
    if len(sensors) != v.shape[1]:
        raise DataFileError(f"{where}: {v.shape[1]} column(s) but {len(sensors)} sensor name(s)")
    if len(set(sensors)) != len(sensors):
        raise DataFileError(f"{where}: sensor names repeat ({', '.join(sensors)})")
    for name, a in (("time", t), ("values", v)):
        if not np.issubdtype(a.dtype, np.number):
            raise DataFileError(f"{where}: {name} is not numeric ({a.dtype})")
        bad = ~np.isfinite(a.astype(float))
        if bad.any():
            idx = int(np.argmax(bad.reshape(t.shape[0], -1).any(axis=1)))
            raise DataFileError(f"{where}: {int(bad.sum())} NaN/inf {name}, first at reading {idx}")
    if t.shape[0] > 1:
        d = np.diff(t.astype(float))
        if np.any(d <= 0):
            k = int(np.argmax(d <= 0))
            raise DataFileError(f"{where}: time does not increase at reading {k + 1} (t = {t[k + 1]} s after {t[k]} s)")
    lo, hi = float(np.min(v)), float(np.max(v))
    if lo < TEMPERATURE_SPAN[0] or hi > TEMPERATURE_SPAN[1]:
        hint = " (kelvin? give the column's unit as K)" if hi > 200.0 and lo > 150.0 else ""
        raise DataFileError(f"{where}: readings {lo:g} .. {hi:g} degC lie outside the plausible "
                            f"{TEMPERATURE_SPAN[0]:g} .. {TEMPERATURE_SPAN[1]:g} degC{hint}")


@dataclass
class Record:
    """An IMU record in memory (SI), as :func:`read_record` returns it and :func:`write_record` writes it.

    Parameters
    ----------
    time : numpy.ndarray
        (N,) end time of each increment interval [s], uniform at ``rate_hz``.
    dtheta : numpy.ndarray
        (N, 3) angular increments in the IMU s-frame [rad].
    dvel : numpy.ndarray
        (N, 3) velocity increments in the IMU s-frame [m/s].
    gimbal : numpy.ndarray or None
        (N, 2) gimbal angles (outer, inner) [rad], None for a strapdown record.
    rate_hz : float
        The sample rate [Hz].
    site : Site
        Where the record was made (latitude, longitude, height, gravity model).
    path : RotationPath or None
        The turntable's rotation path, if known.
    truth : Truth or None
        What a simulated record was made with (None for measured data).
    scenario : str
        The scenario's name ("" when none).
    source : str
        The file it was read from ("" when built in memory).
    temperature : Temperature or None
        Temperature sensor readings, if any.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.earth import Site
    >>> from inscal.io import Record
    >>> t = np.arange(1, 201) / 100.0
    >>> rec = Record(t, np.zeros((200, 3)), np.zeros((200, 3)), None, 100.0, Site(np.radians(45.0)))
    >>> rec.n_samples, rec.duration
    (200, 2.0)
    """

    time: np.ndarray
    dtheta: np.ndarray
    dvel: np.ndarray
    gimbal: np.ndarray | None
    rate_hz: float
    site: Site
    path: RotationPath | None = None
    truth: Truth | None = None
    scenario: str = ""
    source: str = ""
    temperature: Temperature | None = None

    @property
    def n_samples(self) -> int:
        """The number of samples N."""
        return int(self.time.shape[0])

    @property
    def duration(self) -> float:
        """The record's length N / rate [s]."""
        return float(self.n_samples / self.rate_hz)


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
def _rate(h5, path) -> float:
    if "rate_hz" not in h5.attrs:
        raise DataFileError(f"{path}: missing attribute rate_hz (not an inscal record, or a damaged one)")
    try:
        return float(h5.attrs["rate_hz"])
    except (TypeError, ValueError):
        raise DataFileError(f"{path}: attribute rate_hz is not a number") from None


def validate_arrays(time, dtheta, dvel, gimbal, rate_hz, where: str = "record") -> None:
    """Check a record's arrays: shapes, floating point, finiteness and a uniform time grid.

    Parameters
    ----------
    time : array_like
        (N,) sample times [s].
    dtheta, dvel : array_like or None
        (N, 3) increments (None: not checked).
    gimbal : array_like or None
        (N, 2) gimbal angles (None: not checked).
    rate_hz : float
        The nominal rate; every time step must be within 1 % of ``1 / rate_hz``.
    where : str
        What the message names as the place of a fault.

    Raises
    ------
    DataFileError
        One line saying what is wrong, with the first faulty sample and its time.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.io import DataFileError, validate_arrays
    >>> t = np.array([0.01, 0.02, 0.04])
    >>> try:
    ...     validate_arrays(t, None, None, None, 100.0)
    ... except DataFileError as exc:
    ...     print(str(exc)[:60])
    record: time is not uniform at 100 Hz: 1 irregular step(s),
    """
    n = np.shape(time)[0] if np.ndim(time) == 1 else None
    if n is None:
        raise DataFileError(f"{where}: time must be a 1-D array, got shape {np.shape(time)}")
    for name, a, cols in (("dtheta", dtheta, 3), ("dvel", dvel, 3), ("gimbal", gimbal, 2)):
        if a is None:
            continue
        if not np.issubdtype(np.asarray(a).dtype, np.floating):
            raise DataFileError(f"{where}: {name} must be floating point (SI units), got {np.asarray(a).dtype}")
        if np.shape(a) != (n, cols):
            raise DataFileError(f"{where}: {name} has shape {np.shape(a)}, expected ({n}, {cols}) to match time")
    if not (math.isfinite(rate_hz) and rate_hz > 0):
        raise DataFileError(f"{where}: rate_hz must be positive, got {rate_hz}")
    if n < 2:
        raise DataFileError(f"{where}: fewer than 2 samples")
    for name, a in (("time", time), ("dtheta", dtheta), ("dvel", dvel), ("gimbal", gimbal)):
        if a is None:
            continue
        bad = ~np.isfinite(np.asarray(a))
        if bad.any():
            idx = int(np.argmax(bad.reshape(n, -1).any(axis=1)))
            raise DataFileError(f"{where}: {name} has {int(bad.sum())} NaN/inf value(s), first at sample {idx} (t = {time[idx]} s)")
    dt = np.diff(time)
    nominal = 1.0 / rate_hz
    gaps = np.flatnonzero(np.abs(dt - nominal) > 0.01 * nominal)
    if gaps.size:
        k = int(gaps[0])
        raise DataFileError(
            f"{where}: time is not uniform at {rate_hz:g} Hz: {gaps.size} irregular step(s), first between "
            f"t = {time[k]:.6f} s and {time[k + 1]:.6f} s (step {dt[k]:.6g} s, expected {nominal:.6g} s)"
        )


#: what HDF5 and the decoding of a damaged file raise (h5py: OSError, RuntimeError, KeyError, ...)
_DAMAGE = (OSError, RuntimeError, KeyError, ValueError, TypeError, IndexError, AttributeError, UnicodeDecodeError,
           OverflowError)


@contextmanager
def _reading(path):
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


def _open(path) -> h5py.File:
    p = Path(path)
    check_input(p, "file", DataFileError)  # a FIFO would block h5py forever
    try:
        h5 = h5py.File(p, "r")
    except OSError as exc:
        raise DataFileError(f"{p}: not a readable HDF5 file (truncated or not HDF5?): {exc}") from None
    try:
        with _reading(p):
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


def _meta(h5, p):
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
    with _open(path) as h5, _reading(path):
        try:
            time = h5["time"][()]
            dth = h5["dtheta"][()]
            dv = h5["dvel"][()]
            gim = h5["gimbal"][()] if "gimbal" in h5 else None
        except OSError as exc:
            raise DataFileError(f"{path}: cannot read data (truncated file?): {exc}") from None
        rate = _rate(h5, path)
        site, p, truth = _meta(h5, path)
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


@dataclass
class RecordInfo:
    """A record's metadata without its arrays (what :func:`record_info` reads, :func:`write_stream` writes).

    Parameters
    ----------
    n_samples : int
        The number of samples N.
    rate_hz : float
        The sample rate [Hz].
    site : Site
        Where the record was made.
    path : RotationPath or None
        The turntable's rotation path, if known.
    truth : Truth or None
        What a simulated record was made with.
    scenario : str
        The scenario's name.
    has_gimbal : bool
        Whether the record has gimbal angles.
    temperature : Temperature or None
        Temperature readings, if any.
    source : str
        The file the metadata was read from ("" when built in memory).

    Examples
    --------
    >>> from inscal.core.earth import Site
    >>> from inscal.io import RecordInfo
    >>> info = RecordInfo(1000, 100.0, Site(0.7), None, None, "", has_gimbal=False)
    >>> info.n_samples / info.rate_hz
    10.0
    """
    n_samples: int
    rate_hz: float
    site: Site
    path: RotationPath | None
    truth: Truth | None
    scenario: str
    has_gimbal: bool
    temperature: Temperature | None = None
    #: the file the metadata was read from ("" when built in memory)
    source: str = ""


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
    with _open(path) as h5, _reading(path):
        check_datasets(h5, path)
        site, p, truth = _meta(h5, path)
        return RecordInfo(int(h5["time"].shape[0]), _rate(h5, path), site, p, truth,
                          str(h5.attrs.get("scenario", "")), "gimbal" in h5, read_temperature(h5, path), str(path))


def iter_chunks(path, chunk_size: int = 1 << 19) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]]:
    """The samples of a record in chunks, each validated, one chunk in memory (multi-day records).

    Parameters
    ----------
    path : str or pathlib.Path
        An inscal HDF5 record.
    chunk_size : int
        Samples per chunk.

    Yields
    ------
    tuple of numpy.ndarray
        ``(time, dtheta, dvel, gimbal)`` of each chunk (``gimbal`` None when the record has none).

    Raises
    ------
    DataFileError
        A file that is not a readable record, samples that cannot be read, NaN/inf, or a time grid
        that is not uniform (across chunk boundaries too).

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.earth import Site
    >>> from inscal.io import Record, iter_chunks, write_record
    >>> t = np.arange(1, 201) / 100.0
    >>> write_record("still.h5", Record(t, np.zeros((200, 3)), np.zeros((200, 3)), None, 100.0, Site(0.7)))
    >>> [len(time) for time, dtheta, dvel, gimbal in iter_chunks("still.h5", chunk_size=64)]
    [64, 64, 64, 8]
    """
    with _open(path) as h5, _reading(path):
        rate = _rate(h5, path)
        n = h5["time"].shape[0]
        last_t = None
        for k0 in range(0, n, chunk_size):
            check_cancel()
            sl = slice(k0, min(n, k0 + chunk_size))
            try:
                t = h5["time"][sl]
                dth = h5["dtheta"][sl]
                dv = h5["dvel"][sl]
                g = h5["gimbal"][sl] if "gimbal" in h5 else None
            except OSError as exc:
                raise DataFileError(f"{path}: cannot read samples {sl.start}..{sl.stop} (truncated file?): {exc}") from None
            tt = t if last_t is None else np.concatenate([[last_t], t])
            if tt.shape[0] >= 2:
                validate_arrays(tt, None, None, None, rate, where=f"{path} samples {sl.start}..{sl.stop}")
            for name, a in (("dtheta", dth), ("dvel", dv), ("gimbal", g)):
                if a is not None and not np.all(np.isfinite(a)):
                    raise DataFileError(f"{path}: {name} has NaN/inf in samples {sl.start}..{sl.stop}")
            last_t = t[-1]
            yield t, dth, dv, g


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


@dataclass(frozen=True)
class Window:
    """The samples ``i0 .. i1 - 1`` of a record whose time lies in ``(start_s, stop_s]`` (:func:`record_window`).

    Parameters
    ----------
    path : str
        The record.
    n_total : int
        The record's number of samples.
    rate_hz : float
        Its sample rate [Hz].
    i0, i1 : int
        The first sample of the window and one past its last.
    has_gimbal : bool
        Whether the record has gimbal angles.

    Examples
    --------
    >>> from inscal.io import Window
    >>> Window("still.h5", 200, 100.0, 50, 150, False).n
    100
    """

    path: str
    n_total: int
    rate_hz: float
    i0: int
    i1: int
    has_gimbal: bool

    @property
    def n(self) -> int:
        """The number of samples in the window, ``i1 - i0``."""
        return self.i1 - self.i0


def record_window(path, start_s: float = 0.0, stop_s: float | None = None) -> Window:
    """Locate the samples with ``start_s < time <= stop_s`` by bisection of ``/time`` (a few reads).

    The samples themselves are validated as they are streamed (:func:`iter_window`).

    Parameters
    ----------
    path : str or pathlib.Path
        An inscal HDF5 record.
    start_s : float
        The window's start [s] (excluded).
    stop_s : float, optional
        The window's end [s] (included); None: the end of the record.

    Returns
    -------
    Window
        The indices of the window and the record's size and rate.

    Raises
    ------
    DataFileError
        A file that is not a readable record, datasets of the wrong shape, or a rate that is not positive.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.earth import Site
    >>> from inscal.io import Record, record_window, write_record
    >>> t = np.arange(1, 201) / 100.0
    >>> write_record("still.h5", Record(t, np.zeros((200, 3)), np.zeros((200, 3)), None, 100.0, Site(0.7)))
    >>> w = record_window("still.h5", 0.5, 1.0)
    >>> w.i0, w.i1, w.n
    (50, 100, 50)
    """

    with _open(path) as h5, _reading(path):
        rate = _rate(h5, path)
        n = check_datasets(h5, path)
        if not (math.isfinite(rate) and rate > 0):
            raise DataFileError(f"{path}: rate_hz must be positive, got {rate}")
        t = h5["time"]
        try:
            i0 = bisect.bisect_right(t, start_s)
            i1 = n if stop_s is None else bisect.bisect_right(t, stop_s)
        except OSError as exc:
            raise DataFileError(f"{path}: cannot read /time (truncated file?): {exc}") from None
        return Window(str(path), n, rate, i0, max(i0, i1), "gimbal" in h5)


def iter_window(path, names: tuple[str, ...], i0: int, i1: int, chunk_size: int = 1 << 18) -> Iterator[tuple]:
    """Stream some datasets of a record over samples ``i0 .. i1 - 1``, one chunk at a time, checked.

    Each chunk is checked for finite values, and ``/time`` for a uniform grid at ``rate_hz``
    (across chunk boundaries too) when ``"time"`` is among ``names``.

    Parameters
    ----------
    path : str or pathlib.Path
        An inscal HDF5 record.
    names : tuple of str
        The datasets to read ("time", "dtheta", "dvel", "gimbal").
    i0, i1 : int
        The first sample and one past the last (e.g. from :func:`record_window`).
    chunk_size : int
        Samples per chunk.

    Yields
    ------
    tuple of numpy.ndarray
        One array per name (None for an absent gimbal).

    Raises
    ------
    DataFileError
        Samples that cannot be read, NaN/inf, or a time grid that is not uniform.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.earth import Site
    >>> from inscal.io import Record, iter_window, write_record
    >>> t = np.arange(1, 201) / 100.0
    >>> write_record("still.h5", Record(t, np.zeros((200, 3)), np.zeros((200, 3)), None, 100.0, Site(0.7)))
    >>> [float(time[0]) for (time,) in iter_window("still.h5", ("time",), 50, 150, chunk_size=50)]
    [0.51, 1.01]
    """
    with _open(path) as h5, _reading(path):
        rate = _rate(h5, path)
        check_datasets(h5, path)
        last_t = None
        for k0 in range(i0, i1, chunk_size):
            check_cancel()
            sl = slice(k0, min(i1, k0 + chunk_size))
            try:
                out = tuple(h5[nm][sl] if nm in h5 else None for nm in names)
            except OSError as exc:
                raise DataFileError(f"{path}: cannot read samples {sl.start}..{sl.stop} (truncated file?): {exc}") from None
            for nm, a in zip(names, out):
                if a is None:
                    continue
                if not np.all(np.isfinite(a)):
                    bad = ~np.isfinite(a.reshape(a.shape[0], -1)).all(axis=1)
                    raise DataFileError(f"{path}: {nm} has NaN/inf value(s), first at sample {sl.start + int(np.argmax(bad))}")
                if nm == "time":
                    tt = a if last_t is None else np.concatenate([[last_t], a])
                    if tt.shape[0] >= 2:
                        validate_arrays(tt, None, None, None, rate, where=f"{path} samples {sl.start}..{sl.stop}")
                    last_t = a[-1]
            yield out


class LazyArray:
    """A record dataset read on demand, the samples staying on disk.

    ``a[i:j]`` reads those rows, ``a[::step]`` / ``a[::step, k]`` reads the decimated rows chunk by
    chunk (contiguous reads, cached per step) for plots; ``np.asarray(a)`` reads it all (avoid it on
    long records).

    Parameters
    ----------
    ds : h5py.Dataset
        The dataset of an open record.
    chunk_size : int
        Rows per contiguous read when decimating.
    where : str
        The file, for the messages of a damaged one (default: the dataset's name).

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.earth import Site
    >>> from inscal.io import Record, open_record, write_record
    >>> t = np.arange(1, 201) / 100.0
    >>> write_record("still.h5", Record(t, np.zeros((200, 3)), np.zeros((200, 3)), None, 100.0, Site(0.7)))
    >>> with open_record("still.h5") as rec:
    ...     lazy = rec.time
    ...     print(type(lazy).__name__, len(lazy), lazy[::50].tolist())
    LazyArray 200 [0.01, 0.51, 1.01, 1.51]
    """

    def __init__(self, ds, chunk_size: int = 1 << 18, where=""):
        self._ds, self._chunk, self._dec, self._where = ds, chunk_size, {}, where or ds.name
        self.shape, self.dtype, self.ndim = ds.shape, ds.dtype, ds.ndim

    def __len__(self) -> int:
        return int(self.shape[0])

    def decimated(self, step: int) -> np.ndarray:
        """Rows 0, step, 2 step, ... (read in contiguous chunks)."""
        if step not in self._dec:
            n, parts = self.shape[0], []
            block = max(step, (self._chunk // step) * step)
            for a in range(0, n, block):
                check_cancel()
                with _reading(self._where):
                    parts.append(self._ds[a:min(n, a + block)][::step].copy())  # not a view of the block
            self._dec[step] = np.concatenate(parts) if parts else self._ds[0:0]
        return self._dec[step]

    def __getitem__(self, key):
        first, rest = (key[0], key[1:]) if isinstance(key, tuple) else (key, ())
        if isinstance(first, slice) and first.step not in (None, 1) and first.start is None and first.stop is None:
            d = self.decimated(int(first.step))
            return d[(slice(None), *rest)] if rest else d
        with _reading(self._where):
            return self._ds[key]

    def __array__(self, dtype=None, copy=None):
        a = self._ds[()]
        return a if dtype is None else a.astype(dtype)


@contextmanager
def open_record(path, validate: bool = True, chunk_size: int = 1 << 19):
    """A :class:`Record` whose samples stay on disk, for reports of multi-day records in bounded memory.

    Its arrays are :class:`LazyArray`; the file is open inside the ``with`` block.

    Parameters
    ----------
    path : str or pathlib.Path
        An inscal HDF5 record.
    validate : bool
        First stream the samples once through the checks of :func:`read_record` (finite values,
        uniform time), one chunk at a time.
    chunk_size : int
        Samples per chunk of that check.

    Yields
    ------
    Record
        The record, with :class:`LazyArray` samples.

    Raises
    ------
    DataFileError
        A file that is not a readable record, a rate that is not positive, fewer than 2 samples, or
        samples that fail the checks.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.earth import Site
    >>> from inscal.io import Record, open_record, write_record
    >>> t = np.arange(1, 201) / 100.0
    >>> write_record("still.h5", Record(t, np.zeros((200, 3)), np.zeros((200, 3)), None, 100.0, Site(0.7)))
    >>> with open_record("still.h5") as rec:
    ...     print(rec.n_samples, rec.dtheta[10:12].shape)
    200 (2, 3)
    """
    with _open(path) as h5:
        with _reading(path):
            n = check_datasets(h5, path)
            rate = _rate(h5, path)
            if not (math.isfinite(rate) and rate > 0):
                raise DataFileError(f"{path}: rate_hz must be positive, got {rate}")
            if n < 2:
                raise DataFileError(f"{path}: fewer than 2 samples")
            site, p, truth = _meta(h5, path)
            scen = str(h5.attrs.get("scenario", ""))
            temp = read_temperature(h5, path)
            if validate:
                for _ in iter_chunks(path, chunk_size):
                    pass
            lazy = {k: LazyArray(h5[k], where=path) for k in ("time", "dtheta", "dvel", "gimbal") if k in h5}
        yield Record(lazy["time"], lazy["dtheta"], lazy["dvel"], lazy.get("gimbal"), rate, site, p, truth, scen, str(path),
                     temp)


def record_attrs(path: RotationPath, names=("scenario", "imu_serial", "compensated_with")) -> dict[str, str | None]:
    """String attributes of a record file, read without validating the record.

    Parameters
    ----------
    path : str or pathlib.Path
        An HDF5 file.
    names : tuple of str
        The attributes to read.

    Returns
    -------
    dict
        ``{name: value}``, None for an attribute that is absent or empty (every name None for a
        file that cannot be read).

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.earth import Site
    >>> from inscal.io import Record, record_attrs, write_record
    >>> t = np.arange(1, 201) / 100.0
    >>> write_record("still.h5", Record(t, np.zeros((200, 3)), np.zeros((200, 3)), None, 100.0, Site(0.7),
    ...                                 scenario="bench"))
    >>> record_attrs("still.h5")
    {'scenario': 'bench', 'imu_serial': None, 'compensated_with': None}
    """

    out = {}
    try:
        with h5py.File(path, "r") as h5:
            for n in names:
                v = h5.attrs.get(n)
                v = v.decode() if isinstance(v, bytes) else (None if v is None else str(v))
                out[n] = v or None
    except (OSError, RuntimeError, KeyError, ValueError, TypeError, AttributeError):  # a damaged file: no attributes
        out = {n: None for n in names}
    return out


def compensated_with(attrs: dict) -> str | None:
    """A short description of a record's ``compensated_with`` attribute (the calibration applied to it).

    Parameters
    ----------
    attrs : dict
        The record's attributes (:func:`record_attrs`).

    Returns
    -------
    str or None
        ``"FILE (METHOD)"``, the raw text when it is not JSON, None when the record was not compensated.

    Examples
    --------
    >>> from inscal.io import compensated_with
    >>> compensated_with({"compensated_with": '{"file": "cal.toml", "method": "n25"}'})
    'cal.toml (n25)'
    >>> compensated_with({}) is None
    True
    """
    raw = attrs.get("compensated_with")
    if not raw:
        return None
    try:
        cw = json.loads(raw)
        return f"{cw.get('file', '?')} ({cw.get('method', '?')})"
    except (ValueError, AttributeError):
        return str(raw)
