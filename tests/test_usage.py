"""Every command answers a user's mistake with one line on stderr and exit code 2, never a traceback:
unknown options, bad values, unknown scenarios, unreadable files and occupied ports."""

from __future__ import annotations

import os
import socket
import sys
import time
from pathlib import Path

import pytest

from conftest import ROOT, run_cli
from forked_cli import run_forked
from swarm_procs import our_processes

LAUNCH = str(ROOT / "launch.py")

# {busy}: a port something listens on; {junk}: a file of garbage; {dir}: a directory; {missing}: nothing
CASES = [
    # design
    (["-m", "zswarm", "design", "--nope"], "unrecognized arguments"),
    (["-m", "zswarm", "design", "--set", "l_o=-1"], "l_o must be"),
    (["-m", "zswarm", "design", "--set", "n_agents=abc"], "n_agents must be an integer"),
    (["-m", "zswarm", "design", "--set", "zz=1"], "unknown parameter"),
    (["-m", "zswarm", "design", "--save", "{missing}/x.rrd"], "does not exist"),
    (["-m", "zswarm", "design", "--figure", "{dir}/f.txt"], "give a file name ending in .png"),
    (["-m", "zswarm", "design", "--figure", "{missing}/f.png"], "does not exist"),
    (["-m", "zswarm", "design", "--set", "interaction=swarm"], "unknown interaction"),
    (["-m", "zswarm", "design", "--scenario", "nope"], "unknown scenario"),
    (["-m", "zswarm", "design", "--paper", "--scenario", "moving-prey"], "give one"),
    # sim
    (["-m", "zswarm", "sim", "--scenario", "nope"], "unknown scenario"),
    (["-m", "zswarm", "sim", "--seed", "x"], "invalid int value"),
    (["-m", "zswarm", "sim", "--seed", "-1"], "a seed is an integer in [0, 2^63)"),
    (["-m", "zswarm", "sim", "--scenario", "large-swarm", "--set", "n_agents=1e6"], "<= 100000"),
    (["-m", "zswarm", "bench", "soak", "--seed", "-5"], "a seed is an integer"),
    (["-m", "zswarm", "sim", "--duration", "-1"], "--duration"),
    (["-m", "zswarm", "sim", "--potential", "both"], "--potential"),
    (["-m", "zswarm", "sim", "--set", "v_max=0"], "v_max must be"),
    (["-m", "zswarm", "sim", "--set", "interaction=mean+gate+x"], "unknown interaction"),
    (["-m", "zswarm", "sim", "--set", "c_o=2.5", "--require-design"], "the design fails for this run (prop2"),
    (["-m", "zswarm", "bench", "interactions", "--interactions", "paper,foo"], "unknown interaction"),
    (["-m", "zswarm", "bench", "guidelines", "--scenarios", "nope"], "unknown scenario"),
    (["-m", "zswarm", "sim", "--scenario", "{missing}.toml"], "does not exist"),
    (["-m", "zswarm", "sim", "--scenario", "{junk}.toml"], "scenario"),
    (["-m", "zswarm", "sim", "--record", "{dir}"], "is a directory"),
    (["-m", "zswarm", "design", "--params", "{missing}.toml"], "does not exist"),
    (["-m", "zswarm", "design", "--params", "{junk}.toml"], "not valid TOML"),
    (["-m", "zswarm", "bench", "sim", "--batch", "4", "--dropout", "2"], "expected a loss probability in [0, 1)"),
    # tune
    (["-m", "zswarm", "tune", "--out", "{dir}/t", "--tune", "c_o,foo"], "cannot tune foo"),
    (["-m", "zswarm", "tune", "--out", "{dir}/t", "--tune", "v_max"], "cannot tune v_max"),
    (["-m", "zswarm", "tune", "--out", "{dir}/t", "--budget", "0"], "expected an integer >= 1"),
    (["-m", "zswarm", "tune", "--out", "{dir}/t", "--scenario", "{junk}.toml"], "scenario"),
    (["-m", "zswarm", "tune", "--out", "{dir}/t", "--waive", "prop9"], "invalid choice"),
    (["-m", "zswarm", "tune", "--out", "{dir}/t", "--set", "c_a_prime=0"], "from 0 in log space"),
    (["-m", "zswarm", "tune", "--out", "{junk}"], "is a file; give a directory"),
    (["-m", "zswarm", "tune", "--out", "/proc/zswarm-out"], "cannot create --out /proc/zswarm-out"),
    (["-m", "zswarm", "bench", "guidelines", "--out", "/proc/zswarm-out", "--sets", "1"],
     "cannot create --out /proc/zswarm-out"),
    (["-m", "zswarm", "bench", "guidelines", "--out", "{junk}", "--sets", "1"], "is a file; give a directory"),
    ([LAUNCH, "sweep", "--out", "/proc/zswarm-out", "--sim-only"], "cannot create --out /proc/zswarm-out"),
    # live viewing
    (["-m", "zswarm", "sim", "--viewer", "rerun+http://127.0.0.1:1/proxy"], "no Rerun viewer answers there"),
    (["-m", "zswarm", "sim", "--viewer", "tcp/127.0.0.1:1"], "expected a Rerun viewer URL"),
    ([LAUNCH, "--viewer", "rerun+http://127.0.0.1:1/proxy"], "no Rerun viewer answers there"),
    (["-m", "world", "--viewer", "rerun+http://127.0.0.1:1/proxy"], "no Rerun viewer answers there"),
    ([LAUNCH, "--connect", "rerun+http://127.0.0.1:1/proxy"], "give --viewer rerun+http://127.0.0.1:1/proxy"),
    # replay / compare
    (["-m", "zswarm", "replay", "{missing}.rrd"], "does not exist"),
    (["-m", "zswarm", "replay", "{junk}"], "cannot read"),
    (["-m", "zswarm", "compare", "{junk}", "{missing}.rrd"], "cannot read"),
    # certs
    (["-m", "zswarm", "certs", "{junk}"], "cannot write"),
    (["-m", "zswarm", "certs", "{dir}/pki", "--router", "tcp/localhost:1"], "must be a tls/HOST:PORT"),
    (["-m", "zswarm", "bench", "net", "--agents", "0"], "expected a number of agents >= 1"),
    # launch
    ([LAUNCH, "--nope"], "unrecognized arguments"),
    ([LAUNCH, "--agents", "0"], "expected a number of agents >= 1"),
    ([LAUNCH, "--agents", "500", "--duration", "1"], "more than 4 times what it can step"),
    ([LAUNCH, "--role", "agents"], "--connect"),
    ([LAUNCH, "--ids", "x-y"], "--ids"),
    ([LAUNCH, "--routers", "0"], "expected a number of routers from 1 to 64"),
    ([LAUNCH, "--routers", "2", "--role", "agents", "--connect", "tcp/127.0.0.1:1"], "give the router role"),
    ([LAUNCH, "--migrate-every", "5"], "give --routers K (K >= 2) or --cluster"),
    ([LAUNCH, "--migrate-every", "0.5", "--routers", "2"], "--migrate-every must be at least 1 second"),
    ([LAUNCH, "--migrate-every", "5", "--routers", "2", "--clock", "lockstep"], "free clock only"),
    ([LAUNCH, "--scenario", "nope"], "unknown scenario"),
    ([LAUNCH, "--set", "c_o=2.5", "--require-design"], "the design fails for this run (prop2"),
    ([LAUNCH, "--set", "interaction=nope"], "unknown interaction"),
    ([LAUNCH, "--scenario", "{junk}.toml"], "scenario"),
    ([LAUNCH, "--dropout", "2"], "expected a loss probability in [0, 1)"),
    ([LAUNCH, "--latency", "5parsecs"], "expected a duration"),
    ([LAUNCH, "--world-crash", "x"], "expected T or T:S"),
    ([LAUNCH, "--listen", "tcp/127.0.0.1:{busy}"], "already in use"),
    ([LAUNCH, "--listen", "nonsense"], "must look like tcp/HOST:PORT"),
    ([LAUNCH, "--secure", "{junk}"], "is not a directory"),
    ([LAUNCH, "--secure", "{dir}/pki", "--listen", "tcp/127.0.0.1:1"], "must be a tls/HOST:PORT"),
    ([LAUNCH, "--record", "{missing}/run.rrd"], "does not exist"),
    ([LAUNCH, "--config", "{junk}"], "cannot read zenoh config"),
    ([LAUNCH, "--router-config", "{missing}.json5"], "does not exist"),
    ([LAUNCH, "--config", "{junk}", "--secure", "{dir}/pki"], "give one"),
    # faults the run does not have, refused before anything starts
    ([LAUNCH, "--agents", "10", "--kill", "99@5"], "--kill 99@5: this machine runs 10 agents (give K <= 10)"),
    ([LAUNCH, "--kill", "3@100", "--duration", "5"], "100 s is after the run's end: the run lasts 5 s"),
    ([LAUNCH, "--world-crash", "100", "--duration", "5"], "--world-crash 100: 100 s is after the run's end"),
    ([LAUNCH, "--world-outage", "2:25", "--duration", "30"], "the agents leave a world silent for 30 s"),
    ([LAUNCH, "--world-outage", "3:1", "--role", "agents", "--connect", "tcp/127.0.0.1:1"], "give this machine the world role"),
    ([LAUNCH, "--agents", "4", "--pause", "agent-7@2:1"], "--pause agent-7@2:1: this machine runs no agent-7 "
                                                        "(its processes: router, world, agent-0 ... agent-3)"),
    ([LAUNCH, "--routers", "2", "--pause", "router-2@2:1"], "this machine runs no router-2"),
    ([LAUNCH, "--pause", "router@2:25", "--duration", "30"], "a router may be paused 20 s at most"),
    ([LAUNCH, "--pause", "world@40:1", "--duration", "30"], "--pause world@40:1: 40 s is after the run's end"),
    ([LAUNCH, "--pause", "robot@2:1"], "expected WHAT@T:S with WHAT world, router, router-K or agent-ID"),
    ([LAUNCH, "--pause", "agent-1@2"], "expected T:S"),
    ([LAUNCH, "--restart-after", "2"], "give --kill K@T too"),
    ([LAUNCH, "--kill", "2@3", "--restart-after", "9", "--duration", "10"], "the restart falls after the run's end"),
    ([LAUNCH, "--routers", "2", "--migrate-every", "30", "--duration", "10"], "no move falls within the run"),
    # the router given is not there: the same line and exit code in every command
    ([LAUNCH, "--connect", "tcp/127.0.0.1:1", "--connect-timeout", "1"], "cannot reach the router at tcp/127.0.0.1:1 within 1 s"),
    ([LAUNCH, "--role", "agents", "--connect", "tcp/127.0.0.1:1", "--connect-timeout", "1"],
     "cannot reach the router at tcp/127.0.0.1:1 within 1 s"),
    (["-m", "zswarm", "monitor", "--run", "x", "--connect", "tcp/127.0.0.1:1", "--connect-timeout", "1"],
     "cannot reach the router at tcp/127.0.0.1:1 within 1 s"),
    # a simulation this machine would spend hours on; keys where nothing can be written
    (["-m", "zswarm", "sim", "--agents", "100000", "--duration", "300"], "would take about"),
    ([LAUNCH, "--secure", "/sys/zswarm-pki"], "--secure /sys/zswarm-pki: cannot write the keys there"),
    # sweep
    ([LAUNCH, "--seed", "-1"], "a seed is an integer"),
    ([LAUNCH, "--time-scale", "0"], "--time-scale must be in (0, 1000)"),
    ([LAUNCH, "sweep", "--bogus"], "--out"),
    ([LAUNCH, "sweep", "--out", "{dir}/s", "--seed", "-1"], "a seed is an integer"),
    (["-m", "zswarm", "run", "--agents", "0"], "expected a number of agents >= 1"),
    (["-m", "zswarm", "sweep", "--out", "{junk}"], "is a file"),
    ([LAUNCH, "sweep", "--out", "{dir}/s", "--scenario", "nope"], "unknown scenario"),
    ([LAUNCH, "sweep", "--out", "{dir}/s", "--pause", "agent-10@1:1"], "a sweep's run has a world, a router and agents 0-9"),
    ([LAUNCH, "sweep", "--out", "{dir}/s", "--pause", "world@1:1", "--sim-only"], "not with --sim-only"),
    ([LAUNCH, "sweep", "--out", "{dir}/s", "--latency", "1ms,x"], "expected a duration"),
    ([LAUNCH, "sweep", "--out", "{dir}/s", "--latency", "0,100"], "'100' needs a unit: 100ms or 100s"),
    ([LAUNCH, "sweep", "--out", "{dir}/s", "--dropout", "1.5"], "expected a loss probability in [0, 1)"),
    ([LAUNCH, "sweep", "--out", "{dir}/s", "--duration", "-1"], "--duration: expected a duration > 0"),
    ([LAUNCH, "sweep", "--out", "{junk}"], "is a file"),
    # files that cannot be written, or would be written under the wrong name
    (["-m", "zswarm", "design", "--save", "/proc/x.rrd"], "cannot create a file in /proc"),
    (["-m", "zswarm", "design", "--figure", "/proc/x.png"], "cannot create a file in /proc"),
    ([LAUNCH, "--record", "/proc/x.rrd"], "cannot create a file in /proc"),
    (["-m", "zswarm", "design", "--figure", "{dir}"], "ending in .png or .svg or .pdf"),
    ([LAUNCH, "--summary", "{dir}"], "ending in .json"),
    (["-m", "zswarm", "design", "--save", "{dir}/x.txt"], "ending in .rrd"),
    ([LAUNCH, "--record", "{dir}/x.txt"], "ending in .rrd"),
    (["-m", "zswarm", "sim", "--record", "{dir}/x.txt"], "ending in .rrd"),
    (["-m", "zswarm", "replay", "{dir}"], "is a directory"),
    # monitor, tune
    (["-m", "zswarm", "monitor", "--run", "x", "--connect", "foo:bar"], "must look like tcp/HOST:PORT"),
    (["-m", "zswarm", "monitor", "--run", "x", "--wait", "-1"], "argument --wait: expected a duration > 0"),
    (["-m", "zswarm", "monitor", "--run", "x", "--connect", "tcp/999.1.1.1:7447"], "999.1.1.1 is not an IP address"),
    (["-m", "agents", "--id", "0", "--connect", "tcp/127.0.0.1:70000"], "the port must be in 1..65535"),
    ([LAUNCH, "--record", "{old}"], "exists (an earlier run's): give --force to overwrite it, or another --record"),
    (["-m", "zswarm", "sim", "--record", "{old}"], "old.rrd exists; give another path or --force"),
    (["-m", "zswarm", "design", "--save", "{old}"], "old.rrd exists; give another path or --force"),
    (["-m", "zswarm", "sim", "--agents", "0"], "--agents"),
    (["-m", "zswarm", "monitor", "--run", "x", "--stop-after", "-1"], "--stop-after: expected a duration > 0"),
    (["-m", "zswarm", "tune", "--out", "{dir}/t", "--popsize", "1"], "--popsize must be >= 2"),
    (["-m", "zswarm", "tune", "--out", ""], "--out needs a directory"),
    # the processes
    (["-m", "zswarm.net.router", "--listen", "tcp/127.0.0.1:{busy}"], "cannot listen"),
    (["-m", "zswarm.net.router", "--config", "{junk}"], "cannot read zenoh config"),
    (["-m", "zswarm.net.router", "--config", "{missing}.json5"], "does not exist"),
    (["-m", "agents", "--id", "0", "--mode", "peer", "--listen", "tcp/127.0.0.1:{busy}"], "cannot listen"),
    (["-m", "agents", "--id", "0", "--scenario", "nope"], "unknown scenario"),
    (["-m", "agents", "--id", "0", "--clock", "lockstep", "--takeover"], "free clock only"),
    (["-m", "agents", "--id", "0", "--node", "70000"], "--node must be in 0..65535"),
    (["-m", "agents", "--id", "0", "--robots", "{junk}", "--odom-lost", "0.5"], "--odom-lost must be above --odom-timeout (1 s)"),
    (["-m", "agents", "--id", "0", "--connect", "tcp/127.0.0.1:1", "--connect-timeout", "1"],
     "cannot reach the router at tcp/127.0.0.1:1 within 1 s"),
    (["-m", "agents", "--id", "0", "--start", "1;2"], "--start expects X,Y"),
    (["-m", "agents", "--id", "99", "--scenario", "moving-prey"], "has no spawn position"),
    (["-m", "world", "--scenario", "nope"], "unknown scenario"),
    (["-m", "world", "--config", "{dir}"], "cannot read zenoh config"),
    (["-m", "world", "--record", "{missing}/w.rrd"], "does not exist"),
    (["-m", "world", "--resume", "--clock", "lockstep"], "free clock only"),
    (["-m", "world", "--design", "oops"], "expects a design verdict in JSON"),
    # ROS 2 robots
    (["-m", "agents", "--id", "0", "--robots", "{missing}.toml"], "does not exist"),
    ([LAUNCH, "--robots", "{missing}.toml"], "does not exist"),
    (["-m", "zswarm", "robot-sim", "--robots", "{missing}.toml"], "does not exist"),
    (["-m", "zswarm", "robot-sim", "--robots", "{missing}.toml", "--rate", "0"], "--rate must be in"),
    # over a cluster, and machines started by hand (no Ray process starts in any of these)
    ([LAUNCH, "--cluster", "127.0.0.1:1"], "cannot reach the Ray cluster at 127.0.0.1:1"),
    ([LAUNCH, "--cluster", "nope"], "--cluster takes HOST:PORT"),
    ([LAUNCH, "--cluster", "local:99"], "1 to 16"),
    ([LAUNCH, "--cluster", "local", "--role", "agents"], "--cluster runs every role itself"),
    ([LAUNCH, "--cluster", "local", "--ids", "0-3"], "--cluster places every agent itself"),
    ([LAUNCH, "--cluster", "local", "--tracks", "{dir}"], "--tracks over a cluster is not supported yet"),
    ([LAUNCH, "--tracks", "{junk}"], "cannot make the folder"),
    ([LAUNCH, "--role", "agents", "--connect", "tcp/127.0.0.1:1", "--agents", "10", "--ids", "0-50"],
     "--ids 0-50 goes beyond the run's agents 0-9"),
    ([LAUNCH, "--connect-timeout", "0"], "--connect-timeout must be between"),
    # 3-D
    (["-m", "agents", "--id", "0", "--scenario", "moving-prey-3d", "--start", "1,2"], "--start expects X,Y,Z"),
    (["-m", "agents", "--id", "0", "--start", "1,2,3"], "--start expects X,Y in moving-prey (2-D"),
    (["-m", "zswarm", "sim", "--scenario", "moving-prey-3d", "--set", "body=unicycle"], "drives on the ground"),
    (["-m", "zswarm", "sim", "--scenario", "moving-prey", "--set", "dimensions=3"], "in 3-D, prey_start must be"),
]


