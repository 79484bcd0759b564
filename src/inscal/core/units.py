"""Unit conversion between the field's units and SI, in one place.

Everything inside inscal is SI (rad, rad/s, m/s^2, m, s).  Configuration files,
reports and the CLI use the field's units; they are converted here and only here.

Each unit has a factor such that ``si = value * FACTOR[unit]``.
"""

from __future__ import annotations

import math

import numpy as np

#: Standard gravity used for g-based units (µg, µg/g², °/h/g).  This is the
#: conventional 9.80665 m/s^2, not local gravity: a µg is a fixed quantity.
G0 = 9.80665

DEG = math.pi / 180.0
ARCSEC = DEG / 3600.0
HOUR = 3600.0

#: SI factor of every unit the project accepts.  Keys are the canonical spellings;
#: ALIASES maps common alternatives onto them.
FACTOR: dict[str, float] = {
    # dimensionless
    "1": 1.0,
    "ppm": 1e-6,
    # angles
    "rad": 1.0,
    "deg": DEG,
    "arcsec": ARCSEC,
    # angular rate
    "rad/s": 1.0,
    "deg/s": DEG,
    "deg/h": DEG / HOUR,
    # angle random walk
    "rad/sqrt(s)": 1.0,
    "deg/sqrt(h)": DEG / math.sqrt(HOUR),
    # specific force
    "m/s^2": 1.0,
    "g": G0,
    "mg": 1e-3 * G0,
    "ug": 1e-6 * G0,
    "mGal": 1e-5,  # the gravimetric milligal (KF-GINS's accelerometer bias unit)
    # velocity random walk
    "m/s/sqrt(s)": 1.0,
    "ug/sqrt(Hz)": 1e-6 * G0,  # (m/s^2)/sqrt(Hz) == m/s/sqrt(s)
    "m/s/sqrt(h)": 1.0 / math.sqrt(HOUR),  # KF-GINS's velocity random walk unit
    # accelerometer nonlinearity (output per input squared)
    "1/(m/s^2)": 1.0,
    "ug/g^2": 1e-6 * G0 / G0**2,
    # gyro g-sensitivity ((rad/s) per (m/s^2))
    "(rad/s)/(m/s^2)": 1.0,
    "deg/h/g": DEG / HOUR / G0,
    # lengths
    "m": 1.0,
    "cm": 1e-2,
    "mm": 1e-3,
    "nmi": 1852.0,  # international nautical mile
    # time
    "s": 1.0,
    "ms": 1e-3,
    "us": 1e-6,
    "h": HOUR,
    "min": 60.0,
    # angle quantisation
    "urad": 1e-6,
    # velocity
    "m/s": 1.0,
    "mm/s": 1e-3,
    "ug*s": 1e-6 * G0,  # a velocity increment of 1 ug over 1 s (PSINS's accelerometer quantum unit)
    # gyro bias per rate of change of temperature ((rad/s) per (K/s) = rad/K): the thermal-gradient
    # (Shupe) bias of a fibre-optic gyro
    "rad/degC": 1.0,
    "deg/h/(degC/min)": DEG / HOUR * 60.0,
    "deg/h/(degC/s)": DEG / HOUR,
    # stochastic-process coefficients (IEEE Std 952-2020 and 1293-2018 units)
    "rad/s/sqrt(s)": 1.0,  # rate random walk
    "deg/h/sqrt(h)": DEG / HOUR / math.sqrt(HOUR),
    "m/s^2/sqrt(s)": 1.0,  # acceleration random walk
    "ug*sqrt(Hz)": 1e-6 * G0,  # (m/s^2)*sqrt(Hz) == m/s^2/sqrt(s)
    "m/s/h/sqrt(h)": 1.0 / HOUR**1.5,
    "rad/s^2": 1.0,  # rate ramp
    "deg/h^2": DEG / HOUR**2,
    "m/s^3": 1.0,  # acceleration ramp
    "ug/h": 1e-6 * G0 / HOUR,
}

