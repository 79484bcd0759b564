"""A calibration station (turntable, site, clock, chamber) as the Type-B inputs of an
uncertainty budget (JCGM 100:2008, the GUM, section 4.3).

A station file (``station.toml``) names every input of :data:`INPUTS` in its field unit, with
its value, its uncertainty and the distribution that uncertainty describes, and where it comes
from::

    [station]
    name = "T-2, lab 3"

    [inputs.table_angle]           # turntable position accuracy, each stop, each axis
    unit = "arcsec"
    distribution = "normal"
    uncertainty = 2.0              # normal: the standard uncertainty u(x)
    source = "table certificate 2025-03"

    [inputs.encoder_resolution]
    unit = "arcsec"
    distribution = "rectangular"
    half_width = 0.18              # rectangular / triangular / arcsine: the half-width a
    source = "encoder data sheet (0.36 arcsec count)"

    [inputs.gravity]
    value = 9.79363                # the value the calibration used
    unit = "m/s^2"
    uncertainty_unit = "mGal"      # optional: the unit of the uncertainty if not ``unit``
    distribution = "normal"
    uncertainty = 1.0
    source = "absolute gravimeter survey 2024"

The standard uncertainty of each distribution from its half-width ``a`` (GUM 4.3.7, 4.3.9;
JCGM 101:2008 6.4.2-6.4.6): rectangular ``a / sqrt(3)``, triangular ``a / sqrt(6)``, arcsine
(U-shaped) ``a / sqrt(2)``.  An optional ``dof`` gives the degrees of freedom of an uncertainty
that is itself uncertain (GUM G.4.2, eq. G.3); the default is infinite.

Everything is converted to SI in :mod:`inscal.core.units`; a file with a missing input or field,
a negative or non-finite uncertainty, an unknown distribution, input, key or unit is refused with
one line (:class:`StationError`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from inscal.core import units
from inscal.io.tomlfile import read_toml
from inscal.uncertainty import distributions
from inscal.uncertainty.distributions import DISTRIBUTION_ALIASES, DISTRIBUTIONS

@dataclass(frozen=True)
class InputSpec:
    """What a station input is: its physical kind, its default field unit, whether its value is
    needed (a site quantity) and whether it acts independently at every stop of the table."""

    kind: str
    unit: str
    needs_value: bool
    per_position: bool
    description: str


#: every input a station file describes (all are required)
INPUTS: dict[str, InputSpec] = {
    "table_angle": InputSpec("angle", "arcsec", False, True,
                             "turntable angle (position) accuracy, each stop, each axis"),
    "table_rate": InputSpec("dimensionless", "ppm", False, False, "turntable rate accuracy (relative)"),
    "axis_wobble": InputSpec("angle", "arcsec", False, True,
                             "axis wobble: tilt of the table top at each stop, about each horizontal axis"),
    "axis_nonorthogonality": InputSpec("angle", "arcsec", False, False, "non-orthogonality of the two table axes"),
    "encoder_resolution": InputSpec("angle", "arcsec", False, True,
                                    "encoder resolution: the reading's rounding at each stop, each axis"),
    "gravity": InputSpec("accel", "m/s^2", True, False, "the site's gravity magnitude"),
    "latitude": InputSpec("angle", "deg", True, False, "the site's geodetic latitude"),
    "height": InputSpec("length", "m", True, False, "the site's ellipsoidal height"),
    "time_base": InputSpec("dimensionless", "ppm", False, False, "accuracy of the acquisition time base"),
    "temperature_stability": InputSpec("temperature", "K", False, False,
                                       "chamber temperature stability during the run"),
}

_INPUT_KEYS = {"value", "unit", "uncertainty_unit", "distribution", "uncertainty", "half_width", "dof", "source"}


class StationError(ValueError):
    """A station description that cannot be used, with the reason in one line.

    Parameters
    ----------
    message : str
        The reason (a missing input or field, a bad number, distribution or unit, another site).

    Examples
    --------
    >>> station_from_dict({"station": {"name": "T"}, "inputs": {}})
    Traceback (most recent call last):
    ...
    inscal.uncertainty.station.StationError: missing input(s) table_angle, table_rate, axis_wobble, \
