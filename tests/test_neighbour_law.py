"""The interactions of zswarm.paper.neighbour_law: each force against its potential, the gate, and the
same law in the agent's floats, the vectorized field and the batched simulator."""

from __future__ import annotations

import math

import numpy as np
import pytest

from zswarm.errors import ParamError
from zswarm.laws.apf import _velocity_2d as agent_velocity

from test_one_law import sensed_2d
from zswarm.paper.interaction import parse_interaction
from zswarm.paper.neighbour_law import CUTOFF_INNER, PairList, cutoff_weight, neighbour_force, neighbour_law
from zswarm.paper.params import DEFAULT_PARAMS, PAPER_PARAMS
from zswarm.paper.field import field, make_law, sense_one

R = 1.5


def _law(name: str, **extra):
    params = DEFAULT_PARAMS.with_values({"interaction": name, "sensing_radius": R, **extra})
    return params, neighbour_law(params)


def _force(position, neighbours, name, **extra):
    params, law = _law(name, **extra)
    psi = position - neighbours
    f, weight = neighbour_force(PairList(np.zeros(len(psi), dtype=np.intp), 1), psi,
                                np.zeros((1, 2)), params.potential, law)
    return f[0], weight[0]


def _pair_potentials(r, p):
    """The repulsion and attraction parts of eq 26 (without c_f) as functions of distance."""
    rep = p.c_r * np.exp(-r**2 / p.l_r**2)
    att = -p.c_a * np.exp(-r**2 / p.l_a**2) + p.c_a_prime * r**2
    return rep, att


def _cutoff_potential(r, p):
    """u_c(r) = -int_r^R g(s) s rho(s/R) ds, by the trapezoid rule on a fine grid."""
    s = np.linspace(r, R, 20001)
    g = (-2 * p.c_r / p.l_r**2 * np.exp(-s**2 / p.l_r**2) + 2 * p.c_a / p.l_a**2 * np.exp(-s**2 / p.l_a**2)
         + 2 * p.c_a_prime)
    return -np.trapezoid(g * s * cutoff_weight(s, R), s)


def _potential(x, neighbours, name, p, k=10):
    r = np.linalg.norm(x - neighbours, axis=1)
    if name == "nearest":
        r = np.sort(r)[:k]
    if name == "cutoff":
        return sum(_cutoff_potential(ri, p) for ri in r)
    rep, att = _pair_potentials(r, p)
    if name == "mean":
        return rep.sum() + att.sum() / max(len(r), 1)
    return rep.sum() + att.sum()


@pytest.mark.parametrize("name", ["mean", "cutoff", "nearest"])
def test_each_variant_is_minus_the_gradient_of_its_potential(name):
    rng = np.random.default_rng(7)
    params, _ = _law(name, k_nearest=4)
    p, h = params.potential, 1e-6
    for _ in range(20):
        x = rng.uniform(-0.2, 0.2, 2)
        neighbours = x + np.array([[math.cos(a), math.sin(a)] for a in rng.uniform(0, 2 * np.pi, 7)]) \
            * rng.uniform(0.2, R * 0.98, (7, 1))
        f, _ = _force(x, neighbours, name, k_nearest=4)
        grad = [(_potential(x + e, neighbours, name, p, 4) - _potential(x - e, neighbours, name, p, 4)) / (2 * h)
                for e in (np.array([h, 0.0]), np.array([0.0, h]))]
        np.testing.assert_allclose(f, -np.array(grad), rtol=1e-5, atol=1e-6)


def test_mean_cohesion_pulls_no_harder_than_one_neighbour_whatever_their_number():
    params, _ = _law("mean")
    p = params.potential
    one = lambda r: 2 * p.c_a * r / p.l_a**2 * math.exp(-r**2 / p.l_a**2) + 2 * p.c_a_prime * r  # noqa: E731
    worst = max(one(r) for r in np.linspace(0, R, 1001))
    no_repulsion = {"c_r": 0.0}
    for n in (1, 5, 40, 200):
        behind = np.column_stack([np.full(n, -R * 0.99), np.linspace(-0.05, 0.05, n)])
        f_mean, _ = _force(np.zeros(2), behind, "mean", **no_repulsion)
        f_sum, _ = _force(np.zeros(2), behind, "nearest", k_nearest=10**5, **no_repulsion)
        assert np.linalg.norm(f_mean) <= worst * (1 + 1e-9)
        assert np.linalg.norm(f_sum) == pytest.approx(n * np.linalg.norm(f_mean), rel=1e-3)


def test_the_cutoff_takes_the_pair_force_smoothly_to_zero_at_the_sensing_radius():
    r = np.array([0.5, CUTOFF_INNER * R, 0.9 * R, R * (1 - 1e-9), R])
    w = cutoff_weight(r, R)
    assert w[0] == w[1] == 1.0 and 0 < w[2] < 1 and w[3] < 1e-12 and w[4] == 0.0
    f_paper = _force(np.zeros(2), np.array([[R * 0.999, 0.0]]), "nearest")[0]
    f_cut = _force(np.zeros(2), np.array([[R * 0.999, 0.0]]), "cutoff")[0]
    assert np.linalg.norm(f_paper) > 0.3 and np.linalg.norm(f_cut) < 1e-4  # the jump of 2 c'_a R is gone