ALIASES: dict[str, str] = {
    "µg": "ug",
    "μg": "ug",
    "µg/g²": "ug/g^2",
    "μg/g²": "ug/g^2",
    "ug/g2": "ug/g^2",
    "µg/√Hz": "ug/sqrt(Hz)",
    "ug/√Hz": "ug/sqrt(Hz)",
    "°": "deg",
    "°/s": "deg/s",
    "°/h": "deg/h",
    "°/√h": "deg/sqrt(h)",
    "deg/rt(h)": "deg/sqrt(h)",
    "°/h/g": "deg/h/g",
    "″": "arcsec",
    "\"": "arcsec",
    "asec": "arcsec",
    "m/s2": "m/s^2",
    "m/s²": "m/s^2",
    "hz": "Hz",
    "µg*s": "ug*s",
    "μg*s": "ug*s",
    "ug.s": "ug*s",
    "ug·s": "ug*s",
    "µg·s": "ug*s",
    "°/h/(°C/min)": "deg/h/(degC/min)",
    "deg/h/(K/min)": "deg/h/(degC/min)",
    "°/h/(°C/s)": "deg/h/(degC/s)",
    "rad/K": "rad/degC",
    "µs": "us",
    "μs": "us",
    "°/h/√h": "deg/h/sqrt(h)",
    "deg/h/rt(h)": "deg/h/sqrt(h)",
    "µg*√Hz": "ug*sqrt(Hz)",
    "ug*√Hz": "ug*sqrt(Hz)",
    "µg·√Hz": "ug*sqrt(Hz)",
    "°/h²": "deg/h^2",
    "deg/h2": "deg/h^2",
    "µg/h": "ug/h",
    "m/s/√h": "m/s/sqrt(h)",
}


class UnitError(ValueError):
    """An unknown unit, or a unit of the wrong kind for a quantity."""


#: Physical kind of each unit, so a value given in a unit of the wrong kind is refused.
KIND: dict[str, str] = {
    "1": "dimensionless", "ppm": "dimensionless",
    "rad": "angle", "deg": "angle", "arcsec": "angle", "urad": "angle",
    "rad/s": "rate", "deg/s": "rate", "deg/h": "rate",
    "rad/sqrt(s)": "arw", "deg/sqrt(h)": "arw",
    "m/s^2": "accel", "g": "accel", "mg": "accel", "ug": "accel", "mGal": "accel",
    "m/s/sqrt(s)": "vrw", "ug/sqrt(Hz)": "vrw", "m/s/sqrt(h)": "vrw",
    "1/(m/s^2)": "nonlinearity", "ug/g^2": "nonlinearity",
    "(rad/s)/(m/s^2)": "g-sensitivity", "deg/h/g": "g-sensitivity",
    "m": "length", "cm": "length", "mm": "length", "nmi": "length",
    "s": "time", "ms": "time", "us": "time", "h": "time", "min": "time",
    "m/s": "velocity", "mm/s": "velocity", "ug*s": "velocity",
    "rad/degC": "rate-per-temperature-rate", "deg/h/(degC/min)": "rate-per-temperature-rate",
    "deg/h/(degC/s)": "rate-per-temperature-rate",
    "rad/s/sqrt(s)": "rrw", "deg/h/sqrt(h)": "rrw",
    "m/s^2/sqrt(s)": "arrw", "ug*sqrt(Hz)": "arrw", "m/s/h/sqrt(h)": "arrw",
    "rad/s^2": "rate-ramp", "deg/h^2": "rate-ramp",
    "m/s^3": "accel-ramp", "ug/h": "accel-ramp",
}


def canonical(unit: str) -> str:
    """The canonical name of ``unit`` (aliases such as ``°/h`` resolved); an unknown unit is a :class:`UnitError`."""
    u = unit.strip()
    u = ALIASES.get(u, u)
    if u not in FACTOR:
        raise UnitError(f"unknown unit {unit!r}; known units: {', '.join(sorted(FACTOR))}")
    return u


def check_kind(unit: str, kind: str) -> str:
    """Canonical spelling of ``unit``; raises UnitError if it is not of ``kind``."""
    u = canonical(unit)
    if KIND[u] != kind:
        good = sorted(k for k, v in KIND.items() if v == kind)
        raise UnitError(f"unit {unit!r} is a {KIND[u]} unit, expected a {kind} unit ({', '.join(good)})")
    return u


def to_si(value, unit: str, kind: str | None = None):
    """Convert ``value`` given in ``unit`` to SI (checking its kind if given)."""
    f = FACTOR[check_kind(unit, kind) if kind else canonical(unit)]
    if isinstance(value, (int, float)):
        return value * f
    return np.asarray(value, dtype=float) * f


