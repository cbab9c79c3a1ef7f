import math

import numpy as np
import pytest

from zswarm.swarm.prey import PreyMotion, step


def test_circle_keeps_radius_and_speed():
    m = PreyMotion(kind="circle", speed=0.2, center=(1.0, 0.0), radius=0.5)
    p = np.array([1.5, 0.0])
    for _ in range(100):
        q = step(m, p, 0.05, np.zeros((0, 2)))
        assert np.linalg.norm(q - [1.0, 0.0]) == pytest.approx(0.5)
        assert np.linalg.norm(q - p) == pytest.approx(0.2 * 0.05, rel=1e-3)  # chord ~ arc
        p = q


def test_straight_moves_along_heading():
    q = step(PreyMotion(kind="straight", speed=0.5, heading_deg=90.0), np.zeros(2), 2.0, np.zeros((0, 2)))
    np.testing.assert_allclose(q, [0.0, 1.0], atol=1e-12)


def test_evasive_flees_nearest_sensed_agent_and_stays_in_bounds():
    m = PreyMotion(kind="evasive", speed=1.0, sense_radius=1.0, bounds=(-1.0, -1.0, 1.0, 1.0))
    agents = np.array([[0.5, 0.0], [-3.0, 0.0]])
    q = step(m, np.zeros(2), 0.1, agents)
    np.testing.assert_allclose(q, [-0.1, 0.0])
    assert np.array_equal(step(m, np.zeros(2), 0.1, np.array([[2.0, 0.0]])), np.zeros(2))  # none sensed
    q = np.zeros(2)
    for _ in range(50):
        q = step(m, q, 0.1, np.array([[q[0] + 0.5, q[1]]]))
    assert q[0] == -1.0


@pytest.mark.parametrize("kw", [dict(kind="zigzag"), dict(speed=-1.0), dict(kind="circle", radius=0.0),
                                dict(bounds=(1.0, 0.0, 0.0, 1.0)), dict(speed=math.nan)])
def test_bad_prey_is_rejected(kw):
    with pytest.raises(ValueError):
        PreyMotion(**kw)
