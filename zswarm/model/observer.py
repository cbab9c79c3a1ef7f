"""One observer of a swarm, fed the same way by the simulator, the world and replay.

Built from a scenario (and the obstacle-goal combination in use), it owns what measuring a swarm
needs: the obstacle index, the metric context (robot radius, sensing radius, the design's spacing
d^f), the energy of eq 35 and the run's :class:`~zswarm.model.metrics.Summary`. Each observed step is
``(t, ids, positions, velocities, prey)``; nothing else about where the states came from matters,
so a live run, its reference simulation and a replay of its recording fold into identical summaries.
"""

from __future__ import annotations

import numpy as np

from zswarm.model.design import epsilon
from zswarm.model.formation import equilibria
from zswarm.model.metrics import MetricContext, Summary, step_metrics
from zswarm.model.neighbour_law import neighbour_law
from zswarm.model.neighbours import ObstacleIndex, pairs_within
from zswarm.model.potentials import (
    Combination,
    Controller,
    field,
    make_controller,
    obstacle_offsets,
)
from zswarm.model.scenarios import Scenario

_NO_PAIRS = np.zeros(0, dtype=np.intp)


def swarm_field(controller: Controller, obstacles: ObstacleIndex, positions: np.ndarray, goal: np.ndarray,
                pairs: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Every agent's U_i and F_i = -grad_i U_i (eqs 12/14 with eqs 25-28) from what it senses.

    Obstacles are the ones within the sensing radius of ``obstacles``; ``pairs`` is ``(i, psi_f)``,
    the neighbour terms each agent i uses with psi^f = P_i - P_j as it believes it (default: every
    pair within the sensing radius, at the true positions). ``goal`` is (2,) or one per agent (N, 2).
    """
    c = controller
    if not c.formation:
        i, psi_f = _NO_PAIRS, np.zeros((0, positions.shape[1]))
    elif pairs is None:
        i, j = pairs_within(positions, obstacles.sensing_radius)
        psi_f = positions[i] - positions[j]
    else:
        i, psi_f = pairs
    a, m = obstacles.sensed(positions)
    psi_o = obstacle_offsets(positions[a], obstacles.centers[m], obstacles.radii[m])
    return field(positions - goal, a, psi_o, i, psi_f, c.p, c.combination, c.c_f, c.law)


class SwarmObserver:
    """Measures a swarm step by step and folds the steps into a summary (see the module doc)."""

    def __init__(self, scenario: Scenario, combination: Combination | None = None) -> None:
        p = scenario.params
        self.scenario = scenario
        self.combination: Combination = combination or scenario.combination
        self.controller = make_controller(p.potential, self.combination, scenario.formation, neighbour_law(p))
        centers, radii = scenario.obstacle_arrays()
        self.obstacles = ObstacleIndex(centers, radii, p.swarm.sensing_radius)
        self.context = MetricContext(
            robot_radius=p.swarm.robot_radius, sensing_radius=p.swarm.sensing_radius,
            spacing=equilibria(p.potential).spacing if scenario.formation else None, obstacles=self.obstacles)
        self.summary = Summary(capture_radius=scenario.capture_radius,
                               epsilon=epsilon(p.potential, scenario.n_agents))

    def thresholds(self) -> dict[str, float]:
        """The lines the metrics are read against: capture radius, 2 d^r, d_m^ro and Prop 3's epsilon."""
        p = self.scenario.params
        return {"capture_radius": self.scenario.capture_radius, "collision_distance": 2.0 * p.swarm.robot_radius,
                "d_m_ro": p.margins.d_m_ro, "epsilon": self.summary.epsilon}

    def energy(self, positions: np.ndarray, goal: np.ndarray) -> float:
        """Sum of the agents' potentials U_i (eq 35), each from what it senses at ``positions``."""
        u, _ = swarm_field(self.controller, self.obstacles, positions, goal)
        return float(u.sum())

    def observe(self, t: float, ids: np.ndarray, positions: np.ndarray, velocities: np.ndarray,
                prey: np.ndarray, energy: float | None = None) -> dict[str, float]:
        """Measure one step and add it to the summary; ``energy`` if the caller has it already."""
        if energy is None:
            energy = self.energy(positions, prey)
        metrics, colliding, contacts = step_metrics(positions, velocities, prey, self.context, energy)
        self.summary.add(t, metrics, np.asarray(ids)[colliding] if len(colliding) else colliding, contacts)
        return metrics
