"""Across machines, for real: two network namespaces joined by a veth pair act as two hosts."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

import pytest

from conftest import ROOT

pytestmark = pytest.mark.skipif(os.geteuid() != 0 or shutil.which("ip") is None,
                                reason="needs root and iproute2 to create network namespaces")


def sh(*args: str) -> None:
    subprocess.run(args, check=True, capture_output=True, timeout=30)


def make_hosts() -> tuple[str, str]:
    """Two network namespaces joined by a veth pair (10.77.0.1 and 10.77.0.2), loopback up, each one's
    default route the other, which forwards nothing (skips the test where they cannot be made)."""
    tag = f"{os.getpid() % 100000}"
    a, b = f"zswA{tag}", f"zswB{tag}"
    veth_a, veth_b = f"zva{tag}", f"zvb{tag}"
    try:
        sh("ip", "netns", "add", a)
        sh("ip", "netns", "add", b)
        sh("ip", "link", "add", veth_a, "type", "veth", "peer", "name", veth_b)
        sh("ip", "link", "set", veth_a, "netns", a)
        sh("ip", "link", "set", veth_b, "netns", b)
        sh("ip", "-n", a, "addr", "add", "10.77.0.1/24", "dev", veth_a)
        sh("ip", "-n", b, "addr", "add", "10.77.0.2/24", "dev", veth_b)
        for ns, dev, peer in ((a, veth_a, "10.77.0.2"), (b, veth_b, "10.77.0.1")):
            sh("ip", "-n", ns, "link", "set", dev, "up")
            sh("ip", "-n", ns, "link", "set", "lo", "up")
            # a default route, as a user's machine has (Ray's address guess finds the interface by it); the
            # other host does not forward, so nothing sent there leaves the machine
            sh("ip", "-n", ns, "route", "add", "default", "via", peer)
    except (subprocess.CalledProcessError, OSError) as exc:
        remove_hosts(a, b)
        pytest.skip(f"cannot create network namespaces here: {exc}")
    return a, b


def remove_hosts(*names: str) -> None:
    for ns in names:
        subprocess.run(["ip", "netns", "del", ns], capture_output=True, timeout=30)


@pytest.fixture
def two_hosts():
    a, b = make_hosts()
    try:
        yield a, b
    finally:
        remove_hosts(a, b)


def test_router_and_world_on_one_host_agents_on_another(two_hosts, tmp_path, secure=True):
    """docs/running.md's recipe for machines started by hand, secure: on host A the router and the
    world, on host B the agents; ``zswarm certs`` names host A's address and writes B's bundle (the CA's
    certificate and the agents' identities, no ``ca.key``), each host's folder at a path of its own;
    every process speaks mutual TLS with its own identity, and the summary says so. (``secure=False`` runs the open recipe: the
    Ray cluster's two-host test crosses hosts over plain TCP already, so the suite runs this one.)"""
    a, b = two_hosts
    # at real time: paced faster than a loaded machine can hold (the suite beside two busy loops), a swarm
    # ticks late and may not catch the prey in its 40 s. The reference catches it at 26.7 s and a free run
    # alone at about 23; the world ends the run 2 s after the capture
    common = ["--agents", "10", "--scenario", "moving-prey", "--duration", "40", "--time-scale", "1", "--run", "netns",
              "--end-after-capture", "2", "--quiet"]
    launch = [sys.executable, str(ROOT / "launch.py")]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proto, identity = "tcp", []
    identity_b = []
    if secure:  # the recipe: certificates for host A's address, B's bundle, then each host with --secure
        pki, bundle = tmp_path / "host-a" / "pki", tmp_path / "host-b" / "keys"
        for argv in (["--agents", "10", "--router", "tls/10.77.0.1:7447", "--hosts", "10.77.0.1,localhost"],
                     ["--bundle", str(bundle), "--names", "agent-*"]):
            subprocess.run([sys.executable, "-m", "zswarm", "certs", str(pki), *argv], check=True, env=env,
                           capture_output=True, timeout=60)
        assert (pki / "ca.key").is_file() and not (bundle / "ca.key").exists()  # the CA's key stays on A
        assert sorted(p.stem for p in bundle.glob("*.json5")) == sorted(f"agent-{i}" for i in range(10))
        proto, identity, identity_b = "tls", ["--secure", str(pki)], ["--secure", str(bundle)]
    host_a = subprocess.Popen(["ip", "netns", "exec", a, *launch, "--role", "router,world", *identity,
                               "--listen", f"{proto}/10.77.0.1:7447", "--record", str(tmp_path / "n.rrd"), *common],
                              env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    # host B's output goes to a file: a pipe nobody reads while host A runs fills under load, and then
    # every process that writes to it (the launcher, its agents) stops in the middle of the run
    said_b = tmp_path / "host-b.txt"
    with open(said_b, "w") as b_out:
        host_b = subprocess.Popen(["ip", "netns", "exec", b, *launch, "--role", "agents", *identity_b,
                                   "--connect", f"{proto}/10.77.0.1:7447", *common],
                                  env=env, stdout=b_out, stderr=subprocess.STDOUT, text=True)
    try:
        out_a, err_a = host_a.communicate(timeout=180)
        host_b.wait(timeout=60)
    finally:
        for p in (host_a, host_b):
            if p.poll() is None:
                p.kill()
                p.wait()
    assert host_a.returncode == 0, err_a
    assert host_b.returncode == 0, said_b.read_text()[-2000:]
    summary = json.loads((tmp_path / "n.json").read_text())
    assert summary["agents_reporting"] == 10
    assert summary["capture_time"] is not None and summary["collisions"] == 0
    assert summary["capture_time"] + 2.0 <= summary["duration"] < 40.0
    assert summary["security"]["tls"] is secure and summary["security"]["acl"] is secure, summary["security"]
