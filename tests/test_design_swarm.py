"""The design checks for our agents (sensing radius, interaction), each against a brute-force worst case."""

from __future__ import annotations

import math

import numpy as np
import pytest

from zswarm.design.guidelines import check
from zswarm.design.swarm_checks import SQUEEZE_MAX, packing_bound, pulling_count
from zswarm.paper.neighbour_law import PairList, neighbour_force, neighbour_law
from zswarm.paper.params import DEFAULT_PARAMS
from zswarm.paper.potentials import goal_terms, obstacle_terms


def _random_packing(rng, radius, d_min, tries=20000):
    """Random sequential placement of points at least d_min apart within radius of the origin (which is
    taken): how many fit, by brute force."""
    points = [np.zeros(2)]
    for _ in range(tries):
        q = rng.uniform(-radius, radius, 2)
        if np.linalg.norm(q) <= radius and all(np.linalg.norm(q - p) >= d_min for p in points):
            points.append(q)
    return len(points) - 1


@pytest.mark.parametrize("radius,d_min", [(1.0, 0.5), (1.5, 0.4), (1.0, 0.25)])
def test_the_packing_bound_holds_for_brute_force_and_lattice_packings(radius, d_min):
    bound = packing_bound(radius, d_min)
    rng = np.random.default_rng(1)
    assert max(_random_packing(rng, radius, d_min) for _ in range(3)) <= bound
    # the densest regular packing (hexagonal, spacing d_min) about the point
    k = np.arange(-40, 41)
    a, b = np.meshgrid(k, k)
    hexagonal = d_min * np.column_stack([(a + 0.5 * b).ravel(), (b * math.sqrt(3) / 2).ravel()])
    inside = int(np.sum(np.linalg.norm(hexagonal, axis=1) <= radius)) - 1
    assert inside <= bound
    assert inside >= bound / 4  # and the bound is of the right order


def _pull_toward(behind, params):
    """The attraction (no repulsion) an agent at the origin takes from neighbours, along -x."""
    law = neighbour_law(params.with_values({"c_r": 0.0}))
    psi = -behind
    f, _ = neighbour_force(PairList(np.zeros(len(psi), np.intp), 1), psi,
                           np.zeros((1, 2)), params.with_values({"c_r": 0.0}).potential, law)
    return -f[0, 0]


@pytest.mark.parametrize("interaction,n", [("paper", 8), ("mean", 40), ("nearest", 30)])
def test_prop4_for_our_agents_flips_with_the_pull_of_the_agents_that_can_reach(interaction, n):
    """Eq 39 at |psi_o| = l_o/sqrt2: the obstacle push against what c_p(R) sensed agents at r* pull,
    with the agents placed (at least d_min apart) on an arc of radius r* behind the agent."""
    params = DEFAULT_PARAMS.with_values({"n_agents": n, "sensing_radius": 1.5, "interaction": interaction,
                                         "k_nearest": 5})
    r = check(params, swarm=False).prop4
    spacing = check(params, swarm=False).formation["equilibrium_spacing"]
    count, _ = pulling_count(params, spacing)
    angles = np.linspace(-1, 1, count) * (count * 0.12 / r["r_star"] / 2)
    behind = -r["r_star"] * np.column_stack([np.cos(angles), np.sin(angles)])
    pull = _pull_toward(behind, params)
    # the bound: c_p agents at r* straight behind (c_p counts N for N - 1 others, as the paper's does;
    # the arc costs a little of the straight pull)
    bound = r["rhs"] * 2.0 / (math.sqrt(2.0) * math.exp(0.5))
    share = 1.0 if interaction == "mean" else count / r["c_p"]
    assert pull <= bound * (1 + 1e-9) and pull >= 0.9 * bound * share
    stacked = np.tile([[-r["r_star"], 0.0]], (int(r["c_p"]) if interaction != "mean" else 7, 1))
    for factor, expect in ((1.02, True), (0.98, False)):
        c_o = r["rhs"] * params.potential.l_o * factor
        candidate = params.with_values({"c_o": c_o})
        assert check(candidate, swarm=False).prop4["holds"] is expect
        push = obstacle_terms(np.array([[candidate.potential.l_o / math.sqrt(2), 0.0]]), candidate.potential)[1][0, 0]
        law = candidate.with_values({"k_nearest": 10**5}) if interaction == "nearest" else candidate
        assert bool(push > _pull_toward(stacked, law)) is expect
    if interaction == "mean":
        assert r["c_p"] == 1 and r["paper_c_p"] == n and not r["paper_holds"] and r["holds"]


