"""The network benchmark's bookkeeping: repeats folded into medians, every repeat's ratio kept."""

from zswarm.bench.net import _medians


def test_repeats_fold_into_medians_key_by_key():
    runs = [{"n_agents": 50, "cpu": 1.0, "latency_ms": {"p50": 0.25, "p99": None}, "ok": True, "gone": None},
            {"n_agents": 50, "cpu": 3.0, "latency_ms": {"p50": 0.75, "p99": 2.0}, "ok": False, "gone": None},
            {"n_agents": 50, "cpu": 2.0, "latency_ms": {"p50": 0.5, "p99": 6.0}, "ok": True, "gone": 7}]
    out = _medians(runs)
    assert out["cpu"] == 2.0 and out["n_agents"] == 50
    assert out["latency_ms"] == {"p50": 0.5, "p99": 4.0}  # a repeat without a figure is left out
    assert out["ok"] is True and out["gone"] == 7
