"""A unit's history from the database, and the fleet view: every unit with its flags."""

from __future__ import annotations

from dataclasses import dataclass

from inscal.lab.database import Database, DatabaseError
from inscal.lab.drift import DEFAULT_K, History, history
from inscal.lab.model import Calibration, Unit, iso
from inscal.lab.store import calibrations, current_calibration, list_units


def unit_history(db: Database, serial: str, method: str | None = None, k: float = DEFAULT_K) -> History:
    """The :class:`~inscal.lab.drift.History` of unit ``serial`` (results that no other supersedes; one per
    session) for ``method``: by default the method of its current calibration (else of its newest)."""
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
    """One unit in the fleet view."""

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
    """Every unit (by serial) with its current calibration and the flags of its history (of the current
    calibration's method); ``flagged_only``: the units with a flag."""
    out = []
    for unit, n, cur_id in list_units(db):
        cur = current_calibration(db, unit.serial) if cur_id is not None else None
        h = unit_history(db, unit.serial, cur.method, k) if cur is not None else None
        if flagged_only and (h is None or not h.flagged):
            continue
        out.append(FleetEntry(unit, n, cur, h))
    return out
