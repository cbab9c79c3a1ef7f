"""The front door: a README that is short, its set-up and demo first, every command in it and in the
guides one that the real parsers take, every link one that leads somewhere, and no page, docstring or
comment that narrates the order of the work (that is CHANGELOG.md's and git's)."""
from __future__ import annotations

import re
import shlex

import pytest

from conftest import ROOT

README = (ROOT / "README.md").read_text()
LINES = README.splitlines()


def commands(text: str = README, bash_only: bool = True) -> list[list[str]]:
    """Every zswarm or launch.py command of ``text``'s code blocks (its ``bash`` blocks only, with
    ``bash_only``), as argv, with ``.venv/bin/`` and ``python`` spelled either way; ``&&`` split."""
    out, shell = [], False
    for line in text.splitlines():
        if line.startswith("```"):
            shell = not shell and (line.strip() == "```bash" or not bash_only)
            continue
        if not shell or "\u2500" in line:  # not a command, or a drawing of one
            continue
        code = re.split(r"\s#\s", line)[0].strip().replace("[--json]", "--json")
        for part in re.split(r"&&|;", code):
            try:
                argv = [a for a in shlex.split(part) if a != "&"]
            except ValueError:
                continue
            if argv[:1] in ([".venv/bin/zswarm"], ["zswarm"]) or (
                    len(argv) > 1 and argv[0].endswith(("python", "python3")) and argv[1] == "launch.py"):
                out.append(argv)
    return out


def parse(argv: list[str]) -> None:
    """``argv`` through the very parser its command runs with (SystemExit when it is refused)."""
    from zswarm.cli import launch, sweep
    from zswarm.cli.main import build_parser

    if argv[0].endswith(("python", "python3")):  # launch.py is zswarm run
        parser, rest = launch.build_parser("launch.py"), argv[2:]
    elif argv[1] == "run":
        parser, rest = launch.build_parser(), argv[2:]
    elif argv[1] == "sweep":
        parser, rest = sweep.build_parser(), argv[2:]
    else:
        parser, rest = build_parser(), argv[1:]
    parser.parse_args(rest)


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
    try:
        parse(argv)
    except SystemExit as exc:
        pytest.fail(f"{' '.join(argv)}: refused by its parser (exit {exc.code})")


def test_every_command_in_the_guides_is_taken_by_its_parser():
    """The guides' commands too (a ``--params FILE`` the reader writes first is left out: its parser reads it)."""
    refused, seen = [], 0
    for page in sorted((ROOT / "docs").glob("*.md")):
        for argv in commands(page.read_text(), bash_only=False):
            if "--params" in argv:
                k = argv.index("--params")
                argv = argv[:k] + argv[k + 2:]
            seen += 1
            try:
                parse(argv)
            except SystemExit:
                refused.append(f"{page.name}: {' '.join(argv)}")
    assert seen >= 80 and refused == [], refused


def test_the_readme_shows_every_task_and_its_links_lead_somewhere():
    assert len(commands()) >= 12
    for task in ("design", "sim", "run", "sweep", "--law", "3d", "robot-sim", "--cluster", "--secure", "replay",
                 "tune"):
        assert any(task in " ".join(a) for a in commands()), task


#: Where a link may leave the repository: the dependencies' own references and the paper (DOI).
OUTSIDE = ("https://zenoh.io/docs/", "https://rerun.io/docs/", "https://docs.ray.io/en/latest/",
           "https://github.com/ray-project/ray/issues/", "https://github.com/ros2/rmw_zenoh",
           "https://doi.org/10.1007/s10846-006-9050-8")


def test_every_link_of_the_readme_and_the_docs_leads_somewhere_inside_the_repository_or_to_a_dependency():
    """Every link of README.md, CHANGELOG.md and docs/ names a file of the repository (and a heading of
    it, where it names one), or a dependency's own reference (:data:`OUTSIDE`); and the references a user
    needs are linked: Zenoh's configuration, the Rerun viewer, ray start, Ray's tokens, rmw_zenoh, the paper."""
    bad, outside = [], set()
    for page in [ROOT / "README.md", ROOT / "CHANGELOG.md", *sorted((ROOT / "docs").rglob("*.md"))]:
        for path, anchor in re.findall(r"\]\(([^)#]*)(?:#([^)]+))?\)", page.read_text()):
            if "://" in path:
                if not path.startswith(OUTSIDE):
                    bad.append(f"{page.name}: {path} leaves the repository for no dependency's reference")
                outside.add(next((o for o in OUTSIDE if path.startswith(o)), path))
                continue
            target = (page.parent / path).resolve() if path else page
            if not target.exists():
                bad.append(f"{page.name}: {path} does not exist")
            elif anchor:
                headings = [re.sub(r"[^\w\- ]", "", h.strip("# ").lower()).replace(" ", "-")
                            for h in target.read_text().splitlines() if h.startswith("#")]
                if anchor not in headings:
                    bad.append(f"{page.name}: {path}#{anchor} names no heading")
    assert bad == [], bad
    assert outside == set(OUTSIDE), set(OUTSIDE) - outside