@pytest.fixture(scope="module")
def busy_port():
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        yield s.getsockname()[1]


def _prepare(folder: Path) -> dict[str, str]:
    """A case's own folder, with a file of garbage, a broken TOML file and a directory in it."""
    folder.mkdir(parents=True)
    junk = folder / "junk"
    junk.write_bytes(b"\x00\xff not what you think [[[ = \n")
    (folder / "junk.toml").write_bytes(b"[[[ = \n")
    (folder / "d").mkdir()
    (folder / "old.rrd").write_bytes(b"an earlier run's recording")
    return {"junk": str(junk), "dir": str(folder / "d"), "missing": str(folder / "missing"),
            "old": str(folder / "old.rrd")}


@pytest.fixture(scope="module")
def mistakes(tmp_path_factory, busy_port):
    """Every case of CASES run once, each its own process in its own folder, as many at a time as there
    are cores, forked from one interpreter that imported the project once (:mod:`forked_cli`: a hundred
    interpreters starting up would cost the suite a core for a minute). Returns each case's result and
    folder, by index."""
    root = tmp_path_factory.mktemp("mistakes")
    jobs = []
    for k, (argv, _) in enumerate(CASES):
        folder = root / f"case{k}"
        fill = {"busy": str(busy_port), **_prepare(folder)}
        jobs.append(([a.format(**fill) for a in argv], folder))
    results = run_forked(jobs, root / "output", timeout=60)
    return {k: (res, folder) for k, (res, (_, folder)) in enumerate(zip(results, jobs))}


