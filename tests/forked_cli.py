"""Run many short commands as forks of one interpreter that imported the project once.

``python tests/forked_cli.py JOBS.json RESULTS.json`` runs each job (``argv`` as given to ``python``:
``-m MODULE ARG...``, ``-c CODE ARG...`` or ``SCRIPT ARG...``, its ``cwd``, its ``timeout``) in a process forked from this
one, as ``agents.fleet`` starts agents: the interpreter and the project's imports (numpy, Zenoh's
bindings, the command-line programs) are paid once instead of once per command, and each command still
runs in a process of its own, from its ``__main__``, with its own stdin (empty), stdout, stderr and exit
status. A job that outlives its timeout is killed with everything it started (its process group).

:func:`run_forked` is the tests' side: it writes the jobs, runs this file and returns one
``subprocess.CompletedProcess`` per job. For tests that run a command dozens of times to see it refuse
a mistake (``tests/test_usage.py``).

:class:`ForkServer` is the same for one command at a time: ``python tests/forked_cli.py --serve SCRATCH``
imports the project once and then forks each command it is sent (a line of JSON on its standard input)
and answers when it ends (a line on its standard output). ``run_cli`` (tests/conftest.py) runs every
command of the suite through one: a hundred and more interpreters starting up (numpy, Zenoh's bindings,
the project) cost the suite about 40 CPU-seconds, a tenth of its work on 2 cores.
"""

from __future__ import annotations

import atexit
import json
import os
import runpy
import select
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import traceback
from pathlib import Path

#: What every command imports first; nothing here opens a session or starts a thread. (Not a module a
#: job runs as ``__main__``: ``runpy`` warns when it finds one imported already.)
PRELOAD = ("numpy", "msgpack", "zenoh", "zswarm.cli.main", "zswarm.cli.launch", "agents.main", "world.main")


def _exit_code(exc: SystemExit) -> int:
    """What the interpreter makes of ``sys.exit(code)``."""
    if exc.code is None:
        return 0
    if isinstance(exc.code, int):
        return exc.code
    print(exc.code, file=sys.stderr)
    return 1


def _child(job: dict, out: str, err: str) -> None:
    """In the fork: its own process group, its own files (and environment, where the job gives one),
    then the program as ``python ARGV`` runs it."""
    code = 1
    try:
        os.setpgid(0, 0)
        if "env" in job:
            os.environ.clear()
            os.environ.update(job["env"])
        os.chdir(job["cwd"])
        for fd, path, flags in ((0, os.devnull, os.O_RDONLY), (1, out, os.O_WRONLY | os.O_CREAT | os.O_TRUNC),
                                (2, err, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)):
            os.dup2(os.open(path, flags, 0o644), fd)
        signal.signal(signal.SIGINT, signal.default_int_handler)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        argv = job["argv"]
        try:
            if argv[0] == "-c":
                sys.argv = ["-c", *argv[2:]]
                sys.path[0] = ""
                exec(compile(argv[1], "<string>", "exec"), {"__name__": "__main__"})
            elif argv[0] == "-m":
                sys.argv = [argv[1], *argv[2:]]
                sys.path[0] = os.getcwd()  # as ``python -m`` puts it first
                runpy.run_module(argv[1], run_name="__main__", alter_sys=True)
            else:
                sys.argv = list(argv)
                sys.path[0] = str(Path(argv[0]).resolve().parent)
                runpy.run_path(argv[0], run_name="__main__")
            code = 0
        except SystemExit as exc:
            code = _exit_code(exc)
        except KeyboardInterrupt:
            traceback.print_exc()
            code = 130
        except BaseException:
            traceback.print_exc()  # as the interpreter prints an uncaught exception
            code = 1
        atexit._run_exitfuncs()
    finally:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:
                pass
        os._exit(code)


def run_jobs(jobs: list[dict], folder: Path, parallel: int) -> list[dict]:
    """Each job forked, ``parallel`` at a time; returns returncode, stdout and stderr of each, in order."""
    for module in PRELOAD:
        __import__(module)
    results: list[dict | None] = [None] * len(jobs)
    running: dict[int, tuple[int, float]] = {}  # pid -> (job, deadline)
    waiting = list(range(len(jobs)))[::-1]
    while waiting or running:
        while waiting and len(running) < parallel:
            k = waiting.pop()
            out, err = str(folder / f"{k}.out"), str(folder / f"{k}.err")
            sys.stdout.flush()
            sys.stderr.flush()
            pid = os.fork()
            if pid == 0:
                _child(jobs[k], out, err)
            running[pid] = (k, time.monotonic() + jobs[k]["timeout"])
        pid, status = os.waitpid(-1, os.WNOHANG)
        if pid == 0:
            for pid, (k, deadline) in list(running.items()):
                if time.monotonic() > deadline:
                    try:
                        os.killpg(pid, signal.SIGKILL)
                    except ProcessLookupError:
                        pass
            time.sleep(0.01)
            continue
        if pid not in running:
            continue
        k, _ = running.pop(pid)
        results[k] = {"returncode": os.waitstatus_to_exitcode(status), "stdout": Path(folder / f"{k}.out").read_text(errors="replace"),
                      "stderr": Path(folder / f"{k}.err").read_text(errors="replace")}
    return results  # type: ignore[return-value]


