import math

import numpy as np
import pytest

from zswarm.swarm.metrics import MetricContext, Summary, algebraic_connectivity, components, step_metrics
from zswarm.paper.neighbours import ObstacleIndex


def ctx(radius=1.0, obstacles=((5.0, 5.0, 0.5),)):
    c = np.array([o[:2] for o in obstacles], dtype=float).reshape(-1, 2)
    r = np.array([o[2] for o in obstacles], dtype=float)
    return MetricContext(robot_radius=0.05, sensing_radius=radius, spacing=0.5,
                         obstacles=ObstacleIndex(c, r, radius))


def test_components_of_a_known_graph():
    i = np.array([0, 1, 1, 2, 3, 4])
    j = np.array([1, 0, 2, 1, 4, 3])
    labels = components(6, i, j)
    assert len(np.unique(labels)) == 3  # {0,1,2}, {3,4}, {5}
    assert labels[0] == labels[2] and labels[3] == labels[4] != labels[0] and labels[5] == 5


def test_algebraic_connectivity_of_a_path_graph():
    n = 6
    i = np.r_[np.arange(n - 1), np.arange(1, n)]
    j = np.r_[np.arange(1, n), np.arange(n - 1)]
    assert algebraic_connectivity(n, i, j) == pytest.approx(2 - 2 * math.cos(math.pi / n))
    assert algebraic_connectivity(3, np.array([0, 1]), np.array([1, 0])) == pytest.approx(0.0, abs=1e-12)


def test_fiedler_value_of_random_graphs_with_and_without_the_components_shortcut():
    """Knowing the graph is disconnected gives exactly 0 without an eigensolve; the full solve agrees,
    and a connected graph is still solved."""
    rng = np.random.default_rng(3)
    seen = set()
    for _ in range(40):
        n = int(rng.integers(2, 30))
        pos = rng.uniform(0, 3, size=(n, 2))
        d = np.linalg.norm(pos[:, None] - pos[None], axis=-1)
        i, j = np.nonzero((d <= 1.2) & ~np.eye(n, dtype=bool))
        k = len(np.unique(components(n, i, j)))
        full, fast = algebraic_connectivity(n, i, j), algebraic_connectivity(n, i, j, k)
        seen.add(k > 1)
        if k > 1:
            assert fast == 0.0 and full == pytest.approx(0.0, abs=1e-9)
        else:
            assert fast == full > 1e-9
    assert seen == {True, False}


def test_step_metrics_hand_computed():
    pos = np.array([[0.0, 0.0], [0.06, 0.0], [3.0, 0.0], [4.3, 5.0]])
    vel = np.array([[1.0, 0.0], [1.0, 0.0], [1.0, 0.0], [-1.0, 0.0]])
    prey = np.array([0.0, 4.0])
    m, colliding, contacts = step_metrics(pos, vel, prey, ctx())
    assert m["min_pair_distance"] == pytest.approx(0.06)
    assert m["colliding_pairs"] == 1 and colliding.tolist() == [[0, 1]]
    assert m["components"] == 3 and m["union"] == pytest.approx(1 / 3)
    assert m["min_obstacle_clearance"] == pytest.approx(0.2)  # agent 3 is 0.7 from the centre, r = 0.5
    assert m["obstacle_contacts"] == 0
    assert m["order"] == pytest.approx(2 / 4)
    centroid = pos.mean(axis=0)
    assert m["centroid_goal_distance"] == pytest.approx(np.linalg.norm(centroid - prey))
    assert m["cohesion"] == pytest.approx(np.linalg.norm(pos - centroid, axis=1).max())
    assert m["spacing_error"] == pytest.approx(abs(0.06 - 0.5))


def test_min_pair_distance_is_exact_when_nobody_is_in_range():
    pos = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 7.0]])
    m, _, _ = step_metrics(pos, np.zeros_like(pos), np.zeros(2), ctx(radius=1.0))
    assert m["min_pair_distance"] == pytest.approx(7.0)


def test_summary_counts_collision_onsets_and_capture():
    s = Summary(capture_radius=0.5, epsilon=2.0)
    base = {k: 1.0 for k in s.series}
    for t, d, pairs in ((0.0, 2.0, []), (0.1, 0.4, [[0, 1]]), (0.2, 0.3, [[0, 1]]), (0.3, 0.2, []),
                        (0.4, 0.6, [[0, 1], [2, 3]])):
        s.add(t, {**base, "centroid_goal_distance": d}, np.array(pairs).reshape(-1, 2), np.zeros((0, 2)))
    out = s.result()
    assert out["collisions"] == 3  # (0,1) at 0.1, again at 0.4, and (2,3) at 0.4
    assert out["capture_time"] == 0.1 and out["max_lag_after_capture"] == 0.6


def test_a_summary_of_no_steps_has_no_values_and_does_not_fail():
    """A world whose agents never came observes nothing: its summary says so instead of crashing."""
    from zswarm.swarm.metrics import SUMMARY_KEYS

    empty = Summary(capture_radius=0.5, epsilon=1.0).result()
    assert empty["steps_observed"] == 0 and empty["capture_time"] is None and empty["collisions"] == 0
    assert set(SUMMARY_KEYS) <= set(empty)
