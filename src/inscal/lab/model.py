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
    """A date (``2025-01-31``) or ISO time (``2025-01-31T12:00:00Z``, ``...+01:00``; no zone: UTC) as naive UTC.

    Parameters
    ----------
    text : str
        The date or time.

    Returns
    -------
    datetime.datetime
        Naive UTC.

    Raises
    ------
    ValueError
        Not a date, or not one between :data:`EARLIEST` and now.

    Examples
    --------
    >>> from inscal import lab
    >>> lab.parse_date("2025-01-31T12:00:00+01:00")
    datetime.datetime(2025, 1, 31, 11, 0)
    """
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
    """A date as naive UTC if it lies between :data:`EARLIEST` and now plus :data:`CLOCK_SKEW`.

    A date in the future would stay a unit's current calibration for ever.

    Parameters
    ----------
    t : datetime.datetime
        Naive UTC, or with a zone.
    what : str
        What the message calls it.
    now : datetime.datetime, optional
        Now (default: the clock).

    Returns
    -------
    datetime.datetime
        ``t`` as naive UTC.

    Raises
    ------
    ValueError
        A date in the future or before :data:`EARLIEST` (one line).

    Examples
    --------
    >>> import datetime as dt
    >>> from inscal import lab
    >>> lab.check_date(dt.datetime(2025, 1, 31, 12, tzinfo=dt.timezone(dt.timedelta(hours=2))))
    datetime.datetime(2025, 1, 31, 10, 0)
    >>> try:
    ...     lab.check_date(dt.datetime(1900, 1, 1))
    ... except ValueError as exc:
    ...     print(exc)
    the date 1900-01-01 lies before 1950: not the date of a record
    """
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
    """An instrument the lab calibrates (its serial is its identity; :func:`~inscal.lab.store.add_unit`).

    Parameters
    ----------
    id : int
        The unit's id.
    serial : str
        Its serial.
    model : str or None
        Its model.
    notes : str or None
        Free text.
    created_at : datetime.datetime
        When it was registered (UTC).

    Examples
    --------
    >>> from inscal import lab
    >>> db, created = lab.init_database("calib.sqlite")
    >>> unit, _ = lab.add_unit(db, "IMU-1", "nav-grade", "bench 2")
    >>> unit.to_json()["model"], unit.to_json()["notes"]
    ('nav-grade', 'bench 2')

    >>> db.close()
    """

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
    """The calibration run a result comes from: its record, where, when and by whom.

    Parameters
    ----------
    record_sha256 : str
        The record file's sha256 (as :func:`inscal.io.files.file_hash` writes it).
    date : datetime.datetime
        When the record was taken (UTC).
    record_path : str, optional
        The record's path.
    station, operator : str, optional
        Where and by whom.
    latitude_deg, longitude_deg, height_m : float, optional
        The site.
    gravity_model : str, optional
        The JSON text of the record's :class:`~inscal.core.earth.GravityModel`.
    g_site_m_s2 : float, optional
        The gravity at the site.
    temperature_c : float, optional
        The IMU's temperature, when known.
    path_name : str, optional
        The rotation path's name.

    Examples
    --------
    >>> import datetime as dt
    >>> from inscal import lab
    >>> s = lab.SessionInfo(record_sha256="sha256:" + "1" * 64, date=dt.datetime(2025, 1, 31), station="bench-2")
    >>> s.to_json()["date"], s.to_json()["station"]
    ('2025-01-31T00:00:00Z', 'bench-2')
    """

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
    """A session as stored: a :class:`SessionInfo` with its id and when it was recorded.

    Parameters
    ----------
    id : int
        The session's id.
    recorded_at : datetime.datetime
        When it was recorded (UTC).
    **info
        The fields of :class:`SessionInfo`.

    Examples
    --------
    >>> from inscal import lab
    >>> db, (first,) = lab.example_history("calib.sqlite", (0.010,))  # its record: "sha256:111..."
    >>> session = lab.get_calibration(db, first).session
    >>> session.id, session.record_sha256 == "sha256:" + "1" * 64
    (1, True)

    >>> db.close()
    """

    id: int
    recorded_at: dt.datetime

    def to_json(self) -> dict:
        """The stored run as JSON: :meth:`SessionInfo.to_json` with its id and the time it was recorded."""
        return {"id": self.id, **super().to_json(), "recorded_at": iso(self.recorded_at)}


@dataclass(frozen=True)
class Parameter:
    """One estimated parameter of a recorded calibration, in its field unit.

    Parameters
    ----------
    name : str
        The parameter (a name of :data:`~inscal.core.error_model.PARAMETERS`).
    unit : str
        Its field unit.
    value : numpy.ndarray
        The estimate, the parameter's shape.
    sigma : numpy.ndarray
        The reported 1 sigma (NaN where held fixed).
    sigma_formal : numpy.ndarray or None
        The formal 1 sigma, None unless the reported sigma was scaled.
    labels : tuple of str
        Its components' labels (``accel_bias[x]`` ...).

    Examples
    --------
    >>> import numpy as np
    >>> from inscal import lab
    >>> p = lab.Parameter("gyro_bias", "deg/h", np.array([0.01, 0.0, 0.0]), np.full(3, 0.001), None,
    ...                   ("gyro_bias[x]", "gyro_bias[y]", "gyro_bias[z]"))
    >>> value, sigma = p.si()  # rad/s
    >>> round(float(value[0]) * 1e8, 4)
    4.8481
    """

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
    """One recorded calibration result with its provenance (:func:`~inscal.lab.queries.get_calibration`).

    Parameters
    ----------
    id : int
        The result's id.
    serial : str
        The unit.
    method : str
        The calibration method.
    state_set : str or None
        The systematic filter's state set.
    options : dict
        The calibration's options, and ``options_hash`` their hash.
    options_hash : str
        :func:`~inscal.lab.record.options_hash` of ``options``.
    parameters : dict of str to Parameter
        The estimates, in the parameter file's field units.
    covariance : dict or None
        ``{"basis": "parameters" | "states", "labels", "units": "field" | "SI", "correlations": bool,
        "matrix"}``.
    fit : dict or None
        The parameter file's ``[fit]`` table, or the filter's innovation statistics.
    fit_chi2, fit_dof, fit_p : float or None
        The fit's chi^2, degrees of freedom and p-value.
    notes : tuple of str
        The method's notes.
    inscal_version : str
        The inscal that computed it.
    param_text : str
        The parameter file exactly as written.
    param_file_sha256 : str
        Its hash.
    supersedes : int or None
        The result it replaces.
    superseded_by : tuple of int
        The results that replace it.
    current : bool
        Whether it is the unit's current calibration.
    recorded_at : datetime.datetime
        When it was recorded (UTC).
    session : Session
        Its calibration run.
    unit_model : str or None
        The unit's model.

    Examples
    --------
    >>> from inscal import lab
    >>> db, (first,) = lab.example_history("calib.sqlite", (0.010,))  # one unit, one result
    >>> cal = lab.get_calibration(db, first)
    >>> cal.date, cal.current, cal.to_json()["parameters"]["gyro_bias"]["value"]
    (datetime.datetime(2025, 1, 31, 0, 0), True, [0.01, 0.0, 0.0])

    >>> db.close()
    """

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
