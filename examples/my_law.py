"""Two swarm laws written outside zswarm, for docs/laws.md's tutorial (run by tests/test_law_processes.py).

    zswarm sim --scenario moving-prey --law examples/my_law.py:seek --json
    zswarm sim --scenario moving-prey --law examples/my_law.py:Spring --set law.stiffness=2 --json
"""

from dataclasses import dataclass

import numpy as np

from zswarm.laws import SwarmLaw, param


def seek(obs):
    """At the target at full speed, stepping aside from neighbours closer than 0.6."""
    to = obs.target - obs.position
    v = obs.v_max * to / max(float(np.linalg.norm(to)), 1e-9)
    for nb in obs.neighbours:
        away = obs.position - nb.position
        d = float(np.linalg.norm(away))
        if 0.0 < d < 0.6:
            v = v + 2.0 * obs.v_max * (0.6 - d) / 0.6 * away / d
    return v


@dataclass(frozen=True)
class SpringParams:
    stiffness: float = param(1.0, "rate", "pull toward the neighbours' centre, per second")
    rest: float = param(0.8, "length", "no pull within this distance of the centre")


class Spring(SwarmLaw):
    """Seek the target, held to the neighbours by a spring; a batched form for the batched simulator."""

    name = "spring"
    reference = "examples/my_law.py (the tutorial in docs/laws.md)"
    Params = SpringParams
    needs = ()
    ranges = {"stiffness": (0.1, 5.0)}

    def batch(self, obs):
        p = self.params
        to = obs.target - obs.position
        dist = np.linalg.norm(to, axis=-1, keepdims=True)
        v = np.asarray(obs.v_max, dtype=float)[..., None] * to / np.maximum(dist, 1e-9)
        count = obs.neighbour_mask.sum(axis=-1)[..., None]
        centre = np.where(obs.neighbour_mask[..., None], obs.neighbour_position, 0.0).sum(axis=-2)
        off = np.where(count > 0, centre / np.maximum(count, 1) - obs.position, 0.0)
        stretch = np.maximum(np.linalg.norm(off, axis=-1, keepdims=True) - p.rest, 0.0)
        v = v + p.stiffness * stretch * off / np.maximum(np.linalg.norm(off, axis=-1, keepdims=True), 1e-9)
        speed = np.linalg.norm(v, axis=-1, keepdims=True)
        top = np.asarray(obs.v_max, dtype=float)[..., None]
        return v * np.minimum(1.0, top / np.maximum(speed, 1e-12))
