"""A free-running agent's transport latency is timed on poses that crossed the router, never on its own.

Zenoh hands a publication to a subscriber of the same session without the router, so an agent that
timed its own pose would report the session's own hand-over as transport latency. Two agent
processes' worth of state (:class:`agents.main.Process`, as ``python -m agents`` builds it) run here
over a real router, ticking by hand.
"""

from __future__ import annotations

import time

import zenoh

from agents import probe
from agents.free import take_in
from agents.main import Process, build_parser
from conftest import free_port
from zswarm.net import messages as msg
from zswarm.net.config import zenoh_config
from zswarm.net.runspec import spec_from_args


def agent(endpoint: str, agent_id: int, x: float) -> Process:
    args = build_parser().parse_args(["--id", str(agent_id), "--start", f"{x},0.5", "--run", "latency",
                                      "--scenario", "bench-field", "--set", "n_agents=2", "--connect", endpoint])
    proc = Process(spec_from_args(args), args, loop=None)
    proc.announce()
    proc.agent.reach.follow_cells()
    return proc


def tick(*procs: Process, now: float | None = None) -> None:
    """One free-clock tick of each (as :func:`agents.free.run_free`, without the control law);
    ``now``: the monotonic time the probe's windows are judged at (default: now)."""
    for p in procs:
        take_in(p.agent, None)
        p.agent.reach.follow_cells()
        p.agent.reach.follow_probe(time.monotonic() if now is None else now)
        p.agent.publish_pose(-1)


def samples(p: Process) -> int:
    return sum(p.agent.counters.latency.values())


def test_a_ring_agent_times_a_neighbours_poses_and_not_its_own_echo():
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with zenoh.open(zenoh_config("router", listen=[endpoint])):
        alone = agent(endpoint, 0, 0.5)
        try:
            assert alone.bridge.channels is not None and alone.agent.sensing.latency_from_probe
            for _ in range(40):  # its own poses come back to it through its cell, without the router
                tick(alone)
                time.sleep(0.01)
            assert alone.agent.sensing.probe is None
            assert samples(alone) == 0, "an agent alone timed its own pose"
            assert alone.agent.counters.received == 0, "its own poses came back through its cell"

            neighbour = agent(endpoint, 1, 0.9)
            try:
                deadline = time.monotonic() + 15.0
                while samples(alone) < 20:
                    assert time.monotonic() < deadline, "no latency samples from the neighbour's poses"
                    tick(alone, neighbour)
                    time.sleep(0.01)
                assert alone.agent.sensing.probe is not None and alone.agent.sensing.probe[0] == 1
                assert neighbour.agent.sensing.probe is not None and neighbour.agent.sensing.probe[0] == 0
                assert alone.agent.counters.poses > 0

                # between its windows the probe holds no subscription, and times nothing
                first = alone.agent.sensing.latency_probe.first
                shut = first + probe.ON_S + 0.5
                tick(alone, now=shut)
                assert alone.agent.sensing.probe is None, "the probe listened between its windows"
                subs = len(alone.bridge.channels)
                tick(alone, now=shut)
                before, poses = samples(alone), alone.agent.counters.poses
                while alone.agent.counters.poses < poses + 10:
                    assert time.monotonic() < deadline, "the neighbour's poses stopped"
                    tick(alone, neighbour, now=shut)
                    time.sleep(0.01)
                assert samples(alone) == before and len(alone.bridge.channels) == subs
                # a pose Zenoh was still handing over when the subscription closed is not timed either
                late = msg.encode(msg.Pose(1, 999, time.time() - 0.05, -1, 0.9, 0.0, 0.0, 0.0))
                alone.agent.sensing.latency_probe.heard(late, time.time())
                assert samples(alone) == before
                tick(alone, now=first + probe.EVERY_S)  # the next window: the probe is back
                assert alone.agent.sensing.probe is not None and alone.agent.sensing.probe[0] == 1
            finally:
                neighbour.close(final_stats=False)

            deadline = time.monotonic() + 15.0
            while alone.agent.sensing.probe is not None:  # the neighbour's token went: the probe with it
                assert time.monotonic() < deadline, "the probe outlived its neighbour"
                tick(alone)
                time.sleep(0.01)
            before = samples(alone)
            for _ in range(40):
                tick(alone)
                time.sleep(0.01)
            assert samples(alone) == before
        finally:
            alone.close(final_stats=False)
