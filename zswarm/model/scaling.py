"""How a registered scenario grows to N agents (``--set n_agents=N``): one rule, written down here.

A scenario is designed at its own size N0. Asked for N agents, it keeps what made it work there:

- **density**: the spawn box grows by sqrt(N/N0) in both directions, away from the goal (its right
  edge, which faces the goal in every registered scenario, stays where it is; its height grows about
  its centre);
- **the goal's pull at the start**: with D(N) the distance from the spawn box's centre to the goal,
  l_g, c_g and c_o are multiplied by D(N)/D(N0) (never less than 1). The start stays at the same
  fraction of l_g, so its pull is not lost in the Gaussian tail of eq 7; the peak pull c_g/l_g and
  Props 1-2's ratio c_g/c_o are unchanged;
- **time to get there**: the duration is at least 2 D(N)/v_max + 20 s (the swarm must cover D at
  less than v_max, then settle);
- **the interaction**: the paper's (eqs 26-28) up to :data:`PAPER_MAX_N` agents, where the default
  set passes every guideline; ``scalable`` above it (docs/scaling.md: the paper's sum squeezes
  larger swarms onto each other).

``large-swarm`` and ``bench-field`` are built for any N by their own functions, and take the
interaction rule only. An explicit ``--set`` of any of these values wins over the rule.
"""

from __future__ import annotations

import dataclasses
import math

from zswarm.model.scenario import Scenario

#: Up to this N the registered scenarios use the paper's interaction; the default set passes every
#: design check with it up to here (``zswarm design --set n_agents=N``), and fails from N = 15.
PAPER_MAX_N = 12


def interaction_for(n_agents: int) -> str:
    return "paper" if n_agents <= PAPER_MAX_N else "scalable"


def run_time(distance: float, v_max: float) -> float:
    """The time a run is given to cover ``distance`` and settle."""
    return 3.0 * distance / v_max + 20.0


def start_distance(scenario: Scenario) -> float:
    x0, y0, x1, y1 = scenario.spawn
    return math.hypot((x0 + x1) / 2 - scenario.prey_start[0], (y0 + y1) / 2 - scenario.prey_start[1])


def scale_to(scenario: Scenario, n_agents: int) -> Scenario:
    """``scenario`` grown (or shrunk) to ``n_agents`` by the rule of this module."""
    n0 = scenario.params.swarm.n_agents
    x0, y0, x1, y1 = scenario.spawn
    f = math.sqrt(n_agents / n0)
    cy, h = (y0 + y1) / 2, (y1 - y0) * f
    grown = dataclasses.replace(scenario, spawn=(x1 - (x1 - x0) * f, cy - h / 2, x1, cy + h / 2))
    k = max(1.0, start_distance(grown) / start_distance(scenario))
    p = scenario.params.potential
    v_max = scenario.params.swarm.v_max
    params = scenario.params.with_values({
        "n_agents": n_agents, "l_g": p.l_g * k, "c_g": p.c_g * k, "c_o": p.c_o * k,
        "interaction": interaction_for(n_agents)})
    duration = max(scenario.duration, run_time(start_distance(grown), v_max))
    return dataclasses.replace(grown, params=params, duration=duration)