axis_nonorthogonality, encoder_resolution, gravity, latitude, height, time_base, temperature_stability \
(a station describes all of: table_angle, table_rate, axis_wobble, axis_nonorthogonality, encoder_resolution, \
gravity, latitude, height, time_base, temperature_stability)
    """


@dataclass(frozen=True)
class StationInput:
    """One input quantity of the budget (SI): its value, standard uncertainty ``u`` and the
    distribution it was stated with (``half_width`` for the non-normal ones), in the field
    units of the file for display."""

    name: str
    value: float
    u: float
    distribution: str
    source: str
    unit: str
    uncertainty_unit: str
    half_width: float | None = None
    dof: float = math.inf

    @property
    def spec(self) -> InputSpec:
        """The :class:`InputSpec` of this input."""
        return INPUTS[self.name]

    def field(self, si: float, unit: str | None = None) -> float:
        """An SI value of this input's kind in its field unit (``unit``: the uncertainty's by default)."""
        return _from_si(si, unit or self.uncertainty_unit, self.spec.kind)

    def draw(self, rng: np.random.Generator, size=None) -> np.ndarray:
        """Deviations from the value drawn from this input's distribution (SI; JCGM 101 6.4,
        :func:`inscal.uncertainty.distributions.draw`): normal ``N(0, u)`` (a finite ``dof`` too), rectangular
        ``U(-a, a)``, triangular on ``[-a, a]``, arcsine ``a sin(2 pi U)``."""
        return distributions.draw(self.distribution, rng, size, u=self.u, a=self.half_width)

    def to_dict(self) -> dict:
        """The input as a station file's table (field units), as :func:`station_from_dict` reads it."""
        d = {"value": self.field(self.value, self.unit), "unit": self.unit, "uncertainty_unit": self.uncertainty_unit,
             "distribution": self.distribution, "source": self.source}
        if self.half_width is None:
            d["uncertainty"] = self.field(self.u)
        else:
            d["half_width"] = self.field(self.half_width)
        if math.isfinite(self.dof):
            d["dof"] = self.dof
        return d


@dataclass(frozen=True)
class Station:
    """A station: its name and every input of :data:`INPUTS` (:class:`StationInput`), ``station[name]`` one input.

    Parameters
    ----------
    name : str
        The station's name (the session's station in the database).
    inputs : dict of str to StationInput
        Every input of :data:`INPUTS`, in SI.

    Examples
    --------
    >>> st = example_station()
    >>> st.name, st["gravity"].distribution, round(st["table_angle"].field(st["table_angle"].u), 6)
    ('T-2, lab 3', 'normal', 2.0)
    """

    name: str
    inputs: dict[str, StationInput]

    def to_dict(self) -> dict:
        """The station as a station file's document (field units)."""
        return {"station": {"name": self.name}, "inputs": {k: v.to_dict() for k, v in self.inputs.items()}}

    def __getitem__(self, name: str) -> StationInput:
        return self.inputs[name]


def _to_si(value: float, unit: str, kind: str) -> float:
    if kind == "temperature":
        return float(units.temperature_step_to_si(value, unit))
    return float(units.to_si(value, unit, kind))


def _from_si(value: float, unit: str, kind: str) -> float:
    if kind == "temperature":
        return float(units.temperature_step_from_si(value, unit))
    return float(units.from_si(value, unit, kind))


def _number(name: str, key: str, v) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise StationError(f"input {name}: {key} must be a finite number, got {v!r}")
    return float(v)


