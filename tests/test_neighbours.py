import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from zswarm.paper.neighbours import ObstacleIndex, cell_pairs, pairs_within


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(0, 300), dims=st.sampled_from([2, 3]), radius=st.floats(0.05, 3.0),
       spread=st.floats(0.1, 20.0))
def test_grid_pairs_equal_brute_force(seed, n, dims, radius, spread):
    """Both ways of finding pairs (every pair at once up to DENSE_MAX points, the cell index beyond it,
    and the cell index at any N) find exactly the pairs within the radius."""
    x = np.random.default_rng(seed).uniform(-spread, spread, (n, dims))
    d = np.linalg.norm(x[:, None] - x[None], axis=-1)
    bi, bj = np.nonzero((d <= radius) & ~np.eye(n, dtype=bool))
    want = sorted(zip(bi.tolist(), bj.tolist()))
    for i, j in (pairs_within(x, radius), cell_pairs(x, radius)):
        assert sorted(zip(i.tolist(), j.tolist())) == want


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.one_of(st.integers(1, 50), st.integers(800, 1500)), m=st.integers(0, 20),
       radius=st.floats(0.1, 3.0))
def test_obstacle_sensing_uses_the_boundary_distance(seed, n, m, radius):
    """Every (agent, obstacle) pair at once for few, through the cell index for many: the same pairs."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(-5, 5, (n, 2))
    centers, radii = rng.uniform(-5, 5, (m, 2)), rng.uniform(0, 1.5, m)
    a, k = ObstacleIndex(centers, radii, radius).sensed(x)
    gap = np.linalg.norm(x[:, None] - centers[None], axis=-1) - radii[None]
    ba, bk = np.nonzero(gap <= radius)
    assert sorted(zip(a.tolist(), k.tolist())) == sorted(zip(ba.tolist(), bk.tolist()))
