"""Fixtures of the command-line tests."""

from __future__ import annotations

import os

import pytest
from forkserver import ServerPool

from inscal.uncertainty import sensitivity as S


@pytest.fixture(scope="session")
def fork_servers():
    """The fork servers (:class:`forkserver.ServerPool`) of this test process, shared by the command-line
    tests that run commands in forks: ``fork_servers.get(k)``.  Started unbuffered (the signal tests read a
    killed command's lines); a test's ``COLUMNS`` or ``PATH`` goes with each of its commands."""
    pool = ServerPool(dict(os.environ, PYTHONUNBUFFERED="1"))
    yield pool
    pool.close()


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
