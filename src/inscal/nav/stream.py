"""Streams of IMU increments for the navigator: records in chunks, their compensation by a
parameter set on the fly, and the thermal model's inverse applied from the record's temperature.

Thermal compensation (:class:`ThermalCompensation`): when a parameter set comes with a thermal model
(:mod:`inscal.core.thermal`), each sample's increments are first mapped to the reference temperature
with :meth:`~inscal.core.thermal.ThermalModel.to_reference`, at the temperature and dT/dt of the
middle of the sample interval (:func:`~inscal.core.thermal.sample_temperature`: the readings of the
model's sensor interpolated, dT/dt their least-squares slope over a window computed once on the whole
series), and then compensated with the base errors as before.  Every sample is mapped on its own, so
any chunking of the record gives the same numbers.
"""

from __future__ import annotations

import math
from typing import Iterable, Iterator

import numpy as np

from inscal.core.error_model import ImuErrors
from inscal.core.thermal import (
    ThermalError,
    ThermalModel,
    sample_temperature,
    temperature_rate,
)


# =============================================================================== streams
class SampleStream:
    """A stream of IMU samples over an iterable of ``(time, dtheta, dvel, gimbal)`` chunks.

    ``take(n)`` returns the next ``n`` samples (concatenated across chunks), ``chunks()`` the rest,
    chunk by chunk, and ``peek()`` the next chunk without consuming it.

    Parameters
    ----------
    chunks : iterable
        ``(time, dtheta, dvel, gimbal)`` tuples, or the simulator's chunks (with those attributes).

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.nav import SampleStream
    >>> t = np.arange(1, 11) / 10.0
    >>> stream = SampleStream([(t[:6], np.zeros((6, 3)), np.zeros((6, 3)), None),
    ...                        (t[6:], np.zeros((4, 3)), np.zeros((4, 3)), None)])
    >>> stream.take(8)[0].shape
    (8,)
    >>> [c[0].tolist() for c in stream.chunks()]
    [[0.9, 1.0]]
    """

    def __init__(self, chunks: Iterable):
        self._it = iter(chunks)
        self._pending = None

    def _next(self):
        if self._pending is not None:
            p, self._pending = self._pending, None
            return p
        c = next(self._it)
        if hasattr(c, "dtheta"):  # simulate.Chunk
            c = (c.time, c.dtheta, c.dvel, c.gimbal)
        return c

    def peek(self):
        """The next chunk without consuming it (None at the end)."""
        if self._pending is None:
            try:
                self._pending = self._next()
            except StopIteration:
                return None
        return self._pending

    def take(self, n: int):
        """The next ``n`` samples as one ``(time, dtheta, dvel, gimbal)`` tuple (fewer at the end; None when none are left)."""
        parts, have = [], 0
        while have < n:
            try:
                t, dth, dv, g = self._next()
            except StopIteration:
                break
            need = n - have
            if t.shape[0] > need:
                self._pending = (t[need:], dth[need:], dv[need:], None if g is None else g[need:])
                t, dth, dv, g = t[:need], dth[:need], dv[:need], None if g is None else g[:need]
            parts.append((t, dth, dv, g))
            have += t.shape[0]
        if not parts:
            return None
        g = None if any(p[3] is None for p in parts) else np.concatenate([p[3] for p in parts])
        return (np.concatenate([p[0] for p in parts]), np.concatenate([p[1] for p in parts]),
                np.concatenate([p[2] for p in parts]), g)

    def chunks(self) -> Iterator:
        """The remaining samples, chunk by chunk."""
        while True:
            try:
                yield self._next()
            except StopIteration:
                return