def test_contact_with_mean_cohesion_flips_where_a_lone_touching_pair_stops_separating():
    """The mean form's bound is exact for a pair alone (K = 1) and safe with any number of others sensed
    beyond the repulsion's reach (the check's premise, as for the paper's form: only attraction there)."""
    base = DEFAULT_PARAMS.with_values({"interaction": "mean", "sensing_radius": 3.0, "n_agents": 50})
    p = base.potential
    c_r_star = p.l_r**2 / 2 * (2 * p.c_a_prime + p.c_g / p.l_g**2 + 2 * p.c_a / p.l_a**2)
    pair = np.array([[5e-5, 0.0], [-5e-5, 0.0]])

    def separating(q, others):
        x = np.vstack([pair, others])
        n = len(x)
        i, k = np.nonzero(~np.eye(n, dtype=bool) & (np.linalg.norm(x[:, None] - x[None], axis=-1) <= 3.0))
        f, _ = neighbour_force(PairList(i, n), x[i] - x[k], np.zeros((n, 2)), q,
                               neighbour_law(base.with_values({"c_r": q.c_r})))
        f = f + goal_terms(x, q)[1]
        return bool((f[0, 0] - f[1, 0]) > 0)

    rng = np.random.default_rng(5)
    for factor, expect in ((1.03, True), (0.97, False)):
        q = p.__class__(**{**p.__dict__, "c_r": c_r_star * factor})
        assert check(base.with_values({"c_r": q.c_r}), swarm=False).contact["holds"] is expect
        assert separating(q, np.zeros((0, 2))) is expect
        if expect:  # with neighbours anywhere within reach, the pair still separates
            for _ in range(50):
                m = int(rng.integers(1, 30))
                angle, dist = rng.uniform(0, 2 * np.pi, m), rng.uniform(4 * p.l_r, 2.9, m)
                others = dist[:, None] * np.column_stack([np.cos(angle), np.sin(angle)])
                assert separating(q, others)


def test_prop5_with_the_gate_carries_no_goal_load():
    params = DEFAULT_PARAMS.with_values({"c_g": 50.0, "c_o": 150.0})
    paper = check(params, swarm=False).prop5
    gated = check(params.with_values({"interaction": "mean+gate"}), swarm=False).prop5
    assert not paper["holds"] and not paper["paper_holds"]
    assert gated["holds"] and gated["gated"] and not gated["paper_holds"]


def test_the_swarm_check_runs_the_law_in_use_at_30():
    paper = check(DEFAULT_PARAMS.with_values({"n_agents": 30, "sensing_radius": 1.5})).swarm
    scalable = check(DEFAULT_PARAMS.with_values({"n_agents": 30, "sensing_radius": 1.5, "interaction": "scalable"})).swarm
    assert not paper["holds"] and paper["min_pair_distance"] < 0.1  # the sum crushes the swarm
    assert scalable["holds"] and scalable["min_pair_distance"] > 0.3


def test_the_swarm_check_knows_what_n_it_cannot_reach():
    paper = check(DEFAULT_PARAMS.with_values({"n_agents": 100, "sensing_radius": 1.5})).swarm
    scalable = check(DEFAULT_PARAMS.with_values({"n_agents": 100, "sensing_radius": 1.5, "interaction": "scalable"})).swarm
    assert not paper["holds"] and paper["min_pair_distance"] < 0.1
    assert scalable["holds"] and scalable["min_pair_distance"] > 0.3
    beyond = DEFAULT_PARAMS.with_values({"n_agents": SQUEEZE_MAX + 100, "sensing_radius": 1.5})
    assert not check(beyond.with_values({"interaction": "mean"})).swarm["holds"]  # no gate: not established
    assert check(beyond.with_values({"interaction": "scalable"})).swarm["holds"]
    mean = {n: check(DEFAULT_PARAMS.with_values({"n_agents": n, "sensing_radius": 1.5, "interaction": "mean"})).swarm
            for n in (100, 150)}
    assert mean[100]["holds"]  # up to UNGATED_MAX (measured: mean collides at N = 300 in large-swarm)
    assert mean[150]["min_pair_distance"] > 0.3 and not mean[150]["holds"]  # the squeeze holds; the N does not


def test_the_time_step_check_flips_at_v_max_dt_equal_to_the_robot_radius():
    d_r = DEFAULT_PARAMS.swarm.robot_radius
    assert check(DEFAULT_PARAMS, swarm=False, dt=d_r * 0.99).step["holds"]
    bad = check(DEFAULT_PARAMS, dt=d_r * 1.01)
    assert not bad.step["holds"] and "step" in bad.failures()
    assert check(DEFAULT_PARAMS).step is None and check(DEFAULT_PARAMS).ok


def test_prop3_does_not_bind_a_local_sensing_swarm_and_the_paper_verdict_stays_visible():
    local = check(DEFAULT_PARAMS.with_values({"sensing_radius": 1.0}))
    assert not local.prop3["holds"] and not local.prop3["binding"]
    assert "prop3" not in local.failures() and "prop3" in local.paper_failures() and local.ok
