"""A hostile peer floods a running swarm's keys: nobody crashes, nobody acts on it, the outcome holds."""

from __future__ import annotations

import io
import math
import signal
import struct
import subprocess
import threading
import time

import msgpack
import numpy as np
import pytest
import zenoh

from zswarm.net import messages as msg
from zswarm.net.config import zenoh_config
from zswarm.net.keys import Keys
from zswarm.host.procs import start_router

from swarm_procs import Watch, host_of, processes, split_spec, start_agent, wait_exit, with_reference


def garbage(rng: np.random.Generator, keys: Keys, cell: tuple[int, int], i: int) -> list[tuple[str, bytes]]:
    pose_key = keys.pose(cell, 1)
    good = msg.encode(msg.Pose(1, 10**9 + i, time.time(), -1, 0.0, 0.0, 0.0, 0.0))
    nan_pose = struct.pack(msg.POSE_LAYOUT + "4d", 0xC1, msg.VERSION, 0, 0, 1, 10**9 + i, 0.0, -1, 0, 0,
                           math.nan, 0.0, 0.0, math.inf)
    return [
        (pose_key, rng.bytes(int(rng.integers(1, 64)))),                       # random bytes
        (pose_key, good[: len(good) // 2]),                                     # a truncated record
        (pose_key, msgpack.packb({"v": 7, "k": "pose"})),                       # wrong version
        (pose_key, bytes([0xC1, 7]) + good[2:]),                                # a record of another version
        (pose_key, nan_pose),                                                   # NaN / infinite
        (pose_key, b"\x92" * (msg.MAX_PAYLOAD + 10)),                           # huge payload
        (pose_key, msg.encode(msg.Pose(1, 10**9 + i, time.time(), -1, 500.0, 500.0, 0.0, 0.0))),  # jump
        (keys.pose(cell, 999), msg.encode(msg.Pose(999, i, time.time(), -1, cell[0] + 0.5, cell[1] + 0.5,
                                                   0.0, 0.0))),                  # an agent nobody announced
        (keys.prey, rng.bytes(16)),
        (keys.stats(4), rng.bytes(32)),
        (keys.tick, msgpack.packb({"v": msg.VERSION, "k": "tick", "s": "soon"})),
    ]


def ended_after_capture(world, hold: float, timeout: float) -> float | None:
    """Read the world's progress lines until it says the prey is caught, let the swarm hold it ``hold``
    wall seconds more, then end the run as Ctrl-C would (the world's summary is written as at its end).
    Returns the capture time it printed (None: not caught within ``timeout``; the run is left to end)."""
    deadline = time.monotonic() + timeout
    caught = None
    lines = io.TextIOWrapper(world.proc.stdout)
    for line in lines:
        if "captured at" in line:
            caught = float(line.split("captured at")[1].split()[0])
            break
        if time.monotonic() > deadline:
            break
    reader = threading.Thread(target=lambda: sum(1 for _ in lines), daemon=True)
    reader.start()  # the pipe drained to the end
    if caught is not None:
        time.sleep(hold)
        world.proc.send_signal(signal.SIGINT)
    return caught


def test_flood_of_hostile_messages_changes_nothing(tmp_path):
    rng = np.random.default_rng(666)
    run = "hostile"
    with processes() as kids:
        endpoint = start_router(kids)
        # at the wall clock: at twice it (as other free-running swarms of the suite run), an agent under
        # the flood once took more than 20 s to end after the world had (CI, 4 workers; not explained).
        # Alone it catches the prey at 22-23 s; in the loaded suite it once took 32.2 s, and once 43.1 s
        # (it stayed together; cause not found). The run ends 5 s after the world says it is caught (60 s
        # at most, so a slow capture costs no time unless it happens): what the flood must not change is
        # that it catches it and stays together
        summary_path, record = tmp_path / f"{run}.json", tmp_path / f"{run}.rrd"
        spec, rest = split_spec(run, "moving-prey", "--duration", "60")
        world = host_of(kids).spawn_world(spec, endpoint, *rest, "--summary", str(summary_path), "--record",
                                          str(record), "--progress", "0.25", stdout=subprocess.PIPE)
        agents = [start_agent(kids, endpoint, run, "moving-prey", i) for i in range(10)]
        keys = Keys(run, 1.0)
        cells = [(cx, cy) for cx in range(-5, -1) for cy in range(-2, 2)]
        with Watch(endpoint, run) as watch, zenoh.open(zenoh_config("client", [endpoint])) as peer:
            watch.reach_step(10)  # the run is under way
            sent = 0
            end = time.monotonic() + 10.0
            i = 0
            while time.monotonic() < end:
                for key, payload in garbage(rng, keys, cells[i % len(cells)], i):
                    if len(payload) > msg.MAX_PAYLOAD and i % 25:
                        continue  # a 256 KiB one every 25th round (two a second): fifty a second filled
                        # the peer's own queues faster than loopback drains them, and its close then timed
                        # out. Each is copied to every subscriber of its cell: load the test does not
                        # need (CI once saw this swarm miss the prey under the flood, cause not found)
                    peer.put(key, payload)
                    sent += 1
                i += 1
                time.sleep(0.02)
        caught = ended_after_capture(world, 5.0, 90.0)
        assert wait_exit(world, 120) == 0
        assert all(wait_exit(a, 20) == 0 for a in agents)
    s = with_reference(summary_path, run, "moving-prey", "--duration", "60")
    assert sent > 1000
    rejected = s["rejected_by_reason"]
    # not "size": Zenoh may drop a 256 KiB message on a congested link before anyone sees it (shared
    # memory is off); the size rule itself is tested on the decoder (tests/test_messages.py)
    for reason in ("malformed", "version", "nonfinite", "jump"):
        assert rejected.get(reason, 0) > 0, (reason, rejected)
    how = {k: s[k] for k in ("capture_time", "final_centroid_goal_distance", "late_ticks", "ticks",
                             "world_late_ticks", "on_time_ratio", "observed_dropout", "messages_rejected")}
    how["reference_capture_time"] = s["reference"]["capture_time"]
    assert caught is not None and s["capture_time"] == pytest.approx(caught, abs=0.01), how
    assert s["capture_time"] is not None and s["collisions"] == 0 and s["final_components"] == 1, how
    assert s["capture_time"] + 4.0 <= s["duration"] < 60.0, how  # it held the prey, and the run ended early
    assert s["reference"]["collisions"] == 0
    assert s["agents_reporting"] == 10