@pytest.mark.parametrize("k", range(len(CASES)), ids=[" ".join(a[:4]).replace(LAUNCH, "launch.py") for a, _ in CASES])
def test_user_mistakes_get_one_line_and_exit_2(k, mistakes):
    res, folder = mistakes[k]
    needle = CASES[k][1]
    assert res.returncode == 2, (res.returncode, res.stderr[-2000:])
    assert needle in res.stderr, res.stderr
    assert "Traceback" not in res.stderr and len(res.stderr.strip().splitlines()) == 1, res.stderr
    assert not any(p.name not in ("junk", "junk.toml", "d", "old.rrd") for p in folder.iterdir()), "left files behind"
    assert (folder / "old.rrd").read_bytes() == b"an earlier run's recording"


def test_a_machine_whose_agents_all_fail_exits_non_zero_and_says_so(tmp_path, busy_port):
    """Machines started by hand: agents that cannot open a session with what answers on the router's
    port (a listener that is no Zenoh router; given 1 s) end the machine's run with exit 1 and a last
    line that says so, not 0 and "the others carry on". (Nothing on the port at all: one line at once,
    tests/test_reliability.py.)"""
    res = run_cli(LAUNCH, "--role", "agents", "--connect", f"tcp/127.0.0.1:{busy_port}", "--agents", "10", "--ids",
                  "0-1", "--run", "x", "--duration", "5", "--connect-timeout", "1", timeout=60, cwd=tmp_path)
    assert res.returncode == 1, res.stderr
    last = res.stderr.strip().splitlines()[-1]
    assert "every one of this machine's agents exited with an error (agents 0-1" in last, res.stderr
    assert "cannot open a zenoh session after 1 s" in res.stderr  # each agent's own line says why
    assert our_processes("--run x") == []


