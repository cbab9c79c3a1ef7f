"""Whom to believe first: a peer that publishes a forged pose under an agent's id before the agent
starts, and keeps publishing it, cannot lock the real agent out of its neighbours' tables, or out of
the world's record, for longer than a stated bound (zswarm.net.poses.Contest: TAKEOVER seconds once
the real agent's member token is heard, or once the forger falls silent). A forged pose within reach
of the real agent's last is taken as a move: what an open run cannot stop (docs/running.md)."""

from __future__ import annotations

import asyncio
import threading
import time

import numpy as np
import pytest
import zenoh

from agents.free import take_in, wait_for_world
from zswarm.net import messages as msg
from zswarm.net.config import zenoh_config
from zswarm.net.pose_batch import PoseArrays
from zswarm.net.poses import TAKEOVER, PoseTable
from zswarm.host.procs import free_port, start_router

from swarm_procs import agent_state, processes, stand_in_world, start_agent, start_world, wait_exit

PERIOD, MAX_STEP = 0.05, 0.15
FORGED, REAL = (500.0, 500.0), (0.0, 0.0)


class Arrays:
    """The world's batched table behind the per-pose table's interface, for the same sequences."""

    def __init__(self) -> None:
        self.arrays = PoseArrays(MAX_STEP, PERIOD, 2)

    def accept(self, key, pose, now, vouch=None):
        rows, _ = msg.decode_pose_records([msg.encode(pose)])
        return [None, "schema", "jump"][int(self.arrays.accept(np.array([key]), rows, now, vouch)[0])]

    def where(self, who):
        ids, rows = self.arrays.latest({who})
        return tuple(self.arrays.position[rows[0]]) if len(ids) else None


class Table:
    def __init__(self) -> None:
        self.table = PoseTable(MAX_STEP, PERIOD)

    def accept(self, key, pose, now, vouch=None):
        return self.table.accept(key, pose, now, vouch)

    def where(self, who):
        e = self.table.get(who)
        return None if e is None else e.latest.position


def play(table, forger_until: float, vouch=None, seconds: float = 3.0) -> float | None:
    """The forger's poses of agent 1 from t = 0 (until ``forger_until``), the real agent's from t = 1,
    both at 20 Hz; returns when the table first held the real agent after it started (None: never)."""
    got = None
    for k in range(int(seconds / PERIOD)):
        t = 100.0 + k * PERIOD
        if k * PERIOD < forger_until:
            table.accept(1, msg.Pose(1, k + 1, t, -1, *FORGED, 0.0, 0.0), t, vouch)
        if k * PERIOD >= 1.0:
            real = msg.Pose(1, k - 19, t, -1, REAL[0] + 0.01 * k, REAL[1], 0.2, 0.0)
            table.accept(1, real, t, vouch)
            if got is None and table.where(1) == real.position:
                got = k * PERIOD - 1.0
            elif got is not None:
                assert table.where(1) != FORGED, "the forger took the id back"
    return got


@pytest.mark.parametrize("make", [Table, Arrays], ids=["table", "world arrays"])
def test_a_forger_that_falls_silent_loses_the_id_within_the_bound(make) -> None:
    took = play(make(), forger_until=0.5)
    assert took is not None and took <= TAKEOVER + 2 * PERIOD


@pytest.mark.parametrize("make", [Table, Arrays], ids=["table", "world arrays"])
def test_a_forger_that_keeps_publishing_loses_the_id_to_the_member_token(make) -> None:
    cell_of_real = lambda p: abs(p.x - REAL[0]) < 10 and abs(p.y - REAL[1]) < 10  # noqa: E731 - the token's cell
    took = play(make(), forger_until=99.0, vouch=cell_of_real)
    assert took is not None and took <= TAKEOVER + 2 * PERIOD
    assert play(make(), forger_until=99.0) is None  # no token heard: the first sender keeps it (the docs say so)


def agent(endpoint: str, agent_id: int, x: float):
    return agent_state(endpoint, "forged", agent_id, x)


