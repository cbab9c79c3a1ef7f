import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from zswarm.net.keys import Keys, cells_in_disc, parse_parameters


@settings(max_examples=200, deadline=None)
@given(x=st.floats(-50, 50), y=st.floats(-50, 50), r=st.floats(0.1, 3.0), size=st.floats(0.5, 4.0))
def test_cells_cover_exactly_the_disc(x, y, r, size):
    keys = Keys("t", size)
    cells = cells_in_disc(keys, (x, y), r)
    # every point of the disc lies in a listed cell
    rng = np.random.default_rng(0)
    ang, rad = rng.uniform(0, 2 * np.pi, 400), r * np.sqrt(rng.uniform(0, 1, 400))
    for px, py in zip(x + rad * np.cos(ang), y + rad * np.sin(ang)):
        assert keys.cell(px, py) in cells
    # and every listed cell touches the disc
    for cx, cy in cells:
        nx, ny = min(max(x, cx * size), (cx + 1) * size), min(max(y, cy * size), (cy + 1) * size)
        assert math.hypot(nx - x, ny - y) <= r + 1e-9
    if size >= r:
        assert len(cells) <= 9


def test_keys_are_namespaced_by_run_and_cell():
    k = Keys("exp-1", 2.0)
    assert k.pose(k.cell(3.9, -0.1), 7) == "zswarm/exp-1/pose/1/-1/7"
    assert k.cell_poses((1, -1)) == "zswarm/exp-1/pose/1/-1/*"
    assert Keys.agent_of(k.alive(12)) == 12 and Keys.agent_of("zswarm/x/pose/1/2/abc") is None
    assert parse_parameters(k.obstacle_query((1.5, -2.0), 3.0).split("?", 1)[1]) == {"x": "1.5", "y": "-2.0", "r": "3.0"}
    assert k.any_cell_pose(7) == "zswarm/exp-1/pose/*/*/7"


def test_3d_keys_have_a_voxel_segment():
    k = Keys("sky", 2.0, dims=3)
    assert k.pose(k.cell(3.9, -0.1, 4.0), 7) == "zswarm/sky/pose/1/-1/2/7"
    assert k.cell_poses((1, -1, 2)) == "zswarm/sky/pose/1/-1/2/*"
    assert k.any_cell_pose(7) == "zswarm/sky/pose/*/*/*/7"
    assert Keys.agent_of(k.pose((0, 0, 0), 12)) == 12
    query = parse_parameters(k.obstacle_query((1.5, -2.0, 0.25), 3.0).split("?", 1)[1])
    assert query == {"x": "1.5", "y": "-2.0", "z": "0.25", "r": "3.0"}


@settings(max_examples=150, deadline=None)
@given(x=st.floats(-50, 50), y=st.floats(-50, 50), z=st.floats(-50, 50), r=st.floats(0.1, 3.0),
       size=st.floats(0.5, 4.0))
def test_voxels_cover_exactly_the_ball(x, y, z, r, size):
    """3-D: every point of the ball of radius r lies in a listed voxel, and every listed voxel meets it."""
    keys = Keys("t", size, dims=3)
    cells = cells_in_disc(keys, (x, y, z), r)
    rng = np.random.default_rng(0)
    d = rng.normal(size=(400, 3))
    d *= (r * rng.uniform(0, 1, 400) ** (1 / 3) / np.linalg.norm(d, axis=1))[:, None]
    for p in np.array([x, y, z]) + d:
        assert keys.cell(*p) in cells
    for cell in cells:
        nearest = [min(max(c, k * size), (k + 1) * size) for c, k in zip((x, y, z), cell)]
        assert math.dist(nearest, (x, y, z)) <= r + 1e-9
    if size >= r:
        assert len(cells) <= 27
