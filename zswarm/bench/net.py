"""The distributed swarm's transport figures, measured with real processes on loopback (``zswarm bench net``).

Starts routers, the world and N agent processes in the ``bench-field`` setting (constant density: the
area grows with N, so each agent has about the same number of neighbours), runs them in free mode and
measures pose latency publish-to-neighbour (p50, p99), the share of control ticks on time, pose
messages received per agent per second (beside the poses in reach), the time until every agent is
alive, CPU per control tick and the memory of an agent process; :func:`run_floor` measures the same
traffic from bare Zenoh processes (:mod:`zswarm.bench.floor`).
"""

from __future__ import annotations

import json
import statistics
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

from zswarm.bench.measure import CpuWindow, pss_mb, rss_mb
from zswarm.launch.plan import judge_design
from zswarm.launch.world_watch import wait_for_start
from zswarm.swarm.faults import FaultModel
from zswarm.host.local import LocalHost
from zswarm.host.procs import Child, Children, agent_argv
from zswarm.net.runspec import RunSpec


def field_spec(n_agents: int, run: str, duration: float, scenario: str = "bench-field",
               faults: FaultModel | None = None, seed: int = 0, safety: str = "barrier", law: str = "apf",
               body: str = "point") -> RunSpec:
    """The benchmark's run: ``scenario`` at N agents for ``duration`` seconds."""
    return RunSpec(run=run, scenario_name=scenario, overrides=(("n_agents", n_agents), ("law", law), ("body", body)),
                   seed=seed,
                   duration=duration,
                   faults=faults or FaultModel(), safety=safety)


def start_routers(host: LocalHost, k: int) -> list[str]:
    """K routers on free ports of the host, meshed as ``zswarm run --routers K`` meshes them."""
    return host.start_routers([host.endpoint() for _ in range(k)])


def judged(spec: RunSpec) -> list[str]:
    """The world's ``--design`` with the set's verdict, judged here by ``zswarm run``'s own judge before
    anything starts. A world left to judge it spends a core for over a second beside its starting swarm:
    on 2 cores that doubled the start-up and the pose latency p99 of 50 agents (docs/benchmarks.md)."""
    return ["--design", json.dumps(judge_design(spec, required=False))]


def start_field(kids: Children, spec: RunSpec, summary_path: Path, routers: int = 1) -> tuple[str, Child, list[Child]]:
    """Routers, the world (waiting up to 120 s for the agents) and the N agent processes of ``spec``,
    forked from one fleet as ``zswarm run`` starts them (agent i on router i mod K). Returns the first
    router's endpoint, the world and the agents."""
    host = LocalHost(kids)
    design = judged(spec)
    endpoints = start_routers(host, routers)
    world = host.spawn_world(spec, endpoints[0], "--summary", str(summary_path), "--progress", "0",
                             "--start-timeout", "120", *design)
    agents = [host.spawn_agent(f"agent-{i}", agent_argv(spec, i, endpoints[i % routers], "--node", str(i % routers))[2:])
              for i in range(spec.scenario.n_agents)]
    return endpoints[0], world, agents


