"""Installed from a wheel, outside the checkout: the commands and their child processes still work
(children are started as installed modules, never through the checkout's path)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys

from conftest import ROOT


def test_a_wheel_installed_elsewhere_runs_a_swarm_and_a_sweep(tmp_path):
    wheels, target, work, source = tmp_path / "wheels", tmp_path / "site", tmp_path / "work", tmp_path / "src"
    work.mkdir()
    source.mkdir()
    for name in ("pyproject.toml", "README.md", "zswarm", "agents", "world"):  # built away from the checkout
        if (ROOT / name).is_dir():
            shutil.copytree(ROOT / name, source / name, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy(ROOT / name, source / name)
    build = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(wheels), str(source)],
                           capture_output=True, text=True, timeout=300)
    assert build.returncode == 0, build.stderr[-2000:]
    (wheel,) = wheels.glob("zswarm-*.whl")
    install = subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(target),
                              str(wheel)], capture_output=True, text=True, timeout=300)
    assert install.returncode == 0, install.stderr[-2000:]
    # the wheel's modules come first on the path (an editable install of the checkout may sit behind)
    env = {**os.environ, "PYTHONPATH": str(target)}
    where = subprocess.run([sys.executable, "-c", "import zswarm, agents, world; "
                            "print(zswarm.__file__, agents.__file__, world.__file__)"],
                           capture_output=True, text=True, env=env, cwd=work, timeout=60)
    assert where.stdout.count(str(target)) == 3, where.stdout + where.stderr
    zswarm = [sys.executable, str(target / "bin" / "zswarm")]

    run = subprocess.run([*zswarm, "run", "--agents", "3", "--duration", "5", "--run", "wheelrun", "--quiet"],
                         capture_output=True, text=True, env=env, cwd=work, timeout=180)
    assert run.returncode == 0, run.stderr[-2000:]
    summary = json.loads((work / "run.json").read_text())
    assert summary["agents_reporting"] == 3 and summary["steps"] == 100 and "reference" in summary

    sweep = subprocess.run([*zswarm, "sweep", "--scenario", "moving-prey", "--latency", "0", "--dropout", "0",
                            "--seeds", "1", "--agents", "3", "--duration", "3", "--out", "sw"],
                           capture_output=True, text=True, env=env, cwd=work, timeout=300)
    assert sweep.returncode == 0, sweep.stderr[-2000:]
    cell = work / "sw" / "cells" / "lat0ms_drop0_rep0_barrier"
    assert json.loads((cell / "run.json").read_text())["agents_reporting"] == 3
    assert (work / "sw" / "results.md").read_text().count("| distributed |") == 1