def chunks_of(data, chunk_size: int = 1 << 19) -> Iterator:
    """Chunk tuples from an in-memory record, for the navigator's streams.

    Parameters
    ----------
    data : Record or SimData
        Anything with ``time``, ``dtheta``, ``dvel`` and ``gimbal`` arrays.
    chunk_size : int
        Samples per chunk.

    Yields
    ------
    tuple of numpy.ndarray
        ``(time, dtheta, dvel, gimbal)`` slices (``gimbal`` None when the record has none).

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.earth import Site
    >>> from inscal.io import Record
    >>> from inscal.nav import chunks_of
    >>> t = np.arange(1, 11) / 10.0
    >>> rec = Record(t, np.zeros((10, 3)), np.zeros((10, 3)), None, 10.0, Site(0.7))
    >>> [len(c[0]) for c in chunks_of(rec, chunk_size=4)]
    [4, 4, 2]
    """
    n = data.time.shape[0]
    for k in range(0, n, chunk_size):
        sl = slice(k, k + chunk_size)
        yield data.time[sl], data.dtheta[sl], data.dvel[sl], None if data.gimbal is None else data.gimbal[sl]


def compensated_chunks(chunks, params: ImuErrors, dt: float):
    """Chunks compensated with a parameter set, one chunk of look-ahead.

    The compensation of a sample uses its neighbours (time asynchrony, size effect), so each chunk is
    compensated knowing the last sample of the one before and the first of the one after: any chunking
    gives the same numbers.

    Parameters
    ----------
    chunks : iterable of tuple
        ``(time, dtheta, dvel, gimbal)`` chunks in order.
    params : ImuErrors
        The errors to remove (:meth:`~inscal.core.error_model.ImuErrors.compensate_increments`).
    dt : float
        The sample interval [s].

    Yields
    ------
    tuple of numpy.ndarray
        ``(time, dtheta, dvel, gimbal)`` with the increments compensated.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.error_model import ImuErrors
    >>> from inscal.nav import compensated_chunks
    >>> bias = ImuErrors(gyro_bias=np.array([1e-6, 0.0, 0.0]))
    >>> chunk = (np.array([0.1, 0.2]), np.full((2, 3), 1e-7), np.zeros((2, 3)), None)
    >>> (_, dth, _, _), = compensated_chunks([chunk], bias, 0.1)
    >>> np.round(dth[:, 0] * 1e7, 6).tolist()  # 1e-7 rad minus 1e-6 rad/s * 0.1 s
    [0.0, 0.0]
    """
    prev = None
    it = iter(chunks)
    cur = next(it, None)
    while cur is not None:
        nxt = next(it, None)
        t, dth, dv, g = cur
        after = (nxt[1][0], nxt[2][0]) if nxt is not None and len(nxt[1]) else None
        cdth, cdv = params.compensate_increments(dt, dth, dv, prev=prev, next=after)
        if len(dth):
            prev = (dth[-1], dv[-1])
        yield t, cdth, cdv, g
        cur = nxt


# =============================================================================== thermal
#: samples a survey of the temperature evaluates at once (bounded memory on multi-day records)
SURVEY_BLOCK = 1 << 20


def out_of_range_message(model: ThermalModel, n_outside: int, n_samples: int, lo: float, hi: float,
                         where: str = "record") -> str | None:
    """The one line for ``n_outside`` of ``n_samples`` samples outside the model's calibrated range (the
    record spanning ``lo .. hi`` degC), worded for the model's policy; None when none is outside."""
    if n_outside == 0:
        return None
    head = (f"{where}: {n_outside} of {n_samples} samples lie outside the thermal model's calibrated range "
            f"{model.t_min:g} .. {model.t_max:g} degC (the temperature spans {lo:.2f} .. {hi:.2f} degC)")
    if model.out_of_range == "error":
        return f"{head}; not compensated (out_of_range = \"error\")"
    if model.out_of_range == "clamp":
        return f"{head}: the model is evaluated at the range ends there (out_of_range = \"clamp\")"
    return f"{head}: the model is extrapolated there (out_of_range = \"warn\")"