def _input(name: str, d) -> StationInput:
    spec = INPUTS[name]
    if not isinstance(d, dict):
        raise StationError(f"input {name}: expected a table, got {d!r}")
    unknown = set(d) - _INPUT_KEYS
    if unknown:
        raise StationError(f"input {name}: unknown key(s) {sorted(unknown)}; known: {sorted(_INPUT_KEYS)}")
    for key in ("unit", "distribution", "source"):
        if key not in d:
            raise StationError(f"input {name}: missing field {key!r}")
    if spec.needs_value and "value" not in d:
        raise StationError(f"input {name}: missing field 'value' (the value the calibration used)")
    dist = str(d["distribution"]).strip().lower()
    dist = DISTRIBUTION_ALIASES.get(dist, dist)
    if dist not in DISTRIBUTIONS:
        raise StationError(f"input {name}: unknown distribution {d['distribution']!r}; "
                           f"known: {', '.join(DISTRIBUTIONS)}")
    unit = str(d["unit"])
    u_unit = str(d.get("uncertainty_unit", unit))
    try:
        value = _to_si(_number(name, "value", d.get("value", 0.0)), unit, spec.kind)
        key = "uncertainty" if DISTRIBUTIONS[dist] is None else "half_width"
        other = "half_width" if key == "uncertainty" else "uncertainty"
        if key not in d:
            raise StationError(f"input {name}: missing field {key!r} (a {dist} distribution is given by its "
                               f"{'standard uncertainty' if key == 'uncertainty' else 'half-width'})")
        if other in d:
            raise StationError(f"input {name}: a {dist} distribution takes {key!r}, not {other!r}")
        x = _number(name, key, d[key])
        if x < 0:
            raise StationError(f"input {name}: negative {key.replace('_', '-')} {x:g} {u_unit}")
        x_si = _to_si(x, u_unit, spec.kind)
    except units.UnitError as exc:
        raise StationError(f"input {name}: {exc}") from None
    dof = _number(name, "dof", d.get("dof", math.inf)) if "dof" in d else math.inf
    if not dof >= MIN_DOF:
        raise StationError(f"input {name}: dof must be >= {MIN_DOF:g}, got {dof:g} (fewer says the uncertainty "
                           "is itself uncertain by more than +-71 %, GUM G.4.2: state a larger u instead)")
    factor = DISTRIBUTIONS[dist]
    u = x_si if factor is None else x_si / factor
    source = str(d["source"]).strip()
    if not source:
        raise StationError(f"input {name}: empty 'source' (say where the figure comes from)")
    return StationInput(name, value, u, dist, source, unit, u_unit, None if factor is None else x_si, dof)


def station_from_dict(doc: dict) -> Station:
    """A :class:`Station` from a station file's document; :class:`StationError` on any defect."""
    unknown = set(doc) - {"station", "inputs"}
    if unknown:
        raise StationError(f"unknown table(s) {sorted(unknown)}; a station file has [station] and [inputs.*]")
    head = doc.get("station", {})
    if not isinstance(head, dict) or not str(head.get("name", "")).strip():
        raise StationError("missing field 'name' in [station]")
    if set(head) - {"name", "description"}:
        raise StationError(f"[station]: unknown key(s) {sorted(set(head) - {'name', 'description'})}")
    raw = doc.get("inputs", {})
    if not isinstance(raw, dict):
        raise StationError("[inputs] must be tables, one per input")
    unknown = set(raw) - set(INPUTS)
    if unknown:
        raise StationError(f"unknown input(s) {sorted(unknown)}; known: {', '.join(INPUTS)}")
    missing = [k for k in INPUTS if k not in raw]
    if missing:
        raise StationError(f"missing input(s) {', '.join(missing)} (a station describes all of: {', '.join(INPUTS)})")
    inputs = {k: _input(k, raw[k]) for k in INPUTS}
    lat = inputs["latitude"].value
    if abs(lat) > math.pi / 2:
        raise StationError(f"input latitude: {math.degrees(lat):g} deg is not within +-90 deg")
    for key, (lo, hi) in SITE_RANGES.items():
        inp = inputs[key]
        if not lo <= inp.value <= hi:
            raise StationError(f"input {key}: {inp.field(inp.value, inp.unit):g} {inp.unit} is not a site on the "
                               f"Earth's surface ({inp.field(lo, inp.unit):g} .. {inp.field(hi, inp.unit):g} "
                               f"{inp.unit})")
    return Station(str(head["name"]).strip(), inputs)


#: the least degrees of freedom of a stated uncertainty (GUM G.4.2: nu = 1/2 (u/du)^-2; nu = 1 is du/u = 71 %;
#: the coverage factor t_95(1) = 12.7)
MIN_DOF = 1.0
#: the site values a station may state (SI): gravity on the Earth's surface (9.76-9.84 m/s^2 and local
#: anomalies), heights from the deepest mines to above the highest summits
SITE_RANGES = {"gravity": (9.7, 9.9), "height": (-5000.0, 10000.0)}
#: how far (in the station's own standard uncertainties) a site value may be from the record's
SITE_K = 3.0
#: beyond these (SI) the station is of another site: refused (latitude 0.1 deg, height 100 m, gravity 100 mGal)
SITE_GROSS = {"latitude": math.radians(0.1), "height": 100.0, "gravity": 1e-3}


