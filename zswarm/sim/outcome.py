"""What one simulated run did, measured lean: the outcome a study of many runs needs.

:func:`run_outcome` steps the reference simulator (its cell grid scales to thousands of agents) as a
batch of one (:class:`zswarm.sim.simulator.OneRun`) through the step loop and tally of
:mod:`zswarm.sim.tally` that the batched simulator's runs go through: the same keys, each counted as
:class:`zswarm.model.metrics.Summary` counts it.
"""

from __future__ import annotations

import numpy as np

from zswarm.model.scenarios import Scenario
from zswarm.sim.simulator import OneRun, Shield, Simulator
from zswarm.sim.tally import Outcome, OutcomeTally, drive


def run_outcome(scenario: Scenario, seed: int, stop_at_collision: bool = False, safety: str = "off",
                shield: Shield | None = None) -> Outcome:
    """The run's outcome; with ``stop_at_collision`` the run ends at its first collision. ``safety``:
    the filter's mode (:mod:`zswarm.model.safety`); ``shield``: another filter of the commands, called
    with the simulator and the law's commands (``zswarm bench safety`` puts ORCA there)."""
    sim = Simulator(scenario, seed, safety=safety)
    p = scenario.params.swarm
    tally = OutcomeTally(1, scenario.n_agents, scenario.dt, np.array([scenario.capture_radius]),
                         np.array([p.robot_radius]))
    run = OneRun(sim, shield)
    drive(run, scenario.steps, tally, stop_at_collision)
    return tally.outcomes(run.safety_counts())[0]
