"""``calibrate … --station FILE.toml --mc N``: the JCGM 101 Monte Carlo of the budget (:mod:`inscal.lab.budget_mc`),
in this process or on a local Dask cluster (``--mc-workers``), with its progress on stderr."""

from __future__ import annotations

import sys

from inscal.cli.common import CliError


class _Progress:
    """Trials done on stderr: at every 10 % (a log) or a Rich bar (a terminal)."""

    def __init__(self, total: int):
        from rich.console import Console

        self.total, self.next_pct, self.bar = total, 10, None
        con = Console(stderr=True)
        if con.is_terminal:
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

            self.bar = Progress(TextColumn("JCGM 101 Monte Carlo"), BarColumn(), MofNCompleteColumn(),
                                TimeElapsedColumn(), console=con)
            self.bar.start()
            self.task = self.bar.add_task("mc", total=total)

    def update(self, done: int, total: int) -> None:
        if self.bar is not None:
            self.bar.update(self.task, completed=done, total=total)
            return
        pct = 100.0 * done / max(1, total)
        if pct >= self.next_pct:
            print(f"budget Monte Carlo: {done} trials (at most {total})", file=sys.stderr, flush=True)
            while self.next_pct <= pct:
                self.next_pct += 10

    def close(self) -> None:
        if self.bar is not None:
            self.bar.stop()


def run_budget_mc(res, station, budget, runs: int, seed: int, workers: int = 1, options: dict | None = None) -> dict:
    """The Monte Carlo of ``budget`` (a :class:`inscal.lab.budget.Budget` of ``res`` at ``station``) as JSON:
    adaptive (JCGM 101 7.9) up to ``runs`` trials, ``workers`` > 1 on a local Dask cluster."""
    from inscal.lab.budget_mc import monte_carlo
    from inscal.lab.sensitivity import WINDOW_METHODS

    if res.method not in WINDOW_METHODS:
        raise CliError(f"--mc: the Monte Carlo of the budget runs the window-mean methods ({', '.join(WINDOW_METHODS)}),"
                       f" not {res.method}: its site and clock inputs enter the filter linearly, and a thousand filter "
                       "runs would take hours")
    client = cluster = None
    map_fn = map
    if workers > 1:
        from inscal.lab.batch import start_client

        client, cluster = start_client("local", workers)

        def map_fn(fn, seeds, sizes):
            return (f.result() for f in client.map(fn, list(seeds), list(sizes), pure=False))

    bar = _Progress(runs)
    try:
        mc = monte_carlo(res, station, budget, runs=runs, seed=seed, adaptive=True, options=options, map_fn=map_fn,
                         progress=bar.update)
    except ValueError as exc:
        raise CliError(f"--mc: {exc}") from None
    finally:
        bar.close()
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
    return mc.to_dict()
