"""ORCA beside the safety filter: RVO2 (van den Berg, Guy, Lin & Manocha 2011) through ``pyrvo``.

An anchor for ``zswarm bench safety``, not part of zswarm: ``pyrvo`` is imported only here, and only
where it installs (``pip install pyrvo``). Each step every agent's preferred velocity is the law's
command; RVO2 returns the velocity closest to it inside its half-planes (each agent taking half of
each pair's avoidance, as the filter does) and the speed disc, from the exact positions and
velocities of every agent (ORCA assumes exact neighbour states; it has no notion of data age). The
agents' radius is d^r (plus the filter's hair), the neighbour distance the sensing radius, and obstacles are their circles as
32-gons drawn around them (so the polygon contains the circle).
"""

from __future__ import annotations

import math

import numpy as np

from zswarm.control.safety import HAIR, Filtered, judged

TIME_HORIZON = 2.0  # s: RVO2's examples use 10 at speed 2; this swarm is dense, so a shorter horizon
SIDES = 32


def available() -> bool:
    try:
        import pyrvo  # noqa: F401
    except ImportError:
        return False
    return True


class Orca:
    """One RVO2 simulator for one swarm, fed the swarm's state each step."""

    def __init__(self, n: int, params, dt: float, centers: np.ndarray, radii: np.ndarray) -> None:
        import pyrvo

        s = params.swarm
        self.sim = pyrvo.RVOSimulator()
        self.sim.set_time_step(dt)
        # neighbour distance, max neighbours, time horizon (agents, obstacles), radius, max speed
        radius = s.robot_radius * (1.0 + HAIR)  # the hair the filter keeps too, so both count collisions alike
        self.sim.set_agent_defaults(s.sensing_radius, 64, TIME_HORIZON, TIME_HORIZON, radius, s.v_max)
        for _ in range(n):
            self.sim.add_agent((0.0, 0.0))
        outer = 1.0 / math.cos(math.pi / SIDES)  # the polygon's inscribed circle is the obstacle's
        for c, r in zip(centers, radii):
            ring = [(float(c[0] + outer * r * math.cos(2 * math.pi * k / SIDES)),
                     float(c[1] + outer * r * math.sin(2 * math.pi * k / SIDES))) for k in range(SIDES)]
            if r > 0:
                self.sim.add_obstacle(ring)
        if len(radii):
            self.sim.process_obstacles()

    def command(self, positions: np.ndarray, velocities: np.ndarray, preferred: np.ndarray) -> np.ndarray:
        """The velocity RVO2 picks for every agent this step (2-D only)."""
        out = np.empty_like(preferred)
        for i, (p, u, w) in enumerate(zip(positions, velocities, preferred)):
            self.sim.set_agent_position(i, (float(p[0]), float(p[1])))
            self.sim.set_agent_velocity(i, (float(u[0]), float(u[1])))
            self.sim.set_agent_pref_velocity(i, (float(w[0]), float(w[1])))
        self.sim.do_step()
        for i in range(len(out)):
            v = self.sim.get_agent_velocity(i)
            out[i] = v.to_tuple() if hasattr(v, "to_tuple") else tuple(v)
        return out

    def __call__(self, wanted: np.ndarray, obs, guard, state) -> Filtered:
        """ORCA in the safety filter's place (:data:`zswarm.control.step.Filter`): one swarm, (1, N, D)."""
        v = self.command(state.position[0], state.velocity[0], wanted[0])
        return judged(wanted[0], v, np.zeros(len(v), dtype=bool))
