"""``python -m agents.fleet``: import the agent program once, then fork one process per agent, each with
its own Zenoh session and pid, the imported pages shared until written; why, and its protocol on stdin
and stdout: docs/architecture.md, "An agent's tick"."""

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
