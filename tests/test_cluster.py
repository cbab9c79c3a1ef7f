"""A swarm over a Ray cluster (``zswarm run --cluster``), for real: Ray's own nodes, pinned actors, a
router per node, agents as processes. Ray starts only inside a network namespace that has nothing but
loopback (made here with ``unshare --net``): whatever it tries, nothing leaves the machine.

One 3-node cluster run serves the checks of a run; a second is killed mid-run to show that nothing is
left behind."""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest

import zswarm
from conftest import ROOT

NO_RAY = importlib.util.find_spec("ray") is None


def _can_unshare() -> bool:
    if os.geteuid() != 0 or shutil.which("unshare") is None or shutil.which("ip") is None:
        return False
    return subprocess.run(["unshare", "--net", "true"], capture_output=True).returncode == 0


pytestmark = [pytest.mark.skipif(NO_RAY, reason='Ray is not installed (pip install -e ".[cluster]")'),
              pytest.mark.skipif(not _can_unshare(), reason="needs root, unshare and iproute2 for a loopback-only "
                                                            "network namespace (Ray must not reach past it)")]

#: In a fresh network namespace: loopback up, then a record of the namespace's links and routes, then
#: the command. Nothing but loopback, and no route: nothing the command opens can leave the machine.
OFFLINE = 'ip link set lo up && ip -o link > "$NS_LINKS" && ip route > "$NS_ROUTES" && exec "$@"'


def offline(cwd: Path, *argv: str, mark: str) -> tuple[list[str], dict[str, str]]:
    env = {**os.environ, "PYTHONPATH": str(ROOT), "ZSWARM_TEST_MARK": mark,
           "NS_LINKS": str(cwd / "links.txt"), "NS_ROUTES": str(cwd / "routes.txt")}
    return ["unshare", "--net", "--", "sh", "-c", OFFLINE, "offline", sys.executable, *argv], env


def left_behind(mark: str) -> list[str]:
    """Processes of a run still there: Ray's (their command line names Ray; no other test starts Ray)
    and every process that inherited the run's mark (the world, the routers, the fleets, the agents)."""
    out = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit() or int(d.name) == os.getpid():
            continue
        try:
            cmd = (d / "cmdline").read_bytes()
            env = (d / "environ").read_bytes()
        except OSError:
            continue
        if cmd and (cmd.startswith(b"ray::") or b"/site-packages/ray/" in cmd or
                    f"ZSWARM_TEST_MARK={mark}".encode() in env.split(b"\0")):
            text = cmd.replace(b"\0", b" ")[:120].decode(errors="replace")
            out.append(f"{d.name}: {text}")
    return out


def wait_gone(mark: str, seconds: float) -> list[str]:
    deadline = time.monotonic() + seconds
    while (left := left_behind(mark)) and time.monotonic() < deadline:
        time.sleep(0.2)
    return left


@pytest.fixture(scope="module")
def three_nodes(tmp_path_factory):
    """``zswarm run --cluster local:3 --agents 12``: three Ray nodes (Ray's ``cluster_utils``) on this
    machine, at twice the wall clock (the reference catches the prey at 13.9 s of 25)."""
    tmp = tmp_path_factory.mktemp("cluster3")
    mark, started = uuid.uuid4().hex, time.time()
    argv, env = offline(tmp, "-m", "zswarm", "run", "--cluster", "local:3", "--agents", "12", "--duration", "25",
                        "--time-scale", "2", "--record", str(tmp / "c.rrd"), mark=mark)
    res = subprocess.run(argv, env=env, cwd=tmp, capture_output=True, text=True, timeout=240)
    left = wait_gone(mark, 10.0)
    summary = json.loads((tmp / "c.json").read_text()) if (tmp / "c.json").exists() else None
    return res, summary, left, tmp, started


def test_a_swarm_over_three_nodes_catches_the_prey_and_says_where_each_agent_ran(three_nodes):
    res, s, _, _, _ = three_nodes
    assert res.returncode == 0, res.stderr[-3000:]
    assert s["capture_time"] is not None and s["collisions"] == 0 and s["final_components"] == 1, s
    assert s["agents_reporting"] == 12 and s["messages_rejected"] == 0
    cluster = s["cluster"]
    nodes = cluster["nodes"]
    assert len(nodes) == 3 and len({n["label"] for n in nodes}) == 3 and len({n["router"] for n in nodes}) == 3
    assert all(n["version"] == zswarm.__version__ for n in nodes)  # each node greeted with its version
    agent_node = cluster["agent_node"]
    assert sorted(map(int, agent_node)) == list(range(12))
    assert {n["label"] for n in nodes} == set(agent_node.values())  # every node ran agents (4 each: 2 cores / 3)
    # each agent's router is its node's: the summary's routers line up with the nodes
    assert all(s["routers"][s["agent_router"][a]] == next(n["router"] for n in nodes if n["label"] == label)
               for a, label in agent_node.items())
    # the routers meshed: agents heard agents whose poses came in through another node's router
    assert s["cross_router_heard"] > 0 and 0 < s["cross_router_share"] < 1
    assert cluster["placement"] == "space"
    assert "12 agents on 3 nodes" in res.stdout


def test_the_cluster_ran_with_nothing_but_loopback_and_left_nothing_behind(three_nodes):
    res, _, left, tmp, started = three_nodes
    assert res.returncode == 0, res.stderr[-3000:]
    links = (tmp / "links.txt").read_text().split("\n")
    assert [ln.split(":")[1].strip() for ln in links if ln.strip()] == ["lo"]  # no interface but loopback
    assert (tmp / "routes.txt").read_text().strip() == ""  # and no route anywhere
    assert left == [], left
    assert not [p for p in Path("/tmp").glob("zs-ray-*") if p.stat().st_ctime >= started]  # its Ray folder too


def test_a_driver_killed_mid_run_leaves_no_process_within_ten_seconds(tmp_path):
    mark = uuid.uuid4().hex
    argv, env = offline(tmp_path, "-m", "zswarm", "run", "--cluster", "local:3", "--agents", "6", "--duration", "60",
                        "--record", str(tmp_path / "k.rrd"), mark=mark)
    driver = subprocess.Popen(argv, env=env, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                              text=True)
    try:
        deadline = time.monotonic() + 120
        for line in driver.stdout:  # the run is under way: every node's router and agents are up
            if line.startswith("world: started") or time.monotonic() > deadline:
                break
        assert driver.poll() is None, "the run ended before it was killed"
        assert len(left_behind(mark)) > 10  # Ray's nodes, the routers, the world, the agents
        driver.send_signal(signal.SIGKILL)  # unshare and sh exec'd it: this pid is the driver itself
        driver.wait(timeout=10)
        left = wait_gone(mark, 10.0)
        assert left == [], left
    finally:
        if driver.poll() is None:
            driver.kill()
        for pid in (int(p.split(":")[0]) for p in left_behind(mark)):
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
