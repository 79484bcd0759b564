"""The plan kernels' slices (:mod:`inscal.core.slices`) with the cancellation of :mod:`inscal.core.cancel`.

The covariance pass of :mod:`inscal.plan.bound` and the observability factor of
:mod:`inscal.plan.observability` run in slices of steps through :func:`run_in_slices`, which is
:func:`inscal.core.slices.run_in_slices` with :func:`inscal.core.cancel.check_cancel` (a SIGINT or
SIGTERM whose exception Python had to drop) run between two calls.
"""

from __future__ import annotations

from collections.abc import Callable

from inscal.core import slices as core_slices
from inscal.core.cancel import check_cancel
from inscal.core.slices import GROWTH, SLICE_S

__all__ = ["GROWTH", "SLICE_S", "check_cancel", "run_in_slices"]


def run_in_slices(total: int, kernel: Callable[[int, int], None], first: int = 256,
                  target_s: float = SLICE_S) -> int:
    """:func:`inscal.core.slices.run_in_slices` with :func:`~inscal.core.cancel.check_cancel` after each call
    (looked up when called, so that a test may replace it).  Returns the number of calls."""
    return core_slices.run_in_slices(total, kernel, first=first, target_s=target_s, check=check_cancel)
