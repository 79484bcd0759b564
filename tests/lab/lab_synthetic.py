"""Synthetic calibration results for the database tests (values and 1 sigma given in field units)."""

from __future__ import annotations

from inscal.calibrate.result import CalibrationResult


def synthetic_result(values: dict, sigma: dict, method: str = "manual") -> CalibrationResult:
    """A :class:`CalibrationResult` with ``values`` / ``sigma`` given per parameter name in field units."""
    return CalibrationResult.from_field(values, sigma, method)