class ThermalCompensation:
    """The inverse thermal model, applied sample by sample.

    Increments measured at the record's temperature become those ``base`` measures at
    ``model.t_ref``: compensate them with ``base`` afterwards.  Outside the calibrated range the
    model's policy applies: ``warn`` extrapolates (counted, see :meth:`message`), ``clamp`` evaluates at
    the range ends, ``error`` raises :class:`~inscal.core.thermal.ThermalError`.

    Parameters
    ----------
    model : ThermalModel
        The thermal coefficients, reference temperature and range.
    base : ImuErrors or None
        The errors at ``t_ref`` (None: none).
    temperature : Temperature, float or callable
        The record's readings (:class:`~inscal.io.records.Temperature`, or anything with its ``time``,
        ``sensors`` and ``series(sensor)``: the series of ``model.sensor``, the mean of the sensors when
        it names none), a constant in degC (dT/dt = 0), or a function ``t -> (T, dT/dt)`` [s -> degC,
        degC/s] evaluated at the middle of each sample interval.
    rate_hz : float
        The sample rate [Hz].
    where : str
        The record's name in messages.

    Raises
    ------
    TypeError
        ``model`` is not a :class:`~inscal.core.thermal.ThermalModel`.
    ValueError
        A rate that is not positive.
    ThermalError
        No temperature, a sensor the readings lack, or a temperature that is not a finite number.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.thermal import ThermalModel
    >>> from inscal.nav import ThermalCompensation
    >>> model = ThermalModel(t_ref=20.0, t_min=10.0, t_max=30.0, gyro_bias=np.array([[1e-8, 0.0, 0.0]]))
    >>> comp = ThermalCompensation(model, None, 25.0, rate_hz=100.0)
    >>> dth, dv = comp.apply(np.array([0.01]), np.zeros((1, 3)), np.zeros((1, 3)))
    >>> round(float(dth[0, 0]) * 1e10, 6)  # 5 degC * 1e-8 rad/s/degC * 0.01 s = 5e-10 rad removed
    -5.0
    >>> comp.summary()["temperature"]
    'constant 25 degC'
    """

    def __init__(self, model: ThermalModel, base: ImuErrors | None, temperature, rate_hz: float,
                 where: str = "record"):
        if not isinstance(model, ThermalModel):
            raise TypeError(f"thermal model expected, got {type(model).__name__}")
        self.model = model
        self.base = base if base is not None else ImuErrors()
        self.rate_hz = float(rate_hz)
        if not (math.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise ValueError(f"rate_hz must be positive, got {rate_hz}")
        self.dt = 1.0 / self.rate_hz
        self.where = where
        self._readings = self._fn = self._const = None
        if temperature is None:
            raise ThermalError(f"{where}: the thermal model needs the temperature of the samples, and none was given "
                               "(the record has no /temperature readings)")
        if hasattr(temperature, "series"):  # io.records.Temperature (the estimators' layer reads no file module)
            try:
                T = temperature.series(model.sensor)
            except ValueError as exc:
                raise ThermalError(f"{where}: {exc}") from None
            self._readings = (temperature.time, T, temperature_rate(temperature.time, T))
            self.source = (f"/temperature sensor {model.sensor}" if model.sensor else
                           "/temperature" + (f" (mean of {len(temperature.sensors)} sensors)"
                                             if len(temperature.sensors) > 1 else f" sensor {temperature.sensors[0]}"))
        elif callable(temperature):
            self._fn = temperature
            self.source = "a temperature function"
        else:
            try:
                c = float(temperature)
            except (TypeError, ValueError):
                raise ThermalError(f"temperature: a number of degC expected, got {temperature!r}") from None
            if not math.isfinite(c):
                raise ThermalError(f"temperature: a finite number of degC expected, got {temperature!r}")
            self._const = c
            self.source = f"constant {c:g} degC"
        self.n_samples = 0
        self.n_outside = 0
        self.lo, self.hi = math.inf, -math.inf

    def at(self, t) -> tuple[np.ndarray, np.ndarray]:
        """Temperature [degC] and dT/dt [degC/s] of the samples that end at times ``t`` (the middle of
        each sample interval); a record whose readings do not cover the samples is a ThermalError."""
        t = np.asarray(t, dtype=float)
        if self._readings is not None:
            tt, T, rate = self._readings
            return sample_temperature(t, self.rate_hz, tt, T, rate, where=self.where)
        if self._fn is not None:
            T, rate = self._fn(t - 0.5 * self.dt)
            return (np.broadcast_to(np.asarray(T, dtype=float), t.shape),
                    np.broadcast_to(np.asarray(rate, dtype=float), t.shape))
        return np.full(t.shape, self._const), np.zeros(t.shape)

    def apply(self, t, dth, dv) -> tuple[np.ndarray, np.ndarray]:
        """The increments of the samples ending at ``t`` mapped to ``t_ref`` (counted for :meth:`summary`)."""
        T, rate = self.at(t)
        if T.size:
            n_out = self.model.outside(T)
            self.n_samples += int(T.size)
            self.n_outside += n_out
            self.lo, self.hi = min(self.lo, float(np.min(T))), max(self.hi, float(np.max(T)))
            if n_out and self.model.out_of_range == "error":
                raise ThermalError(out_of_range_message(self.model, n_out, int(T.size), float(np.min(T)),
                                                        float(np.max(T)), self.where))
        return self.model.to_reference(self.base, self.dt, dth, dv, self.model.effective(T), rate)

    def survey(self, t_first: float, n: int) -> dict:
        """The temperature of ``n`` samples from ``t_first`` on the record's nominal grid, checked before
        any work: coverage by the readings and, with ``out_of_range = "error"``, the calibrated range
        (ThermalError with the one line).  Returns ``{"samples", "samples_outside", "seen_c", "message"}``."""
        n_out, lo, hi = 0, math.inf, -math.inf
        for k0 in range(0, int(n), SURVEY_BLOCK):
            T, _ = self.at(float(t_first) + np.arange(k0, min(int(n), k0 + SURVEY_BLOCK)) * self.dt)
            n_out += self.model.outside(T)
            lo, hi = min(lo, float(np.min(T))), max(hi, float(np.max(T)))
        msg = out_of_range_message(self.model, n_out, int(n), lo, hi, self.where)
        if msg is not None and self.model.out_of_range == "error":
            raise ThermalError(msg)
        return {"samples": int(n), "samples_outside": n_out, "seen_c": [lo, hi], "message": msg}

    def message(self) -> str | None:
        """The out-of-range line of the samples mapped so far (None when all were in range)."""
        return out_of_range_message(self.model, self.n_outside, self.n_samples, self.lo, self.hi, self.where)

    def summary(self) -> dict:
        """What was applied, for reports and a compensated record's ``compensated_with`` (JSON-ready)."""
        m = self.model
        rng = [v if math.isfinite(v) else None for v in (m.t_min, m.t_max)]  # None: unbounded
        return {"t_ref_c": m.t_ref, "range_c": rng, "out_of_range": m.out_of_range,
                "sensor": m.sensor, "temperature": self.source, "samples": self.n_samples,
                "samples_outside": self.n_outside,
                "seen_c": [self.lo, self.hi] if self.n_samples else None}


def thermal_chunks(chunks, comp: ThermalCompensation) -> Iterator:
    """Chunks mapped to the thermal model's reference temperature.

    Parameters
    ----------
    chunks : iterable
        ``(time, dtheta, dvel, gimbal)`` chunks (or the simulator's chunks).
    comp : ThermalCompensation
        The inverse thermal model and the record's temperature.

    Yields
    ------
    tuple of numpy.ndarray
        ``(time, dtheta, dvel, gimbal)`` with the increments at ``t_ref``.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.core.thermal import ThermalModel
    >>> from inscal.nav import ThermalCompensation, thermal_chunks
    >>> comp = ThermalCompensation(ThermalModel(t_ref=20.0), None, 20.0, rate_hz=10.0)
    >>> chunk = (np.array([0.1, 0.2]), np.full((2, 3), 1e-6), np.zeros((2, 3)), None)
    >>> [c[1].shape for c in thermal_chunks([chunk], comp)]
    [(2, 3)]
    """
    for c in chunks:
        if hasattr(c, "dtheta"):  # simulate.Chunk
            c = (c.time, c.dtheta, c.dvel, c.gimbal)
        t, dth, dv, g = c
        a, b = comp.apply(t, dth, dv)
        yield t, a, b, g
