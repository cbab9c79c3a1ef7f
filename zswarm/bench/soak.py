"""A long run under loss, watched from outside for leaks and a growing backlog (``zswarm bench soak``):
each process's resident set, and each agent's inbound queue and late ticks, in the first and second
halves after a warm-up; flat and steady as docs/reliability.md defines them."""

from __future__ import annotations

import json
import statistics
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np

from zswarm.bench.measure import rss_mb
from zswarm.bench.net import field_spec, start_field
from zswarm.swarm.faults import FaultModel
from zswarm.host.procs import Children

FLAT_MB_PER_MIN = 1.0


def _slope_mb_per_min(t: np.ndarray, mb: np.ndarray) -> float:
    if len(t) < 3:
        return float("nan")
    return float(np.polyfit(t / 60.0, mb, 1)[0])


def _halves(rows: list[dict[str, float]], t0: float, t1: float) -> tuple[list[dict], list[dict]]:
    mid = 0.5 * (t0 + t1)
    return [r for r in rows if t0 <= r["t"] < mid], [r for r in rows if mid <= r["t"] <= t1]


def _late_share(rows: list[dict[str, float]]) -> float | None:
    """Late ticks / ticks between the first and last stats message of each agent in ``rows``."""
    by_agent: dict[int, list[dict]] = {}
    for r in rows:
        by_agent.setdefault(int(r["id"]), []).append(r)
    ticks = late = 0.0
    for rs in by_agent.values():
        if len(rs) >= 2:
            ticks += rs[-1]["ticks"] - rs[0]["ticks"]
            late += rs[-1]["late"] - rs[0]["late"]
    return late / ticks if ticks else None


def run_soak(n_agents: int = 30, dropout: float = 0.2, duration: float = 300.0, sample_every: float = 5.0,
             warmup: float | None = None, seed: int = 0) -> dict[str, Any]:
    """Run the soak and judge it (see the module doc)."""
    warmup = warmup if warmup is not None else max(30.0, 0.2 * duration)
    rss, stats_rows, summary = _watch(n_agents, dropout, duration, sample_every, seed)
    return {"n_agents": n_agents, "dropout": dropout, "duration_s": duration, "warmup_s": warmup, "seed": seed,
            **_judge(rss, stats_rows, summary, warmup, duration)}


def _watch(n_agents: int, dropout: float, duration: float, sample_every: float, seed: int
           ) -> tuple[dict[str, list[tuple[float, float]]], list[dict[str, float]], dict[str, Any]]:
    """Run the swarm; sample every process's memory and collect every agent's stats message from the
    start of the world's clock. Returns the memory samples, the stats rows and the world's summary."""
    import zenoh

    from zswarm.launch.world_watch import wait_for_start
    from zswarm.net import messages as msg
    from zswarm.net.config import zenoh_config
    from zswarm.net.keys import Keys

    run = f"soak{n_agents}"
    keys = Keys(run, 1.0)
    kids = Children()
    stats_rows: list[dict[str, float]] = []
    rss: dict[str, list[tuple[float, float]]] = {}
    lock = threading.Lock()
    with tempfile.TemporaryDirectory() as tmp:
        summary_path = Path(tmp) / "soak.json"
        try:
            spec = field_spec(n_agents, run, duration, faults=FaultModel(dropout=dropout, seed=seed), seed=seed)
            endpoint, world, agents = start_field(kids, spec, summary_path)
            router = kids.named("router")[0]
            wait_for_start(keys, endpoint)  # the world's clock
            t0 = time.monotonic()

            def on_stats(sample) -> None:
                try:
                    s = msg.decode(sample.payload.to_bytes())
                except msg.DecodeError:
                    return
                if isinstance(s, msg.Stats):
                    with lock:
                        stats_rows.append({"t": time.monotonic() - t0, "id": s.id, "ticks": s.ticks,
                                           "late": s.late_ticks, "queue": float(s.health.queue_max),
                                           "lag_ms": s.health.tick_lag_max_ms})

            with zenoh.open(zenoh_config("client", [endpoint])) as session:
                sub = session.declare_subscriber(keys.all_stats, on_stats)
                next_sample = 0.0
                while world.alive():
                    now = time.monotonic() - t0
                    if now >= next_sample:
                        for c in [router, world, *agents]:
                            r = rss_mb(c.pid)
                            if r is not None:
                                rss.setdefault(c.name, []).append((now, r))
                        next_sample += sample_every
                    time.sleep(0.2)
                sub.undeclare()
            if world.proc.wait() != 0:
                raise RuntimeError(f"the world exited with code {world.proc.returncode}")
            return rss, stats_rows, json.loads(summary_path.read_text())
        finally:
            kids.stop_all(grace=5.0)


def _judge(rss: dict[str, list[tuple[float, float]]], stats_rows: list[dict[str, float]], summary: dict[str, Any],
           warmup: float, end: float) -> dict[str, Any]:
    """Memory slopes and the two halves' backlog after the warm-up, and the verdicts."""
    memory = {}
    for name, series in rss.items():
        a = np.array([s for s in series if s[0] >= warmup])
        if len(a) >= 3:
            memory[name] = {"first_mb": float(a[0, 1]), "last_mb": float(a[-1, 1]), "growth_mb": float(a[-1, 1] - a[0, 1]),
                            "slope_mb_per_min": _slope_mb_per_min(a[:, 0], a[:, 1])}
    agent_mem = [m for k, m in memory.items() if k.startswith("agent")]
    first, second = _halves(stats_rows, warmup, end)
    q1 = float(np.percentile([r["queue"] for r in first], 99)) if first else None
    q2 = float(np.percentile([r["queue"] for r in second], 99)) if second else None
    lag1 = float(np.percentile([r["lag_ms"] for r in first], 99)) if first else None
    lag2 = float(np.percentile([r["lag_ms"] for r in second], 99)) if second else None
    late1, late2 = _late_share(first), _late_share(second)
    slopes = [m["slope_mb_per_min"] for m in memory.values()]
    flat = bool(memory) and all(s < FLAT_MB_PER_MIN for s in slopes)
    no_backlog = (q1 is not None and q2 is not None and q2 <= 2 * q1 + 10
                  and late1 is not None and late2 is not None and late2 <= late1 + 0.02)
    return {
        "memory": {
            "agent_rss_mb_median": statistics.median(m["last_mb"] for m in agent_mem) if agent_mem else None,
            "agent_slope_mb_per_min_median": statistics.median(m["slope_mb_per_min"] for m in agent_mem)
            if agent_mem else None,
            "agent_slope_mb_per_min_max": max(m["slope_mb_per_min"] for m in agent_mem) if agent_mem else None,
            "agent_growth_mb_max": max(m["growth_mb"] for m in agent_mem) if agent_mem else None,
            "world": memory.get("world"), "router": memory.get("router"),
        },
        "backlog": {"queue_p99_first_half": q1, "queue_p99_second_half": q2,
                    "tick_lag_p99_ms_first_half": lag1, "tick_lag_p99_ms_second_half": lag2,
                    "late_share_first_half": late1, "late_share_second_half": late2,
                    "stats_messages": len(stats_rows)},
        "run": {k: summary.get(k) for k in ("on_time_ratio", "observed_dropout", "collisions", "world_late_ticks",
                                           "world_ticks", "messages_received", "messages_rejected",
                                           "agents_reporting", "pose_latency_ms")},
        "memory_flat": flat, "backlog_flat": no_backlog, "flat_mb_per_min": FLAT_MB_PER_MIN,
    }
