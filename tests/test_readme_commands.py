"""The README's commands, every one, as written (with short durations where a command takes one), in a
folder of their own, twice in a row: the second time must work too (a file the first wrote is no
obstacle). Slow: run it with ``pytest -m slow tests/test_readme_commands.py`` (or ``-m "not slow"`` skips it)."""
from __future__ import annotations

import os
import re
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import ROOT
from ray_procs import NO_RAY, can_make_hosts, hostlike, remove_hostlike

pytestmark = pytest.mark.slow

README = (ROOT / "README.md").read_text()

#: Shorter runs of the same commands: what a flag is set to here, where the README gives it or the
#: command would take minutes. Nothing else changes.
SHORT = {"--duration": "4", "--budget": "4"}
EXTRA = {"sweep": ["--duration", "3", "--seeds", "1"],
         "tune": ["--duration", "4", "--seeds", "1", "--validate", "1", "--holdout", "1", "--popsize", "4"],
         "robots": ["--duration", "4"], "secure": ["--duration", "4"], "sim-law": ["--duration", "4"],
         "sim": ["--duration", "4"]}


def readme_lines() -> list[str]:
    """The lines of the README's command blocks, comments cut, `.venv/bin/` left as written."""
    out, shell = [], False
    for line in README.splitlines():
        if line.startswith("```"):
            shell = not shell and line.strip() == "```bash"
            continue
        if shell and line.strip():
            out.append(re.split(r"\s#\s", line)[0].strip())
    return out


def shorter(argv: list[str]) -> list[str]:
    argv = [SHORT.get(argv[k - 1], a) if k else a for k, a in enumerate(argv)]
    kind = ("sim-law" if "--law" in argv else "sim") if argv[1:2] == ["sim"] else (
        "robots" if "--robots" in argv and argv[1:2] == ["run"] else "secure" if "--secure" in argv else argv[1])
    extra = [a for a in EXTRA.get(kind, []) if True]
    given = set(argv)
    pairs = [extra[k:k + 2] for k in range(0, len(extra), 2)]
    return argv + [x for flag, value in pairs if flag not in given for x in (flag, value)]


def zswarm(argv: list[str]) -> list[str]:
    """``zswarm ...`` or ``.venv/bin/python launch.py ...`` with this interpreter."""
    if argv[0].endswith("zswarm"):
        return [sys.executable, "-m", "zswarm", *argv[1:]]
    if argv[0].endswith(("python", "python3")):
        return [sys.executable, *argv[1:]]
    raise AssertionError(argv)


def run(argv: list[str], cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run(zswarm(argv), cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    """A user's folder: the README's paths (examples/) as in a clone."""
    d = tmp_path_factory.mktemp("readme")
    for name in ("examples", "launch.py"):
        (d / name).symlink_to(ROOT / name)
    return d


def test_every_readme_command_works_twice_in_a_row(folder):
    lines = readme_lines()
    done = []
    for attempt in (1, 2):
        for line in lines:
            if line.startswith(("python3 -m venv", ".venv/bin/rerun", ".venv/bin/python -m pytest")):
                continue  # set-up, the viewer and the tests: not commands of zswarm
            if "robot-sim" in line or "monitor" in line or "--cluster" in line:
                continue  # below: each needs its partner, or a namespace of its own
            for part in line.split("&&"):
                argv = shorter(shlex.split(part))
                res = run(argv, folder)
                assert res.returncode in (0, 1) if argv[1:2] == ["tune"] else res.returncode == 0, (
                    attempt, argv, res.stderr[-2000:])
                done.append(argv[1] if argv[0].endswith("zswarm") else "demo")
        robots(lines, folder)
        monitor(folder)
        if not NO_RAY and can_make_hosts():
            cluster(lines, folder)
    assert {"demo", "design", "sim", "run", "sweep", "certs", "replay", "tune"} <= set(done), done


def robots(lines: list[str], folder: Path) -> None:
    """The stand-in robots (in the background, as the README's ``&``) and the run that drives them."""
    sim_line = next(line for line in lines if "robot-sim" in line)
    run_line = next(line for line in lines if "--robots" in line and "robot-sim" not in line)
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    robot_sim = subprocess.Popen(zswarm([a for a in shlex.split(sim_line) if a != "&"]), cwd=folder, env=env,
                                 stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        res = run(shorter(shlex.split(run_line)), folder)
        assert res.returncode == 0, res.stderr[-2000:]
        _, err = robot_sim.communicate(timeout=60)  # it stops once the run that drove it has ended
        assert robot_sim.returncode == 0, err[-2000:]
    finally:
        if robot_sim.poll() is None:
            os.killpg(robot_sim.pid, signal.SIGKILL)
            robot_sim.wait()


def monitor(folder: Path) -> None:
    """``zswarm monitor --run RUN`` beside a demo run named RUN: it ends with the run, exit 0."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    name = f"readme-{os.getpid()}-{time.monotonic_ns()}"
    demo = subprocess.Popen([sys.executable, str(ROOT / "launch.py"), "--duration", "6", "--run", name, "--quiet"],
                            cwd=folder, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while True:  # the run is announced once its router is up
            res = run(["zswarm", "monitor", "--run", name], folder, timeout=90)
            if res.returncode == 0 or time.monotonic() > deadline or demo.poll() is not None:
                break
            time.sleep(0.5)
        assert res.returncode == 0 and "the run ended" in res.stdout, res.stderr[-2000:]
        assert demo.wait(timeout=60) == 0, demo.stderr.read()[-2000:]
    finally:
        if demo.poll() is None:
            os.killpg(demo.pid, signal.SIGKILL)
            demo.wait()


def cluster(lines: list[str], folder: Path) -> None:
    """The Ray line, in a namespace that looks like a user's machine (an interface, a default route into a
    gateway that forwards nothing: Ray must not reach past it)."""
    line = next(line for line in lines if "--cluster" in line)
    argv, env = hostlike(folder, *zswarm(shorter(shlex.split(line)))[1:], mark=f"readme-{os.getpid()}")
    try:
        res = subprocess.run(argv, cwd=folder, env=env, capture_output=True, text=True, timeout=300)
    finally:
        remove_hostlike()
    assert res.returncode == 0, res.stderr[-2000:]
