"""Starting Dask for every parallel runner (the Monte Carlo engine, the path design): a local cluster
of single-threaded worker processes, or a connection to a running scheduler."""

from __future__ import annotations

import logging
import warnings

#: the environment of the workers of a local cluster.  Dask's nanny sets ``MALLOC_TRIM_THRESHOLD_``
#: (64 kB) to hand freed memory back to the OS at once; that also pins glibc's mmap threshold, so
#: every array of a run (MB each) is mapped, page-faulted and unmapped again, which made a run of
#: ``n25-fig5`` 1.6x slower on a worker than in the driver.  A run's memory is freed and reused by
#: the next run of the same size, so the default allocator is kept.
LOCAL_WORKER_ENVIRON = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}


def start_client(scheduler: str | None, workers: int, timeout, error: type[Exception],
                 environ: dict | None = None):
    """A Dask client and its local cluster (``None`` when connected to a scheduler): ``scheduler`` None,
    ``""`` or ``"local"`` starts a ``LocalCluster`` of ``workers`` single-threaded processes without a
    dashboard, with the Dask settings ``environ`` (e.g. :data:`LOCAL_WORKER_ENVIRON`) while it starts;
    otherwise connects to the scheduler at that address within ``timeout``, raising ``error`` with one
    line when it cannot.  The caller closes the client, then the cluster."""
    # Dask loads in a second or two: only when a parallel run starts
    import dask
    from distributed import Client, LocalCluster

    if scheduler in (None, "", "local"):
        with warnings.catch_warnings(), dask.config.set(environ or {}):
            # the scheduler's health-check HTTP server moves off a busy port by itself
            warnings.filterwarnings("ignore", message=r"(?s)Port \d+ is already in use")
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                                   silence_logs=logging.ERROR)
        try:
            return Client(cluster), cluster
        except BaseException:  # nothing left running
            cluster.close()
            raise
    try:
        return Client(scheduler, timeout=timeout), None
    except (OSError, TimeoutError) as exc:
        raise error(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
