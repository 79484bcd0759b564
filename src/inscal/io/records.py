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
file is never overwritten unless asked (:mod:`inscal.io.recordfile` writes and reads the file,
:mod:`inscal.io.streaming` reads it piece by piece).

This module holds the record's types (:class:`Record`, :class:`RecordInfo`, :class:`Truth`,
:class:`Temperature`), the checks of its arrays and readings (:func:`validate_arrays`,
:func:`validate_temperature`), and its string attributes read without validating it
(:func:`record_attrs`).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import h5py
import numpy as np

from inscal.core.samples import SampleSpan

if TYPE_CHECKING:  # imported on first use: they pull in scipy and numba (seconds), which reading a record does not need
    from inscal.core.earth import Site
    from inscal.core.error_model import GimbalErrors, ImuErrors, ImuNoise
    from inscal.core.thermal import ThermalModel
    from inscal.core.turntable import RotationPath

#: the root attribute ``kind`` of every record
KIND = "inscal-record"
#: the unit of each dataset (the root attribute ``units``)
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
class Record(SampleSpan):
    """An IMU record in memory (SI), as :func:`~inscal.io.recordfile.read_record` returns it and
    :func:`~inscal.io.recordfile.write_record` writes it.

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

@dataclass
class RecordInfo:
    """A record's metadata without its arrays (what :func:`~inscal.io.recordfile.record_info` reads,
    :func:`~inscal.io.recordfile.write_stream` writes).

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
