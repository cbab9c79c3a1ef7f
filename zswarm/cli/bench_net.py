"""``zswarm bench net``: the distributed swarm's transport figures, with real processes on loopback.

Starts a router, the world and N agent processes in the ``bench-field`` setting (constant density:
the area grows with N, so each agent has about the same number of neighbours), runs them in free
mode and reports pose latency publish-to-neighbour (p50, p99), the share of control ticks on time,
pose messages received per agent per second, the time until every agent is alive, and the resident
memory of an agent process.
"""

from __future__ import annotations

import json
import statistics
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

from zswarm.cli.figures import figure
from zswarm.model.faults import FaultModel
from zswarm.net.procs import (
    Child,
    Children,
    agent_argv,
    rss_mb,
    start_router,
    world_argv,
)
from zswarm.net.runspec import RunSpec


def field_spec(n_agents: int, run: str, duration: float, scenario: str = "bench-field",
               faults: FaultModel | None = None, seed: int = 0) -> RunSpec:
    """The benchmark's run: ``scenario`` at N agents for ``duration`` seconds."""
    return RunSpec(run=run, scenario_name=scenario, overrides=(("n_agents", n_agents),), seed=seed, duration=duration,
                   faults=faults or FaultModel())


def start_field(kids: Children, spec: RunSpec, summary_path: Path,
                world_stdout: int = subprocess.DEVNULL) -> tuple[str, Child, list[Child]]:
    """A router, the world (waiting up to 120 s for the agents) and the N agent processes of ``spec``.
    Returns the router's endpoint, the world and the agents."""
    endpoint = start_router(kids)
    world = kids.spawn("world", world_argv(spec, endpoint, "--summary", str(summary_path), "--progress", "0",
                                           "--start-timeout", "120"), stdout=world_stdout)
    agents = [kids.spawn(f"agent-{i}", agent_argv(spec, i, endpoint), stdout=subprocess.DEVNULL)
              for i in range(spec.scenario.n_agents)]
    return endpoint, world, agents


def run(n_agents: int, duration: float, scenario: str = "bench-field") -> dict[str, Any]:
    kids = Children()
    with tempfile.TemporaryDirectory() as tmp:
        summary_path = Path(tmp) / "bench.json"
        try:
            _, world, agents = start_field(kids, field_spec(n_agents, f"bench{n_agents}", duration, scenario),
                                           summary_path)
            t0 = time.monotonic()
            rss: list[float] = []
            sampled = False
            while world.alive():
                if not sampled and time.monotonic() - t0 > 0.5 * duration + 5 and summary_path.parent.exists():
                    rss = [r for r in (rss_mb(a.pid) for a in agents) if r is not None]
                    sampled = bool(rss)
                time.sleep(0.2)
            if world.proc.returncode != 0:
                raise RuntimeError(f"the world exited with code {world.proc.returncode}")
            s = json.loads(summary_path.read_text())
        finally:
            kids.stop_all(grace=5.0)
    poses = s.get("poses_received", 0)
    return {
        "n_agents": n_agents, "rate_hz": round(1.0 / 0.05, 3), "duration_s": duration,
        "latency_ms": s["pose_latency_ms"], "age_at_use_ms": s["pose_age_ms"],
        "on_time_ratio": s["on_time_ratio"],
        "received_per_agent_per_s": poses / n_agents / duration if duration else None,
        "startup_s": s["startup_s"],
        "rss_mb_per_agent": statistics.median(rss) if rss else None,
        "messages_rejected": s["messages_rejected"], "agents_reporting": s["agents_reporting"],
    }


def main_bench(args) -> int:
    from zswarm.provenance import machine

    results = [run(n, args.duration) for n in args.agents]
    if args.json:
        print(json.dumps(results[0] if len(results) == 1 else {"runs": results, "machine": machine()}))
        return 0
    for r in results:
        print(f"N={r['n_agents']:>4}  latency p50 {r['latency_ms']['p50']} ms  p99 {r['latency_ms']['p99']} ms  "
              f"on time {figure(r['on_time_ratio'], '.3f')}  received/agent/s {figure(r['received_per_agent_per_s'], '.1f')}  "
              f"startup {figure(r['startup_s'], '.2f')} s  rss/agent {figure(r['rss_mb_per_agent'], '.1f')} MB")
    print(f"machine: {machine()}")
    return 0
