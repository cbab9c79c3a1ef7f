"""The free clock: one agent's life as a loop at 1/period on an asyncio event loop (uvloop's where it is
installed), at a phase of its own in the period (:func:`first_tick`); what a tick does:
docs/architecture.md, "An agent's tick"."""

from __future__ import annotations

import asyncio
import time
from typing import Callable

from agents.agent import STATS_PERIOD, Agent
from agents.handoff import Desk
from zswarm.net.injector import FaultInjector


#: Agent i ticks at the fraction frac(i * PHASE_STEP) of each period of the wall clock: the golden
#: ratio's conjugate spreads any number of consecutive ids evenly over the period. Agents that started
#: together (a fleet forks 50 in about a second) would otherwise tick together, and each pose would wait
#: behind the others' ticks for its receiver: on 2 cores that raised the pose latency p99 of 50 agents by
#: half (docs/benchmarks.md, "An agent against an earlier version").
PHASE_STEP = 0.6180339887498949


def first_tick(agent_id: int, period: float) -> float:
    """When (monotonic) agent ``agent_id`` ticks first: the next instant at its phase of the period."""
    phase = (agent_id * PHASE_STEP) % 1.0 * period
    return time.monotonic() + (phase - time.time()) % period


def take_in(agent: Agent, injector: FaultInjector | None) -> int:
    """Everything that arrived (and, under injected delay, fell due) since the last call; returns how
    many samples were waiting (the inbound queue at this tick)."""
    n = agent.bridge.drain()
    if injector is not None:
        injector.release(time.time())
    return n


async def wait_for_world(agent: Agent, injector: FaultInjector | None, timeout: float,
                         stopped: Callable[[], bool]) -> bool:
    """Until the world has answered the first obstacle query (it is there) and, beside a robot, the
    robot's first odometry came (the agent starts where it is), then enter the cells and hear who is
    in them (:func:`hear_cells`); False if that took longer than ``timeout`` seconds, the world
    answered in another dimension, or the agent was stopped."""
    s = agent.sensing
    deadline = time.monotonic() + timeout
    while s.obstacle_query_at is None or (agent.robot is not None and not agent.follow_robot()):
        if stopped() or time.monotonic() > deadline or s.obstacle_view.foreign_dims is not None:
            return False
        agent.reach.request_obstacles(time.time(), timeout=1.0)
        await asyncio.sleep(0.2)  # a few wake-ups a second: hundreds of agents waiting must not load the machine
        take_in(agent, injector)
    agent.reach.follow_cells()
    await hear_cells(agent, injector, min(CELLS_WAIT, max(deadline - time.monotonic(), 0.0)), stopped)
    return True


CELLS_WAIT = 2.0  # the longest an agent waits, at its start, for its cells' agents to answer


async def hear_cells(agent: Agent, injector: FaultInjector | None, wait: float, stopped: Callable[[], bool]) -> None:
    """Take in the answers of the cells it just entered before its first step: an agent that joins a
    swarm under way (a restart, a late start) then steers, and filters, from its first tick on the
    neighbours around it, not as if it were alone until their next poses come."""
    deadline = time.monotonic() + wait
    while agent.reach.asking and time.monotonic() < deadline and not stopped():
        await asyncio.sleep(0.01)
    take_in(agent, injector)


async def run_free(agent: Agent, injector: FaultInjector | None, stopped: Callable[[], bool],
                   desk: Desk | None = None) -> bool:
    """Tick until the run ends (False) or, after a tick, a process asks to take this agent over
    (``desk``, :mod:`agents.handoff`; True: the caller hands its state over and leaves). Each tick is a
    callback the loop calls at its time: no task step and no future per tick, which cost an agent more
    than its tick's sleep did (docs/benchmarks.md, "An agent against an earlier version")."""
    loop = asyncio.get_running_loop()
    ended: asyncio.Future[bool] = loop.create_future()
    period = agent.spec.period
    s, c = agent.sensing, agent.counters
    stats_every = max(int(round(STATS_PERIOD / period)), 1)
    next_tick = first_tick(agent.id, period)

    def tick() -> bool | None:
        """One tick; what the run's end is, or None to go on."""
        nonlocal next_tick
        if stopped() or s.final_tick:
            return False
        now = time.monotonic()
        c.window_lag_ms = max(c.window_lag_ms, 1000.0 * (now - next_tick))
        if now - next_tick > 0.5 * period:
            c.late_ticks += 1
            c.late_s += now - next_tick  # the ticks let go by (skipped_ticks): ticks + skipped is the schedule's
            next_tick = max(next_tick, now)  # skip, never queue up a backlog
        c.ticks += 1
        c.window_queue_max = max(c.window_queue_max, take_in(agent, injector))
        agent.reach.request_obstacles(time.time())
        if s.prey is not None:
            agent.move(s.prey)
        agent.body.step += 1
        agent.reach.follow_cells()
        agent.reach.check_members(time.time())
        agent.reach.follow_probe(now)
        agent.publish_pose(-1)
        if agent.law_failure is not None:  # braked this tick and said where: the process ends on it
            return False
        if agent.world_gone(now):
            return False
        if c.ticks % stats_every == 0:
            agent.publish_stats_now()
        if desk is not None and desk.due:
            return True
        next_tick += period
        return None

    def on_time() -> None:
        try:
            end = tick()
        except Exception as exc:  # noqa: BLE001 - the coroutine awaiting the run raises it
            ended.set_exception(exc)
            return
        if end is None:
            loop.call_later(max(next_tick - time.monotonic(), 0.0), on_time)
        else:
            ended.set_result(end)

    loop.call_later(max(next_tick - time.monotonic(), 0.0), on_time)
    return await ended
