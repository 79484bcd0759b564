"""``calibrate … --station FILE.toml --mc N`` and ``observability --crlb --station --method M --mc N``: the JCGM 101
Monte Carlo of the budget (:func:`inscal.uncertainty.montecarlo.budget_monte_carlo`), refused with one line."""

from __future__ import annotations

from inscal.cli.common import CliError


def run_budget_mc(res, station, budget, runs: int, seed: int, workers: int = 1, options: dict | None = None) -> dict:
    """The Monte Carlo of ``budget`` (a :class:`inscal.uncertainty.budget.Budget` of ``res`` at ``station``) as JSON:
    adaptive (JCGM 101 7.9) up to ``runs`` trials, ``workers`` > 1 on a local Dask cluster."""
    from inscal.uncertainty.montecarlo import budget_monte_carlo

    try:
        return budget_monte_carlo(res, station, budget, runs, seed, workers, options).to_dict()
    except ValueError as exc:
        raise CliError(f"--mc: {exc}") from None
