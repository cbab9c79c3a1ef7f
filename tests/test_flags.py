"""One meaning per flag: every command's parser walked, each long flag's meaning (what its value is:
a Zenoh endpoint, simulated or wall-clock seconds, numbers of agents, ...) the same wherever the name
appears; old spellings refused in one line that names the new one."""
from __future__ import annotations

import argparse

import pytest

from conftest import run_cli


def parsers() -> dict[str, argparse.ArgumentParser]:
    """Every parser a user meets: zswarm's subcommands (nested), zswarm run and sweep (launch.py's), and
    the processes (agent, world, router)."""
    from agents.main import build_parser as agent_parser
    from world.main import build_parser as world_parser
    from zswarm.cli import launch, sweep
    from zswarm.cli.main import build_parser
    from zswarm.net.router import build_parser as router_parser

    out: dict[str, argparse.ArgumentParser] = {}

    def walk(parser: argparse.ArgumentParser, name: str) -> None:
        out[name] = parser
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for sub, p in action.choices.items():
                    walk(p, f"{name} {sub}")

    walk(build_parser(), "zswarm")
    out.update({"zswarm run": launch.build_parser(), "zswarm sweep": sweep.build_parser(),
                "python -m agents": agent_parser(), "python -m world": world_parser(),
                "python -m zswarm.net.router": router_parser()})
    return out


def meaning(action: argparse.Action) -> tuple:
    """What a flag's value is: the meaning its type or action declares, else its type and choices."""
    declared = getattr(action, "meaning", None) or getattr(action.type, "meaning", None)
    kind = declared or (getattr(action.type, "__name__", repr(action.type)) if action.type else type(action).__name__)
    return kind, tuple(action.choices) if action.choices and not declared else None


def meanings(of: dict[str, argparse.ArgumentParser]) -> dict[str, dict[tuple, list[str]]]:
    from zswarm.args import Renamed

    out: dict[str, dict[tuple, list[str]]] = {}
    for command, parser in of.items():
        for action in parser._actions:
            if isinstance(action, Renamed):  # an old spelling, refused
                continue
            for flag in action.option_strings:
                if flag.startswith("--") and flag != "--help":
                    out.setdefault(flag, {}).setdefault(meaning(action), []).append(command)
    return out


def test_every_flag_has_one_meaning_in_every_command():
    found = meanings(parsers())
    twice = {flag: {str(k): v for k, v in m.items()} for flag, m in found.items() if len(m) > 1}
    assert twice == {}, twice
    assert {"--connect", "--duration", "--stop-after", "--viewer", "--agents", "--safety", "--seeds"} <= found.keys()
    assert set(found["--duration"]) == {("simulated seconds", None)}
    assert set(found["--connect"]) == {("a Zenoh endpoint", None)}


def test_a_flag_given_a_second_meaning_fails_the_walk():
    """The check can fail: a wall-clock --duration, or a --connect that takes a viewer URL, beside the rest."""
    from zswarm.args import viewer_url, wall_seconds

    for flag, kind in (("--duration", wall_seconds), ("--connect", viewer_url)):
        odd = argparse.ArgumentParser()
        odd.add_argument(flag, type=kind)
        assert len(meanings({**parsers(), "odd": odd})[flag]) == 2


@pytest.mark.parametrize("argv,says", [
    (["-m", "zswarm", "monitor", "--run", "x", "--duration", "5"], "give --stop-after S"),
    (["-m", "zswarm", "robot-sim", "--robots", "r.toml", "--duration", "5"], "give --stop-after S"),
    (["-m", "zswarm", "bench", "soak", "--duration", "5"], "give --stop-after S"),
    (["-m", "zswarm", "sweep", "--out", "s", "--repeats", "2"], "runs per setting are --seeds K"),
    (["-m", "zswarm", "sim", "--connect", "rerun+http://127.0.0.1:9876/proxy"], "--viewer"),
    (["-m", "zswarm", "run", "--connect", "rerun+http://127.0.0.1:9876/proxy"], "give --viewer rerun+http"),
    (["-m", "zswarm", "sim", "--safety", "off,barrier"], "zswarm sweep --safety off,barrier runs each"),
    (["-m", "zswarm", "sim", "--latency", "100"], "needs a unit: 100ms or 100s"),
])
def test_an_old_spelling_is_refused_in_one_line_that_names_the_new_one(argv, says, tmp_path):
    res = run_cli(*argv, cwd=tmp_path, timeout=60)
    err = res.stderr.strip()
    assert res.returncode == 2 and len(err.splitlines()) == 1 and says in err and "Traceback" not in err, err
