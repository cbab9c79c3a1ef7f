"""The README is the front door: short, its set-up and demo first, every command in it one that the
real parsers take, every link one that leads somewhere."""

from __future__ import annotations

import re
import shlex

import pytest

from conftest import ROOT

README = (ROOT / "README.md").read_text()
LINES = README.splitlines()


def commands() -> list[list[str]]:
    """Every zswarm or launch.py command of the README's shell blocks, as argv (``&&`` split)."""
    out, shell = [], False
    for line in LINES:
        if line.startswith("```"):
            shell = line.strip() == "```bash"
            continue
        if not shell:
            continue
        code = re.split(r"\s#\s", line)[0].strip()
        for part in code.split("&&"):
            argv = shlex.split(part)
            if argv[:1] == [".venv/bin/zswarm"] or argv[:2] == [".venv/bin/python", "launch.py"]:
                out.append(argv)
    return out


def test_the_readme_is_short_and_starts_with_set_up_and_the_demo():
    assert len(LINES) <= 150, len(LINES)
    setup = next(i for i, line in enumerate(LINES) if 'pip install -e ".[dev]"' in line)
    demo = next(i for i, line in enumerate(LINES) if line.startswith(".venv/bin/python launch.py"))
    assert setup < 25 and demo < 25, (setup, demo)


def test_the_readmes_test_command_is_the_one_ci_runs():
    ci = (ROOT / ".ci" / "run").read_text()
    ours = re.search(r'\.venv/bin/python -m pytest ([^\n]*)', README).group(1).strip()
    theirs = re.search(r'"\$VENV/bin/python" -m pytest ([^\n]*)', ci).group(1).strip()
    assert ours == theirs


@pytest.mark.parametrize("argv", commands(), ids=lambda a: " ".join(a[1:4]))
def test_every_readme_command_is_taken_by_its_parser(argv):
    """Parsed by the very parser the command runs with: a flag renamed or a value refused fails here."""
    from zswarm.cli import launch, sweep
    from zswarm.cli.main import build_parser

    if argv[0] == ".venv/bin/python":  # launch.py is zswarm run
        parser, rest = launch.build_parser("launch.py"), argv[2:]
    elif argv[1] == "run":
        parser, rest = launch.build_parser(), argv[2:]
    elif argv[1] == "sweep":
        parser, rest = sweep.build_parser(), argv[2:]
    else:
        parser, rest = build_parser(), argv[1:]
    try:
        parser.parse_args(rest)
    except SystemExit as exc:
        pytest.fail(f"{' '.join(argv)}: refused by its parser (exit {exc.code})")


def test_the_readme_shows_every_task_and_its_links_lead_somewhere():
    assert len(commands()) >= 12
    for task in ("design", "sim", "run", "sweep", "--law", "3d", "robot-sim", "--cluster", "--secure", "replay",
                 "tune"):
        assert any(task in " ".join(a) for a in commands()), task
    for target in re.findall(r"\]\(([^)#]+)(?:#([^)]+))?\)", README):
        path, anchor = target
        if path.startswith("http"):
            continue
        assert (ROOT / path).exists(), path
        if anchor:
            headings = [re.sub(r"[^\w\- ]", "", h.strip("# ").lower()).replace(" ", "-")
                        for h in (ROOT / path).read_text().splitlines() if h.startswith("#")]
            assert anchor in headings, (path, anchor)
