"""The soak (slow: several minutes, outside the default test command): 30 agent processes with 20%
loss on every link; memory must stay flat and no backlog may grow. Run with ``pytest -m slow``."""

from __future__ import annotations

import pytest

from zswarm.bench.soak import FLAT_MB_PER_MIN, run_soak

pytestmark = pytest.mark.slow


def test_soak_30_agents_20_percent_loss_memory_flat_no_backlog():
    r = run_soak(n_agents=30, dropout=0.2, duration=240.0)
    m, b, s = r["memory"], r["backlog"], r["run"]
    assert s["agents_reporting"] == 30 and s["collisions"] == 0
    assert 0.17 < s["observed_dropout"] < 0.23  # the loss was really there
    assert m["agent_slope_mb_per_min_max"] < FLAT_MB_PER_MIN, m
    assert m["world"]["slope_mb_per_min"] < FLAT_MB_PER_MIN and m["router"]["slope_mb_per_min"] < FLAT_MB_PER_MIN, m
    assert b["stats_messages"] > 30 * 150  # every agent reported about once a second
    assert b["queue_p99_second_half"] <= 2 * b["queue_p99_first_half"] + 10, b
    assert b["late_share_second_half"] <= b["late_share_first_half"] + 0.02, b
    assert r["memory_flat"] and r["backlog_flat"]