def run_forked(jobs: list[tuple[list[str], Path]], scratch: Path, timeout: float = 60.0,
               parallel: int | None = None) -> list[subprocess.CompletedProcess]:
    """Run each (argv, cwd) as ``python ARGV`` in ``cwd`` would, forked from one interpreter; their
    output files go to ``scratch`` (not to ``cwd``, which the tests check is left as it was)."""
    root = Path(__file__).resolve().parents[1]
    scratch.mkdir(parents=True, exist_ok=True)
    spec = scratch / "jobs.json"
    spec.write_text(json.dumps([{"argv": list(argv), "cwd": str(cwd), "timeout": timeout} for argv, cwd in jobs]))
    parallel = parallel or (os.cpu_count() or 2) + 1  # one more: some wait on a port
    env = {**os.environ, "PYTHONPATH": str(root)}
    subprocess.run([sys.executable, __file__, str(spec), str(scratch / "results.json"), str(parallel)], env=env,
                   check=True, timeout=timeout * len(jobs) + 60)
    done = json.loads((scratch / "results.json").read_text())
    return [subprocess.CompletedProcess([sys.executable, *argv], r["returncode"], r["stdout"], r["stderr"])
            for (argv, _), r in zip(jobs, done)]


def _wait(pid: int, timeout: float) -> int | None:
    """The exit status of child ``pid``, or None (its process group killed) after ``timeout`` s."""
    fd = os.pidfd_open(pid)
    try:
        ready, _, _ = select.select([fd], [], [], timeout)
    finally:
        os.close(fd)
    if not ready:
        try:
            os.killpg(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    status = os.waitpid(pid, 0)[1]
    return os.waitstatus_to_exitcode(status) if ready else None


def serve(scratch: Path) -> None:
    """One job a line on standard input (argv, cwd, env, timeout), each forked as :func:`_child` runs it;
    a line on standard output when it ends: its exit status (null: killed at its timeout) and the files
    that hold its output. Ends at the end of its input, removing ``scratch``."""
    for module in PRELOAD:
        __import__(module)
    try:
        for k, line in enumerate(sys.stdin):
            job = json.loads(line)
            out, err = str(scratch / f"{k}.out"), str(scratch / f"{k}.err")
            sys.stdout.flush()
            pid = os.fork()
            if pid == 0:
                _child(job, out, err)
            code = _wait(pid, job["timeout"])
            print(json.dumps({"returncode": code, "stdout": out, "stderr": err}), flush=True)
    finally:  # its client gone, closed or not: nothing of it is left in /tmp
        shutil.rmtree(scratch, ignore_errors=True)


class ForkServer:
    """A :func:`serve` process, and the client's side of it: :meth:`run` is ``subprocess.run`` with
    ``capture_output=True, text=True`` for ``python ARGV``, one command at a time."""

    def __init__(self, root: Path) -> None:
        # (not die_with_parent: its signal comes when the *thread* that started the server ends, a pool's
        # thread included; a server whose client is gone ends at the end of its input)
        self.scratch = Path(tempfile.mkdtemp(prefix="zs-forks-"))
        env = {**os.environ, "PYTHONPATH": str(root)}
        self.proc = subprocess.Popen([sys.executable, __file__, "--serve", str(self.scratch)], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, text=True, env=env, cwd=root)

    def run(self, argv: list[str], cwd: Path, env: dict[str, str], timeout: float) -> subprocess.CompletedProcess:
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self.proc.stdin.write(json.dumps({"argv": argv, "cwd": str(cwd), "env": env, "timeout": timeout}) + "\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError(f"the fork server ended (exit status {self.proc.wait()})")
        result = json.loads(line)
        out, err = (Path(result[k]).read_text(errors="replace") for k in ("stdout", "stderr"))
        for k in ("stdout", "stderr"):
            Path(result[k]).unlink()
        if result["returncode"] is None:
            raise subprocess.TimeoutExpired([sys.executable, *argv], timeout, out, err)
        return subprocess.CompletedProcess([sys.executable, *argv], result["returncode"], out, err)

    def close(self) -> None:
        if self.proc.stdin is not None:
            self.proc.stdin.close()
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        shutil.rmtree(self.scratch, ignore_errors=True)


def main() -> int:
    if sys.argv[1] == "--serve":
        serve(Path(sys.argv[2]))
        return 0
    spec, results, parallel = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3])
    out = run_jobs(json.loads(spec.read_text()), spec.parent, parallel)
    results.write_text(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
