"""apf's single form in plain floats equals the vectorized law, on random configurations."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from zswarm.laws.apf import _velocity_2d as agent_velocity

from test_one_law import sensed_2d
from zswarm.paper.params import DEFAULT_PARAMS, PAPER_PARAMS
from zswarm.paper.field import make_law, sense_one

coord = st.floats(-4, 4, allow_nan=False)


@settings(max_examples=400, deadline=None)
@given(pos=st.tuples(coord, coord), goal=st.tuples(coord, coord),
       obstacles=st.lists(st.tuples(coord, coord, st.sampled_from([0.0, 0.1, 0.3])), max_size=4),
       neighbours=st.lists(st.tuples(coord, coord), max_size=12),
       radius=st.sampled_from([0.9, 1.5, 12.0]), combination=st.sampled_from(["additive", "multiplicative"]),
       formation=st.booleans(), paper=st.booleans(), v_max=st.sampled_from([0.5, 1.0, 100.0]))
def test_the_scalar_law_is_the_vectorized_law(pos, goal, obstacles, neighbours, radius, combination, formation,
                                              paper, v_max):
    p = (PAPER_PARAMS if paper else DEFAULT_PARAMS).potential
    position = np.array(pos)
    centers = np.array([o[:2] for o in obstacles], dtype=float).reshape(-1, 2)
    radii = np.array([o[2] for o in obstacles], dtype=float)
    controller = make_law(p, combination, formation)
    sensed = sense_one(position, centers, radii, np.array(neighbours, dtype=float).reshape(-1, 2), radius)
    expected = controller.velocity(position, np.array(goal), sensed, v_max)
    circles, near = sensed_2d(position, centers, radii, neighbours, radius)  # what an engine gives the law
    got = agent_velocity(pos[0], pos[1], goal, circles, near, radius, p, combination, formation, v_max)
    assert np.allclose(got, expected, rtol=1e-12, atol=1e-12), (got, expected)
