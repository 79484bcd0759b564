"""What the calibration database holds, as plain frozen dataclasses: a unit, the session of a
record, one calibration with all its parameters (value, 1 sigma, field unit), covariance, fit
and provenance."""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass

import numpy as np

from inscal.core import units
from inscal.core.error_model import PARAMETERS
from inscal.io.jsonfile import to_jsonable


def utc_naive(t: dt.datetime) -> dt.datetime:
    """``t`` in UTC without a zone (how the database stores times; a naive ``t`` is taken as UTC)."""
    if t.tzinfo is not None:
        t = t.astimezone(dt.UTC).replace(tzinfo=None)
    return t


def iso(t: dt.datetime | None) -> str | None:
    """``2025-01-31T12:00:00Z`` (UTC)."""
    return None if t is None else utc_naive(t).isoformat(timespec="seconds") + "Z"


#: the earliest date of a record, a calibration or a certificate (digital IMU records are younger)
EARLIEST = dt.datetime(1950, 1, 1)
#: how far in the future a date may lie (clocks of the lab's machines that disagree) [s]
CLOCK_SKEW = dt.timedelta(hours=1)


def parse_date(text: str) -> dt.datetime:
    """A date (``2025-01-31``) or ISO time (``2025-01-31T12:00:00Z``, ``...+01:00``; no zone: UTC)
    as naive UTC.  Raises ValueError."""
    s = str(text).strip()
    if s.endswith(("Z", "z")):
        s = s[:-1] + "+00:00"
    shown = str(text) if len(str(text)) <= 60 else str(text)[:57] + "..."
    try:
        t = dt.datetime.fromisoformat(s)
        return utc_naive(t)
    except ValueError:
        raise ValueError(f"{shown!r} is not a date (YYYY-MM-DD) nor an ISO time (YYYY-MM-DDTHH:MM:SSZ)") from None
    except OverflowError:  # year 1 or 9999 moved out of range by its zone
        raise ValueError(f"{shown!r}: not a date between {EARLIEST:%Y} and now") from None


def check_date(t: dt.datetime, what: str = "the date", now: dt.datetime | None = None) -> dt.datetime:
    """``t`` (naive UTC, or with a zone) as naive UTC if it lies between :data:`EARLIEST` and ``now`` (default: the
    clock) plus :data:`CLOCK_SKEW`; else ValueError in one line (a date in the future would stay a unit's current
    calibration for ever)."""
    t = utc_naive(t)
    now = utc_naive(now) if now is not None else dt.datetime.now(dt.UTC).replace(tzinfo=None)
    if t > now + CLOCK_SKEW:
        raise ValueError(f"{what} {t:%Y-%m-%d %H:%M:%S} UTC lies in the future (now {now:%Y-%m-%d %H:%M} UTC; clocks may "
                         f"differ by {CLOCK_SKEW.total_seconds() / 3600:g} h at most)")
    if t < EARLIEST:
        raise ValueError(f"{what} {t:%Y-%m-%d} lies before {EARLIEST:%Y}: not the date of a record")
    return t


@dataclass(frozen=True)
class Unit:
    """An instrument the lab calibrates (its serial is its identity)."""

    id: int
    serial: str
    model: str | None
    notes: str | None
    created_at: dt.datetime

    def to_json(self) -> dict:
        """The unit as JSON: serial, model, notes and when it was registered."""
        return {"serial": self.serial, "model": self.model, "notes": self.notes, "created_at": iso(self.created_at)}


@dataclass(frozen=True, kw_only=True)
class SessionInfo:
    """The calibration run a result comes from: its record (sha256 of the file, as
    :func:`inscal.io.files.file_hash` writes it, and its path), where, when and by whom.
    ``date`` is when the record was taken (UTC); ``gravity_model`` the JSON text of the record's
    :class:`~inscal.core.earth.GravityModel`; ``temperature_c`` the IMU's temperature when known."""

    record_sha256: str
    date: dt.datetime
    record_path: str | None = None
    station: str | None = None
    operator: str | None = None
    latitude_deg: float | None = None
    longitude_deg: float | None = None
    height_m: float | None = None
    gravity_model: str | None = None
    g_site_m_s2: float | None = None
    temperature_c: float | None = None
    path_name: str | None = None

    def to_json(self) -> dict:
        """The calibration run as JSON: the record (hash, path, date), station, operator, site, gravity, temperature, path."""
        return {"record_sha256": self.record_sha256, "record_path": self.record_path, "date": iso(self.date),
                "station": self.station, "operator": self.operator,
                "site": {"latitude_deg": self.latitude_deg, "longitude_deg": self.longitude_deg,
                         "height_m": self.height_m},
                "gravity_model": self.gravity_model, "g_site_m_s2": self.g_site_m_s2,
                "temperature_c": self.temperature_c, "path_name": self.path_name}


