"""The pause matrix (slow, some minutes: ``pytest -m slow tests/test_pause_matrix.py -s`` prints the grid).

Each process a run has, the router, the world, an agent and an agent driving a robot (the robot's
bridge to the swarm), is frozen (SIGSTOP) for 0.5, 2 and 8 s at the start, the middle and the end of a
run (the last pause spans the run's end), on the free and the lockstep clock, open and ``--secure``, and
while agents migrate between routers. Every run: no collision at one instant, every agent's final
report, no agent taken for crashed, the pauses in its summary as staged. docs/experiments.md has the grid.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from conftest import ROOT, run_cli
from swarm_procs import processes

pytestmark = pytest.mark.slow

N = 5
LENGTHS = (0.5, 2.0, 8.0)
KINDS = ("router", "world", "agent-1")
#: Each variant's own flags, and the rotation of KINDS it freezes at the start, the middle and the end:
#: over the variants every kind is frozen at every position, at every length.
VARIANTS = {
    "free": ((), 0),
    "lockstep": (("--clock", "lockstep"), 1),
    "secure": (("--secure", "{tmp}/pki"), 2),
    "migrating": (("--routers", "3", "--migrate-every", "2"), 0),
}
ROBOT = """route = "rmw_zenoh"
distro = "jazzy"
[[robot]]
id = 0
namespace = "/robot0"
"""


def plan(length: float, whats: tuple[str, ...]) -> tuple[float, list[tuple[str, float]]]:
    """A run's duration, and each of ``whats`` frozen for ``length`` s: at 1 s, in the middle, and across the end."""
    duration = float(round(3 * length + 12))
    return duration, list(zip(whats, (1.0, duration / 2 - length / 2, duration - length / 2)))


def run(tmp: Path, name: str, length: float, whats: tuple[str, ...], flags: tuple[str, ...]) -> dict:
    """One run of the grid: what it staged, and what went wrong (``failures``: empty when the cell holds)."""
    duration, pauses = plan(length, whats)
    record = tmp / f"{name}.rrd"
    args = [str(ROOT / "launch.py"), "--agents", str(N), "--duration", f"{duration:g}", "--record", str(record),
            "--quiet", *(a.format(tmp=tmp) for a in flags)]
    for what, at in pauses:
        args += ["--pause", f"{what}@{at:g}:{length:g}"]
    res = run_cli(*args, cwd=tmp, timeout=duration + 120)
    cell = {"run": name, "length": length, "pauses": [f"{w}@{at:g}" for w, at in pauses], "failures": []}
    if res.returncode != 0:
        cell["failures"].append(f"exit {res.returncode}: {res.stderr.strip().splitlines()[-1:]}")
        return cell
    s = json.loads(record.with_suffix(".json").read_text())
    at_once = s.get("collisions_at_one_time", s["collisions"])  # lockstep: every step's poses are of one instant
    cell.update(collisions=at_once, reports=s["agents_final_reports"],
                departures=[(d["id"], d["how"]) for d in s["departures"]], stderr=res.stderr)
    if at_once != 0 or s["collisions"] != 0:
        cell["failures"].append(f"collisions {at_once} at one instant, {s['collisions']}")
    if "not staged" in res.stderr:
        cell["failures"].append(res.stderr[res.stderr.index("the run ended before"):].splitlines()[0])
    if s["agents_final_reports"] != N or s["agents_without_final_report"]:
        cell["failures"].append(f"final reports {s['agents_final_reports']} of {N}: "
                                f"missing {s['agents_without_final_report']}")
    if s["crashed_agents"] or any(how == "crashed" for _, how in cell["departures"]):
        cell["failures"].append(f"taken for crashed: {cell['departures']}")
    staged = sorted((e["what"], e["action"]) for e in s["staged"])
    if staged != sorted((w, a) for w, _ in pauses for a in ("pause", "unpause")):
        cell["failures"].append(f"staged {staged}")
    return cell


def test_every_process_paused_at_every_length_and_moment_loses_nothing(tmp_path):
    cells = []
    for variant, (flags, rotation) in VARIANTS.items():
        whats = KINDS[rotation:] + KINDS[:rotation]
        for length in LENGTHS:
            cells.append(run(tmp_path, f"{variant}-{length:g}", length, whats, flags))
    # the robot's bridge: agent 0 drives a stand-in robot, and is frozen at each moment in turn
    robots = tmp_path / "robot.toml"
    robots.write_text(ROBOT)
    from zswarm.host.procs import free_port

    for length in LENGTHS:
        endpoint, said = f"tcp/127.0.0.1:{free_port()}", tmp_path / f"robot-sim-{length:g}.log"
        with processes() as kids, open(said, "w") as log:
            kids.spawn("robot-sim", ["-m", "zswarm", "robot-sim", "--robots", str(robots), "--set", f"n_agents={N}",
                                     "--connect", endpoint, "--idle-exit", "30", "--stop-after", "120"],
                       stdout=subprocess.DEVNULL, stderr=log)
            cell = run(tmp_path, f"robot-{length:g}", length, ("agent-0",) * 3, ("--robots", str(robots),
                                                                                 "--listen", endpoint))
        stops = said.read_text().count("robot-sim: /robot0 stopped: no command")
        if stops < 3:  # each freeze of its bridge outlasts the robot's command timeout (0.25 s): it stops
            cell["failures"].append(f"the robot stopped {stops} times for want of commands, of 3 freezes")
        cell["robot_stops"] = stops
        cells.append(cell)
    grid = "\n".join(f"{c['run']:>16}  {' '.join(c['pauses']):<44} collisions {c.get('collisions', '-')}, "
                     f"reports {c.get('reports', '-')}/{N}, departures {c.get('departures', '-')}"
                     f"{', robot stopped ' + str(c['robot_stops']) + ' times' if 'robot_stops' in c else ''}"
                     f"{'  FAILED: ' + '; '.join(c['failures']) if c['failures'] else ''}" for c in cells)
    print("\n" + grid)
    assert not any(c["failures"] for c in cells), grid