def test_the_gate_takes_the_goal_pull_away_only_with_a_neighbour_close_ahead():
    params, law = _law("gate")
    p = params.potential
    x, goal = np.zeros((1, 2)), np.array([[1.5, 0.0]])
    none, no_obstacle = np.zeros(0, np.intp), np.zeros((0, 2))

    def total(neighbour, psi_g):
        psi_f = x - np.asarray(neighbour, float).reshape(1, 2)
        return field(psi_g, none, no_obstacle, np.zeros(1, np.intp), psi_f, p, "multiplicative", 0.0, law)[1][0]

    goal_alone = field(x - goal, none, no_obstacle, none, no_obstacle, p)[1][0]
    assert goal_alone[0] > 0.1
    ahead = [law.gate_in * 0.9, 0.0]  # toward the goal, inside g_in: no goal pull at all
    np.testing.assert_allclose(total(ahead, x - goal), total(ahead, np.zeros((1, 2))), atol=1e-15)
    for neighbour in ([-law.gate_in * 0.9, 0.0], [0.0, law.gate_in * 0.9], [law.gate_out * 1.01, 0.0]):
        # behind, beside, or ahead beyond g_out: the full goal pull
        np.testing.assert_allclose(total(neighbour, x - goal) - total(neighbour, np.zeros((1, 2))), goal_alone,
                                   atol=1e-15)
    halfway = [0.5 * (law.gate_in + law.gate_out), 0.0]
    part = total(halfway, x - goal) - total(halfway, np.zeros((1, 2)))
    np.testing.assert_allclose(part, 0.5 * goal_alone, rtol=1e-9)


def test_the_swirl_turns_the_goal_pull_a_quarter_turn_within_its_radius_and_only_there():
    params, law = _law("mean+gate+swirl", swirl=1.5, swirl_radius=2.0)
    plain_params, plain = _law("mean+gate")
    p = params.potential
    none = np.zeros(0, np.intp)
    neighbour = np.array([[0.4, 0.3]])  # one neighbour: the swirl is added whatever the gate makes of it
    for dims in (2, 3):
        no_obstacle = np.zeros((0, dims))
        for x, inside in (([1.0, 0.0], True), ([0.0, -1.9], True), ([2.1, 0.0], False), ([-1.5, 1.5], False)):
            x = np.array([x + [0.3] * (dims - 2)])
            goal = np.zeros((1, dims))
            psi_f = x - np.pad(neighbour, ((0, 0), (0, dims - 2)))
            u, f = field(x - goal, none, no_obstacle, np.zeros(1, np.intp), psi_f, p,
                         "multiplicative", 0.0, law)
            u0, f0 = field(x - goal, none, no_obstacle, np.zeros(1, np.intp), psi_f, p,
                           "multiplicative", 0.0, plain)
            f_g = field(x - goal, none, no_obstacle, none, no_obstacle,
                        p)[1][0]  # the goal pull alone, toward the goal
            np.testing.assert_array_equal(u, u0)  # no potential: the energy is the law's without it
            turned = np.array([-f_g[1], f_g[0]] + [0.0] * (dims - 2))
            np.testing.assert_allclose(f[0] - f0[0], 1.5 * turned if inside else 0.0, rtol=1e-12, atol=1e-15)
            if inside:  # clockwise about the goal seen from above (the pull, toward the goal, turned left)
                (rx, ry), (tx, ty) = x[0, :2] - goal[0, :2], (f[0] - f0[0])[:2]
                assert rx * ty - ry * tx < 0
    with pytest.raises(ParamError, match="swirl_radius"):
        neighbour_law(DEFAULT_PARAMS.with_values({"interaction": "scalable+swirl"}))  # no radius given
    assert plain_params.interaction.spec.swirl is False


@pytest.mark.parametrize("name", ["mean", "cutoff", "gate", "nearest", "mean+gate", "mean+gate+swirl",
                                  "mean+cutoff+gate+nearest"])
def test_the_agents_floats_are_the_vectorized_law(name):
    params, law = _law(name, k_nearest=3, swirl_radius=2.5)
    p = params.potential
    rng = np.random.default_rng(11)
    for combination in ("additive", "multiplicative"):
        controller = make_law(p, combination, True, law)
        for _ in range(150):
            pos, goal = rng.uniform(-2, 2, 2), rng.uniform(-3, 3, 2)
            nbrs = pos + rng.uniform(-1.6, 1.6, (int(rng.integers(0, 12)), 2))
            obst = [(float(a), float(b), 0.3) for a, b in rng.uniform(-3, 3, (2, 2))]
            sensed = sense_one(pos, np.array([o[:2] for o in obst]), np.array([o[2] for o in obst]), nbrs, R)
            want = controller.velocity(pos, goal, sensed, 100.0)
            circles, near = sensed_2d(pos, np.array([o[:2] for o in obst]), np.array([o[2] for o in obst]), nbrs, R)
            got = agent_velocity(pos[0], pos[1], tuple(goal), circles, near, R, p, combination, True, 100.0, law)
            np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-12)


def test_interaction_names_parse_and_fail_in_one_line():
    assert parse_interaction("scalable").name == "mean+gate"
    assert parse_interaction("swirl+scalable").name == "mean+gate+swirl"
    assert parse_interaction(" gate + mean ").name == "mean+gate"
    assert parse_interaction("paper").is_paper
    for bad in ("", "swarm", "paper+mean", "mean+"):
        with pytest.raises(ParamError) as err:
            parse_interaction(bad)
        assert "\n" not in str(err.value)
    with pytest.raises(ParamError, match="needs a pair spacing"):
        neighbour_law(PAPER_PARAMS.with_values({"interaction": "gate"}))  # the paper's set has no d^f


def test_the_modules_doc_states_the_gates_constants_as_the_code_has_them():
    from zswarm.paper import neighbour_law as nl

    doc = " ".join(nl.__doc__.split())
    assert f"g_in = {nl.GATE_INNER} g_out" in doc
    assert f"ahead = clip((cos - {nl.AHEAD_COS:g})/" in doc.replace("1/2", "0.5")