def from_si(value, unit: str, kind: str | None = None):
    """Convert an SI ``value`` to ``unit`` (checking its kind if given)."""
    f = FACTOR[check_kind(unit, kind) if kind else canonical(unit)]
    if isinstance(value, (int, float)):
        return value / f
    return np.asarray(value, dtype=float) / f


# ----------------------------------------------------------------------------- temperature
#: Temperatures are kept in degrees Celsius inside inscal as well: only differences ``T - T_ref``
#: enter the models, and a kelvin and a degree Celsius are the same step.  ``(scale, offset)`` with
#: ``celsius = value * scale + offset`` for each temperature unit accepted at the edges.
TEMPERATURE_UNITS: dict[str, tuple[float, float]] = {
    "degC": (1.0, 0.0),
    "K": (1.0, -273.15),
    "degF": (5.0 / 9.0, -32.0 * 5.0 / 9.0),
}
TEMPERATURE_ALIASES = {"°C": "degC", "C": "degC", "celsius": "degC", "kelvin": "K", "°F": "degF", "F": "degF"}
#: the spellings of "per degree" accepted after a coefficient's unit (``ppm/degC^2``)
_PER_DEGREE = ("degC", "°C", "K")


def temperature_unit(unit: str) -> str:
    """Canonical spelling of a temperature unit (degC, K, degF); UnitError otherwise."""
    u = TEMPERATURE_ALIASES.get(unit.strip(), unit.strip())
    if u not in TEMPERATURE_UNITS:
        raise UnitError(f"unknown temperature unit {unit!r}; known: {', '.join(TEMPERATURE_UNITS)}")
    return u


def to_celsius(value, unit: str):
    """A temperature in ``unit`` (degC, K, degF) in degrees Celsius."""
    scale, offset = TEMPERATURE_UNITS[temperature_unit(unit)]
    if isinstance(value, (int, float)):
        return value * scale + offset
    return np.asarray(value, dtype=float) * scale + offset


def temperature_step_to_si(value, unit: str):
    """A temperature *difference* (a stability, a step) given in ``unit`` (degC, K, degF) in kelvin
    (= degrees Celsius): the offset of the scale does not enter a difference."""
    scale, _ = TEMPERATURE_UNITS[temperature_unit(unit)]
    if isinstance(value, (int, float)):
        return value * scale
    return np.asarray(value, dtype=float) * scale


def temperature_step_from_si(value, unit: str):
    """Inverse of :func:`temperature_step_to_si`: a difference in kelvin in ``unit``."""
    scale, _ = TEMPERATURE_UNITS[temperature_unit(unit)]
    if isinstance(value, (int, float)):
        return value / scale
    return np.asarray(value, dtype=float) / scale


def per_degree_unit(unit: str, order: int) -> str:
    """The field unit of a thermal coefficient of ``order`` (``ppm`` -> ``ppm/degC``, ``ppm/degC^2``)."""
    return f"{unit}/degC" if order == 1 else f"{unit}/degC^{order}"


def split_per_degree(unit: str) -> tuple[str, int]:
    """``(base unit, order)`` of a coefficient unit written ``<unit>/degC^k`` (also ``/°C``, ``/K``;
    ``k`` = 1 when no exponent is given).  UnitError when the unit has no such suffix."""
    u = unit.strip()
    for deg in _PER_DEGREE:
        for form in ("/" + deg + "^", "/" + deg):
            i = u.rfind(form)
            if i <= 0:
                continue
            tail = u[i + len(form):]
            if form.endswith("^"):
                if not tail.isdigit():
                    continue
                return u[:i], int(tail)
            if tail == "":
                return u[:i], 1
    raise UnitError(f"unit {unit!r} is not a per-degree unit (expected '<unit>/degC' or '<unit>/degC^k')")


def thermal_to_si(value, unit: str, kind: str, order: int):
    """A thermal coefficient of ``order`` given in ``<unit>/degC^order`` in SI per degree^order (a degree
    Celsius is a kelvin, so only the base unit is converted); the order written must match."""
    base, k = split_per_degree(unit)
    if k != order:
        raise UnitError(f"unit {unit!r} is per degree^{k}, expected per degree^{order}")
    return to_si(value, base, kind)