def site_check(station: Station, latitude: float, height: float, gravity: float | None) -> list[str]:
    """The record's site (SI: latitude [rad], height [m], gravity used [m/s^2], None: not checked) against
    the station's: a note per value more than :data:`SITE_K` of its own standard uncertainty away; a value
    farther than both that and :data:`SITE_GROSS` raises :class:`StationError` (the station file is of
    another site)."""
    notes = []
    for key, have in (("latitude", latitude), ("height", height), ("gravity", gravity)):
        if have is None:
            continue
        inp = station[key]
        diff = abs(have - inp.value)
        if not diff > SITE_K * max(inp.u, 1e-15):
            continue
        line = (f"{key}: the record's {inp.field(have, inp.unit):.10g} {inp.unit}, the station states "
                f"{inp.field(inp.value, inp.unit):.10g} {inp.unit} +- {inp.field(inp.u):.3g} {inp.uncertainty_unit} "
                f"({diff / inp.u:.3g} u apart)")
        if diff > SITE_GROSS[key]:
            raise StationError(f"{line}: the station file describes another site; give this site's {key}"
                               + (", or calibrate with --gravity VALUE (the measured gravity)" if key == "gravity"
                                  else ""))
        notes.append(line)
    return notes


def read_station(path) -> Station:
    """The station described by the TOML file at ``path`` (see the module docstring).

    Parameters
    ----------
    path : str or pathlib.Path
        A station file (``station.toml``).

    Returns
    -------
    Station
        Every input in SI, with its distribution and source.

    Raises
    ------
    StationError
        The file cannot be read, is not TOML, or describes no usable station (one line saying why).

    Examples
    --------
    >>> read_station("no/such/station.toml")
    Traceback (most recent call last):
    ...
    inscal.uncertainty.station.StationError: no/such/station.toml: no such station file
    """
    return station_from_dict(read_toml(path, StationError, "station file"))


#: a station of typical figures (the budget's checks: ``tests/data/station.toml``): 2 arcsec table angle,
#: 10 ppm rate, 1 arcsec wobble, 2 arcsec axis non-orthogonality, 0.36 arcsec encoder counts, 1 mGal gravity,
#: 1 arcsec latitude, 1 m height, 1 ppm time base, +-0.1 K chamber cycling
EXAMPLE = {
    "station": {"name": "T-2, lab 3"},
    "inputs": {
        "table_angle": {"unit": "arcsec", "distribution": "normal", "uncertainty": 2.0, "source": "table certificate"},
        "table_rate": {"unit": "ppm", "distribution": "rectangular", "half_width": 17.32, "source": "data sheet"},
        "axis_wobble": {"unit": "arcsec", "distribution": "normal", "uncertainty": 1.0, "source": "table certificate"},
        "axis_nonorthogonality": {"unit": "arcsec", "distribution": "normal", "uncertainty": 2.0,
                                  "source": "table certificate"},
        "encoder_resolution": {"unit": "arcsec", "distribution": "rectangular", "half_width": 0.18,
                               "source": "encoder data sheet"},
        "gravity": {"value": 9.793788, "unit": "m/s^2", "uncertainty_unit": "mGal", "distribution": "normal",
                    "uncertainty": 1.0, "source": "gravimeter survey"},
        "latitude": {"value": 30.686, "unit": "deg", "uncertainty_unit": "arcsec", "distribution": "normal",
                     "uncertainty": 1.0, "source": "GNSS survey"},
        "height": {"value": 50.0, "unit": "m", "distribution": "normal", "uncertainty": 1.0, "source": "GNSS survey"},
        "time_base": {"unit": "ppm", "distribution": "rectangular", "half_width": 1.0, "source": "oscillator"},
        "temperature_stability": {"unit": "K", "distribution": "arcsine", "half_width": 0.1, "source": "chamber"},
    },
}


def example_station() -> Station:
    """The station of :data:`EXAMPLE` (for examples and documentation)."""
    return station_from_dict(EXAMPLE)
