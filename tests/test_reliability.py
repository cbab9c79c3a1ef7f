"""Lost infrastructure: the router restarts mid-run; agents and world reconnect and carry on."""

from __future__ import annotations

import subprocess
import time

import numpy as np

from swarm_procs import load_summary, processes, start_agent, start_world, wait_exit
from zswarm.procs import free_port, wait_for_port
from zswarm.replay import load_run


def test_router_restart_mid_run(tmp_path):
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    args = ("--set", "n_agents=3")
    with processes() as kids:
        router = kids.spawn("router", ["-m", "zswarm.router", "--listen", endpoint], stdout=subprocess.DEVNULL)
        assert wait_for_port("127.0.0.1", port, 10.0, router)
        world, summary_path, record, _ = start_world(kids, endpoint, "rr", "moving-prey", tmp_path, *args,
                                                     "--duration", "16")
        for i in range(3):
            start_agent(kids, endpoint, "rr", "moving-prey", i, *args)
        deadline = time.monotonic() + 60
        while not record.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        time.sleep(5.0)
        router.proc.terminate()
        router.proc.wait(timeout=10)
        time.sleep(2.0)
        router2 = kids.spawn("router2", ["-m", "zswarm.router", "--listen", endpoint], stdout=subprocess.DEVNULL)
        assert wait_for_port("127.0.0.1", port, 10.0, router2)
        assert wait_exit(world, 90) == 0
    s = load_summary(summary_path)
    assert s["agents_reporting"] == 3
    frames = load_run(record).frames
    gaps = np.diff([f.t for f in frames])
    outage = int(np.argmax(gaps))
    assert gaps[outage] > 1.0  # the world heard nothing while the router was down
    after = frames[outage + 1:]
    complete = [k for k, f in enumerate(after) if set(f.ids.tolist()) == {0, 1, 2}]
    assert complete and after[complete[0]].t - after[0].t < 3.0  # every agent is back within 3 s
    assert len(after) - complete[0] > 40
    assert all(set(f.ids.tolist()) == {0, 1, 2} for f in after[complete[0]:])  # and stays
    first, last = after[complete[0]], after[-1]
    assert first.ids.tolist() == last.ids.tolist()
    assert np.all(np.linalg.norm(last.positions - first.positions, axis=1) > 0.2)  # still moving
    to_prey = lambda f: np.linalg.norm(f.positions - f.prey, axis=1).mean()  # noqa: E731
    assert to_prey(last) < to_prey(first)  # and still closing in on the prey