def test_a_run_never_overwrites_an_earlier_one_unless_forced(tmp_path, monkeypatch):
    """No --record: run.rrd, then run-2.rrd beside an earlier run (said at start); --force takes run.rrd."""
    from zswarm.launch.plan import run_files

    monkeypatch.chdir(tmp_path)
    assert run_files(None, None, False) == (Path("run.rrd"), Path("run.json"), "")
    Path("run.json").write_text("{}")  # an earlier run's summary alone holds the name too
    record, summary, note = run_files(None, None, False)
    assert (record, summary) == (Path("run-2.rrd"), Path("run-2.json")) and "run-2.rrd" in note
    Path("run-2.rrd").write_bytes(b"x")
    assert run_files(None, None, False)[0] == Path("run-3.rrd")
    assert run_files(None, None, True)[:2] == (Path("run.rrd"), Path("run.json"))
    with pytest.raises(Exception, match="give --force"):
        run_files(Path("run-2.rrd"), None, False)


def test_a_scenario_file_with_an_interaction_its_potential_cannot_use_is_refused_when_read(tmp_path):
    f = tmp_path / "gated.toml"
    f.write_text('[params]\ninteraction = "mean+gate"\nl_a = 0.5\nl_r = 1.0\nc_r = 0.3333\n')
    for argv in (["-m", "zswarm", "sim", "--scenario", str(f)], [LAUNCH, "--scenario", str(f)]):
        res = run_cli(*argv, timeout=60, cwd=tmp_path)
        assert res.returncode == 2 and "needs a pair spacing" in res.stderr, res.stderr
        assert "Traceback" not in res.stderr and len(res.stderr.strip().splitlines()) == 1
    crowded = tmp_path / "crowded.toml"  # an N that no set can serve at this density
    crowded.write_text('spawn = [-1, -1, 0, 0]\n[params]\nn_agents = 500\n')
    for argv in (["-m", "zswarm", "sim", "--scenario", str(crowded)], [LAUNCH, "--scenario", str(crowded)]):
        start = time.monotonic()
        res = run_cli(*argv, timeout=60, cwd=tmp_path)
        assert res.returncode == 2 and "cannot place 500 agents" in res.stderr and "Traceback" not in res.stderr
        assert len(res.stderr.strip().splitlines()) == 1 and time.monotonic() - start < 20  # no agent started
    res = run_cli(LAUNCH, "--agents", "100000", "--duration", "1", timeout=60, cwd=tmp_path)  # placeable, not holdable
    assert res.returncode == 2 and "100000 agent processes need about" in res.stderr, res.stderr
    assert len(res.stderr.strip().splitlines()) == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["crowded.toml", "gated.toml"]


