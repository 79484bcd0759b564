"""Long compiled loops run in slices, so that an interrupt is honoured within a fraction of a second.

A numba ``nopython`` call cannot be interrupted: Python runs a signal handler only when the call
returns.  The kernels that loop over filter steps (the systematic filter and smoother of
:mod:`inscal.calibrate.systematic.kernel`, the covariance pass of :mod:`inscal.plan.bound`, the
observability factor of :mod:`inscal.plan.observability`) therefore process a range of steps
``[k0, k1)`` and keep what one step hands to the next in arrays their caller owns.
:func:`run_in_slices` calls such a kernel over consecutive ranges, each sized to last about
:data:`SLICE_S`.  Between two calls the interpreter runs any pending signal handler (the command
line's raises its interrupt there), and ``check``, when given, runs too: a caller that honours the
cancellation of :mod:`inscal.core.cancel` passes its ``check_cancel`` (a SIGINT or SIGTERM whose
exception Python had to drop; :mod:`inscal.plan.slices` does so).  Every step does the same
arithmetic whatever the slicing, so the results are bit-identical to one call over all steps
(``tests/plan/test_slices.py``, ``tests/calibrate/test_kernel_slices.py``).

The check is handed in, never imported: a pure computation runs without one.
"""

from __future__ import annotations

import time
from collections.abc import Callable

#: target wall time of one kernel call [s]; an interrupt waits about this long (a few times it on a
#: loaded machine)
SLICE_S = 0.05
#: a slice grows by at most this factor from one call to the next (the first call may include loading
#: the compiled code, and a short slice costs only the call)
GROWTH = 4


def run_in_slices(total: int, kernel: Callable[[int, int], None], first: int = 256, target_s: float = SLICE_S,
                  check: Callable[[], None] | None = None) -> int:
    """Call ``kernel(k0, k1)`` over ``[0, total)`` in consecutive slices of about ``target_s`` each,
    starting with ``first`` steps; after each call run ``check`` (when given), which raises to stop.
    Returns the number of calls."""
    k0, n, calls = 0, max(1, int(first)), 0
    while k0 < total:
        k1 = min(total, k0 + n)
        t = time.perf_counter()
        kernel(k0, k1)
        dt = time.perf_counter() - t
        calls += 1
        if check is not None:
            check()
        k0 = k1
        n = max(1, min(GROWTH * n, int(n * target_s / max(dt, 1e-9))))
    return calls
