"""The agent fleet forks agents that share its scheduling group: on Linux with autogroup scheduling
(the default on desktop and server kernels) every session is a group that gets an equal share of the
CPU, so an agent in a session of its own made a 100-agent swarm 100 groups against the router's one,
and the router, starved, queued seconds of poses (docs/safety.md, "A machine that falls behind")."""

from __future__ import annotations

import os
import time
from pathlib import Path

from zswarm.net.procs import Children, Fleet, free_port


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
