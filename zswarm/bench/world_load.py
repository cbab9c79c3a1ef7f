"""What the world costs at N agents (``zswarm bench world``), measured with crowd processes for agents.

One world observes, judges and records every pose of a run, so it is the one process that grows with
N. A router, the world (free clock, recording to a file, as a run's) and K crowd processes
(:mod:`zswarm.bench.crowd`) that carry N agents' pose traffic, each agent at its spawn point: the
world does the same work per pose and per step as with agent processes, which a small machine could
not hold at N = 1000. After the world's clock has started, each process's CPU is read from ``/proc``
over the middle of the run (30 % to 90 % of its duration); the world's late ticks and the poses it
took in come from its summary.
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path
from typing import Any

from zswarm.bench.measure import CpuWindow
from zswarm.bench.net import judged, start_routers
from zswarm.launch.world_watch import wait_for_start
from zswarm.host.local import LocalHost
from zswarm.host.procs import Children
from zswarm.net.runspec import RunSpec


def world_spec(n_agents: int, duration: float, scenario: str, time_scale: float) -> RunSpec:
    return RunSpec(run=f"world{n_agents}", scenario_name=scenario, overrides=(("n_agents", n_agents),),
                   duration=duration, time_scale=time_scale)


def measure(n_agents: int, duration: float, scenario: str = "large-swarm", time_scale: float = 1.0,
            crowds: int = 2, intake: str = "auto") -> dict[str, Any]:
    """One run of the world at N (``crowds`` processes carry the agents' traffic; ``intake``: the world's)."""
    spec = world_spec(n_agents, duration, scenario, time_scale)
    crowds = max(1, min(crowds, n_agents))
    kids = Children()
    with tempfile.TemporaryDirectory() as tmp:
        summary_path, record = Path(tmp) / "world.json", Path(tmp) / "world.rrd"
        try:
            host = LocalHost(kids)
            design = judged(spec)
            endpoint = start_routers(host, 1)[0]
            world = host.spawn_world(spec, endpoint, "--summary", str(summary_path), "--record", str(record),
                                     "--progress", "0", "--intake", intake, "--start-timeout", "120", *design)
            share, first = -(-n_agents // crowds), 0
            while first < n_agents:
                count = min(share, n_agents - first)
                kids.spawn(f"crowd-{first}", ["-m", "zswarm.bench.crowd", "--first", str(first), "--count",
                                              str(count), *spec.to_argv(), "--connect", endpoint])
                first += count
            names = {c.name: c.pid for c in kids.children}
            window = CpuWindow(names)
            wait_for_start(spec.keys, endpoint)
            wall = duration / time_scale
            t0 = time.monotonic()
            time.sleep(0.3 * wall)
            window.start(time.monotonic())
            time.sleep(0.6 * wall)
            window.stop(time.monotonic())
            while world.alive() and time.monotonic() - t0 < wall + 120:
                time.sleep(0.2)
            if world.proc.wait(timeout=60) != 0:
                raise RuntimeError(f"the world exited with code {world.proc.returncode}")
            s = json.loads(summary_path.read_text())
            recorded_mb = record.stat().st_size / 2**20
        finally:
            kids.stop_all(grace=5.0)
    world_share = window.share(["world"])[0]
    rate = n_agents / spec.period  # poses a second the agents send
    return {
        "n_agents": n_agents, "scenario": scenario, "time_scale": time_scale, "duration_s": duration, "intake": intake,
        "rate_hz": round(1.0 / spec.period, 3), "poses_per_s_sent": rate,
        "poses_per_s_taken_in": s["messages_received"] / wall,
        "world_cpu_share": world_share, "world_us_per_pose": 1e6 * world_share / rate,
        "world_late_ticks": s["world_late_ticks"], "world_ticks": s["world_ticks"],
        "judged_at_one_time_s": s.get("judged_at_one_time_s"), "recording_mb": recorded_mb,
        "router_cpu_share": window.share(["router"])[0],
        "crowd_cpu_share": sum(window.share(n for n in names if n.startswith("crowd"))),
    }
