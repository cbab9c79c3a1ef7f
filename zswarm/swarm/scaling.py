"""How a registered scenario grows to N agents (``--set n_agents=N``): one rule, its layout magnified
about the goal, its goal range, duration and time step grown with it, the paper's interaction up to
:data:`PAPER_MAX_N` agents (docs/scaling.md, "Scenarios that can be won, at any N"). An explicit
``--set`` of any of these values wins over the rule."""

from __future__ import annotations

import dataclasses
import math

from zswarm.paper.params import Params
from zswarm.swarm.scenario import Scenario

#: Up to this N the registered scenarios use the paper's interaction; the default set passes every
#: design check with it up to here (``zswarm design --set n_agents=N``), and fails from N = 15.
PAPER_MAX_N = 12


def interaction_for(n_agents: int) -> str:
    return "paper" if n_agents <= PAPER_MAX_N else "scalable"


def run_time(distance: float, v_max: float) -> float:
    """The time a run is given to cover ``distance`` and settle."""
    return 3.0 * distance / v_max + 20.0


def start_distance(scenario: Scenario) -> float:
    d = scenario.dimensions
    lo, hi = scenario.spawn[:d], scenario.spawn[d:]
    return math.hypot(*((lo[k] + hi[k]) / 2 - scenario.prey_start[k] for k in range(d)))


def scale_to(scenario: Scenario, n_agents: int) -> Scenario:
    """``scenario`` grown (or shrunk) to ``n_agents`` by the rule of this module."""
    n0, d = scenario.params.swarm.n_agents, scenario.dimensions
    f = math.sqrt(n_agents / n0) if d == 2 else math.cbrt(n_agents / n0)  # constant density in d dimensions
    g = scenario.prey_start
    spawn = tuple(g[k % d] + f * (c - g[k % d]) for k, c in enumerate(scenario.spawn))
    gz = g[2] if d == 3 else 0.0
    grown = dataclasses.replace(
        scenario, spawn=spawn,
        obstacles=tuple(dataclasses.replace(o, x=g[0] + f * (o.x - g[0]), y=g[1] + f * (o.y - g[1]),
                                            z=gz + f * (o.z - gz) if d == 3 else o.z)
                        for o in scenario.obstacles),
        capture_radius=scenario.capture_radius * max(f, 1.0))
    p = scenario.params.potential
    k = max(1.0, start_distance(grown) / math.sqrt(2.0) / p.l_g) if n_agents > n0 else 1.0
    v_max = scenario.params.swarm.v_max
    params = scenario.params.with_values({
        "n_agents": n_agents, "l_g": p.l_g * k, "c_g": p.c_g * k, "c_o": p.c_o * k,
        "interaction": interaction_for(n_agents)})
    duration = max(scenario.duration, run_time(start_distance(grown), v_max))
    return dataclasses.replace(grown, params=params, duration=duration, dt=stable_dt(params, scenario.dt))


def stable_dt(params: Params, dt: float) -> float:
    """``dt``, halved until the design's time step check holds for ``params`` (at most five times)."""
    from zswarm.paper.stiffness import time_step

    for _ in range(5):
        if time_step(params, dt)["holds"]:
            break
        dt /= 2.0
    return dt
