"""S16's two systematic methods as named methods, with the state set fixed or chosen from the data."""

from __future__ import annotations

from inscal.calibrate.result import CalibrationResult
from inscal.calibrate.systematic.driver import systematic
from inscal.calibrate.systematic.selection import check_named, select_states, with_auto


def _run(record, base: str, extra: str | None, method_name: str, kw: dict) -> CalibrationResult:
    opts, auto = with_auto(extra, "")
    spec = base + ("," + opts if opts else "")
    if auto:
        return select_states(record, spec, method_name=method_name, **kw)
    return check_named(record, systematic(record, spec, method_name=method_name, **kw), method_name=method_name, **kw)


def systematic51(ws_or_record, **kw) -> CalibrationResult:
    """S16's 51-state systematic calibration (``states="51"`` plus options, e.g. ``"lever9,async"``: a named set with
    the full lever arm is checked for the lever-arm timing and the frame by
    :func:`~inscal.calibrate.systematic.selection.check_named`; ``"auto"``: the terms chosen from the data by
    :func:`~inscal.calibrate.systematic.selection.select_states`)."""
    return _run(ws_or_record, "51", kw.pop("states", None), "systematic51", kw)


def systematic30(ws_or_record, **kw) -> CalibrationResult:
    """S16's traditional 30-state filter (no g-sensitivity, nonlinearity, cross-coupling, lever arm);
    ``states="auto"`` may add the time asynchrony."""
    return _run(ws_or_record, "30", kw.pop("states", None), "systematic30", kw)
