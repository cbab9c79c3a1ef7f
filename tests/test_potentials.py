"""Every force is the negative gradient of its potential (central finite differences)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from zswarm.paper.formation import formation_offset
from zswarm.paper.params import DEFAULT_PARAMS, PAPER_PARAMS, PotentialParams
from zswarm.paper.field import field, make_law, sense_one
from zswarm.paper.potentials import formation_terms, goal_terms, obstacle_offsets, obstacle_terms, saturate

H = 1e-6
coord = st.floats(-3.0, 3.0, allow_nan=False)
point = st.tuples(coord, coord).map(np.array)


def fd_grad(fn, x):
    """Central finite difference of a scalar function of a 2-vector."""
    g = np.zeros(2)
    for k in range(2):
        e = np.zeros(2)
        e[k] = H
        g[k] = (fn(x + e) - fn(x - e)) / (2 * H)
    return g


def assert_grad(force, potential, x):
    np.testing.assert_allclose(force, -fd_grad(potential, x), rtol=1e-5, atol=1e-6)


params_st = st.builds(
    PotentialParams,
    l_o=st.floats(0.1, 1.0), l_g=st.floats(0.5, 3.0), l_a=st.floats(0.2, 2.0), l_r=st.floats(0.2, 2.0),
    c_o=st.floats(0.0, 5.0), c_g=st.floats(0.1, 3.0), c_a=st.floats(0.0, 2.0), c_r=st.floats(0.0, 2.0),
    c_a_prime=st.floats(0.0, 0.5),
)


@settings(max_examples=200, deadline=None)
@given(x=point, g=point, p=params_st)
def test_goal_force_is_gradient_eq_8(x, g, p):
    u = lambda y: goal_terms((y - g)[None], p)[0][0]  # noqa: E731
    assert_grad(goal_terms((x - g)[None], p)[1][0], u, x)


@settings(max_examples=200, deadline=None)
@given(x=point, o=point, p=params_st)
def test_obstacle_force_is_gradient_eq_11(x, o, p):
    u = lambda y: obstacle_terms((y - o)[None], p)[0][0]  # noqa: E731
    assert_grad(obstacle_terms((x - o)[None], p)[1][0], u, x)


@settings(max_examples=200, deadline=None)
@given(x=point, k=point, p=params_st)
def test_formation_force_is_gradient_eq_28(x, k, p):
    u = lambda y: formation_terms((y - k)[None], p, 0.3)[0][0]  # noqa: E731
    assert_grad(formation_terms((x - k)[None], p)[1][0], u, x)


def _total(p, comb, obstacles, neighbours, goal, force=True):
    def evaluate(x):
        return field((x - goal)[None], np.zeros(len(obstacles), dtype=np.intp), x - obstacles,
                     np.zeros(len(neighbours), dtype=np.intp), x - neighbours, p, comb, 0.1, force=force)
    return evaluate


@settings(max_examples=150, deadline=None)
@given(x=point, g=point, p=params_st, comb=st.sampled_from(["additive", "multiplicative"]),
       obs=st.lists(point, min_size=0, max_size=4), nbrs=st.lists(point, min_size=0, max_size=4))
def test_total_force_is_gradient_eqs_13_15_36(x, g, p, comb, obs, nbrs):
    obstacles, neighbours = np.array(obs).reshape(-1, 2), np.array(nbrs).reshape(-1, 2)
    evaluate = _total(p, comb, obstacles, neighbours, g)
    assert_grad(evaluate(x)[1][0], lambda y: evaluate(y)[0][0], x)
    u, f = _total(p, comb, obstacles, neighbours, g, force=False)(x)  # the energy alone (an observer's)
    assert f is None and u[0] == evaluate(x)[0][0]


def test_multiplicative_matches_printed_eq_15_term_by_term():
    p = PAPER_PARAMS.potential
    x, g, o = np.array([0.3, -0.2]), np.array([0.0, 0.0]), np.array([-0.1, 0.0])
    psi_g, psi_o = x - g, x - o
    e_o = np.exp(-psi_o @ psi_o / p.l_o**2)
    e_g = np.exp(-psi_g @ psi_g / p.l_g**2)
    printed = (2 * p.c_o * psi_o / p.l_o**2 * e_o * (1 - e_g)
               + p.c_o * e_o * (-2 * psi_g / p.l_g**2 * e_g)
               - 2 * p.c_g * psi_g / p.l_g**2 * e_g)
    got = field(psi_g[None], np.zeros(1, dtype=np.intp), psi_o[None], np.zeros(0, dtype=np.intp),
                np.zeros((0, 2)), p, "multiplicative")[1][0]
    np.testing.assert_allclose(got, printed, rtol=1e-12)


def test_multiplicative_vanishes_at_goal_additive_does_not():
    """Section 3.2.1: at the goal every term of eq 15 is zero; eq 13 keeps the obstacle's push."""
    p = PAPER_PARAMS.potential
    args = (np.zeros((1, 2)), np.zeros(1, dtype=np.intp), np.array([[0.1, 0.0]]),
            np.zeros(0, dtype=np.intp), np.zeros((0, 2)), p)
    u_m, f_m = field(*args, "multiplicative")
    u_a, f_a = field(*args, "additive")
    assert np.allclose(f_m, 0.0) and np.allclose(u_m, 0.0)
    assert f_a[0, 0] > 1.0 and u_a[0] > 0.0


