"""A Ray cluster over two hosts, by docs/cluster.md's recipe: network namespaces joined by a veth pair,
Ray's head on one and a worker node on the other, nothing but the pair and loopback in either (made here
with ``ip netns``; tests/ray_procs.py has the helpers). Its own module, so that it runs beside
tests/test_cluster.py rather than after it: each is about a minute and a half at the wall clock."""

from __future__ import annotations

import json
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

from ray_procs import (FAST_HEALTH, HEAD, RAY_TESTS, WORKER, fake_zswarm, in_ns, is_zswarm, kill_all, left_behind,
                       node_processes, ray_node_env, read_until, stale_keys, start_ray)

pytestmark = RAY_TESTS


def test_two_hosts_a_lost_worker_node_and_a_killed_driver(tmp_path):
    from test_netns import make_hosts, remove_hosts

    a, b = make_hosts()
    mark, started = uuid.uuid4().hex, time.time()
    nodes_dir = Path(tempfile.mkdtemp(prefix="zst-", dir="/tmp"))  # short: Ray's socket paths are limited
    env_a, env_b = ray_node_env(nodes_dir / "a", mark), ray_node_env(nodes_dir / "b", mark)
    # at the wall clock (the reference catches the prey at 14.75 s): at twice it, on 2 cores beside the
    # rest of the suite, an agent restarted at its spawn point once met one passing there before either
    # had heard the other (0.098 apart, 2 d^r = 0.1; CI, 4 workers)
    run = in_ns(a, sys.executable, "-m", "zswarm", "run", "--cluster", f"{HEAD}:6379", "--agents", "12")
    try:
        start_ray(a, env_a, "--head", "--node-ip-address", HEAD, "--port", "6379", "--include-dashboard", "false",
                  "--system-config", FAST_HEALTH)
        start_ray(b, env_b, "--address", f"{HEAD}:6379", "--node-ip-address", WORKER)
        # 0. a pace its cores cannot hold, refused in one line that names them, before any agent starts
        res = subprocess.run([*run, "--agents", "500", "--time-scale", "10"], env=env_a, cwd=tmp_path,
                             capture_output=True, text=True, timeout=120)
        lines = [ln for ln in res.stderr.splitlines() if "network_util" not in ln and "logging.cc" not in ln]
        assert res.returncode == 2 and len(lines) == 1, res.stderr[-2000:]
        assert re.search(r"500 agents stepping 400 times a second .* the cluster has \d+", lines[0]), lines
        assert not [p for p in left_behind(mark) if is_zswarm(p)]
        # 1. the swarm, half on each host, catches the prey; then the worker host's Ray dies, and its
        # agents rejoin on the head's host a second later (--restart-after)
        # (32 simulated seconds: a loaded machine gets its restarted agents up well before the end).
        # --secure: each host's router and agents use keys made on that host, signed by the driver's CA
        driver = subprocess.Popen([*run, "--duration", "32", "--restart-after", "1", "--record",
                                   str(tmp_path / "two.rrd"), "--secure", str(tmp_path / "pki")], env=env_a,
                                  cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            read_until(driver, "captured at", 120)
            kill_all(node_processes(nodes_dir / "b"))  # the node dies: raylet, workers, the actor, with it
            out, err = driver.communicate(timeout=120)
        finally:
            if driver.poll() is None:
                driver.kill()
        assert driver.returncode == 0, err[-3000:]
        s = json.loads((tmp_path / "two.json").read_text())
        nodes = {n["address"]: n for n in s["cluster"]["nodes"]}
        assert set(nodes) == {HEAD, WORKER} and nodes[WORKER]["lost"] and not nodes[HEAD]["lost"]
        assert s["capture_time"] is not None and s["collisions"] == 0, s
        assert s["cross_router_heard"] > 0  # agents on one host heard agents on the other, router to router
        assert s["security"] == {"tls": True, "acl": True, "ray_auth": "token"}, s["security"]
        assert s["messages_rejected"] == 0 and s["agents_final_reports"] == 12
        lost = [ln for ln in err.splitlines() if f"node1@{WORKER} lost" in ln]
        assert lost and "crashed" in lost[0], err[-3000:]
        on_worker = {d["id"] for d in s["departures"]}  # the world saw the worker host's agents go ...
        assert 0 < len(on_worker) < 12 and all(d["how"] == "crashed" for d in s["departures"]), s["departures"]
        assert on_worker <= set(s["stopped_at_end"])  # ... and come back, alive at the end
        assert f"of a lost node on node0@{HEAD}" in err
        assert all(HEAD in label for label in s["cluster"]["agent_node_at_end"].values())  # where they ran at the end
        assert {int(i) for i, label in s["cluster"]["agent_node"].items() if WORKER in label} == on_worker  # placed
        # 2. the worker host back (its first actor removes the keys the lost one left), a new run, its
        # driver SIGKILLed: nothing of zswarm left on either host
        kill_all(node_processes(nodes_dir / "b"))
        start_ray(b, ray_node_env(nodes_dir / "b2", mark), "--address", f"{HEAD}:6379", "--node-ip-address", WORKER)
        driver = subprocess.Popen([*run, "--duration", "60", "--record", str(tmp_path / "k.rrd")], env=env_a,
                                  cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        try:
            read_until(driver, "world: started", 120)
            zswarm_procs = [p for p in left_behind(mark) if "ray::" not in p and "/ray/" not in p]
            assert any("agents.fleet" in p for p in zswarm_procs) and any("zswarm.net.router" in p for p in zswarm_procs)
            driver.send_signal(signal.SIGKILL)
            driver.wait(timeout=10)
            deadline = time.monotonic() + 10.0
            while time.monotonic() < deadline and [p for p in left_behind(mark) if is_zswarm(p)]:
                time.sleep(0.2)
            assert [p for p in left_behind(mark) if is_zswarm(p)] == []
        finally:
            if driver.poll() is None:
                driver.kill()
        assert stale_keys(started) == []  # no host keeps the keys of a run that is over
        # 3. a worker host with another zswarm: refused in one line, before any agent starts. (A host
        # without zswarm is not made here: this project's editable install is found on any path.)
        for fake, needle in ((fake_zswarm(nodes_dir / "other", "9.9.9"), f"node1@{WORKER} has zswarm 9.9.9"),):
            kill_all(node_processes(nodes_dir / "b2") + node_processes(nodes_dir / "b3"))
            shutil.rmtree(nodes_dir / "b3", ignore_errors=True)
            start_ray(b, {**ray_node_env(nodes_dir / "b3", mark), "PYTHONPATH": str(fake)}, "--address", f"{HEAD}:6379",
                      "--node-ip-address", WORKER)
            res = subprocess.run([*run, "--duration", "5"], env=env_a, cwd=tmp_path, capture_output=True, text=True,
                                 timeout=120)
            lines = [ln for ln in res.stderr.splitlines() if "network_util" not in ln and "logging.cc" not in ln]
            assert res.returncode == 2 and len(lines) == 1 and needle in lines[0], res.stderr[-2000:]
            assert not [p for p in left_behind(mark) if is_zswarm(p)]
    finally:
        kill_all(node_processes(nodes_dir))  # both hosts' Ray
        remove_hosts(a, b)
        shutil.rmtree(nodes_dir, ignore_errors=True)
