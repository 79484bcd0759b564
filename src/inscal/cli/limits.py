"""What a command's size options ask for, refused up front in one line.

Before a command allocates anything that grows with a size option (a duration, a rate, a number of
candidates, runs or workers), it estimates the memory that option asks for (the estimates live with
the algorithms: :func:`inscal.plan.bound.bound_bytes`, :func:`inscal.plan.observability.observability_bytes`,
:func:`inscal.plan.design.search_size`) and :func:`check_memory` refuses (a :class:`CliError`: one
line on stderr, exit code 2) a run that needs more than :data:`MEMORY_FRACTION` of the memory
available now.  Absolute caps (a number of filter steps, samples or runs beyond which no run is
sensible, whatever the machine) are checked beside it by each command.
"""

from __future__ import annotations

import math

from inscal.cli.common import CliError

#: a run may take at most this fraction of the memory available when it starts (the rest: the
#: interpreter, the compiled kernels, the other programs)
MEMORY_FRACTION = 0.8
#: memory of one process of a local Dask cluster: a worker (265 MB measured with the plan kernels
#: loaded) and its nanny
DASK_WORKER_BYTES = 400e6


def available_memory() -> float | None:
    """Memory available to a new allocation without swapping [bytes] (psutil, else MemAvailable of
    /proc/meminfo); None where neither says."""
    try:
        import psutil

        return float(psutil.virtual_memory().available)
    except (ImportError, OSError, AttributeError):
        pass
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except (OSError, ValueError, IndexError):
        pass
    return None


def human_bytes(nbytes: float) -> str:
    """``12.3 GB`` (decimal units)."""
    if not math.isfinite(nbytes):
        return "an unbounded amount"
    for unit in ("B", "kB", "MB", "GB", "TB", "PB"):
        if abs(nbytes) < 1000 or unit == "PB":
            return f"{nbytes:.3g} {unit}"
        nbytes /= 1000
    return f"{nbytes:.3g} PB"  # pragma: no cover


def human_seconds(s: float) -> str:
    """A duration in the largest sensible unit (``40 s``, ``12 min``, ``7.2 h``, ``3.1 days``, ``2e+03 years``)."""
    if not math.isfinite(s):
        return "forever"
    for unit, size in (("years", 365.25 * 86400), ("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if s >= 2 * size:
            return f"{s / size:.3g} {unit}"
    return f"{s:.2g} s"


def check_memory(need: float, what: str, hint: str) -> None:
    """Refuse (:class:`CliError`) ``what`` when it ``need`` s more than :data:`MEMORY_FRACTION` of the
    available memory: "WHAT needs about X of memory (this machine has Y available); HINT"."""
    avail = available_memory()
    if avail is None:
        return
    if not need <= MEMORY_FRACTION * avail:
        raise CliError(f"{what} needs about {human_bytes(need)} of memory (this machine has {human_bytes(avail)} "
                       f"available); {hint}")


def check_count(value: float, cap: float, what: str, hint: str) -> None:
    """Refuse (:class:`CliError`) a count (steps, samples, runs) above an absolute cap."""
    if not value <= cap:
        raise CliError(f"{what} (at most {cap:.0e}); {hint}")


#: memory per trial of the budget's Monte Carlo (JCGM 101): every trial's estimate is kept (at most 48
#: parameter components, 8 bytes) and each component's column is copied, drawn into and sorted once more
MC_TRIAL_BYTES = 48 * 8 * 3


def check_mc_trials(mc: int | None) -> None:
    """Refuse (:class:`CliError`) a ``--mc`` outside 100 .. 10^7 trials or beyond the available memory."""
    if mc is None:
        return
    if not 100 <= mc <= 10**7:
        raise CliError(f"--mc {mc}: between 100 and 10^7 trials")
    check_memory(mc * MC_TRIAL_BYTES, f"--mc {mc} (the budget's Monte Carlo keeps every trial)",
                 "lower --mc (the adaptive run stops once every component is decided)")
