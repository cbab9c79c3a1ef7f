"""What one simulated run did, measured lean: the outcome a study of many runs needs.

:func:`run_outcome` steps the reference simulator (its cell grid scales to thousands of agents) as a
batch of one (:class:`zswarm.sim.simulator.OneRun`) through the step loop and tally of
:mod:`zswarm.swarm.tally` that the batched simulator's runs go through: the same keys, each counted as
:class:`zswarm.swarm.metrics.Summary` counts it.
"""

from __future__ import annotations

import numpy as np

from zswarm.swarm.scenarios import Scenario
from zswarm.control.step import Filter
from zswarm.sim.simulator import OneRun, Simulator
from zswarm.swarm.tally import Outcome, OutcomeTally, drive


def run_outcome(scenario: Scenario, seed: int, stop_at_collision: bool = False, safety: str = "off",
                shield: Filter | None = None) -> Outcome:
    """The run's outcome; with ``stop_at_collision`` the run ends at its first collision. ``safety``:
    the filter's mode (:mod:`zswarm.control.safety`); ``shield``: another filter in its place
    (:data:`zswarm.control.step.Filter`; ``zswarm bench safety`` puts ORCA there)."""
    sim = Simulator(scenario, seed, safety=safety, shield=shield)
    p = scenario.params.swarm
    tally = OutcomeTally(1, scenario.n_agents, scenario.dt, np.array([scenario.capture_radius]),
                         np.array([p.robot_radius]))
    run = OneRun(sim)
    drive(run, scenario.steps, tally, stop_at_collision)
    return tally.outcomes(run.safety_counts())[0]
