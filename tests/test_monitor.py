"""zswarm monitor on a live run, and the payload encoding a stock Zenoh subscriber sees."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time

import zenoh

from conftest import ROOT, free_port, run_cli, wait_for_port
from spool import Spool
from zswarm.net.messages import ENCODING, POSE_ENCODING


def _stock_subscriber(endpoint: str, run: str, agents: int, until: float) -> tuple[dict[str, set[str]], dict[int, int]]:
    """What a plain zenoh-python subscriber (z_sub) sees: the encoding of each kind of key; and, asked
    once the run is under way and again until every agent has come up (agents start one by one; the
    deadline is only for failing), how many member tokens each agent holds (z_liveliness)."""
    conf = zenoh.Config.from_json5(json.dumps({"mode": "client", "connect": {"endpoints": [endpoint]},
                                               "scouting": {"multicast": {"enabled": False}}}))
    seen: dict[str, set[str]] = {}
    lock = threading.Lock()

    def on_sample(sample) -> None:
        kind = str(sample.key_expr).split("/")[2]  # zswarm/RUN/<kind>/...
        with lock:
            seen.setdefault(kind, set()).add(str(sample.encoding))

    with zenoh.open(conf) as session:
        sub = session.declare_subscriber(f"zswarm/{run}/**", on_sample)
        while time.monotonic() < until:
            with lock:
                if {"pose", "prey", "stats"} <= seen.keys():
                    break
            time.sleep(0.05)
        sub.undeclare()
        while True:
            tokens: dict[int, int] = {}
            for reply in session.liveliness().get(f"zswarm/{run}/in/**", timeout=5.0):
                if reply.ok is not None:
                    who = int(str(reply.ok.key_expr).rsplit("/", 1)[1])
                    tokens[who] = tokens.get(who, 0) + 1
            if len(tokens) >= agents or time.monotonic() > until:
                return seen, tokens
            time.sleep(0.1)


def test_monitor_matches_the_runs_summary_and_payloads_name_their_encoding(tmp_path):
    port, run = free_port(), "monitor-test"
    endpoint = f"tcp/127.0.0.1:{port}"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    swarm = subprocess.Popen([sys.executable, str(ROOT / "launch.py"), "--agents", "10", "--duration", "12",
                              "--record", str(tmp_path / "run.rrd"), "--listen", endpoint, "--run", run, "--quiet"],
                             stdout=subprocess.DEVNULL, stderr=(said := Spool()), env=env,
                             start_new_session=True)
    try:
        wait_for_port(port)
        seen, tokens = _stock_subscriber(endpoint, run, 10, time.monotonic() + 20)
        # the live view with no --duration: it ends with the run, in one line
        live = subprocess.Popen([sys.executable, "-m", "zswarm", "monitor", "--run", run, "--connect", endpoint],
                                cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                                start_new_session=True)
        # no --connect: a run of this machine is found by its name
        mon = run_cli("-m", "zswarm", "monitor", "--run", run, "--stop-after", "4", "--json", timeout=60)
        unknown = run_cli("-m", "zswarm", "monitor", "--run", "not-running-here", timeout=60)
        nobody = run_cli("-m", "zswarm", "monitor", "--run", "nobody-here", "--connect", endpoint, "--wait", "1",
                         timeout=60)
        swarm.wait(timeout=90)
        err = said.text()
        swarm_ended = time.monotonic()
        assert swarm.returncode == 0, err[-2000:]
        view, view_err = live.communicate(timeout=30)
        live_ended = time.monotonic()
    finally:
        for proc in (swarm, live):
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
    assert live.returncode == 0, view_err
    assert live_ended - swarm_ended < 3.0  # it ended with the run, not after it
    assert view.strip().splitlines()[-1] == "zswarm monitor: the run ended: 10 agents stopped with it", view[-500:]
    assert "CRASHED" not in view and "crashed" not in view
    assert {"pose", "prey", "stats"} <= seen.keys(), seen
    assert tokens == {i: 1 for i in range(10)}, tokens  # each agent in one cell, by its member token
    assert seen.pop("pose") == {POSE_ENCODING}, seen  # a fixed record
    assert all(encodings == {ENCODING} for encodings in seen.values()), seen  # msgpack

    assert mon.returncode == 0, mon.stderr
    snapshots = [json.loads(line) for line in mon.stdout.splitlines()]
    assert len(snapshots) >= 3
    last = snapshots[-1]
    summary = json.loads((tmp_path / "run.json").read_text())
    assert last["alive"] == summary["n_agents"] == 10
    rate = summary["ticks"] / (summary["n_agents"] * summary["duration"])  # one pose per agent tick
    assert abs(last["mean_pose_rate"] - rate) <= 0.1 * rate, (last["mean_pose_rate"], rate)
    assert last["agents_reporting"] == 10 and last["prey"] is not None
    assert last["rejected"] == {} and summary["messages_rejected"] == 0

    assert nobody.returncode == 2 and "no agent of run 'nobody-here'" in nobody.stderr, nobody.stderr
    assert "Traceback" not in nobody.stderr
    assert unknown.returncode == 2 and len(unknown.stderr.strip().splitlines()) == 1, unknown.stderr
    assert "no run 'not-running-here' is running on this machine" in unknown.stderr
    from zswarm.launch.local_runs import endpoint_of

    assert endpoint_of(run) is None  # the run's entry went with it


def test_a_local_run_whose_launcher_was_killed_is_no_run(tmp_path, monkeypatch):
    """An entry a launcher killed outright left behind names a router nobody runs: looked up, it is
    removed, not connected to (the monitor would wait out its connect timeout)."""
    import subprocess as sp

    from zswarm.launch.local_runs import announce, endpoint_of

    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    path = announce("alive-run", "tcp/127.0.0.1:1")
    assert endpoint_of("alive-run") == ("tcp/127.0.0.1:1", None)  # this process is its launcher
    dead = sp.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    path.write_text(f"tcp/127.0.0.1:2 {dead.pid}\n")
    assert endpoint_of("alive-run") is None and not path.exists()


def test_the_monitor_command_a_secure_run_prints_works_as_printed(tmp_path):
    """``zswarm run --secure DIR`` prints ``... monitor --run RUN``: pasted as it is, it joins the run over
    TLS (the world's identity, announced with the run) and ends with the run; so does the docs' form with
    ``--config DIR/world.json5`` (the run's router found by its name)."""
    import re

    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    swarm = subprocess.Popen([sys.executable, str(ROOT / "launch.py"), "--agents", "4", "--duration", "15",
                              "--record", str(tmp_path / "s.rrd"), "--secure", str(tmp_path / "pki"), "--run",
                              "secure-watch"], cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                             text=True, env=env, start_new_session=True)
    views: list[subprocess.Popen] = []
    try:
        printed = None
        for line in swarm.stdout:
            if m := re.search(r"watch it live: (\S+) monitor --run (\S+)$", line.strip()):
                printed = m.groups()
                break
        assert printed is not None and printed[1] == "secure-watch"
        # a command that is there: on PATH, or the one beside this Python (relative to the run's folder)
        assert printed[0] == "zswarm" or (tmp_path / printed[0]).is_file(), printed
        # both at once, each to the run's end (a view told to stop after S seconds may stop before its first
        # refresh on a busy machine)
        views += [subprocess.Popen([sys.executable, "-m", "zswarm", "monitor", "--run", "secure-watch", "--json", *extra],
                                   cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                                   start_new_session=True)
                  for extra in ([], ["--config", str(tmp_path / "pki" / "world.json5")])]
        rest = swarm.stdout.read()
        swarm.wait(timeout=60)
        said = [view.communicate(timeout=60) for view in views]
    finally:
        for proc in (swarm, *views):
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
    assert swarm.returncode == 0, rest[-2000:]
    for view, (out, err) in zip(views, said):  # as printed; in the docs' form
        assert view.returncode == 0, err[-2000:]
        assert max(json.loads(line)["alive"] for line in out.splitlines()) == 4, out[-2000:]
        assert "the run ended" in err, err[-2000:]
