"""Beyond one router: K meshed routers, agents spread over them, one swarm."""

from __future__ import annotations

import json

import pytest
from swarm_procs import cross_router_share, our_processes, run_launch


def test_three_meshed_routers_carry_one_swarm_that_catches_the_prey(tmp_path):
    """At real time: faster than a loaded machine can hold, a swarm ticks late and may not catch the prey
    in its run (it moves slower than asked), which is not what this test is about."""
    record = tmp_path / "mesh.rrd"
    res = run_launch(tmp_path, "--routers", "3", "--agents", "6", "--duration", "24", "--time-scale", "1",
                     "--end-after-capture", "2", "--run", "mesh3", "--record", str(record), "--quiet", timeout=180)
    assert res.returncode == 0, res.stderr
    s = json.loads(record.with_suffix(".json").read_text())
    assert len(s["routers"]) == 3 and len(set(s["routers"])) == 3
    assert s["agent_router"] == {str(i): i % 3 for i in range(6)}
    assert s["agents_reporting"] == 6 and s["capture_time"] is not None and s["collisions"] == 0
    assert s["capture_time"] + 2.0 <= s["duration"] < 24.0  # ended 2 s after the capture
    # agents on different routers heard each other: every agent heard someone on another router
    heard = {int(k): set(v) for k, v in s["heard"].items()}
    for i, others in heard.items():
        assert any(j % 3 != i % 3 for j in others), (i, others)
    # each pose names its sender's router: the share measured pose by pose is the one computed from
    # who heard whom and where each agent ran
    counts = {int(r): {int(j): n for j, n in senders.items()} for r, senders in s["heard_poses"].items()}
    assert s["cross_router_share"] == pytest.approx(cross_router_share(counts, {i: i % 3 for i in range(6)}))
    assert 0.3 < s["cross_router_share"] < 1 and s["cross_router_heard"] == 6
    assert our_processes("mesh3") == []


def test_a_process_never_hands_out_one_port_twice(monkeypatch):
    """The K routers of one run get K ports picked before any of them binds: drawn from a range, each
    port once (a run's two routers once drew the same port, and the second could not listen)."""
    import socket

    from zswarm.errors import UsageError
    from zswarm.ports import free_port

    span = range(31990, 32000)  # no suite worker's range (tests/conftest.py)
    free = []
    for port in span:
        with socket.socket() as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                continue
        free.append(port)
    monkeypatch.setenv("ZSWARM_PORTS", f"{span[0]}-{span[-1]}")
    assert sorted(free_port() for _ in free) == free
    with pytest.raises(UsageError, match="widen the range"):
        free_port()
