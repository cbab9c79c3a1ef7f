"""Every registered law as real processes: lockstep agents reproduce the reference simulator to 1e-6
at every step (2-D and 3-D, a user's law file among them), and a law that fails inside a running agent
brakes that agent, records the law's traceback in its log and leaves the others running."""

from __future__ import annotations

import numpy as np
import pytest

from zswarm.laws.registry import BUILTIN
from zswarm.swarm.scenarios import get_scenario
from zswarm.host.procs import start_router
from zswarm.sim.simulator import simulate

from conftest import ROOT
from swarm_procs import load_summary, processes, recorded_events, start_agent, start_world, wait_exit

RUSH = '''import numpy as np


def rush(obs):
    """At the target, at full speed."""
    to = obs.target - obs.position
    d = float(np.linalg.norm(to))
    return obs.v_max * to / d if d > 0 else 0.0 * to
'''


def lockstep_against_reference(tmp_path, scenario: str, law: str, n: int, duration: float) -> dict:
    sets = ["--set", f"law={law}", "--set", f"n_agents={n}", "--safety", "barrier"]
    with processes() as kids:
        endpoint = start_router(kids)
        world, summary_path, _, traj = start_world(kids, endpoint, "laws", scenario, tmp_path, "--clock", "lockstep",
                                                   "--duration", str(duration), *sets)
        agents = [start_agent(kids, endpoint, "laws", scenario, i, "--clock", "lockstep", *sets) for i in range(n)]
        assert wait_exit(world, 180) == 0
        for a in agents:
            assert wait_exit(a, 20) == 0
    summary = load_summary(summary_path)
    ref = simulate(get_scenario(scenario, {"law": law, "n_agents": n}), 0, duration=duration, keep_trajectory=True,
                   safety="barrier")
    observed = np.load(traj)["positions"]
    assert observed.shape == ref.trajectory.shape
    assert np.max(np.abs(observed - ref.trajectory)) < 1e-6  # at every step, every agent
    assert np.max(np.abs(observed[-1] - observed[0])) > 0.1  # and they moved
    assert summary["missed_lockstep_poses"] == 0 and summary["agents_final_reports"] == n  # every step, every report
    return summary


@pytest.mark.parametrize("law", [name for name in BUILTIN if name != "apf"])  # apf: tests/test_distributed.py
def test_lockstep_processes_run_each_law_as_the_reference_does(tmp_path, law) -> None:
    summary = lockstep_against_reference(tmp_path, "moving-prey", law, 6, 4.0)
    assert summary["law"]["name"] == law and summary["law"]["params"]


@pytest.mark.parametrize("law,scenario", [("seek", "moving-prey"), ("Spring", "moving-prey-3d")])
def test_the_tutorials_laws_run_as_lockstep_processes(tmp_path, law, scenario) -> None:
    """examples/my_law.py (docs/laws.md): a function in 2-D, a class with a parameter in 3-D."""
    path = ROOT / "examples" / "my_law.py"
    summary = lockstep_against_reference(tmp_path, scenario, f"{path}:{law}", 4, 3.0)
    assert summary["law"]["source"] == f"file {path}" and summary["collisions"] == 0


def test_a_law_that_fails_in_a_running_agent_brakes_it_and_the_others_carry_on(tmp_path) -> None:
    """The law raises in agent 0 only, after 30 ticks: agent 0 brakes, says why in one line (the law's
    exception and where it was raised, no traceback), exits 3 and the run records it; the other agents run
    to the end and report."""
    from swarm_procs import our_processes, run_launch

    start = get_scenario("moving-prey", {"n_agents": 4}).initial_positions(np.random.default_rng(0))[0]
    law = tmp_path / "brittle.py"
    law.write_text(RUSH.replace("def rush(obs):", f"""START = np.array({start.tolist()!r})
calls, first = 0, None


def brittle(obs):
    global calls, first
    calls += 1
    if first is None:
        first = obs.position.copy()
    if calls > 30 and np.allclose(first, START):
        raise RuntimeError("brittle law gave up")
    return 0.5 * rush(obs)


def rush(obs):"""))
    res = run_launch(tmp_path, "--law", f"{law}:brittle", "--agents", "4", "--duration", "6", "--run", "brittlerun",
                     "--record", str(tmp_path / "b.rrd"))
    assert res.returncode == 0, res.stderr
    assert "agent 0: law " in res.stderr and "raised RuntimeError: brittle law gave up (brittle.py:" in res.stderr
    assert "Traceback" not in res.stderr
    assert res.stderr.count("agent 0: law ") == 1 and "agent-0 exited" not in res.stderr  # one line, the agent's
    assert "open run: any program that reaches its router can join it" in res.stdout  # said as an open run starts
    summary = load_summary(tmp_path / "b.json")
    assert summary["law_failures"] == summary["crashed_agents"] == [0]
    assert summary["crashes"] == {"0": "its law failed"}
    # it left with its counts (once, in a loaded suite run, 3 of 4: the recording's events say what the world saw)
    assert summary["agents_final_reports"] == 4 and summary["collisions"] == 0, (
        summary["agents_without_final_report"], summary["departures"], recorded_events(tmp_path / "b.rrd"))
    assert summary["world_ticks"] == 121  # the others ran to the end
    assert our_processes("brittlerun") == []


