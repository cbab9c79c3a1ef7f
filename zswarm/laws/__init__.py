"""Swarm laws behind one contract (:mod:`zswarm.laws.contract`): the paper's ``apf`` and three laws
from the literature (``olfati-saber``, ``vasarhelyi``, ``boids``), or a user's own function or class,
found by name (:mod:`zswarm.laws.registry`) and bound to a run (:class:`zswarm.laws.bound.BoundLaw`).

    def rush(obs):                       # zswarm sim --law my_law.py:rush
        to = obs.target - obs.position
        return obs.v_max * to / max(float((to @ to) ** 0.5), 1e-9)
"""

from zswarm.laws.contract import Context, Neighbour, Observation, Observations, Obstacle, SwarmLaw, param

__all__ = ["Context", "Neighbour", "Observation", "Observations", "Obstacle", "SwarmLaw", "param"]