def test_the_real_agent_is_back_in_its_neighbours_table_within_the_bound() -> None:
    """Over a real router: a forger publishes agent 1 at a plausible point of agent 0's cell from
    before agent 1 starts, and goes on; agent 0's table holds the real agent 1 within the bound of its
    first pose, and the rule never gives the id back to the forger while it goes on."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with zenoh.open(zenoh_config("router", listen=[endpoint])) as router:
        first = agent(endpoint, 0, 0.5)
        keys = first.spec.keys
        world = stand_in_world(router, keys)
        stop = threading.Event()
        forged = (0.95, 0.1)  # in agent 0's cell, 0.72 from where agent 1 is

        def forge() -> None:
            with zenoh.open(zenoh_config("client", [endpoint])) as peer:
                key, seq = keys.pose(keys.cell(*forged), 1), 0
                while not stop.is_set():
                    seq += 1
                    peer.put(key, msg.encode(msg.Pose(1, seq, time.time(), -1, *forged, 0.0, 0.0)))
                    time.sleep(PERIOD)

        forger = threading.Thread(target=forge, daemon=True)
        forger.start()
        second = None
        try:
            assert asyncio.run(wait_for_world(first.agent, None, 10.0, lambda: False))
            first.announce()
            deadline = time.monotonic() + 10.0
            while first.agent.sensing.neighbours.get(1) is None:  # the forger's pose came first
                assert time.monotonic() < deadline, "the forger's poses never reached agent 0"
                take_in(first.agent, None)
                time.sleep(0.02)
            assert first.agent.sensing.neighbours.get(1).latest.position == forged
            second = agent(endpoint, 1, 0.35)
            assert asyncio.run(wait_for_world(second.agent, None, 10.0, lambda: False))
            second.announce()
            started, back, real = time.monotonic(), None, (0.35, 0.5)
            silent, sent = 0.0, started  # the longest the real agent went without a pose (a starved test)
            contest, taken = first.agent.sensing.neighbours.contest, None
            while time.monotonic() - started < 4.0:
                silent, sent = max(silent, time.monotonic() - sent), time.monotonic()
                second.agent.publish_pose(-1)  # in its cell, with its member token there
                take_in(second.agent, None)
                take_in(first.agent, None)
                held = first.agent.sensing.neighbours.get(1).latest.position
                if back is None and held == real:
                    back, taken = time.monotonic() - started, contest.takeovers
                elif back is not None:
                    # The rule never gives the id back to the forger (once the real agent fell silent over
                    # TAKEOVER, it gives the id to the track that sends). A forged pose within reach of the
                    # real agent's last is another thing, which docs/running.md says an open run cannot stop:
                    # the reach grows with the time since that pose, and a loaded receiver that went 0.15 s
                    # without one takes the forger's, 0.72 away, as a move.
                    assert contest.takeovers == taken or silent > TAKEOVER, ("the forger took agent 1 back", silent)
                time.sleep(PERIOD)
            assert back is not None and back <= TAKEOVER + 1.0, back  # the bound, plus the token's way here
            assert first.agent.sensing.counters.rejections.counts.get("jump", 0) > 0
        finally:
            stop.set()
            forger.join(5.0)
            if second is not None:
                second.close(final_stats=False)
            world.undeclare()
            first.close(final_stats=False)


@pytest.mark.procs
def test_the_worlds_record_follows_the_real_agent_while_a_forger_publishes(tmp_path) -> None:
    """A run of 6 agents; a peer publishes agent 1 at a plausible fixed point from before it starts to
    its end. The world's record of agent 1 is the forged point for no longer than the bound."""
    run = "forgedrun"
    with processes() as kids:
        endpoint = start_router(kids)
        stop = threading.Event()
        point = (-4.2, -1.2)  # inside the spawn region, 2 from where agent 1 starts

        def forge() -> None:
            from zswarm.net.keys import Keys

            keys = Keys(run, 1.0)
            with zenoh.open(zenoh_config("client", [endpoint])) as peer:
                seq = 0
                while not stop.is_set():
                    seq += 1
                    peer.put(keys.pose(keys.cell(*point), 1), msg.encode(msg.Pose(1, seq, time.time(), -1, *point,
                                                                                    0.0, 0.0)))
                    time.sleep(PERIOD)

        forger = threading.Thread(target=forge, daemon=True)
        forger.start()
        try:
            time.sleep(0.5)
            world, summary_path, _, traj = start_world(kids, endpoint, run, "moving-prey", tmp_path, "--duration", "8",
                                                       "--set", "n_agents=6")
            agents = [start_agent(kids, endpoint, run, "moving-prey", i, "--set", "n_agents=6") for i in range(6)]
            assert wait_exit(world, 120) == 0
            assert all(wait_exit(a, 20) == 0 for a in agents)
        finally:
            stop.set()
            forger.join(5.0)
    positions = np.load(traj)["positions"]  # (steps, agents, 2): NaN before an agent's first pose
    others = np.delete(positions, 1, axis=1)
    started = int(np.flatnonzero(~np.isnan(others).any(axis=(1, 2)))[0])  # the others' first poses are in
    at_forged = np.all(np.abs(positions[started:, 1] - np.array(point)) < 1e-9, axis=1)
    assert at_forged.sum() * 0.05 <= TAKEOVER + 1.0, (started, at_forged.sum())  # the bound, and a second's slack
    assert not at_forged[-20:].any()