def run(n_agents: int, duration: float, scenario: str = "bench-field", routers: int = 1,
        safety: str = "barrier", law: str = "apf", body: str = "point") -> dict[str, Any]:
    """One swarm run: the transport figures from the world's summary, and what each process cost
    over the middle of the run (from 30 % to 90 % of its duration)."""
    kids = Children()
    with tempfile.TemporaryDirectory() as tmp:
        summary_path = Path(tmp) / "bench.json"
        try:
            spec = field_spec(n_agents, f"bench{n_agents}", duration, scenario, safety=safety, law=law, body=body)
            endpoint, world, agents = start_field(kids, spec, summary_path, routers=routers)
            wait_for_start(spec.keys, endpoint)
            names = {c.name: c.pid for c in kids.children}
            window = CpuWindow(names)
            memory: dict[str, list[float]] = {"rss": [], "pss": []}
            t0 = time.monotonic()
            time.sleep(0.3 * duration)
            window.start(time.monotonic())
            time.sleep(0.6 * duration)
            window.stop(time.monotonic())
            memory["rss"] = [v for v in (rss_mb(a.pid) for a in agents) if v is not None]
            memory["pss"] = [v for v in (pss_mb(a.pid) for a in agents) if v is not None]
            while world.alive() and time.monotonic() - t0 < duration + 60:
                time.sleep(0.2)
            if world.proc.wait(timeout=60) != 0:
                raise RuntimeError(f"the world exited with code {world.proc.returncode}")
            s = json.loads(summary_path.read_text())
        finally:
            kids.stop_all(grace=5.0)
    per_tick = [1000.0 * c * spec.period for c in window.share(a.name for a in agents)]
    poses = s.get("poses_received", 0)
    router_names = [c for c in names if c.startswith("router")]
    received = poses / n_agents / duration if duration else None
    reach = s.get("poses_in_reach_per_s")
    return {
        "n_agents": n_agents, "routers": routers, "rate_hz": round(1.0 / spec.period, 3), "duration_s": duration,
        "latency_ms": s["pose_latency_ms"], "age_at_use_ms": s["pose_age_ms"],
        "on_time_ratio": s["on_time_ratio"],
        "received_per_agent_per_s": received, "in_reach_per_agent_per_s": reach,
        "received_to_in_reach": received / reach if received is not None and reach else None,
        "startup_s": s["startup_s"],
        "cpu_ms_per_tick_agent": statistics.mean(per_tick) if per_tick else None,
        "cpu_ms_per_tick_agent_max": max(per_tick) if per_tick else None,
        "cpu_share_world": _one(window.share(["world"])), "cpu_share_router": sum(window.share(router_names)),
        "rss_mb_per_agent": statistics.median(memory["rss"]) if memory["rss"] else None,
        "pss_mb_per_agent": statistics.median(memory["pss"]) if memory["pss"] else None,
        "world_late_ticks": s.get("world_late_ticks"), "world_ticks": s.get("world_ticks"),
        "messages_rejected": s["messages_rejected"], "agents_reporting": s["agents_reporting"],
    }


def run_floor(n_agents: int, duration: float, scenario: str = "bench-field", handler: str = "ring") -> dict[str, Any]:
    """The same traffic from N bare Zenoh processes (:mod:`zswarm.bench.floor`) over a router, with a
    bare stand-in for the world publishing the prey at the same rate."""
    spec = field_spec(n_agents, f"floor{n_agents}", duration, scenario)
    kids = Children()
    try:
        endpoint = start_routers(LocalHost(kids), 1)[0]
        kids.spawn("floor-world", ["-m", "zswarm.bench.floor", "--prey", *spec.to_argv(), "--connect", endpoint],
                   stdout=subprocess.DEVNULL)
        # in one session, as a fleet's agents are (agents.fleet): one scheduling group under autogroup
        floors = [kids.spawn(f"floor-{i}", ["-m", "zswarm.bench.floor", "--id", str(i), "--handler", handler,
                                            *spec.to_argv(), "--connect", endpoint], stdout=subprocess.DEVNULL,
                             new_session=False)
                  for i in range(n_agents)]
        window = CpuWindow({c.name: c.pid for c in kids.children})
        time.sleep(0.3 * duration + 3.0)  # every process connected and publishing
        window.start(time.monotonic())
        time.sleep(0.6 * duration)
        window.stop(time.monotonic())
        pss = [v for v in (pss_mb(f.pid) for f in floors) if v is not None]
        rss = [v for v in (rss_mb(f.pid) for f in floors) if v is not None]
        alive = sum(f.alive() for f in floors)
    finally:
        kids.stop_all(grace=5.0)
    per_tick = [1000.0 * c * spec.period for c in window.share(f.name for f in floors)]
    return {"n_agents": n_agents, "floor_alive": alive,
            "cpu_ms_per_tick_floor": statistics.mean(per_tick) if per_tick else None,
            "cpu_share_router_floor": _one(window.share(["router"])),
            "pss_mb_per_floor": statistics.median(pss) if pss else None,
            "rss_mb_per_floor": statistics.median(rss) if rss else None}


def _one(values: list[float]) -> float | None:
    return values[0] if values else None