@settings(max_examples=100, deadline=None)
@given(pts=st.lists(point, min_size=2, max_size=8, unique_by=tuple), p=params_st)
def test_pair_forces_sum_to_zero(pts, p):
    """Eq 28 is odd in psi: the internal forces of a swarm cancel (used by Prop 3's proof)."""
    pos = np.array(pts)
    i, k = np.nonzero(~np.eye(len(pos), dtype=bool))
    _, f = formation_terms(pos[i] - pos[k], p)
    np.testing.assert_allclose(f.sum(axis=0), 0.0, atol=1e-9)


@settings(max_examples=200, deadline=None)
@given(x=point, c=point, rho=st.floats(0.0, 1.0), p=params_st)
def test_circular_obstacle_force_is_gradient(x, c, rho, p):
    """psi^o to the nearest boundary point: eq 10's potential, eq 11's force, still a gradient."""
    if abs(np.linalg.norm(x - c) - 0.0) < 1e-3:
        return
    pot = lambda y: obstacle_terms(obstacle_offsets(y[None], c[None], np.array([rho])), p)[0][0]  # noqa: E731
    psi = obstacle_offsets(x[None], c[None], np.array([rho]))
    assert np.isclose(np.linalg.norm(psi), abs(np.linalg.norm(x - c) - rho))
    assert_grad(obstacle_terms(psi, p)[1][0], pot, x)


def test_point_obstacle_is_a_zero_radius_circle():
    x, c = np.array([[0.4, -0.3]]), np.array([[0.1, 0.2]])
    np.testing.assert_allclose(obstacle_offsets(x, c, np.zeros(1)), x - c)


def test_sensing_radius_excludes_what_is_beyond_it():
    pos = np.zeros(2)
    sensed = sense_one(pos, np.array([[1.0, 0.0], [3.0, 0.0]]), np.array([0.0, 0.5]),
                       np.array([[0.0, 1.9], [0.0, 2.1]]), sensing_radius=2.0)
    # the second obstacle's boundary is 2.5 away; its centre would be 3
    assert len(sensed.psi_o) == 1 and len(sensed.psi_f) == 1
    sensed = sense_one(pos, np.array([[2.4, 0.0]]), np.array([0.5]), np.zeros((0, 2)), sensing_radius=2.0)
    assert len(sensed.psi_o) == 1  # boundary at 1.9 is within reach although the centre is not


def test_controller_velocity_matches_field_and_saturates():
    ctrl = make_law(DEFAULT_PARAMS.potential)
    assert ctrl.c_f == pytest.approx(formation_offset(DEFAULT_PARAMS.potential))
    sensed = sense_one(np.zeros(2), np.array([[0.05, 0.0]]), np.zeros(1), np.zeros((0, 2)), 6.0)
    v = ctrl.velocity(np.zeros(2), np.array([2.0, 0.0]), sensed, v_max=0.5)
    assert np.isclose(np.linalg.norm(v), 0.5) and v[0] < 0  # pushed away from the close obstacle


def test_saturate_keeps_slow_rows_and_caps_fast_ones():
    v = np.array([[0.3, 0.4], [3.0, 4.0], [0.0, 0.0]])
    out = saturate(v, 1.0)
    np.testing.assert_allclose(out, [[0.3, 0.4], [0.6, 0.8], [0.0, 0.0]])
