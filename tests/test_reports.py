"""Benchmark reports print what they measured, and n/a for what a short run did not produce."""

from __future__ import annotations


def test_a_soak_report_with_figures_it_did_not_measure_prints_n_a(capsys):
    """A short soak may sample no memory and see no stats message: the report says n/a, not a traceback."""
    from zswarm.cli.soak import print_report

    empty = {"n_agents": 3, "dropout": 0.2, "duration_s": 5.0, "warmup_s": 30.0, "seed": 0,
             "memory": {"agent_rss_mb_median": None, "agent_slope_mb_per_min_median": None,
                        "agent_slope_mb_per_min_max": None, "agent_growth_mb_max": None, "world": None,
                        "router": None},
             "backlog": {"queue_p99_first_half": None, "queue_p99_second_half": None,
                         "tick_lag_p99_ms_first_half": None, "tick_lag_p99_ms_second_half": None,
                         "late_share_first_half": None, "late_share_second_half": None, "stats_messages": 0},
             "run": {"on_time_ratio": None, "observed_dropout": None, "collisions": 0, "pose_latency_ms": None},
             "memory_flat": False, "backlog_flat": False, "machine": {}}
    print_report(empty)
    out = capsys.readouterr().out
    assert out.count("n/a") >= 10 and "GROWING" in out
