"""A unit's history from the database, and the fleet view: every unit with its flags."""

from __future__ import annotations

from dataclasses import dataclass

from inscal.lab.database import Database, DatabaseError
from inscal.lab.drift import DEFAULT_K, History, history
from inscal.lab.model import Calibration, Unit, iso
from inscal.lab.queries import calibrations, current_calibration, list_units


def unit_history(db: Database, serial: str, method: str | None = None, k: float = DEFAULT_K) -> History:
    """The :class:`~inscal.lab.drift.History` of a unit (results that no other supersedes; one per session).

    Parameters
    ----------
    db : Database
        The open database (its results read, nothing written).
    serial : str
        The unit.
    method : str, optional
        The method (default: that of its current calibration, else of its newest).
    k : float
        The flag threshold (``|z| > k``).

    Returns
    -------
    History
        The unit's history.

    Raises
    ------
    DatabaseError
        A unit without a calibration, or an unknown unit.

    Examples
    --------
    >>> from inscal import lab
    >>> db, (first, second) = lab.example_history("calib.sqlite", (0.010, 0.012))  # one unit's two results
    >>> h = lab.unit_history(db, "IMU-1")
    >>> h.method, [d.month for d in h.dates]
    ('six-position', [1, 3])

    >>> db.close()
    """
    cals = calibrations(db, serial)
    if method is None:
        cur = current_calibration(db, serial)
        method = cur.method if cur is not None else (cals[-1].method if cals else None)
        if method is None:
            raise DatabaseError(f"unit {serial} has no calibration yet")
    elif not any(c.method == method for c in cals):
        have = sorted({c.method for c in cals})
        raise DatabaseError(f"unit {serial} has no {method} calibration"
                            + (f" (it has {', '.join(have)})" if have else ""))
    return history(cals, serial, method, k)


@dataclass(frozen=True)
class FleetEntry:
    """One unit in the fleet view (:func:`fleet`).

    Parameters
    ----------
    unit : Unit
        The unit.
    results : int
        Its number of results.
    current : Calibration or None
        Its current calibration.
    history : History or None
        The history of the current calibration's method.

    Examples
    --------
    >>> from inscal import lab
    >>> db, (first,) = lab.example_history("calib.sqlite", (0.010,))  # one unit, one result
    >>> entry, = lab.fleet(db)
    >>> row = entry.to_json()
    >>> row["serial"], row["results"], row["current"]["method"], row["flagged"]
    ('IMU-1', 1, 'six-position', [])

    >>> db.close()
    """

    unit: Unit
    results: int
    current: Calibration | None
    history: History | None

    def to_json(self) -> dict:
        """The unit as one row of ``inscal db list --json``: its results, current calibration and flags."""
        cur = self.current
        h = self.history
        return {**self.unit.to_json(), "results": self.results,
                "current": None if cur is None else {"id": cur.id, "method": cur.method, "date": iso(cur.date)},
                "flagged": [] if h is None else h.to_json()["flagged"],
                "tests": 0 if h is None else h.tests,
                "expected_false_alarms": 0.0 if h is None else h.expected_false_alarms}


def fleet(db: Database, k: float = DEFAULT_K, flagged_only: bool = False) -> list[FleetEntry]:
    """Every unit (by serial) with its current calibration and the flags of its history.

    Parameters
    ----------
    db : Database
        The open database (its results read, nothing written).
    k : float
        The flag threshold (``|z| > k``).
    flagged_only : bool
        Only the units with a flag.

    Returns
    -------
    list of FleetEntry
        One entry a unit: its number of results, its current calibration and that method's history.

    Examples
    --------
    >>> from inscal import lab
    >>> db, (first, second) = lab.example_history("calib.sqlite", (0.010, 0.012))  # one unit's two results
    >>> [(e.unit.serial, e.results) for e in lab.fleet(db)], lab.fleet(db, flagged_only=True)
    ([('IMU-1', 2)], [])

    >>> db.close()
    """
    out = []
    for unit, n, cur_id in list_units(db):
        cur = current_calibration(db, unit.serial) if cur_id is not None else None
        h = unit_history(db, unit.serial, cur.method, k) if cur is not None else None
        if flagged_only and (h is None or not h.flagged):
            continue
        out.append(FleetEntry(unit, n, cur, h))
    return out
