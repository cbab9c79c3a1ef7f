"""The agent fleet forks agents that share its scheduling group: on Linux with autogroup scheduling
(the default on desktop and server kernels) every session is a group that gets an equal share of the
CPU, so an agent in a session of its own made a 100-agent swarm 100 groups against the router's one,
and the router, starved, queued seconds of poses (docs/safety.md, "A machine that falls behind")."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

from zswarm.host.procs import Children, Fleet, free_port


def _autogroup(pid: int) -> str | None:
    try:
        return Path(f"/proc/{pid}/autogroup").read_text().split()[0]
    except OSError:  # a kernel without autogroup scheduling
        return None


def test_a_forked_agent_shares_the_fleets_session_in_a_process_group_of_its_own():
    kids = Children()
    try:
        fleet = Fleet(kids)
        # nothing listens on this port: the agent keeps trying for 20 s, long enough to be looked at
        agent = fleet.spawn("agent-0", ["--id", "0", "--run", "fleet-test", "--scenario", "static-goal",
                                        "--connect", f"tcp/127.0.0.1:{free_port()}", "--connect-timeout", "20"])
        deadline = time.monotonic() + 10.0
        while agent.alive() and time.monotonic() < deadline and os.getpgid(agent.pid) != agent.pid:
            time.sleep(0.01)  # the child sets its group first thing after the fork
        assert agent.alive()
        fleet_pid = fleet.child.pid
        assert os.getsid(agent.pid) == os.getsid(fleet_pid) != os.getsid(0)  # one session: the fleet's
        assert os.getpgid(agent.pid) == agent.pid  # its own group: a terminal's Ctrl-C reaches the launcher only
        assert _autogroup(agent.pid) == _autogroup(fleet_pid)  # (None on both where the kernel has none)
    finally:
        kids.stop_all(grace=2.0)
    assert not agent.alive() and not fleet.child.alive()


def test_the_local_host_forks_every_agent_from_one_fleet_or_starts_each_alone():
    """The host boundary (zswarm.host.local): the supervisor asks a host for an agent and gets a
    handle it can poll and signal; here, forked from one fleet, or each in an interpreter of its own."""
    from zswarm.host.local import LocalHost

    bad = ["--run", "host-test", "--scenario", "static-goal", "--connect", "tcp/127.0.0.1:1", "--id"]
    for fork in (True, False):
        kids = Children()
        try:
            host = LocalHost(kids, fork)
            agents = [host.spawn_agent(f"agent-{i}", [*bad, "nine" if i else "0", "--connect-timeout", "20"])
                      for i in range(2)]
            assert all(a in kids.children for a in agents)
            assert len(kids.named("fleet")) == (1 if fork else 0)
            assert agents[1].proc.wait(30) == 2  # a usage error ("--id nine") through the handle
            assert agents[0].alive()
            agents[0].proc.send_signal(15)
            assert agents[0].proc.wait(10) is not None
        finally:
            kids.stop_all(grace=2.0)
        assert not any(c.alive() for c in kids.children)


def test_a_restarted_child_takes_its_dead_selfs_place():
    """Children.add: a restarted agent takes its dead self's place (the supervisor and a cluster node
    add a thousand agents through it, so it must not scan the list), the same child added twice is
    held once, and a live process is never dropped."""
    from zswarm.host.procs import Child, ForkedProc

    kids = Children()
    first = kids.add(Child("agent-3", ForkedProc(10**6)))  # a pid no process has: nothing is signalled
    assert kids.add(first) is first and kids.children == [first]
    first.proc.exited(-9)
    second = kids.add(Child("agent-3", ForkedProc(10**6 + 2)))
    other = kids.add(Child("agent-4", ForkedProc(10**6 + 3)))
    assert kids.children == [second, other] and kids.get("agent-3") is second
    beside = kids.add(Child("agent-3", ForkedProc(10**6 + 4)))  # second is alive: both are kept
    assert kids.children == [second, other, beside] and kids.get("agent-3") is beside


_IMPORTS_AFTER_PRELOAD = r'''
import json, sys
import agents.free
from agents.main import main, preload
preload()
before = set(sys.modules)
code = main(sys.argv[1:])
print(json.dumps([code, sorted(set(sys.modules) - before)]))
'''


def test_an_agent_imports_nothing_its_fleet_did_not_preload():
    """What a forked agent imports is its own copy (its start slower, its memory private): the fleet's
    preload walks every module an agent loads, whatever its law, body, clock and dimensions. Each
    agent here runs against a router with no world and gives up after 1 s, its sensing, bridge and
    event loop built."""
    import subprocess
    import sys

    from zswarm.host.local import LocalHost

    kids = Children()
    try:
        endpoint = LocalHost(kids).start_routers([f"tcp/127.0.0.1:{free_port()}"])[0]
        for extra in ([], ["--scenario", "moving-prey-3d", "--set", "law=boids"],
                      ["--set", "body=unicycle", "--set", "law=olfati-saber", "--clock", "lockstep"],
                      ["--set", "law=vasarhelyi", "--latency", "50ms"]):
            done = subprocess.run([sys.executable, "-c", _IMPORTS_AFTER_PRELOAD, "--id", "1", "--run", "preload-test",
                                   "--connect", endpoint, "--start-timeout", "1", *extra],
                                  capture_output=True, text=True, timeout=60)
            code, imported = json.loads(done.stdout.strip().splitlines()[-1])
            assert code == 2 and "did not answer for 1 s" in done.stderr, done.stderr  # waited for a world
            assert imported == [], f"{extra}: imported after the fleet's preload: {imported}"
    finally:
        kids.stop_all(grace=2.0)


def test_agents_forked_together_tick_each_at_a_phase_of_its_own(tmp_path):
    """A fleet forks its agents within a second, and each would start ticking as it came up: together.
    Each ticks at its own phase of the period instead (:func:`agents.free.first_tick`), read here off the
    stamps of the poses they publish over a real router."""
    import statistics
    import threading

    from agents.free import PHASE_STEP
    from swarm_procs import Watch, start_agent, start_world
    from zswarm.net import messages as msg
    from zswarm.net.config import open_session, zenoh_config
    from zswarm.host.local import LocalHost
    from zswarm.net.keys import Keys

    n, period = 8, 0.05  # bench-field runs at 20 Hz
    args = ("--set", f"n_agents={n}", "--duration", "6")
    kids = Children()
    stamps: dict[int, list[float]] = {}
    lock = threading.Lock()

    def heard(sample) -> None:
        m = msg.decode(sample.payload.to_bytes())
        with lock:
            stamps.setdefault(m.id, []).append(m.stamp)

    try:
        endpoint = LocalHost(kids).start_routers([f"tcp/127.0.0.1:{free_port()}"])[0]
        start_world(kids, endpoint, "phases", "bench-field", tmp_path, *args)
        for i in range(n):
            start_agent(kids, endpoint, "phases", "bench-field", i, *args[:2])
        with Watch(endpoint, "phases") as watch:
            watch.reach_step(20, timeout=60)
            session = open_session(zenoh_config("client", [endpoint]), "phases", retry_for=10.0)
            sub = session.declare_subscriber(Keys("phases", 1.0).all_poses, heard)
            watch.reach_step(watch.step + 40, timeout=60)
            sub.undeclare()
            session.close()
    finally:
        kids.stop_all(grace=3.0)

    phases = {}
    for who in range(n):
        assert len(stamps.get(who, [])) >= 20, f"agent {who}: {len(stamps.get(who, []))} poses"
        due = (who * PHASE_STEP) % 1.0
        # each pose's phase as a distance from its due phase, signed; the median is robust to late ticks
        off = statistics.median(((s / period - due + 0.5) % 1.0) - 0.5 for s in stamps[who])
        phases[who] = (due + off) % 1.0
        assert abs(off) < 0.2, f"agent {who} ticks {off * period * 1000:.1f} ms off its phase"
    ordered = sorted(phases.values())
    gaps = [b - a for a, b in zip(ordered, ordered[1:])] + [1.0 - ordered[-1] + ordered[0]]
    assert max(gaps) < 0.4, f"the agents' ticks bunch: phases {ordered}"
