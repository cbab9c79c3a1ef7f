"""Experiments: crashes and outages from launch.py, and sweeps that resume."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from conftest import ROOT, run_cli
from swarm_procs import interrupt_when_exists, our_processes, recorded_events


def launch(*args: str, cwd, timeout: float = 180) -> subprocess.CompletedProcess:
    return run_cli(str(ROOT / "launch.py"), *args, cwd=cwd, timeout=timeout)


def test_kill_restart_and_world_outage(tmp_path):
    # killed at 1 s and back 1 s later, at its spawn point: every survivor still hears it come back (killed
    # at 2 s and back 2 s later, the swarm had moved on, only one survivor heard it, and in CI once none)
    res = launch("--agents", "5", "--duration", "10", "--kill", "1@1", "--restart-after", "1",
                 "--world-outage", "6:1.5", "--record", str(tmp_path / "k.rrd"), "--quiet",
                 "--tracks", str(tmp_path / "tracks"), cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    s = json.loads((tmp_path / "k.json").read_text())
    # --tracks: every process that ended wrote what it sent (the SIGKILLed one could not: 4 + its restart),
    # and the collisions judged at one instant from them are in the summary, as the world's own judge's
    tracks = s["tracks"]
    assert tracks["processes"] == 5 == len(list((tmp_path / "tracks").glob("agent-*.npy")))
    assert tracks["poses"] > 5 * 100 and tracks["collisions"] == 0
    assert tracks["closest"] is None or tracks["closest"] > 0.1  # None: no pair came within twice 2 d^r
    assert s["collisions_at_one_time"] == 0 and s["judged_at_one_time_s"] > 8.0
    assert "killed agents" in res.stderr and "restarted agents" in res.stderr and "world paused" in res.stderr
    assert [(e["action"], e.get("what")) for e in s["staged"]] == [
        ("kill_agents", None), ("restart_agents", None), ("pause", "world"), ("unpause", "world")]
    early = [d for d in s["departures"] if d["t"] < 9.9]
    assert len(early) == 1 and 0.5 < early[0]["t"] < 2.5
    victim = str(early[0]["id"])
    assert any(victim in r for r in s["neighbour_returns"].values())  # seen again through liveliness
    assert s["agents_reporting"] == 5
    # the world was frozen for 1.5 s: the recording has a gap there, and no tick in it
    from zswarm.record.replay import load_run

    times = [f.t for f in load_run(tmp_path / "k.rrd").frames]
    gaps = [b - a for a, b in zip(times, times[1:])]
    assert max(gaps) > 1.0
    # and the recording's event log says what happened, on the timeline
    events = " | ".join(recorded_events(tmp_path / "k.rrd"))
    assert f"agent {victim} crashed" in events and f"agent {victim} returned" in events, events
    assert early[0]["how"] == "crashed" and "run ended: 5 agents stopped with it" in events, events
    assert "departed" not in events and "left" not in events  # the end of the run is no departure
    assert "world clock stalled" in events, events


def test_a_paused_router_agent_and_world_each_go_on_and_nothing_is_lost(tmp_path):
    """``--pause WHAT@T:S``: the router, the world and two agents each frozen in turn (SIGSTOP) and let go
    (SIGCONT): no collision, every agent's final report, the pauses in the summary as they were staged.
    Agent 1, frozen for less than its link's lease (10 s), is nobody's departure; agent 2, frozen for
    longer, is seen to go when its router closes its link and to come back, and is told unreachable,
    not crashed."""
    res = launch("--agents", "5", "--duration", "22", "--pause", "router@2:2", "--pause", "world@4:3",
                 "--pause", "agent-1@5:2", "--pause", "agent-2@8:11", "--record", str(tmp_path / "p.rrd"),
                 "--quiet", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    s = json.loads((tmp_path / "p.json").read_text())
    assert s["collisions_at_one_time"] == 0 and s["collisions"] == 0
    assert s["agents_final_reports"] == 5 and s["agents_without_final_report"] == []
    assert [(d["id"], d["how"]) for d in s["departures"]] == [(2, "unreachable")], s["departures"]
    assert 17.0 < s["departures"][0]["t"] < 19.5 and s["crashed_agents"] == []
    staged = [(e["action"], e["what"], e["at_s"]) for e in s["staged"]]
    assert [(a, w) for a, w, _ in staged] == [
        ("pause", "router"), ("unpause", "router"), ("pause", "world"), ("pause", "agent-1"), ("unpause", "world"),
        ("unpause", "agent-1"), ("pause", "agent-2"), ("unpause", "agent-2")]
    assert all(abs(at - due) < 1.0 for (_, _, at), due in zip(staged, (2, 4, 4, 5, 7, 7, 8, 19)))
    for what in ("router", "world", "agent-1", "agent-2"):
        assert f"{what} paused at" in res.stderr and f"{what} resumed at" in res.stderr
    events = " | ".join(recorded_events(tmp_path / "p.rrd"))
    assert "agent 2 was unreachable from" in events and "agent 2 returned" in events, events


def test_a_lockstep_run_is_paused_at_its_own_clock_and_an_unreached_fault_is_said(tmp_path):
    """A lockstep run goes as fast as its agents answer: a fault starts when the world's tick reaches its
    time on the run's clock, which holds there until the launcher has staged it (however late the
    launcher looks: beside two busy loops the clock had run 0.3 s on), and ends its wall seconds later;
    one the run ends before is said in one line."""
    res = launch("--clock", "lockstep", "--agents", "5", "--duration", "30", "--end-after-capture", "0.5",
                 "--pause", "agent-1@3:1", "--kill", "1@25", "--record", str(tmp_path / "l.rrd"), "--quiet",
                 cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    s = json.loads((tmp_path / "l.json").read_text())
    assert [(e["action"], e["what"]) for e in s["staged"]] == [("pause", "agent-1"), ("unpause", "agent-1")]
    pause, unpause = s["staged"]
    assert pause["run_s"] == 3.0 and 0.95 < unpause["at_s"] - pause["at_s"] < 1.5, s["staged"]
    assert unpause["run_s"] - pause["run_s"] < 0.2  # the run's clock stood still while an agent was frozen
    assert s["capture_time"] < 20 and "the run ended before kill agents at 25 s: not staged" in res.stderr, res.stderr
    assert s["agents_final_reports"] == 5 and s["collisions"] == 0 and not s["departures"]


def test_sweep_simulated_resumes_without_touching_finished_cells(tmp_path):
    out = tmp_path / "sw"
    args = ("sweep", "--scenario", "moving-prey", "--latency", "0,100ms", "--dropout", "0.2", "--seeds", "1",
            "--duration", "5", "--out", str(out), "--sim-only")
    assert launch(*args, cwd=tmp_path).returncode == 0
    cells = sorted((out / "cells").iterdir())
    assert len(cells) == 2
    kept = cells[0] / "sim.json"
    mtime = kept.stat().st_mtime_ns
    (cells[1] / "sim.json").unlink()
    res = launch(*args, cwd=tmp_path)
    assert res.returncode == 0 and "1 already finished" in res.stdout
    assert kept.stat().st_mtime_ns == mtime and (cells[1] / "sim.json").exists()
    table = (out / "results.md").read_text().splitlines()
    assert len([line for line in table if line.startswith("| simulated")]) == 2
    column = table[0].split("|").index(" min clearance ")
    clearances = [line.split("|")[column].strip() for line in table if line.startswith("| simulated")]
    assert all(c == "none sensed" or float(c) > 0 for c in clearances), clearances  # never a bare "-"
    assert any(line.startswith("min clearance: the closest any agent came") for line in table)
    assert (out / "results.csv").exists() and (out / "sweep.rrd").stat().st_size > 0
    assert (out / "sweep.png").stat().st_size > 10_000  # the figure, drawn


def test_interrupted_distributed_sweep_resumes(tmp_path):
    out = tmp_path / "sw"
    args = [sys.executable, str(ROOT / "launch.py"), "sweep", "--scenario", "moving-prey", "--latency", "0",
            "--dropout", "0,0.3", "--seeds", "1", "--agents", "3", "--duration", "3", "--out", str(out)]
    proc = subprocess.Popen(args, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    first = out / "cells" / "lat0ms_drop0_rep0_barrier" / "run.json"
    second = out / "cells" / "lat0ms_drop0.3_rep0_barrier" / "run.rrd"
    assert interrupt_when_exists(proc, second)  # interrupted while the second cell's world records
    assert first.exists()
    # the interrupted sweep stopped that world and its agents before it exited: none of them is left
    # writing the cell's recording while the resumed sweep runs the cell again (a corrupt run.rrd)
    assert our_processes(str(out)) == []
    mtime = first.stat().st_mtime_ns
    res = subprocess.run(args, cwd=tmp_path, capture_output=True, text=True, timeout=180)
    assert res.returncode == 0, res.stderr
    assert first.stat().st_mtime_ns == mtime  # the finished cell was not run again
    assert (out / "cells" / "lat0ms_drop0.3_rep0_barrier" / "run.json").exists()
    rows = [line for line in (out / "results.md").read_text().splitlines() if line.startswith("| distributed")]
    assert len(rows) == 2


def test_a_sweep_puts_the_safety_filter_beside_the_law_alone(tmp_path):
    """goal-near-obstacle's 8 agents under the paper's law collide; with the filter, at every latency, none."""
    import csv

    out = tmp_path / "sw"
    res = launch("sweep", "--scenario", "goal-near-obstacle", "--latency", "0,300ms", "--dropout", "0.3",
                 "--seeds", "1", "--duration", "8", "--out", str(out), "--sim-only", "--safety", "off,barrier",
                 cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    rows = list(csv.DictReader(open(out / "results.csv")))
    assert sorted((r["safety"], r["latency_ms"]) for r in rows) == [("barrier", "0.0"), ("barrier", "300.0"),
                                                                    ("off", "0.0"), ("off", "300.0")]
    assert all(float(r["collisions_mean"]) == 0 for r in rows if r["safety"] == "barrier")
    assert all(float(r["collisions_mean"]) > 0 for r in rows if r["safety"] == "off")
    assert "| barrier |" in (out / "results.md").read_text()
    assert launch("sweep", "--scenario", "moving-prey", "--safety", "orca", "--out", str(tmp_path / "x"),
                  cwd=tmp_path).returncode == 2


def test_the_sweep_figure_says_when_nothing_was_caught_and_frames_a_single_latency(tmp_path):
    import re
    import warnings

    from zswarm.record.sweep_figure import save_figure

    cell = {"dropout": 0.0, "latency_ms": 0.0, "capture_time_mean": None, "capture_rate": 0.0}
    rows = [{**cell, "source": "distributed", "min_obstacle_clearance": 0.30},
            {**cell, "source": "simulated", "min_obstacle_clearance": 0.30}]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "no artists with labels" legend warning
        save_figure(rows, tmp_path / "one.svg", "static-goal", d_m_ro=0.2)
    text = (tmp_path / "one.svg").read_text()
    assert "no run caught the prey" in text
    texts = re.findall(r">([^<]*)</text>", text)
    starts = [0] + [k + 1 for k, t in enumerate(texts) if t.startswith("capture time (labels")]
    for first in starts:  # each panel's x tick labels come just before its x label
        label = texts.index("injected latency (ms)", first)
        assert texts[first:label] == ["0"], texts[first:label]  # the one latency, not -0.04..0.04 ms