def test_launch_warns_when_the_machine_cannot_step_the_agents_in_real_time():
    import re

    from zswarm.launch.plan import AGENT_SHARE, AGENT_TICK_MS, pace_warning

    fits = int(AGENT_SHARE * 2 * 0.05 / (AGENT_TICK_MS / 1000.0))  # agents 2 cores step at 20 Hz
    assert pace_warning(fits, 0.05, 1.0, cores=2) is None
    line = pace_warning(fits + 1, 0.05, 1.0, cores=2)
    assert line and "tick late" in line and "\n" not in line
    large = pace_warning(100, 0.025, 1.0, cores=2)  # large-swarm's 100 processes, measured late at 0.5
    scale = float(re.search(r"--time-scale ([0-9.]+)", large).group(1))
    assert scale <= 0.25 and pace_warning(100, 0.025, scale, cores=2) is None
    assert pace_warning(100, 0.025, 1.0, cores=16) is None
    assert "fewer agents" in pace_warning(100_000, 0.05, 1.0, cores=2)


BAD_SCENARIOS = {
    "obstacle at x = nan": ("[[obstacles]]\nx = nan\ny = 0\n", "x and y must be finite"),
    "obstacle at y = inf": ("[[obstacles]]\nx = 0\ny = inf\nradius = 0.2\n", "x and y must be finite"),
    "prey at nan": ("prey_start = [nan, 0]\n", "prey_start must hold finite numbers"),
    "negative radius": ("[[obstacles]]\nx = 1\ny = 0\nradius = -1\n", "radius must be a finite number >= 0"),
    "obstacle without x": ("[[obstacles]]\ny = 0\n", "missing key 'x'"),
    "prey centre at nan": ('[prey]\nkind = "circle"\nspeed = 0.1\ncenter = [nan, 0]\n', "prey center must hold"),
    "three-number prey start": ("prey_start = [1, 2, 3]\n", "prey_start must be [x, y]"),
}


