"""Every run option works under ``--secure`` as it does without: each case runs the same command both
ways, side by side, and compares what the two summaries say. (Under ``--secure`` a migrating run once
moved nobody and said nothing: the access control did not let a moved agent hand over its state.)"""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT
from spool import Spool
from swarm_procs import load_summary

CASES = {
    # agents moved between three routers as the swarm moves. A move is planned only once the swarm has
    # sheared across the blocks it was placed in: a loaded machine's swarm lags its clock, and a run whose
    # three looks all came in its first 6 s once planned none, so the four looks here span 12 s. At real
    # time: two runs at once at twice real time (40 agent ticks a second each) beside the Ray tests asked
    # more of 2 cores than they have, and a swarm that lagged that far sheared across no block (no move)
    "migrate": ["--routers", "3", "--agents", "10", "--duration", "20", "--time-scale", "1", "--migrate-every", "3"],
    # agents killed and restarted, a world killed and restarted, a lossy, late channel, unicycles
    "faults": ["--agents", "6", "--duration", "12", "--kill", "2@4", "--restart-after", "2", "--world-crash", "8:1",
               "--latency", "50ms", "--dropout", "0.1", "--set", "body=unicycle"],
    # the lockstep clock in 3-D: the same trajectory to the last digit either way
    "lockstep-3d": ["--scenario", "moving-prey-3d", "--agents", "5", "--clock", "lockstep", "--duration", "6"],
}


def both_ways(tmp: Path, args: list[str]) -> dict[str, tuple[int, str, dict, Path]]:
    """The same run without and with ``--secure`` (a fresh folder: its certificates made for the run), at
    once: the exit code, the last lines, the summary and the trajectory of each."""
    runs = {}
    for way, extra in (("plain", []), ("secure", ["--secure", str(tmp / "pki")])):
        record, said = tmp / f"{way}.rrd", Spool()
        runs[way] = (record, said, subprocess.Popen(
            [sys.executable, str(ROOT / "launch.py"), *args, *extra, "--run", f"both-{way}", "--seed", "3",
             "--record", str(record), "--trajectory", str(tmp / f"{way}.npz"), "--quiet"],
            cwd=tmp, stdout=said, stderr=subprocess.STDOUT))
    out = {}
    try:
        for way, (record, said, proc) in runs.items():
            proc.wait(timeout=240)
            summary = record.with_suffix(".json")  # none from a launch that failed: its code and lines say why
            out[way] = (proc.returncode, said.text()[-3000:], load_summary(summary) if summary.exists() else None,
                        tmp / f"{way}.npz")
    finally:
        for _, _, proc in runs.values():
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    return out


@pytest.mark.parametrize("case", list(CASES))
def test_an_option_works_under_secure_as_it_does_without(case, tmp_path):
    runs = both_ways(tmp_path, CASES[case])
    for way, (code, text, s, _) in runs.items():
        assert code == 0, (way, text)
        assert s["collisions"] == 0 and s["obstacle_collisions"] == 0, (way, s["collisions"])
        assert s["agents_without_final_report"] == [], (way, s["agents_without_final_report"], text)
        assert s["agents_final_reports"] == s["agents_reporting"] == s["n_agents"], (way, text)
    plain, secure = runs["plain"][2], runs["secure"][2]
    assert plain["security"]["tls"] is False and secure["security"] == {**secure["security"], "tls": True, "acl": True}
    assert secure["crashes"] == plain["crashes"], (plain["crashes"], secure["crashes"], runs["plain"][1], runs["secure"][1])
    assert secure["requested_faults"] == plain["requested_faults"]
    if case == "migrate":
        for way, s in (("plain", plain), ("secure", secure)):  # a look the world did not answer says so
            assert s["migration"]["moves"] > 0, (way, s["migration"], runs[way][1])
    if case == "faults":
        assert plain["crashed_agents"] and plain["world_segments"] == secure["world_segments"] == 2
    if case == "lockstep-3d":
        a, b = (np.load(runs[way][3]) for way in ("plain", "secure"))
        assert a["positions"].shape[-1] == 3 and a["positions"].shape == b["positions"].shape
        assert np.abs(a["positions"] - b["positions"]).max() < 1e-9
        assert plain["capture_time"] == secure["capture_time"]