@pytest.mark.parametrize("command", ["sim", "run", "sweep", "tune", "monitor", "robot-sim", "bench net", "bench world",
                                     "bench laws", "bench placement", "bench soak"])
def test_every_duration_flag_takes_units_and_a_bare_number_is_seconds(command):
    """One meaning per flag: ``--duration 90``, ``90s`` and ``1.5min`` are the same simulated time on
    every command, ``--stop-after`` the same wall-clock time; a fault delay takes no bare number but 0."""
    from zswarm.cli import launch, sweep
    from zswarm.cli.main import build_parser
    from zswarm.swarm.faults import parse_duration

    required = {"sweep": ["--out", "x"], "tune": ["--out", "x"], "monitor": ["--run", "x"], "robot-sim": ["--robots", "r.toml"]}
    parser = {"run": launch.build_parser(), "sweep": sweep.build_parser()}.get(command)
    prefix = [] if parser is not None else command.split()
    parser = parser or build_parser()
    flag = "--stop-after" if command in ("monitor", "robot-sim", "bench soak") else "--duration"
    got = {getattr(parser.parse_args([*prefix, *required.get(command, []), flag, text]), flag[2:].replace("-", "_"))
           for text in ("90", "90s", "1.5min", "90000ms")}
    assert got == {90.0}
    with pytest.raises(SystemExit):
        parser.parse_args([*prefix, *required.get(command, []), flag, "90q"])
    assert parse_duration("100ms") == parse_duration("0.1s") == 0.1 and parse_duration("0") == 0.0
    if command == "robot-sim":  # its other time flags take units too, a bare number being seconds
        args = parser.parse_args([*prefix, *required[command], "--idle-exit", "2s", "--cmd-timeout", "250ms"])
        assert (args.idle_exit, args.cmd_timeout) == (2.0, 0.25)
    assert "a unit is required but for 0" in launch.build_parser().format_help().replace("\n", " ").replace("  ", " ")


#: Phrases that narrate the order of the work; CHANGELOG.md is where that history belongs.
NARRATION = re.compile(r"\ba later (session|commit|issue|version of this)|\b(an )?earlier session|\bthis session\b(?!'s own)"
                       r"|started at commit|\bup to commit|\bthe next day\b|\ba day earlier\b|\bbefore this work\b"
                       r"|\bissue \d+\b|\bthe landed code\b|\bsince the fix\b", re.IGNORECASE)


def narrating(text: str) -> list[str]:
    return [line.strip()[:120] for line in text.splitlines() if NARRATION.search(line)]


def test_no_page_docstring_or_comment_narrates_the_order_of_the_work():
    files = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    for folder in ("zswarm", "agents", "world", "tests", "examples"):
        files += sorted((ROOT / folder).rglob("*.py"))
    found = {str(f.relative_to(ROOT)): hits for f in files
             if f.name != "test_front_door.py" and (hits := narrating(f.read_text()))}
    assert found == {}, found
    assert narrating("as a later session measured") and narrating("the code before this work")  # it can fail
    assert not narrating("not this session's own publications")  # a Zenoh session is no narration


#: A first-person word, a commit hash, a path out of the repository.
FIRST_PERSON = re.compile(r"\b(I|I'm|I've|me|my|we|We|our|Our)\b(?![-=])")
COMMIT = re.compile(r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}\b")


def test_the_docs_speak_to_users_with_no_first_person_no_commit_and_no_link_outside():
    found = {}
    for f in [ROOT / "README.md", ROOT / "CHANGELOG.md", *sorted((ROOT / "docs").rglob("*.md"))]:
        text = f.read_text()
        # code spans (one may wrap onto the next line) name ids such as agent-I, not people
        prose = re.sub(r"`[^`\n]*(\n[^`\n]*)?`", lambda m: "\n" * m.group(0).count("\n"), text)
        for n, (line, said) in enumerate(zip(text.splitlines(), prose.splitlines()), 1):
            if FIRST_PERSON.search(said) or COMMIT.search(said) or "../shared" in line:
                found.setdefault(str(f.relative_to(ROOT)), []).append(n)
    assert found == {}, found
    assert FIRST_PERSON.search("I did not trace it") and COMMIT.search("at commit 1908a61,")  # it can fail
    assert not FIRST_PERSON.search("agents 0..I-1") and not COMMIT.search("12345678 poses")


def test_the_small_cuts_a_new_user_hit_stay_mended():
    """Each a line of the issue that found them: "8 agents on 1 nodes"; *.mcap files (zswarm export)
    not ignored by git; Rerun's analytics on without a word in the README."""
    from zswarm.args import counted

    assert (counted(1, "node"), counted(3, "node"), counted(0, "agent")) == ("1 node", "3 nodes", "0 agents")
    assert "counted(len(self.links), 'node')" in (ROOT / "zswarm" / "cluster" / "launch.py").read_text()
    assert "*.mcap" in (ROOT / ".gitignore").read_text().split()
    assert "rerun analytics disable" in README
