"""Small things a user met on a first try, each held: one error prefix per command, a duration flag's
refusal that says what it takes, output piped into a reader that stops early, and printed commands that
exist as printed."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from conftest import ROOT
from zswarm.cli.main import command_prog


@pytest.mark.parametrize("argv, prog", [(["certs", "x"], "zswarm certs"), (["bench", "net", "--agents", "2"],
                                        "zswarm bench net"), (["sim", "--duration", "0"], "zswarm sim"),
                                        (["--help"], "zswarm")])
def test_every_command_names_itself_in_its_errors(argv, prog):
    assert command_prog(argv) == prog


def test_an_error_of_a_command_begins_with_its_name(tmp_path):
    (tmp_path / "pki").mkdir()
    (tmp_path / "pki" / "ca.pem").write_text("x")
    res = subprocess.run([sys.executable, "-m", "zswarm", "certs", str(tmp_path / "pki")], capture_output=True,
                         text=True, timeout=60, env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert res.returncode == 2 and res.stderr.startswith("zswarm certs: error: "), res.stderr


@pytest.mark.parametrize("text", ["-10", "0", "0s"])
def test_a_duration_that_must_be_positive_says_so_for_every_refused_value(text):
    import argparse

    from zswarm.args import positive_seconds

    with pytest.raises(argparse.ArgumentTypeError, match=r"expected a duration > 0"):
        positive_seconds(text)


def test_output_into_a_reader_that_went_away_ends_quietly():
    """``zswarm scenarios --json | head -c 0``: the reader is gone before the first write. No traceback."""
    proc = subprocess.Popen([sys.executable, "-m", "zswarm", "scenarios", "--json"], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, env={**os.environ, "PYTHONPATH": str(ROOT)})
    proc.stdout.close()
    err = proc.stderr.read().decode()
    assert proc.wait(timeout=60) == 0 and "Traceback" not in err and "BrokenPipe" not in err, err


def test_a_printed_command_is_one_that_exists_here(tmp_path, monkeypatch):
    """``zswarm`` where it is on PATH, else the one installed beside this Python, which is there."""
    from zswarm.launch.ending import installed_command

    monkeypatch.setenv("PATH", str(tmp_path))  # not activated: nothing on PATH
    monkeypatch.chdir(tmp_path)
    command = installed_command("zswarm")
    assert command != "zswarm" and os.path.isfile(command) and os.access(command, os.X_OK), command


def test_more_routers_than_agents_is_refused_at_once(cli):
    import time

    start = time.monotonic()
    res = cli(str(ROOT / "launch.py"), "--routers", "50", "--agents", "10", timeout=60)
    assert res.returncode == 2 and "--routers 50 for 10 agents" in res.stderr and "--routers 10 or fewer" in res.stderr
    assert time.monotonic() - start < 20.0, "refused before any router starts"


def test_a_group_with_an_unknown_body_names_the_body():
    from zswarm.errors import ParamError
    from zswarm.paper.params import groups_of

    with pytest.raises(ParamError, match=r"'tank' in '6:apf/tank' is not a body; the bodies are point"):
        groups_of("6:apf/tank,4:boids")
    assert groups_of("6:examples/my_law.py:seek,4:boids/unicycle") == [(6, "examples/my_law.py:seek", None),
                                                                        (4, "boids", "unicycle")]


def test_what_the_readme_commands_write_in_a_checkout_is_ignored():
    """``git status`` stays clean after the README's commands: their recordings, summaries (beside any
    ``--record``), figures and output folders are ignored."""
    import shutil

    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("not a git checkout")
    written = ["run.rrd", "run.json", "run-2.json", "sim.json", "sg.json", "design.png", "sweep/results.md",
               "tune/best.toml", "pki/ca.key", "mixed-sweep/results.json", "run.npz"]
    res = subprocess.run(["git", "check-ignore", "--no-index", *written], cwd=ROOT, capture_output=True, text=True)
    assert sorted(res.stdout.split()) == sorted(written), set(written) - set(res.stdout.split())


@pytest.mark.parametrize("argv, prog", [(["-m", "world", "--run", "x"], "zswarm world"),
                                        (["-m", "agents", "--id", "3", "--run", "x"], "zswarm agent 3"),
                                        (["-m", "zswarm.net.router", "--listen", "tcp/192.0.2.1:7447"], "zswarm router")])  # not this machine's: binding fails
def test_a_child_process_names_itself_once_in_its_errors(argv, prog):
    """A process the launcher starts says ``zswarm NAME: error: ...`` as every command does, once (not
    ``world: error: world: ...``)."""
    extra = [] if "router" in prog else ["--connect", "tcp/127.0.0.1:1", "--connect-timeout", "0.5"]
    res = subprocess.run([sys.executable, *argv, *extra], capture_output=True, text=True, timeout=60,
                         env={**os.environ, "PYTHONPATH": str(ROOT)})
    line = res.stderr.strip().splitlines()[-1]
    assert res.returncode == 2 and line.startswith(f"{prog}: error: "), res.stderr[-1000:]
    assert line.count(prog.split()[1]) == 1, line


def test_every_commands_scenario_help_names_its_default():
    from zswarm.cli import launch, sweep
    from zswarm.cli.main import build_parser

    parsers = {"run": launch.build_parser(), "sweep": sweep.build_parser(),
               "sim": build_parser()._subparsers._group_actions[0].choices["sim"]}
    for name, parser in parsers.items():
        action = next(a for a in parser._actions if "--scenario" in a.option_strings)
        assert f"default {action.default}" in " ".join(action.help.split()), (name, action.help)
