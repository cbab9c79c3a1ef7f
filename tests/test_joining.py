"""An agent that joins a swarm under way hears the agents in its cells before its first step.

Restarted after a crash, or started late, an agent used to take its first steps before the answers of
the cells it had just entered came in: for a tick or more it steered, and its safety filter guarded, as
if it were alone, and under load for longer (a restarted agent once met one passing its spawn point).
Two agent processes' worth of state (:class:`agents.main.Process`, as ``python -m agents`` builds it)
run here over a real router, with a stand-in for the world's obstacle queryable.
"""

from __future__ import annotations

import asyncio
import time

import zenoh

from agents.free import take_in, wait_for_world
from conftest import free_port
from zswarm.net.config import zenoh_config
from swarm_procs import agent_state, stand_in_world

RUN = "joining"


def agent(endpoint: str, agent_id: int, x: float):
    return agent_state(endpoint, RUN, agent_id, x)


def test_an_agent_that_joins_hears_its_cells_before_its_first_step():
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with zenoh.open(zenoh_config("router", listen=[endpoint])) as router:
        first = agent(endpoint, 0, 0.5)
        keys = first.spec.keys
        world = stand_in_world(router, keys)
        try:
            assert asyncio.run(wait_for_world(first.agent, None, 10.0, lambda: False))
            first.announce()
            first.agent.publish_pose(-1)  # it is there: its queryable answers for its cell
            deadline = time.monotonic() + 10.0
            while not list(router.get(keys.cell_poses(keys.cell(0.5, 0.5)), timeout=1.0)):
                assert time.monotonic() < deadline, "agent 0's queryable never answered"
                time.sleep(0.01)

            late = agent(endpoint, 1, 0.9)
            try:
                assert late.agent.sensing.neighbours.entries == {}
                assert asyncio.run(wait_for_world(late.agent, None, 10.0, lambda: False))
                assert not late.agent.reach.asking, "its start went on before its cells had answered"
                # before any tick of its own, it knows the agent 0.4 away, where that agent is
                heard = late.agent.sensing.neighbours.get(0)
                assert heard is not None, "it would take its first step as if alone"
                assert (heard.latest.x, heard.latest.y) == (0.5, 0.5)
                late.announce()
                deadline = time.monotonic() + 10.0
                while 0 not in late.agent.sensing.membership.alive:  # and its token: the law uses it at once
                    assert time.monotonic() < deadline, "agent 0's liveliness token never came"
                    take_in(late.agent, None)
                    time.sleep(0.01)
                assert [p for p, _, _ in late.agent.sensing.sense(None, 0.5, guard=False)[0]] == [(0.5, 0.5)]
            finally:
                late.close(final_stats=False)
        finally:
            world.undeclare()
            first.close(final_stats=False)
