"""One law, one prey motion: every consumer equals :func:`zswarm.paper.field.field`.

The reference simulator (a batch of one, flat pairs from its cell grid), the batched simulator (a
batch of many, dense blocks), a 3-D agent (the law on one row) and a 2-D agent (apf's plain-float
single form) command the same velocity, to 1e-12, on random states, for every interaction,
combination, formation flag and dimension. Break any of them (a sign, a term, a sum) and this fails.
"""

from __future__ import annotations

import dataclasses

import zlib

import numpy as np
import pytest

from zswarm.control import body as bodies
from zswarm.swarm import prey as prey_motion
from zswarm.laws.apf import _velocity_2d as agent_velocity
from zswarm.paper.field import compile_law, sense_one, swarm_field
from zswarm.paper.neighbours import ObstacleIndex
from zswarm.paper.potentials import obstacle_offsets, saturate
from zswarm.swarm.prey import PreyMotion
from zswarm.swarm.scenarios import get_scenario
from zswarm.sim.batch import BatchSimulator, Member

INTERACTIONS = ["paper", "mean", "cutoff", "gate", "nearest", "swirl", "mean+gate", "mean+gate+swirl",
                "mean+cutoff+gate+nearest"]
CASES = [(scenario, interaction, combination)
         for scenario in ("moving-prey", "moving-prey-3d")
         for interaction in INTERACTIONS
         for combination in ("additive", "multiplicative")]


def _members(name: str, interaction: str, combination: str, n: int) -> list[Member]:
    """Runs that differ in their set (one without formation), so the batch steps several laws at once."""
    base = {"interaction": interaction, "k_nearest": 3, "n_agents": n, "swirl_radius": 1.5}  # some agents inside
    return [Member(get_scenario(name, base), 0, combination=combination),
            Member(get_scenario(name, {**base, "c_o": 5.0, "l_a": 1.7, "swirl": 0.7, "swirl_radius": 2.5}), 1,
                   combination=combination),
            Member(dataclasses.replace(get_scenario(name, base), formation=False), 2, combination=combination),
            Member(get_scenario(name, {**base, "interaction": "paper"}), 3, combination="multiplicative")]


@pytest.mark.parametrize("name,interaction,combination", CASES)
def test_every_consumer_commands_what_the_one_law_commands(name, interaction, combination):
    rng = np.random.default_rng(zlib.crc32(repr((name, interaction, combination)).encode()))
    n = 9
    members = _members(name, interaction, combination, n)
    batch = BatchSimulator(members)
    for _ in range(6):
        centre = rng.uniform(-1.0, 1.0, batch.dims)
        x = centre + rng.uniform(-1.3, 1.3, (len(members), n, batch.dims))  # dense: many pairs in range
        prey = centre + rng.uniform(-2.0, 2.0, (len(members), batch.dims))
        batch.state = bodies.BodyState(x, np.zeros_like(x), np.full(x.shape[:2], np.nan))
        batch.prey = prey
        got_batch = batch.command().command
        for r, m in enumerate(members):
            s = m.scenario
            law = compile_law(s.params, m.combination, s.formation)
            centers, radii = s.obstacle_arrays()
            radius = s.params.swarm.sensing_radius
            obstacles = ObstacleIndex(centers, radii, radius)
            want = saturate(swarm_field(law, obstacles, x[r], prey[r])[1], law.v_max)  # the reference's step
            np.testing.assert_allclose(got_batch[r], want, rtol=0, atol=1e-12, err_msg=f"batch run {r}")
            for i in range(n):
                others = np.delete(x[r], i, axis=0)
                if batch.dims == 3:  # the 3-D agent: the law on one row
                    sensed = sense_one(x[r, i], centers, radii, others, radius)
                    agent = law.velocity(x[r, i], prey[r], sensed)
                else:  # the 2-D agent: plain floats, on what it senses (within the sensing radius)
                    circles, near = sensed_2d(x[r, i], centers, radii, others, radius)
                    agent = agent_velocity(float(x[r, i, 0]), float(x[r, i, 1]), tuple(prey[r]), circles, near,
                                           radius, law.p, law.combination, law.formation, law.v_max, law.neighbours)
                np.testing.assert_allclose(agent, want[i], rtol=0, atol=1e-12, err_msg=f"agent {i} of run {r}")


def sensed_2d(position, centers, radii, others, radius):
    """What a 2-D agent at ``position`` senses, as its float law takes it: the obstacles (cx, cy, rho) whose
    nearest boundary point, and the neighbours, within ``radius`` (the rule of
    :func:`zswarm.paper.field.sense_one`; an engine gives a law no more)."""
    position = np.asarray(position, dtype=float)
    circles = [(float(c[0]), float(c[1]), float(rho)) for c, rho in zip(centers, radii)
               if float(np.sum(obstacle_offsets(position, np.asarray(c), rho) ** 2)) <= radius * radius]
    near = [tuple(q) for q in np.asarray(others, dtype=float).reshape(-1, 2)
            if float(np.sum((position - q) ** 2)) <= radius * radius]
    return circles, near


MOTIONS = [PreyMotion("static"), PreyMotion("straight", 0.4, 30.0, climb_deg=10.0),
           PreyMotion("circle", 0.5, center=(0.5, -0.5, 1.0), radius=2.0, bob=0.3),
           PreyMotion("evasive", 0.6, sense_radius=1.5, bounds=(-2.0, -2.0, 2.0, 2.0))]


@pytest.mark.parametrize("motion", MOTIONS, ids=lambda m: m.kind)
@pytest.mark.parametrize("dims", [2, 3])
def test_the_prey_moves_the_same_in_a_batch_as_alone(motion, dims):
    rng = np.random.default_rng(5)
    prey = rng.uniform(-2.5, 2.5, (32, dims))
    agents = prey[:, None, :] + rng.uniform(-2.0, 2.0, (32, 7, dims))
    together = prey_motion.step(motion, prey, 0.05, agents)
    alone = np.array([prey_motion.step(motion, prey[r], 0.05, agents[r]) for r in range(len(prey))])
    np.testing.assert_allclose(together, alone, rtol=0, atol=1e-12)
    moved = np.linalg.norm(together - prey, axis=1)
    if motion.kind != "static":
        assert moved.max() > 0.0  # the case moved something (the evasive prey: the ones that sensed an agent)
    if motion.kind == "evasive":
        assert (moved == 0.0).any() and (moved > 0.0).any()  # some fled, some sensed nobody
        assert np.all(np.abs(together[moved > 0.0, :2]) <= 2.0 + 1e-12)  # a prey that fled stays in bounds