def test_a_run_whose_every_agent_law_fails_stops_and_exits_1(tmp_path) -> None:
    """The law raises on its 20th call in every process: one line per agent (no traceback), a last line
    that says every agent exited with an error, exit 1, and the world stopped within 5 s of the last
    failure (not at the end of the 20 s asked for), with every agent's final report."""
    from swarm_procs import our_processes, run_launch

    law = tmp_path / "late.py"
    law.write_text(RUSH.replace("def rush(obs):", """calls = 0


def late(obs):
    global calls
    calls += 1
    if calls >= 20:
        raise RuntimeError("late law gave up")
    return rush(obs)


def rush(obs):"""))
    res = run_launch(tmp_path, "--law", f"{law}:late", "--agents", "5", "--duration", "20", "--run", "laterun",
                     "--record", str(tmp_path / "l.rrd"))
    assert res.returncode == 1, res.stderr
    lines = res.stderr.strip().splitlines()
    assert sorted(ln.split(":")[0] for ln in lines if "raised RuntimeError: late law gave up" in ln) == [
        f"agent {i}" for i in range(5)], res.stderr
    assert "every one of this machine's agents exited with an error (agents 0-4" in lines[-1], res.stderr
    assert "Traceback" not in res.stderr
    summary = load_summary(tmp_path / "l.json")
    assert summary["law_failures"] == summary["crashed_agents"] == list(range(5))
    # each agent's law fails at its 20th tick (t = 0.95 s); the world stops within 5 s of the last failure,
    # whether the agents' tokens went before it stopped (departures) or it stopped first (stopped_at_end)
    gone = {d["id"]: d["t"] for d in summary["departures"]}
    assert set(gone) | set(summary["stopped_at_end"]) == set(range(5)), summary
    last_failure = max(gone.values(), default=19 * 0.05)
    assert summary["duration"] - last_failure < 5.0 and summary["duration"] < 20.0, summary["departures"]
    assert summary["agents_final_reports"] == 5
    assert our_processes("laterun") == []


def test_a_users_law_runs_in_a_sweep_and_collides_only_without_the_filter(tmp_path) -> None:
    """``zswarm sweep --law FILE.py:rush``: the reference simulator's cells (a distributed cell of a
    user's law is the processes test above) with the filter off and on."""
    import json

    from zswarm.cli.sweep import main as sweep

    law = tmp_path / "my_law.py"
    law.write_text(RUSH)
    out = tmp_path / "sweep"
    assert sweep(["--scenario", "moving-prey", "--law", f"{law}:rush", "--latency", "0,100ms", "--dropout", "0",
                  "--safety", "off,barrier", "--seeds", "1", "--duration", "5", "--sim-only", "--out", str(out)]) == 0
    cells = {p.parent.name: json.loads(p.read_text()) for p in (out / "cells").glob("*/sim.json")}
    assert len(cells) == 4 and all(c["law"]["name"] == f"{law}:rush" for c in cells.values())
    off = [c for c in cells.values() if c["safety"] == "off"]
    on = [c for c in cells.values() if c["safety"] == "barrier"]
    assert all(c["collisions"] > 0 for c in off) and all(c["collisions"] == 0 for c in on)
    assert (out / "results.md").exists()
