"""``--cluster local:K``'s nodes (zswarm.cluster.local_nodes) when Ray does not come up: a node that ends
as it starts, or says nothing in time, is one line; no process of it is left. Real processes stand in for
``ray start`` here (the real one runs in tests/test_cluster.py)."""

from __future__ import annotations

import os
import stat
import time

import pytest

from zswarm.cluster import local_nodes
from zswarm.cluster.local_nodes import RAY_LOOPBACK, LocalNodes, node_argv
from zswarm.errors import UsageError


def stand_in(tmp_path, monkeypatch, body: str):
    script = tmp_path / "ray"
    script.write_text(f"#!/bin/sh\n{body}\n")
    script.chmod(script.stat().st_mode | stat.S_IEXEC)
    monkeypatch.setattr(local_nodes, "ray_command", lambda: str(script))


def gone(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    return False


def test_a_node_that_ends_as_it_starts_is_one_line_with_rays_last_words(tmp_path, monkeypatch):
    stand_in(tmp_path, monkeypatch, 'echo "2026 INFO starting"; echo "Exception: the raylet died"; exit 3')
    nodes = LocalNodes()
    with pytest.raises(UsageError, match=r"ended as it started \(exit 3\): Exception: the raylet died$"):
        nodes.start(2, 1)
    nodes.close()
    assert nodes.procs == []


def test_a_node_that_is_not_up_in_time_is_given_up_and_ended(tmp_path, monkeypatch):
    stand_in(tmp_path, monkeypatch, 'echo "waiting for the GCS"; exec sleep 100')
    nodes = LocalNodes()
    start = time.monotonic()
    with pytest.raises(UsageError, match=r"did not start within 1 s \(waiting for the GCS\)"):
        nodes.start(1, 1, timeout=1.0)
    assert time.monotonic() - start < 3.0
    pid = nodes.procs[0].pid
    nodes.close(grace=1.0)
    assert gone(pid)


def test_every_node_is_on_the_loopback_address_ray_keeps(tmp_path):
    """127.0.0.1 would be taken by Ray for the machine's interface address (ray-project/ray#59110)."""
    head, joining = node_argv(1, 6390, head=True), node_argv(1, 6390, head=False)
    assert RAY_LOOPBACK.startswith("127.") and RAY_LOOPBACK != "127.0.0.1"
    assert f"--node-ip-address={RAY_LOOPBACK}" in head and f"--node-ip-address={RAY_LOOPBACK}" in joining
    assert "--head" in head and "--port=6390" in head and f"--address={RAY_LOOPBACK}:6390" in joining
    assert "--block" in head and "--block" in joining  # each node lives as long as its ray start
