"""Live viewing: a run streamed to a Rerun gRPC server arrives complete, and the file is still written."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from conftest import ROOT, free_port, run_cli, wait_for_port
from zswarm.record.replay import load_run

RERUN = Path(__import__("sys").executable).with_name("rerun")


@pytest.fixture
def viewer_server(tmp_path):
    """``rerun --serve-grpc --save FILE``: a headless server that writes whatever is streamed to it."""
    port, saved = free_port(), tmp_path / "received.rrd"
    # its own process group: .venv/bin/rerun is a wrapper that starts the real binary as its child
    proc = subprocess.Popen([str(RERUN), "--serve-grpc", "--port", str(port), "--save", str(saved)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        wait_for_port(port)
        yield f"rerun+http://127.0.0.1:{port}/proxy", saved, proc
    finally:
        _stop(proc)


def _stop(proc: subprocess.Popen) -> None:
    """Stop the server and everything it started (it writes what it received, then exits)."""
    for sig, wait in ((signal.SIGTERM, 20), (signal.SIGKILL, 10)):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            break
        try:
            proc.wait(timeout=wait)
        except subprocess.TimeoutExpired:
            continue
        deadline = time.monotonic() + wait  # the wrapper is gone; wait for the rest of its group
        while time.monotonic() < deadline:
            try:
                os.killpg(proc.pid, 0)
            except ProcessLookupError:
                return
            time.sleep(0.05)


def _entities(path: Path) -> set[str]:
    from rerun.chunk import RrdReader

    return {str(c.entity_path).lstrip("/") for c in RrdReader(str(path)).stream().to_chunks()}


THRESHOLD_LINES = {"thresholds/capture_radius", "thresholds/collision_distance", "thresholds/d_m_ro",
                   "thresholds/epsilon"}


def _same_run(local: Path, received: Path) -> int:
    a, b = load_run(local), load_run(received)
    assert len(a.frames) == len(b.frames) > 0
    assert [f.step for f in a.frames] == [f.step for f in b.frames]
    for x, y in zip(a.frames, b.frames):
        np.testing.assert_array_equal(x.positions, y.positions)
    assert a.summary is not None and b.summary == a.summary
    return len(a.frames)


def test_a_simulation_streams_live_and_keeps_its_file(viewer_server, tmp_path):
    url, saved, server = viewer_server
    local = tmp_path / "sim.rrd"
    res = run_cli("-m", "zswarm", "sim", "--scenario", "moving-prey", "--duration", "4", "--record", str(local),
                  "--viewer", url, "--json", cwd=tmp_path, fresh=True)  # its stream ends as the interpreter does
    assert res.returncode == 0, res.stderr
    _stop(server)
    assert _same_run(local, saved) == 81
    assert THRESHOLD_LINES | {"map/sensing_graph"} <= _entities(local)  # the lines plots are read against


def test_a_distributed_run_streams_live_and_keeps_its_file(viewer_server, tmp_path):
    url, saved, server = viewer_server
    local = tmp_path / "run.rrd"
    res = run_cli(str(ROOT / "launch.py"), "--agents", "4", "--duration", "4", "--record", str(local), "--viewer",
                  url, "--quiet", "--run", "live-test", timeout=120, cwd=tmp_path)
    assert res.returncode == 0, res.stderr[-2000:]
    _stop(server)
    assert _same_run(local, saved) > 40
    assert THRESHOLD_LINES | {"map/sensing_graph", "network/poses_per_s", "network/agents_alive"} <= _entities(local)
