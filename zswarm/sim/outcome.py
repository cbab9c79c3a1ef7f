"""What one simulated run did, measured lean: the outcome a study of many runs needs.

:func:`run_outcome` steps the reference simulator (:class:`zswarm.sim.simulator.Simulator`) and
folds, at every step, exactly what :class:`zswarm.model.metrics.Summary` counts for these keys
(collisions as onsets of pairs within the sensing radius closer than 2 d^r, obstacle contacts as
onsets of a clearance below d^r, capture as the first step the centroid is within the capture radius),
without the per-step metrics a recording needs (the Fiedler value alone is an N^3 eigensolve). The
keys are those of :class:`zswarm.sim.batch.BatchOutcome`, so a study can take runs from either.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from zswarm.model.metrics import components
from zswarm.model.neighbours import pairs_within
from zswarm.model.safety import judged
from zswarm.model.safety_tally import SafetyTally
from zswarm.model.scenarios import Scenario
from zswarm.sim.batch import BatchOutcome
from zswarm.sim.simulator import Simulator


def run_outcome(scenario: Scenario, seed: int, stop_at_collision: bool = False, safety: str = "off",
                shield: Callable[[Simulator, np.ndarray], np.ndarray] | None = None) -> BatchOutcome:
    """The run's outcome; with ``stop_at_collision`` the run ends at its first collision (a study that
    only asks whether a set collides need not simulate a crushed swarm to its end). ``safety``: the
    filter's mode (:mod:`zswarm.model.safety`); ``shield``: another filter of the commands, called with
    the simulator and the law's commands (``zswarm bench safety`` puts ORCA there), whose changes
    are counted as the filter's are."""
    sim = Simulator(scenario, seed, safety=safety)
    tally = SafetyTally(scenario.dt)
    p = scenario.params.swarm
    collide, touch = 2.0 * p.robot_radius, p.robot_radius
    was_close: set[tuple[int, int]] = set()
    was_touching: set[tuple[int, int]] = set()
    collisions = contacts = 0
    min_pair, min_clear = math.inf, math.inf
    capture = None
    for k in range(scenario.steps + 1):
        x = sim.positions
        i, j = pairs_within(x, p.sensing_radius)
        d = np.sqrt(np.einsum("ij,ij->i", x[i] - x[j], x[i] - x[j]))
        if len(d):
            min_pair = min(min_pair, float(d.min()))
        close = (d < collide) & (i < j)
        now = set(zip(i[close].tolist(), j[close].tolist()))
        collisions += len(now - was_close)
        was_close = now
        a, m = sim.obstacles.sensed(x)
        clear = np.linalg.norm(x[a] - sim.obstacles.centers[m], axis=1) - sim.obstacles.radii[m]
        if len(clear):
            min_clear = min(min_clear, float(clear.min()))
        now = set(zip(a[clear < touch].tolist(), m[clear < touch].tolist()))
        contacts += len(now - was_touching)
        was_touching = now
        centroid_distance = float(np.linalg.norm(x.mean(axis=0) - sim.prey))
        if capture is None and centroid_distance <= scenario.capture_radius:
            capture = k * scenario.dt
        if stop_at_collision and collisions:
            break  # i, j, d are this step's pairs: the final figures below come from them
        if k < scenario.steps:
            _, v = sim.potential_and_velocity(x, sim.prey)
            if shield is not None:
                wanted, v = v, shield(sim, v)
                tally.add(judged(wanted, v, np.zeros(len(v), dtype=bool)))
            sim.advance(v)
    nearest = np.full(len(x), np.inf)
    np.minimum.at(nearest, i, d)
    has = np.isfinite(nearest)
    counts = tally if shield is not None else sim.tally
    return BatchOutcome(capture_time=capture, min_pair_distance=min_pair, collisions=collisions,
                        min_obstacle_clearance=min_clear if math.isfinite(min_clear) else None,
                        obstacle_collisions=contacts, final_centroid_goal_distance=centroid_distance,
                        final_components=len(np.unique(components(len(x), i, j))),
                        final_median_nearest=float(np.median(nearest[has])) if has.any() else None,
                        safety_interventions=counts.interventions, safety_stalled_ticks=counts.stalled_steps,
                        safety_braked_ticks=counts.braked_steps)
