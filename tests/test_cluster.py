"""A swarm over a Ray cluster (``zswarm run --cluster``), for real: Ray's own nodes, pinned actors, a
router per node, agents as processes. Ray starts only inside a network namespace that has nothing but
loopback (made here with ``unshare --net``): whatever it tries, nothing leaves the machine.

One 3-node cluster run serves the checks of a run, and a --secure one those of a guest on a node's
router. How runs end, and clusters started by hand, are tests/test_cluster_hosts.py's (the two modules
run side by side, this one's runs first in each)."""

from __future__ import annotations

import json
import os
import subprocess
import uuid
from pathlib import Path

import pytest

import zswarm
from conftest import ROOT
from ray_procs import RAY_TESTS, end_run, offline, wait_gone

pytestmark = RAY_TESTS


@pytest.fixture(scope="module")
def three_nodes(tmp_path_factory):
    """``zswarm run --cluster local:3 --agents 12``: three Ray nodes (Ray's ``cluster_utils``) on this
    machine, at twice the wall clock (the reference catches the prey at 14.75 s of 25: the agents of a
    node are one scheduling group, and beside the rest of the suite on 2 cores a run of 20 once ended
    before they caught it); agents are moved between the nodes every 3 s as the swarm moves."""
    tmp = tmp_path_factory.mktemp("cluster3")
    mark = uuid.uuid4().hex
    argv, env = offline(tmp, "-m", "zswarm", "run", "--cluster", "local:3", "--agents", "12", "--duration", "25",
                        "--time-scale", "2", "--migrate-every", "3", "--record", str(tmp / "c.rrd"), mark=mark)
    driver = subprocess.Popen(argv, env=env, cwd=tmp, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        out, err = driver.communicate(timeout=240)
    finally:
        if driver.poll() is None:
            end_run(driver, mark)
    res = subprocess.CompletedProcess(argv, driver.returncode, out, err)
    left = wait_gone(mark, 10.0)
    summary = json.loads((tmp / "c.json").read_text()) if (tmp / "c.json").exists() else None
    return res, summary, left, tmp, driver.pid  # unshare and sh exec'd it: the driver's pid


def test_a_swarm_over_three_nodes_catches_the_prey_and_says_where_each_agent_ran(three_nodes):
    res, s, _, _, _ = three_nodes
    assert res.returncode == 0, res.stderr[-3000:]
    said = {k: s.get(k) for k in ("capture_time", "collisions", "final_components", "final_centroid_goal_distance",
                                  "on_time_ratio", "pose_latency_ms", "safety_braked_ticks", "safety_stalled_ticks",
                                  "ticks", "world_late_ticks", "startup_s")}
    print(said)  # shown when it fails
    assert s["capture_time"] is not None and s["collisions"] == 0 and s["final_components"] == 1, said
    assert s["agents_reporting"] == 12 and s["messages_rejected"] == 0
    cluster = s["cluster"]
    nodes = cluster["nodes"]
    assert len(nodes) == 3 and len({n["label"] for n in nodes}) == 3 and len({n["router"] for n in nodes}) == 3
    assert all(n["version"] == zswarm.__version__ for n in nodes)  # each node greeted with its version
    agent_node = cluster["agent_node"]
    assert sorted(map(int, agent_node)) == list(range(12))
    assert {n["label"] for n in nodes} == set(agent_node.values())  # every node ran agents (4 each: 2 cores / 3)
    # each agent's router is its node's (where it ran at the end): the summary's routers line up with the nodes
    assert all(s["routers"][s["agent_router"][a]] == next(n["router"] for n in nodes if n["label"] == label)
               for a, label in cluster["agent_node_at_end"].items())
    # the routers meshed: agents heard agents whose poses came in through another node's router
    assert s["cross_router_heard"] > 0 and 0 < s["cross_router_share"] < 1
    assert cluster["placement"] == "space"
    assert "12 agents on 3 nodes" in res.stdout
    # moved between nodes, make-before-break: nobody saw an agent leave, every count went on
    assert s["migration"]["moves"] > 0 and s["departures"] == [] and s["agents_final_reports"] == 12
    assert "exited with code" not in res.stderr
    assert "network_util" not in res.stderr and "logging.cc" not in res.stderr  # Ray's start-up lines: dropped
    assert s["ticks"] >= 0.97 * 12 * s["steps"]


def test_the_cluster_ran_with_nothing_but_loopback_and_left_nothing_behind(three_nodes):
    res, _, left, tmp, driver = three_nodes
    assert res.returncode == 0, res.stderr[-3000:]
    links = (tmp / "links.txt").read_text().split("\n")
    assert [ln.split(":")[1].strip() for ln in links if ln.strip()] == ["lo"]  # no interface but loopback
    assert (tmp / "routes.txt").read_text().strip() == ""  # and no route anywhere
    assert left == [], left
    assert not list(Path("/tmp").glob(f"zs-ray-{driver}-*"))  # its Ray folder too


def test_a_pace_the_clusters_cores_cannot_hold_is_refused_before_any_agent_starts(tmp_path):
    """A cluster started here has this machine's cores: refused before Ray is even imported (a ``ray``
    that cannot be imported is put first on the path). Against a cluster that was running already, the
    same line names its cores: the two-host test."""
    mark = uuid.uuid4().hex
    fake = tmp_path.parent / f"{tmp_path.name}-noray"
    (fake / "ray").mkdir(parents=True)
    (fake / "ray" / "__init__.py").write_text('raise ImportError("this refusal must not need Ray")\n')
    argv, env = offline(tmp_path, "-m", "zswarm", "run", "--cluster", "local:2", "--agents", "500",
                        "--time-scale", "10", mark=mark)
    env["PYTHONPATH"] = f"{fake}:{env['PYTHONPATH']}"
    res = subprocess.run(argv, env=env, cwd=tmp_path, capture_output=True, text=True, timeout=120)
    lines = [ln for ln in res.stderr.splitlines() if "network_util" not in ln and "logging.cc" not in ln]
    assert res.returncode == 2 and len(lines) == 1, res.stderr[-2000:]
    machine = len(os.sched_getaffinity(0))
    cores = min(2 * max(machine // 2, 1), machine)  # local:2 on this machine: two nodes of half its cores
    assert "500 agents stepping 400 times a second" in lines[0] and f"the cluster has {cores}:" in lines[0], lines
    assert "--time-scale" in lines[0]  # it names a pace that fits
    assert sorted(p.name for p in tmp_path.iterdir()) == ["links.txt", "routes.txt"]  # nothing recorded
    assert wait_gone(mark, 10.0) == []


def test_a_guest_on_a_secure_clusters_node_reaches_nobody(tmp_path):
    """zswarm run --cluster local:2 --secure DIR: TLS and access control on every node's router, Ray with
    a token; a guest with a valid certificate on the second node's router publishes a far pose of agent
    1, a far prey and a final tick for 5 s: nobody takes any of them (the prey is caught where the world
    put it, no pose is refused, the run lasts its whole duration), and nothing is left behind."""
    mark = uuid.uuid4().hex
    argv, env = offline(tmp_path, str(ROOT / "tests" / "cluster_guest.py"), str(tmp_path), mark=mark)
    res = subprocess.run(argv, env=env, cwd=tmp_path, capture_output=True, text=True, timeout=400)
    assert res.returncode == 0, res.stderr[-3000:]
    out = json.loads(res.stdout.strip().splitlines()[-1])
    assert out["rc"] == 0 and len(out["routers"]) == 2 and out["puts"] > 100, out
    s = json.loads((tmp_path / "g.json").read_text())
    assert s["security"] == {"tls": True, "acl": True, "ray_auth": "token"}
    assert s["messages_rejected"] == 0 and s["capture_time"] is not None and s["collisions"] == 0, s
    assert s["world_ticks"] == 401 and s["agents_final_reports"] == 8  # no agent took the guest's final tick
    assert wait_gone(mark, 10.0) == []
