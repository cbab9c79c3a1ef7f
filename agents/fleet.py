"""``python -m agents.fleet``: import the agent program once, then fork one process per agent.

An agent process spends most of its start importing (Python, numpy, Zenoh's bindings, msgpack); a
hundred of them starting at once on two cores take tens of seconds, and each keeps a private copy of
what it imported. The fleet imports everything once and forks each agent from itself before any Zenoh
session exists; each agent is still its own OS process with its own Zenoh session and its own pid, and
the imported pages stay shared between them until written.

Each agent is a process group of its own (a terminal's Ctrl-C reaches the launcher, which stops the
agents in order) inside the fleet's session, not a session of its own: on Linux with autogroup
scheduling (the default on desktop and server kernels) every session is a group that gets an equal
share of the CPU, so a hundred agents in a hundred sessions left the router and the world a hundredth
each. Starved, the router read the agents' sockets seconds late, and agents steered and filtered on
poses up to 30 s old (docs/safety.md, "A machine that falls behind"). In one session the agents
together weigh what the router weighs: on a machine too small for the swarm, the agents tick late
(their ticks are counted and skipped) while the poses they do send arrive fresh.

Protocol (one line each, on stdin and stdout): the launcher writes ``spawn NAME ARG...`` (JSON, the
agent's command line), the fleet answers ``pid NAME PID``, and ``exit NAME CODE`` when that agent
ends (CODE as ``subprocess`` gives it: negative for a signal). End of input: the fleet stops its
agents (SIGTERM) and exits once they have. Agents die with the fleet, the fleet with its launcher.
"""

from __future__ import annotations

import gc
import json
import os
import select
import signal
import sys

from zswarm.process import die_with_parent, one_blas_thread


def _child(argv: list[str]) -> None:
    """In the forked agent: a process group of its own in the fleet's session, no stdin/stdout, then the
    program."""
    from agents.main import main as agent_main

    code = 1
    try:
        os.setpgid(0, 0)
        die_with_parent()
        devnull = os.open(os.devnull, os.O_RDWR)
        os.dup2(devnull, 0)
        os.dup2(devnull, 1)
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        code = agent_main(argv)
    except SystemExit as exc:  # argparse's usage error (2), as the agent program alone exits with it
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    finally:
        sys.stderr.flush()
        os._exit(code)


def main() -> int:
    # no BLAS thread pool to fork (an agent's control law is plain floats; numpy only draws spawns)
    one_blas_thread(os.environ)
    import agents.free  # noqa: F401  (import the whole agent program once, before any fork)
    from agents.main import preload

    preload()
    gc.freeze()  # what the fleet imported: no agent's collector walks (and so copies) those pages

    die_with_parent()
    children: dict[int, str] = {}
    out = sys.stdout
    closing = False

    def reap() -> None:
        while children:
            try:
                pid, status = os.waitpid(-1, os.WNOHANG)
            except ChildProcessError:
                return
            if pid == 0:
                return
            name = children.pop(pid, None)
            if name is not None:
                out.write(f"exit {name} {os.waitstatus_to_exitcode(status)}\n")
                out.flush()

    stopping: list[bool] = []
    signal.signal(signal.SIGTERM, lambda *_: stopping.append(True))  # or end of input: stop the agents
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    stdin = sys.stdin.fileno()
    buffer = b""
    while not closing or children:
        if stopping and not closing:
            closing = True
            for pid in children:
                os.kill(pid, signal.SIGTERM)
        try:
            ready, _, _ = select.select([] if closing else [stdin], [], [], 0.1)
        except InterruptedError:
            continue
        if ready:
            chunk = os.read(stdin, 65536)
            if not chunk:
                stopping.append(True)
            buffer += chunk
            while b"\n" in buffer:
                line, buffer = buffer.split(b"\n", 1)
                verb, _, rest = line.decode().partition(" ")
                if verb == "spawn":
                    name, _, argv = rest.partition(" ")
                    out.flush()
                    pid = os.fork()
                    if pid == 0:
                        _child(json.loads(argv))
                    children[pid] = name
                    out.write(f"pid {name} {pid}\n")
                    out.flush()
        reap()
    return 0


if __name__ == "__main__":
    sys.exit(main())
