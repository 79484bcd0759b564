"""Temperature profiles and temperature sensors for the simulator.

A profile is data: a start temperature and a list of pieces, each one of

* ``hold``: the temperature stays for ``duration_s``;
* ``ramp``: a straight line to ``target_c`` at ``rate_c_per_min`` (a thermal chamber's ramp);
* ``approach``: ``T = target + (T_start - target) exp(-t / tau_s)`` for ``duration_s`` (the warm-up of
  an IMU after turn-on, or a chamber settling onto a plateau).

``T(t)`` and ``dT/dt`` are evaluated in closed form; before the start and after the last piece the
temperature holds.  The sensor model turns the profile into readings: its own rate, a constant offset
per sensor, white noise and quantization (drawn from a generator passed in).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

import numpy as np

from inscal.io.records import Temperature

PIECE_KINDS = ("hold", "ramp", "approach")


@dataclass(frozen=True)
class Piece:
    """One piece of a temperature profile (see the module docstring)."""

    kind: str
    duration_s: float = 0.0
    target_c: float = math.nan
    rate_c_per_min: float = math.nan
    tau_s: float = math.nan

    def __post_init__(self):
        if self.kind not in PIECE_KINDS:
            raise ValueError(f"temperature piece {self.kind!r}: expected one of {', '.join(PIECE_KINDS)}")
        for name in ("duration_s", "target_c", "rate_c_per_min", "tau_s"):
            try:
                object.__setattr__(self, name, float(getattr(self, name)))
            except (TypeError, ValueError):
                raise ValueError(f"temperature {self.kind}: {name} is not a number ({getattr(self, name)!r})") from None
        need = {"hold": ("duration_s",), "ramp": ("target_c", "rate_c_per_min"),
                "approach": ("target_c", "tau_s", "duration_s")}[self.kind]
        for name in need:
            v = float(getattr(self, name))
            if not math.isfinite(v):
                raise ValueError(f"temperature {self.kind}: {name} must be a finite number")
        if self.kind != "ramp" and not self.duration_s >= 0:
            raise ValueError(f"temperature {self.kind}: duration_s must be >= 0")
        if self.kind == "ramp" and not self.rate_c_per_min > 0:
            raise ValueError("temperature ramp: rate_c_per_min must be > 0")
        if self.kind == "approach" and not self.tau_s > 0:
            raise ValueError("temperature approach: tau_s must be > 0")

    def to_json(self) -> dict:
        keys = {"hold": ("duration_s",), "ramp": ("target_c", "rate_c_per_min"),
                "approach": ("target_c", "tau_s", "duration_s")}[self.kind]
        return {"kind": self.kind, **{k: float(getattr(self, k)) for k in keys}}


@dataclass(frozen=True)
class TemperatureProfile:
    """A temperature history: ``start_c`` at t = 0, then ``pieces`` one after the other."""

    start_c: float
    pieces: tuple[Piece, ...] = ()

    def __post_init__(self):
        if not math.isfinite(float(self.start_c)):
            raise ValueError("temperature profile: start_c must be finite")
        object.__setattr__(self, "start_c", float(self.start_c))
        object.__setattr__(self, "pieces", tuple(p if isinstance(p, Piece) else Piece(**p) for p in self.pieces))

    def _table(self):
        """Per piece: (t0, t1, T0, kind, target, slope [degC/s], tau)."""
        rows, t, T = [], 0.0, self.start_c
        for p in self.pieces:
            if p.kind == "hold":
                rows.append((t, t + p.duration_s, T, 0, T, 0.0, 1.0))
                t += p.duration_s
            elif p.kind == "ramp":
                d = abs(p.target_c - T) / (p.rate_c_per_min / 60.0)
                slope = math.copysign(p.rate_c_per_min / 60.0, p.target_c - T) if d > 0 else 0.0
                rows.append((t, t + d, T, 1, p.target_c, slope, 1.0))
                t, T = t + d, p.target_c
            else:
                rows.append((t, t + p.duration_s, T, 2, p.target_c, 0.0, p.tau_s))
                T = p.target_c + (T - p.target_c) * math.exp(-p.duration_s / p.tau_s)
                t += p.duration_s
        return rows, t, T

    @property
    def duration(self) -> float:
        return self._table()[1]

    def at(self, t) -> tuple[np.ndarray, np.ndarray]:
        """``(T, dT/dt)`` [degC, degC/s] at times ``t`` [s]."""
        t = np.asarray(t, dtype=float)
        rows, t_end, T_end = self._table()
        T = np.full(t.shape, float(T_end))
        rate = np.zeros(t.shape)
        T[t <= 0.0] = self.start_c
        for t0, t1, T0, kind, target, slope, tau in rows:
            m = (t > t0) & (t <= t1) if t1 > t0 else np.zeros(t.shape, bool)
            if not np.any(m):
                continue
            x = t[m] - t0
            if kind == 0:
                T[m] = T0
            elif kind == 1:
                T[m] = T0 + slope * x
                rate[m] = slope
            else:
                e = np.exp(-x / tau)
                T[m] = target + (T0 - target) * e
                rate[m] = -(T0 - target) / tau * e
        return T, rate

    def to_json(self) -> str:
        return json.dumps({"start_c": self.start_c, "pieces": [p.to_json() for p in self.pieces]})

    @classmethod
    def from_json(cls, text: str) -> "TemperatureProfile":
        d = json.loads(text) if isinstance(text, str) else text
        if not isinstance(d, dict) or "start_c" not in d:
            raise ValueError("temperature profile: expected {start_c, pieces}")
        unknown = set(d) - {"start_c", "pieces"}
        if unknown:
            raise ValueError(f"temperature profile: unknown keys {sorted(unknown)}")
        return cls(float(d["start_c"]), tuple(Piece(**p) for p in d.get("pieces", [])))


def plateaus(levels_c, soak_s: float, rate_c_per_min: float, start_c: float | None = None,
             dwell_s: float = 0.0) -> tuple[TemperatureProfile, list[tuple[float, float]]]:
    """A thermal chamber stepping through ``levels_c``: ramp at ``rate_c_per_min``, soak ``soak_s``,
    then hold ``dwell_s`` (the calibration at that plateau).  Returns the profile and the
    ``(start, end)`` times [s] of each dwell."""
    start = float(levels_c[0]) if start_c is None else float(start_c)
    pieces, windows, t, T = [], [], 0.0, start
    for lev in levels_c:
        if lev != T:
            pieces.append(Piece("ramp", target_c=float(lev), rate_c_per_min=rate_c_per_min))
            t += abs(lev - T) / (rate_c_per_min / 60.0)
            T = float(lev)
        if soak_s > 0:
            pieces.append(Piece("hold", duration_s=soak_s))
            t += soak_s
        pieces.append(Piece("hold", duration_s=dwell_s))
        windows.append((t, t + dwell_s))
        t += dwell_s
    return TemperatureProfile(start, tuple(pieces)), windows


@dataclass(frozen=True)
class TemperatureSensor:
    """How the simulator records the temperature: ``rate_hz`` readings of each named sensor, each with
    a constant ``offset_c`` (the sensor is not where the gyros are), white noise and quantization."""

    names: tuple[str, ...] = ("imu",)
    rate_hz: float = 1.0
    offsets_c: tuple[float, ...] = field(default=())
    noise_c: float = 0.0
    quantum_c: float = 0.0

    def __post_init__(self):
        object.__setattr__(self, "names", tuple(str(n) for n in self.names))
        offs = tuple(float(x) for x in self.offsets_c) or (0.0,) * len(self.names)
        if len(offs) != len(self.names) or not self.names:
            raise ValueError("temperature sensor: one offset per sensor name")
        object.__setattr__(self, "offsets_c", offs)
        if not (math.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise ValueError("temperature sensor: rate_hz must be > 0")
        if not (self.noise_c >= 0 and self.quantum_c >= 0):
            raise ValueError("temperature sensor: noise_c and quantum_c must be >= 0")

    def read(self, profile: TemperatureProfile, duration_s: float, rng: np.random.Generator | None) -> Temperature:
        """The readings from t = 0 to ``duration_s`` (inclusive) at the sensor's rate."""
        n = int(math.floor(duration_s * self.rate_hz + 1e-9)) + 1
        t = np.arange(n) / self.rate_hz
        T, _ = profile.at(t)
        vals = np.repeat(T[:, None], len(self.names), axis=1) + np.asarray(self.offsets_c)[None, :]
        if self.noise_c > 0:
            if rng is None:
                raise ValueError("a seeded numpy Generator is required for temperature sensor noise")
            vals = vals + rng.standard_normal(vals.shape) * self.noise_c
        if self.quantum_c > 0:
            vals = np.round(vals / self.quantum_c) * self.quantum_c
        return Temperature(t, vals, self.names)