@dataclass(frozen=True, kw_only=True)
class Session(SessionInfo):
    """A session as stored: its id and when it was recorded."""

    id: int
    recorded_at: dt.datetime

    def to_json(self) -> dict:
        """The stored run as JSON: :meth:`SessionInfo.to_json` with its id and the time it was recorded."""
        return {"id": self.id, **super().to_json(), "recorded_at": iso(self.recorded_at)}


@dataclass(frozen=True)
class Parameter:
    """One estimated parameter: ``value``, ``sigma`` (reported 1 sigma; NaN where held fixed) and
    ``sigma_formal`` (None unless the reported sigma was scaled), arrays of the parameter's
    shape in its field ``unit``; ``labels`` of its components (``accel_bias[x]`` ...)."""

    name: str
    unit: str
    value: np.ndarray
    sigma: np.ndarray
    sigma_formal: np.ndarray | None
    labels: tuple[str, ...]

    def si(self) -> tuple[np.ndarray, np.ndarray]:
        """``(value, sigma)`` in SI (the estimators' units)."""
        kind = PARAMETERS[self.name].kind
        return (np.asarray(units.to_si(self.value, self.unit, kind), dtype=float),
                np.asarray(units.to_si(self.sigma, self.unit, kind), dtype=float))

    def to_json(self) -> dict:
        """The parameter as JSON: value, 1 sigma (and the formal one when scaled) and unit."""
        out = {"value": self.value, "sigma": self.sigma, "unit": self.unit}
        if self.sigma_formal is not None:
            out["sigma_formal"] = self.sigma_formal
        return to_jsonable(out)


@dataclass(frozen=True)
class Calibration:
    """One recorded calibration result with its provenance.

    ``parameters``: name -> :class:`Parameter` (field units, the parameter file's);
    ``covariance``: ``{"basis": "parameters" | "states", "labels", "units": "field" | "SI",
    "correlations": bool, "matrix"}`` (None entries: not available); ``fit``: the parameter file's
    ``[fit]`` table, or the filter's innovation statistics (``chi2``, ``dof``, ``p_value``);
    ``param_text``: the parameter file exactly as written (sha256 ``param_file_sha256``)."""

    id: int
    serial: str
    method: str
    state_set: str | None
    options: dict
    options_hash: str
    parameters: dict[str, Parameter]
    covariance: dict | None
    fit: dict | None
    fit_chi2: float | None
    fit_dof: float | None
    fit_p: float | None
    notes: tuple[str, ...]
    inscal_version: str
    param_text: str
    param_file_sha256: str
    supersedes: int | None
    superseded_by: tuple[int, ...]
    current: bool
    recorded_at: dt.datetime
    session: Session
    unit_model: str | None = None

    @property
    def date(self) -> dt.datetime:
        """When the calibration's record was taken (UTC)."""
        return self.session.date

    def to_json(self, with_covariance: bool = True) -> dict:
        """The result as ``inscal db show --json`` prints it: parameters, fit, notes, provenance and,
        with ``with_covariance``, the covariance.
        """
        out = {"id": self.id, "serial": self.serial, "model": self.unit_model, "method": self.method,
               "state_set": self.state_set, "date": iso(self.date), "current": self.current,
               "supersedes": self.supersedes, "superseded_by": list(self.superseded_by),
               "parameters": {n: p.to_json() for n, p in self.parameters.items()},
               "fit": {"chi2": self.fit_chi2, "dof": self.fit_dof, "p_value": self.fit_p, "table": self.fit},
               "notes": list(self.notes),
               "provenance": {"session": self.session.to_json(), "options": self.options,
                              "options_hash": self.options_hash, "inscal_version": self.inscal_version,
                              "param_file_sha256": self.param_file_sha256, "recorded_at": iso(self.recorded_at)}}
        if with_covariance:
            out["covariance"] = self.covariance
        return to_jsonable(out)
