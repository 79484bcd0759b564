"""A small calibration database to try the lab's functions on: one unit's history of six-position
results (the examples of :mod:`inscal.lab`, the guide and the tests), as
:func:`inscal.uncertainty.station.example_station` is the budget's."""

from __future__ import annotations

import datetime as dt

from inscal.calibrate.result import CalibrationResult
from inscal.lab.database import Database
from inscal.lab.model import SessionInfo
from inscal.lab.opening import init_database
from inscal.lab.store import add_unit, record_result

#: the date of the first session of :func:`example_history`; one more every :data:`EXAMPLE_STEP`
EXAMPLE_START = dt.datetime(2025, 1, 31)
EXAMPLE_STEP = dt.timedelta(days=30)


def example_history(path, biases_deg_h=(0.010, 0.012), serial: str = "IMU-1") -> tuple[Database, tuple[int, ...]]:
    """A new calibration database holding one unit's six-position results, oldest first.

    Result ``i`` (from 0) is the x gyro bias ``biases_deg_h[i]`` [deg/h] with 1 sigma 0.001 deg/h on
    every axis, recorded by :func:`~inscal.lab.store.record_result` from a session dated
    :data:`EXAMPLE_START` + ``i`` :data:`EXAMPLE_STEP` (31 January, 2 March 2025, ...) whose record
    hash is ``"sha256:"`` followed by the digit ``i + 1`` 64 times; the newest is the current one.

    Parameters
    ----------
    path : str or os.PathLike
        The database file to create (SQLite), or a ``postgresql://`` URL of an empty database.
    biases_deg_h : sequence of float
        The x gyro bias of each result [deg/h], 1 to 9 of them.
    serial : str
        The unit (model ``nav-grade``).

    Returns
    -------
    Database
        The open database (close it when done).
    tuple of int
        The results' ids, oldest first.

    Raises
    ------
    ValueError
        No bias, or more than nine.

    Examples
    --------
    >>> from inscal import lab
    >>> db, ids = lab.example_history("calib.sqlite", (0.010, 0.012, 0.011))
    >>> [c.parameters["gyro_bias"].value[0].item() for c in lab.calibrations(db, "IMU-1")] == [0.010, 0.012, 0.011]
    True
    >>> lab.current_calibration(db, "IMU-1").id == ids[-1]
    True
    >>> db.close()
    """
    if not 1 <= len(biases_deg_h) <= 9:
        raise ValueError(f"example_history takes 1 to 9 biases, not {len(biases_deg_h)}")
    db, _ = init_database(path)
    ids = []
    try:
        add_unit(db, serial, "nav-grade")
        for i, bias in enumerate(biases_deg_h):
            result = CalibrationResult.from_field({"gyro_bias": [bias, 0.0, 0.0]}, {"gyro_bias": [0.001] * 3},
                                                  "six-position")
            session = SessionInfo(record_sha256="sha256:" + str(i + 1) * 64, date=EXAMPLE_START + i * EXAMPLE_STEP)
            ids.append(record_result(db, serial, result, session)[0])
    except BaseException:
        db.close()
        raise
    return db, tuple(ids)
