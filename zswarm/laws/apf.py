"""``apf``: the paper's law (Kim, Wang & Shin 2006, eqs 5-15, 25-28, 35-36) behind the law contract,
with every interaction of :mod:`zswarm.model.interaction`. Its parameters are the scenario's own (the
potential, the interaction, the combination, ``--set c_o=...``); it has no ``[law]`` table.

The batched form is :func:`zswarm.model.law.field` on dense blocks; the single form is the same law in
plain floats in 2-D (:mod:`zswarm.model.agent_law`, ten times cheaper at one agent's size) and
:meth:`zswarm.model.law.Law.velocity` in 3-D. Both keep what lies within the sensing radius (neighbours
by their sensed position, obstacles by their nearest boundary point), as the paper's agent senses it;
``tests/test_law_conformance.py`` holds the two forms equal.
"""

from __future__ import annotations

import numpy as np

from zswarm.laws.contract import Context, Observation, Observations, SwarmLaw
from zswarm.model.agent_law import agent_velocity
from zswarm.model.law import Law, field, sense_one
from zswarm.model.neighbour_law import DensePairs
from zswarm.model.potentials import obstacle_offsets, saturate


class Apf(SwarmLaw):
    name = "apf"
    reference = "Kim, Wang & Shin (2006), eqs 5-15, 25-28, 35-36; zswarm design checks it (Propositions 1-5)"
    needs = ("obstacles",)

    def __init__(self, params: Law, context: Context) -> None:
        """``params``: the scenario's compiled law (:func:`zswarm.model.law.compile_law`)."""
        super().__init__(params, context)
        self.law = params

    def floats(self, position: tuple[float, ...], target: tuple[float, ...], obstacles, neighbours) -> tuple:
        """The 2-D single form in plain floats: ``obstacles`` (cx, cy, radius), ``neighbours`` (x, y, ...)."""
        law = self.law
        return agent_velocity(position[0], position[1], target, obstacles, neighbours, self.context.sensing_radius,
                              law.p, law.combination, law.formation, law.v_max, law.neighbours)

    def command(self, obs: Observation) -> np.ndarray:
        law, radius = self.law, self.context.sensing_radius
        if obs.dims == 2:
            return np.array(agent_velocity(
                float(obs.position[0]), float(obs.position[1]), (float(obs.target[0]), float(obs.target[1])),
                [(float(o.centre[0]), float(o.centre[1]), o.radius) for o in obs.obstacles],
                [(float(n.position[0]), float(n.position[1])) for n in obs.neighbours],
                radius, law.p, law.combination, law.formation, obs.v_max, law.neighbours))
        centres = np.array([o.centre for o in obs.obstacles], dtype=float).reshape(-1, obs.dims)
        radii = np.array([o.radius for o in obs.obstacles], dtype=float)
        others = np.array([n.position for n in obs.neighbours], dtype=float).reshape(-1, obs.dims)
        return law.velocity(obs.position, obs.target, sense_one(obs.position, centres, radii, others, radius),
                            obs.v_max)

    def batch(self, obs: Observations) -> np.ndarray:
        law, r2 = self.law, self.context.sensing_radius ** 2
        x = obs.position
        psi_o = obstacle_offsets(x[..., None, :], obs.obstacle_centre, obs.obstacle_radius)
        sensed_o = obs.obstacle_mask & (np.einsum("...k,...k->...", psi_o, psi_o) <= r2)
        psi_f = x[..., None, :] - obs.neighbour_position
        sensed_f = obs.neighbour_mask & (np.einsum("...k,...k->...", psi_f, psi_f) <= r2) & law.formation
        _, f = field(x - obs.target, DensePairs(sensed_o), psi_o, DensePairs(sensed_f), psi_f, law.p,
                     law.combination, law.c_f, law.neighbours, energy=False)
        return saturate(f, np.asarray(obs.v_max, dtype=float))
