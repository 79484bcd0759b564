"""Records of scenarios simulated in memory: the :class:`~inscal.io.records.Record` a built-in or TOML
scenario gives, with its truth, without writing a file (examples, tests, studies)."""

from __future__ import annotations

import numpy as np

from inscal.io.records import Record
from inscal.sim.scenarios import build
from inscal.sim.simulate import simulate


def scenario_record(name: str, rng: np.random.Generator | None, duration_s: float | None = None,
                    rate_hz: float | None = None) -> Record:
    """The record of a scenario, simulated in memory: :func:`~inscal.sim.scenarios.build`, then
    :func:`~inscal.sim.simulate.simulate` and :meth:`~inscal.sim.simulate.SimData.to_record`.

    Parameters
    ----------
    name : str
        A built-in name (``inscal.sim.scenarios.BUILTIN``) or a scenario TOML file, as for
        :func:`~inscal.sim.scenarios.build`.
    rng : numpy.random.Generator or None
        The generator of the noise (None: no noise drawn; a scenario with noise needs one).
    duration_s, rate_hz : float, optional
        The duration [s] and another sample rate [Hz], as for :func:`~inscal.sim.scenarios.build`.

    Returns
    -------
    Record
        The increments, the gimbal angles, the rate, the site, the path and the truth (the scenario's
        errors), as :func:`inscal.io.load_record` returns them from a written simulation.

    Raises
    ------
    inscal.sim.scenarios.ScenarioError
        What :func:`~inscal.sim.scenarios.build` rejects.

    Examples
    --------
    >>> import numpy as np
    >>> from inscal.sim.records import scenario_record
    >>> rec = scenario_record("static", np.random.default_rng(0), duration_s=60.0, rate_hz=10.0)
    >>> rec.dtheta.shape, rec.rate_hz, rec.scenario
    ((600, 3), 10.0, 'static')
    """
    return simulate(build(name, duration_s, rate_hz), rng).to_record()
