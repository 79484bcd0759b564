"""Fixtures of the command-line tests."""

from __future__ import annotations

import pytest

from inscal.uncertainty import sensitivity as S


@pytest.fixture()
def two_windows(monkeypatch):
    """The budget's per-stop coefficients at two windows only (the first static and the first rate window), to
    keep a command-line test short: the full loop runs in ``bench/budget_mc.py`` and the library tests."""
    full = S.sensitivities

    def short(ws, geo, x, kinds, stop_inputs=tuple(S.STOP_INPUTS), windows=None):
        static = [k for k, w in enumerate(ws.windows) if w.kind == "static"]
        rate = [k for k, w in enumerate(ws.windows) if w.kind == "rate"]
        return full(ws, geo, x, kinds, stop_inputs, [static[0], rate[0]])

    monkeypatch.setattr(S, "sensitivities", short)
