"""What the safety filter did over a run, the same counts for the simulators and the processes.

- ``safety_interventions``: agent-steps (ticks) whose command the filter changed;
- ``safety_stalled_ticks``: agent-steps it left under a tenth of the law's speed (a deadlock shows as a
  run of these: two agents facing each other, each waiting for the other; so does a swarm held at its
  goal against a law that would crush it), ``safety_stalled_agents`` the agents stalled for at least a
  second in a row at some point, ``safety_stalled_at_end`` those stalled at the last step;
- ``safety_braked_ticks``: agent-steps stopped because a neighbour's data was older than the bound.

An agent process counts the same per tick (``agents.counters``); the world sums them.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from zswarm.errors import ParamError
from zswarm.control import safety as sf


def safety_of(scenario, mode: str) -> sf.Safety | None:
    """The filter a run of ``scenario`` uses under ``mode`` (None: off), one for all its agents whatever
    their bodies (a unicycle's look-ahead widens the rows of its own pairs:
    :func:`zswarm.control.safety.widening`); raises :class:`ParamError` for a combination the filter cannot
    keep safe."""
    sf.parse_mode(mode)
    if mode == "off":
        return None
    if any(body == "double-integrator" for _, body in scenario.groups()):
        raise ParamError("--safety barrier needs a body that can stop within a step; a double-integrator "
                         "needs v^2/(2 accel) to stop, which this filter does not model: use --safety off")
    return sf.safety_for(scenario.params, scenario.dt)  # each body's look-ahead widens its own rows (the step)


class SafetyTally:
    def __init__(self, dt: float = 0.05) -> None:
        self.steps = 0
        self.interventions = self.stalled_steps = self.braked_steps = 0
        self.stalled_now = np.zeros(0, dtype=bool)
        self.run = np.zeros(0, dtype=np.int64)
        self.long = np.zeros(0, dtype=bool)
        self.second = max(int(round(1.0 / dt)), 1)

    def add(self, f: sf.Filtered) -> None:
        if len(self.run) != len(f.acted):
            self.run = np.zeros(len(f.acted), dtype=np.int64)
            self.long = np.zeros(len(f.acted), dtype=bool)
        self.steps += 1
        self.interventions += int(f.acted.sum())
        self.stalled_steps += int(f.stalled.sum())
        self.braked_steps += int(f.braked.sum())
        self.run = np.where(f.stalled, self.run + 1, 0)
        self.long |= self.run >= self.second
        self.stalled_now = f.stalled

    def result(self) -> dict[str, Any]:
        if self.steps == 0:
            return {}
        return {"safety_interventions": self.interventions, "safety_stalled_ticks": self.stalled_steps,
                "safety_stalled_at_end": int(self.stalled_now.sum()), "safety_stalled_agents": int(self.long.sum()),
                "safety_braked_ticks": self.braked_steps}
