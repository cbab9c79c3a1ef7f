"""One observer of a swarm, fed the same way by the simulator, the world and replay.

Built from a scenario (and the obstacle-goal combination in use), it owns what measuring a swarm
needs: the obstacle index, the metric context (robot radius, sensing radius, the design's spacing
d^f), the energy of eq 35 and the run's :class:`~zswarm.swarm.metrics.Summary`. Each observed step is
``(t, ids, positions, velocities, prey)``; nothing else about where the states came from matters,
so a live run, its reference simulation and a replay of its recording fold into identical summaries.
"""

from __future__ import annotations

import numpy as np

from zswarm.paper.formation import epsilon
from zswarm.paper.field import Law, compile_law, swarm_field
from zswarm.swarm.metrics import GroupTally, MetricContext, Summary, group_names, step_metrics
from zswarm.paper.neighbours import ObstacleIndex, pairs_within
from zswarm.paper.potentials import Combination
from zswarm.swarm.scenarios import Scenario


class SwarmObserver:
    """Measures a swarm step by step and folds the steps into a summary (see the module doc)."""

    def __init__(self, scenario: Scenario, combination: Combination | None = None, law: Law | None = None) -> None:
        """``law``: the scenario's compiled law, when the caller has it already (the simulator)."""
        p = scenario.params
        self.scenario = scenario
        self.law = law or compile_law(p, combination or scenario.combination, scenario.formation)
        self.combination: Combination = self.law.combination
        centers, radii = scenario.obstacle_arrays()
        self.obstacles = ObstacleIndex(centers, radii, p.swarm.sensing_radius)
        self.context = MetricContext(
            robot_radius=p.swarm.robot_radius, sensing_radius=p.swarm.sensing_radius,
            spacing=self.law.spacing if scenario.formation else None, obstacles=self.obstacles)
        self.summary = Summary(capture_radius=scenario.capture_radius,
                               epsilon=epsilon(p.potential, scenario.n_agents))
        if len(scenario.members()) > 1:  # a mixed swarm: each group in the summary
            of, ids = scenario.group_of(np.arange(scenario.n_agents)), np.arange(scenario.n_agents)
            self.summary.groups = [group_names(ids[of == g], choice, body) if (of == g).any() else None
                                   for g, (choice, body) in enumerate(scenario.groups())]
            self.summary.group_tally = GroupTally(1, len(self.summary.groups))

    def thresholds(self) -> dict[str, float]:
        """The lines the metrics are read against: capture radius, 2 d^r, d_m^ro and Prop 3's epsilon."""
        p = self.scenario.params
        return {"capture_radius": self.scenario.capture_radius, "collision_distance": 2.0 * p.swarm.robot_radius,
                "d_m_ro": p.margins.d_m_ro, "epsilon": self.summary.epsilon}

    def energy(self, positions: np.ndarray, goal: np.ndarray,
               pairs: tuple[np.ndarray, np.ndarray] | None = None) -> float:
        """Sum of the agents' potentials U_i (eq 35), each from what it senses at ``positions``;
        ``pairs``: every pair within the sensing radius there, when the caller has them already."""
        sensed = None if pairs is None else (pairs[0], positions[pairs[0]] - positions[pairs[1]])
        u, _ = swarm_field(self.law, self.obstacles, positions, goal, sensed, force=False)
        return float(u.sum())

    def observe(self, t: float, ids: np.ndarray, positions: np.ndarray, velocities: np.ndarray,
                prey: np.ndarray, energy: float | None = None) -> dict[str, float]:
        """Measure one step and add it to the summary; ``energy`` if the caller has it already. The
        pairs within the sensing radius are found once, for the energy and the metrics."""
        pairs = pairs_within(positions, self.context.sensing_radius)
        if energy is None:
            energy = self.energy(positions, prey, pairs)
        metrics, colliding, contacts = step_metrics(positions, velocities, prey, self.context, energy, pairs)
        fresh = self.summary.add(t, metrics, np.asarray(ids)[colliding] if len(colliding) else colliding, contacts)
        groups = self.summary.group_tally
        if groups is not None:  # a mixed swarm: each group's share
            group = self.scenario.group_of(np.asarray(ids))[None]
            i, j = pairs
            keep = i < j
            i, j = i[keep], j[keep]
            zero = np.zeros(len(i), dtype=np.intp)
            groups.observe(group, zero, i, j, np.linalg.norm(positions[i] - positions[j], axis=1),
                           np.linalg.norm(positions - prey, axis=1)[None])
            hit = colliding[fresh]
            groups.collided(group, np.zeros(len(hit), dtype=np.intp), hit[:, 0], hit[:, 1])
        return metrics