def measure(n_agents: int, duration: float, floor: bool, routers: int = 1, repeat: int = 1,
            safety: str = "barrier", law: str = "apf", body: str = "point") -> dict[str, Any]:
    """:func:`measure_once` ``repeat`` times in turn (swarm, floors, swarm, floors, ...): each figure is
    the median over the repeats, and each ratio the median of the repeats' ratios, with every
    repeat's ratios beside it (``*_runs``)."""
    runs = [measure_once(n_agents, duration, floor, routers, safety, law, body) for _ in range(repeat)]
    if repeat == 1:
        return runs[0]
    out = _medians(runs)
    out["repeats"] = repeat
    for key in ("cpu_ratio_agent_to_floor", "cpu_ratio_agent_to_floor_callback"):
        if key in out:
            out[f"{key}_runs"] = [r[key] for r in runs]
    return out


def _medians(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """Key by key: the median of the numbers (of each number, for a dict of them), else the last value."""
    out: dict[str, Any] = {}
    for key, last in runs[-1].items():
        values = [r.get(key) for r in runs]
        numbers = [v for v in values if isinstance(v, (int, float)) and not isinstance(v, bool)]
        if isinstance(last, dict):
            out[key] = _medians(values) if all(isinstance(v, dict) for v in values) else last
        elif numbers and not isinstance(last, bool):
            out[key] = statistics.median(numbers)
        else:
            out[key] = last
    return out


def measure_once(n_agents: int, duration: float, floor: bool, routers: int = 1,
                 safety: str = "barrier", law: str = "apf", body: str = "point") -> dict[str, Any]:
    """The swarm at N and, with ``floor``, the bare middleware with the same traffic, right after."""
    r = run(n_agents, duration, routers=routers, safety=safety, law=law, body=body)
    r["safety"], r["law"], r["body"] = safety, law, body
    if floor:
        r.update(run_floor(n_agents, duration))
        callback = run_floor(n_agents, duration, handler="callback")
        r["cpu_ms_per_tick_floor_callback"] = callback["cpu_ms_per_tick_floor"]
        a = r["cpu_ms_per_tick_agent"]
        for key, f in (("cpu_ratio_agent_to_floor", r["cpu_ms_per_tick_floor"]),
                       ("cpu_ratio_agent_to_floor_callback", r["cpu_ms_per_tick_floor_callback"])):
            r[key] = a / f if a is not None and f else None
    return r


CURVE_COLOURS = ((230, 85, 13), (49, 130, 189), (116, 196, 118))  # orange, blue, green
CURVES = {"cpu ms per tick": ("cpu_ms_per_tick_agent", "cpu_ms_per_tick_floor", "cpu_ms_per_tick_floor_callback"),
          "latency ms": ("latency_p50", "latency_p99", "age_at_use_p99"),
          "ticks on time": ("on_time_ratio",),
          "memory MB per process": ("pss_mb_per_agent", "rss_mb_per_agent", "pss_mb_per_floor")}


def record_curves(results: list[dict[str, Any]], path: Path, settings: dict[str, Any]) -> None:
    """The cost and latency curves against N (agents and floor) as a Rerun recording."""
    import rerun as rr
    import rerun.blueprint as rrb

    from zswarm.record.recording import close_recording, open_recording

    bp = rrb.Blueprint(rrb.Grid(*(rrb.TimeSeriesView(origin=f"bench/{title.replace(' ', '_')}", name=title)
                                  for title in CURVES)), collapse_panels=True)
    rec = open_recording(path, "zswarm-bench-net", bp)
    rec.log("bench/settings", rr.TextDocument(json.dumps(settings, indent=2)), static=True)
    for title, names in CURVES.items():  # a distinct colour per line within a plot
        for name, colour in zip(names, CURVE_COLOURS):
            rec.log(f"bench/{title.replace(' ', '_')}/{name}", rr.SeriesLines(names=name, colors=colour, widths=2.0),
                    static=True)
    for r in results:
        flat = {**r, "latency_p50": r["latency_ms"]["p50"], "latency_p99": r["latency_ms"]["p99"],
                "age_at_use_p99": r["age_at_use_ms"]["p99"]}
        rec.set_time("n_agents", sequence=r["n_agents"])
        for title, names in CURVES.items():
            for name in names:
                if flat.get(name) is not None:
                    rec.log(f"bench/{title.replace(' ', '_')}/{name}", rr.Scalars(float(flat[name])))
    close_recording(rec)
