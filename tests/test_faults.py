"""Injected faults: seeded per link, and observed as injected (real processes, loopback)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from zswarm.swarm.faults import FaultModel, LinkFaults, parse_duration, parse_duration_list

from conftest import ROOT, run_cli


def pattern(model: FaultModel, receiver: int, source: int, n: int = 2000) -> list:
    lf = LinkFaults(model, receiver)
    return [lf.decide(source) for _ in range(n)]


def test_same_seed_same_pattern_and_links_are_independent():
    m = FaultModel(latency=0.1, jitter=0.02, dropout=0.3, seed=5)
    assert pattern(m, 1, 2) == pattern(m, 1, 2)
    assert pattern(m, 1, 2) != pattern(FaultModel(latency=0.1, jitter=0.02, dropout=0.3, seed=6), 1, 2)
    assert pattern(m, 1, 2) != pattern(m, 1, 3) and pattern(m, 1, 2) != pattern(m, 2, 2)
    # interleaving other links does not change a link's pattern
    lf = LinkFaults(m, 1)
    mixed = []
    for _ in range(2000):
        lf.decide(7)
        mixed.append(lf.decide(2))
    assert mixed == pattern(m, 1, 2)


def test_bernoulli_and_gilbert_elliott_losses_have_the_requested_rate_and_burstiness():
    for burst in (0.0, 5.0):
        out = pattern(FaultModel(dropout=0.3, burst=burst, seed=1), 0, 1, n=60_000)
        lost = np.array([d is None for d in out])
        assert lost.mean() == pytest.approx(0.3, abs=0.02)
        edges = np.flatnonzero(np.diff(np.r_[0, lost.astype(int), 0]))
        mean_run = np.mean(edges[1::2] - edges[0::2])
        assert mean_run == pytest.approx(5.0 if burst else 1 / 0.7, rel=0.1)


def test_delay_stays_within_the_jitter_and_distance_loss_grows_with_distance():
    delays = np.array(pattern(FaultModel(latency=0.1, jitter=0.02, seed=2), 0, 1))
    assert delays.min() >= 0.08 and delays.max() <= 0.12 and abs(delays.mean() - 0.1) < 0.002
    lf = LinkFaults(FaultModel(distance_loss=0.8, seed=3), 0)
    near = np.mean([lf.decide(1, 0.2) is None for _ in range(20_000)])
    far = np.mean([lf.decide(2, 1.0) is None for _ in range(20_000)])
    assert near == pytest.approx(0.8 * 0.04, abs=0.01) and far == pytest.approx(0.8, abs=0.02)


def test_durations_parse():
    assert parse_duration("100ms") == 0.1 and parse_duration("0.25s") == 0.25 and parse_duration("0") == 0.0
    with pytest.raises(ValueError, match="needs a unit: 20ms or 20s"):
        parse_duration("20")  # a bare delay could be either unit
    with pytest.raises(ValueError, match="needs a unit"):
        parse_duration_list("0,50")
    assert parse_duration_list("0,50,100,200ms") == [0.0, 0.05, 0.1, 0.2]
    assert parse_duration_list("0,1s") == [0.0, 1.0]
    with pytest.raises(ValueError):
        parse_duration("fast")
    with pytest.raises(ValueError):
        FaultModel(dropout=1.0)


def test_injected_dropout_and_delay_are_observed(tmp_path):
    res = run_cli(str(ROOT / "launch.py"), "--agents", "6", "--scenario", "moving-prey", "--duration", "8",
                  "--dropout", "0.3", "--latency", "100ms", "--jitter", "20ms", "--record", str(tmp_path / "f.rrd"),
                  "--quiet", cwd=tmp_path, timeout=120)
    assert res.returncode == 0, res.stderr
    s = json.loads((tmp_path / "f.json").read_text())
    assert s["requested_faults"]["dropout"] == 0.3
    assert s["observed_dropout"] == pytest.approx(0.3, abs=0.03)  # ~4000 poses: 3 sigma is 0.02
    assert 80.0 <= s["observed_latency_ms"] <= 125.0


def test_simulator_faults_are_seeded_observed_and_inactive_faults_change_nothing():
    from zswarm.swarm.scenarios import get_scenario
    from zswarm.sim.simulator import simulate

    scenario = get_scenario("moving-prey")
    clean = simulate(scenario, 0, duration=10.0).summary
    assert simulate(scenario, 0, duration=10.0, faults=FaultModel(seed=0)).summary == clean
    lossy = FaultModel(dropout=0.3, latency=0.1, jitter=0.02, seed=4)
    a = simulate(scenario, 0, duration=10.0, faults=lossy).summary
    assert a == simulate(scenario, 0, duration=10.0, faults=lossy).summary
    assert a["observed_dropout"] == pytest.approx(0.3, abs=0.02)
    assert a != simulate(scenario, 0, duration=10.0, faults=FaultModel(dropout=0.3, latency=0.1, jitter=0.02,
                                                                       seed=5)).summary
    assert a["final_centroid_goal_distance"] != clean["final_centroid_goal_distance"]


def test_simulator_delay_uses_old_positions():
    """With a 0.2 s delay and no loss, agent i's neighbour data at step k is the position at k - 4."""
    from zswarm.sim.channel import FaultyChannel

    ch = FaultyChannel(3, FaultModel(latency=0.2, seed=0), dt=0.05, sensing_radius=100.0, v_max=1.0)
    pos = lambda k: np.array([[k, 0.0], [k, 1.0], [k, 2.0]], dtype=float)  # noqa: E731
    for k in range(10):
        i, j, believed, goal = ch.step(k, pos(k), np.array([100.0 + k, 0.0]))
    assert np.allclose(believed[:, 0], 9 - 4) and np.allclose(goal[:, 0], 100.0 + 9 - 4)