@pytest.mark.parametrize("body,needle", BAD_SCENARIOS.values(), ids=list(BAD_SCENARIOS))
def test_a_scenario_file_with_impossible_numbers_is_refused_when_read(body, needle, tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text(body)
    for argv in (["-m", "zswarm", "sim", "--scenario", str(f)], [LAUNCH, "--scenario", str(f), "--duration", "1"]):
        res = run_cli(*argv, timeout=60, cwd=tmp_path)
        assert res.returncode == 2 and needle in res.stderr, res.stderr
        assert "Traceback" not in res.stderr and len(res.stderr.strip().splitlines()) == 1, res.stderr
    assert [p.name for p in tmp_path.iterdir()] == ["bad.toml"]  # no recording, no summary


def test_a_refused_tune_leaves_no_out_directory_behind(tmp_path):
    res = run_cli("-m", "zswarm", "tune", "--out", str(tmp_path / "t"), "--popsize", "1", timeout=60, cwd=tmp_path)
    assert res.returncode == 2 and not (tmp_path / "t").exists()  # so the corrected command is not blocked


def test_serve_on_a_taken_port_is_refused_before_anything_starts(tmp_path):
    from zswarm.record.live import SERVE_PORT

    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as holder:  # as another run serving live would
        holder.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            holder.bind(("0.0.0.0", SERVE_PORT))
        except OSError:
            pytest.skip(f"port {SERVE_PORT} is already taken on this machine")
        holder.listen()
        for argv in ([LAUNCH, "--serve", "--duration", "1"], ["-m", "zswarm", "sim", "--serve", "--duration", "1"]):
            res = run_cli(*argv, timeout=60, cwd=tmp_path)
            assert res.returncode == 2 and f"port {SERVE_PORT} is in use" in res.stderr, res.stderr
            assert len(res.stderr.strip().splitlines()) == 1 and not any(tmp_path.iterdir())


def test_a_file_viewer_or_robots_mistake_is_refused_before_the_design_check(tmp_path, monkeypatch):
    """The swarm check simulates for a second or more: a mistake found without it is said first, and the
    check never runs (the cache of its results, a folder of this test's own, stays empty)."""
    kept = tmp_path / "cache"
    monkeypatch.setenv("ZSWARM_CACHE", str(kept))
    for argv, said in ((["-m", "zswarm", "sim", "--record", str(tmp_path)], "is a directory"),
                       (["-m", "zswarm", "sim", "--viewer", "rerun+http://127.0.0.1:1/proxy"], "no Rerun viewer"),
                       ([LAUNCH, "--robots", str(tmp_path / "missing.toml")], "does not exist")):
        res = run_cli(*argv, timeout=60, cwd=tmp_path)
        assert res.returncode == 2 and said in res.stderr, res.stderr
        assert not kept.exists() or not any(kept.iterdir()), argv  # no squeeze was run
    res = run_cli("-m", "zswarm", "sim", "--set", "c_o=2.5", "--require-design", timeout=60, cwd=tmp_path)
    assert res.returncode == 2 and len(list(kept.glob("squeeze-*.json"))) == 1  # what a judged set leaves


def test_sweep_help_shows_every_default():
    res = run_cli("-m", "zswarm", "sweep", "--help", timeout=60)
    assert res.returncode == 0
    text = " ".join(res.stdout.split())
    for default in ("(default static- goal)", "(default 0,50,100,200ms)", "(default 0,0.2,0.5)", "(default 3)",
                    "(default: the scenario's)"):
        assert default.replace("- ", "-") in text.replace("- ", "-"), default


def test_random_scenario_files_are_run_or_refused_in_one_line_leaving_nothing_behind(tmp_path):
    """sim and launch.py on scenario files with NaN, infinities, negative and zero sizes, huge N,
    overlapping obstacles and spawn areas too small for N: each is run (exit 0) or refused (one line,
    exit 2), and neither leaves a process or, when refused, a file behind."""
    from concurrent.futures import ThreadPoolExecutor

    from hypothesis import HealthCheck, given, settings
    from hypothesis import strategies as st

    def toml(v: float) -> str:
        return "nan" if v != v else ("inf" if v == float("inf") else "-inf" if v == -float("inf") else repr(v))

    specials = st.sampled_from([float("nan"), float("inf"), -float("inf"), 0.0, -1.0])
    scenario = st.fixed_dictionaries({
        "n": st.sampled_from([1, 3, 5, 500, 100000]),
        "numbers": st.tuples(st.floats(-5, -2), st.floats(-2, -0.5), st.floats(-2, 0), st.floats(0.5, 2),  # spawn
                             st.floats(-2, 2), st.floats(-2, 2),  # prey
                             *[st.floats(-3, 3), st.floats(-3, 3), st.floats(0, 1.5)] * 2),  # two obstacles
        "obstacles": st.integers(0, 2),
        "poison": st.one_of(st.none(), st.tuples(st.integers(0, 11), specials)),  # one impossible number
    })
    seen: dict[int, int] = {}
    cases = iter(range(10**6))

    @settings(max_examples=5, deadline=None, database=None, derandomize=True, suppress_health_check=list(HealthCheck))
    @given(scenario)
    def one(case):
        k = next(cases)
        folder = tmp_path / f"case{k}"
        folder.mkdir()
        run = f"prop-{k}-{tmp_path.name[-12:]}"
        v = list(case["numbers"])
        if case["poison"] is not None:
            v[case["poison"][0]] = case["poison"][1]
        body = (f"spawn = [{', '.join(map(toml, v[0:4]))}]\nprey_start = [{', '.join(map(toml, v[4:6]))}]\n"
                f"duration = 0.5\n[params]\nn_agents = {case['n']}\n"
                + "".join(f"[[obstacles]]\nx = {toml(v[6 + 3 * j])}\ny = {toml(v[7 + 3 * j])}\n"
                          f"radius = {toml(v[8 + 3 * j])}\n" for j in range(case["obstacles"])))
        commands = {"sim": ["-m", "zswarm", "sim", "--scenario", "s.toml", "--record", "sim.rrd"],
                    "launch": [LAUNCH, "--scenario", "s.toml", "--record", "run.rrd", "--run", run]}
        for name in commands:  # each in a folder of its own, both at once
            (folder / name).mkdir()
            (folder / name / "s.toml").write_text(body)
        with ThreadPoolExecutor(max_workers=2) as pool:
            results = dict(zip(commands, pool.map(lambda n: run_cli(*commands[n], timeout=120, cwd=folder / n),
                                                  commands)))
        for name, res in results.items():
            seen[res.returncode] = seen.get(res.returncode, 0) + 1
            assert res.returncode in (0, 2), (name, body, res.returncode, res.stderr[-1500:])
            assert "Traceback" not in res.stderr and "RuntimeWarning" not in res.stderr, (name, body, res.stderr[-1500:])
            if res.returncode == 2:
                lines = [line for line in res.stderr.strip().splitlines() if not line.startswith("warning:")]
                assert len(lines) == 1 and "Traceback" not in res.stderr, (name, body, res.stderr)
                # nothing that looks like a result
                assert sorted(p.name for p in (folder / name).iterdir()) == ["s.toml"], (name, body)
        assert not our_processes(run), body

    one()
    assert seen.get(0) and seen.get(2), seen  # it reaches both runs and refusals


def test_the_last_line_names_a_viewer_command_that_exists_here(monkeypatch, tmp_path):
    """"open with: rerun run.rrd" only works where rerun is on PATH; from a virtual environment that was
    not activated the line names the rerun installed beside this Python."""
    import shutil
    import sys

    from zswarm.launch.ending import installed_command

    monkeypatch.setenv("PATH", str(tmp_path))  # nothing on it
    command = installed_command()
    assert Path(command).name == "rerun" and (Path.cwd() / command).exists()
    assert (Path.cwd() / command).parent.absolute() == Path(sys.executable).parent.absolute()
    monkeypatch.setenv("PATH", str(Path(sys.executable).parent))
    assert shutil.which("rerun") is not None and installed_command() == "rerun"


def test_cluster_auto_takes_only_the_cluster_ray_start_left_here(tmp_path):
    """``--cluster auto`` is RAY_ADDRESS or the head ``ray start`` left on this machine (its bootstrap
    file), never whatever Ray head a scan of the machine's processes finds (another program's private
    cluster); a head that is gone is said to be gone. No Ray process starts."""
    import subprocess

    env = {k: v for k, v in os.environ.items() if k != "RAY_ADDRESS"}
    env.update(PYTHONPATH=str(ROOT), RAY_TMPDIR=str(tmp_path))

    def auto() -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, LAUNCH, "--cluster", "auto"], capture_output=True, text=True,
                              timeout=60, cwd=tmp_path, env=env)

    res = auto()
    assert res.returncode == 2 and "--cluster auto found no Ray cluster on this machine" in res.stderr, res.stderr
    (tmp_path / "ray").mkdir()
    (tmp_path / "ray" / "ray_current_cluster").write_text("127.0.0.1:1\n")  # a head that has stopped
    res = auto()
    assert res.returncode == 2 and len(res.stderr.strip().splitlines()) == 1, res.stderr
    assert "found no running Ray cluster: the last one ray start left on this machine, 127.0.0.1:1" in res.stderr


def test_sim_says_how_long_a_large_swarm_takes_and_refuses_one_of_hours():
    """``zswarm sim`` estimates its work before it starts: a line for a run of minutes, a refusal (one
    line, exit 2: the CASES above) for one over TOO_LONG_S, nothing for a small one."""
    from zswarm.errors import UsageError
    from zswarm.sim.simulator import NOTE_S, TOO_LONG_S, cost_note
    from zswarm.swarm.scenarios import get_scenario

    scenario = get_scenario("moving-prey", {"n_agents": 100_000})
    assert cost_note(get_scenario("moving-prey", {}), 30.0) is None
    note = cost_note(scenario, 1.0)
    assert note and note.startswith("note: about ") and "100000 agents, 1 s" in note
    assert NOTE_S < float(note.split("about ")[1].split(" s")[0]) < TOO_LONG_S
    with pytest.raises(UsageError, match="would take about"):
        cost_note(scenario, 300.0)
