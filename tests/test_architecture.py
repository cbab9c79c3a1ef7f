"""The tree's layers, kept by a check: every import of every module goes down (or sideways where
allowed), never up, the two engines never import each other, and no module imports itself back
through others (a circle).

    cli            every command: arguments in, a report out      may import anything; no module over 150 lines
    bench          the benchmarks' measurements (net, soak, ...)   cluster, launch, ... and everything below
    cluster        a run over a Ray cluster (nodes, placement)    launch, host, net, ros, sim, tune's floor
    launch         starting and supervising runs (plan, chaos)     host, ros, net, sim and everything below
    host           starting processes: routers, the world, agents  net and everything below
    tune           searching parameter sets (zswarm tune)         sim, record, design and below
    agents, world  the two process programs                       net, ros (agents), record (world), design (world)
    sim | net      the engines: reference simulator | runtime     record (sim only), design and below
    record         Rerun recordings and figures                   design, swarm, paper
    design         the design checks (Props 1-5, swarm, body)     swarm, control, laws, paper
    swarm          scenarios, prey, faults, metrics, the tally     control, laws, paper
    control        the control step: law, filter, body             laws, paper
    laws           the law contract, the built-in laws, loading   paper
    paper          the paper's mathematics and parameters         base
    base           zswarm.errors, args, files, cache, provenance, ports,  nothing of zswarm
                   stopping, process
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import pytest

from conftest import ROOT

BASE = {"zswarm", "zswarm.errors", "zswarm.args", "zswarm.files", "zswarm.cache", "zswarm.provenance", "zswarm.ports",
        "zswarm.stopping", "zswarm.process"}
ALLOWED: dict[str, set[str]] = {
    "base": {"base"},
    "paper": {"base", "paper"},
    "laws": {"base", "paper", "laws"},
    "control": {"base", "paper", "laws", "control"},
    "swarm": {"base", "paper", "laws", "control", "swarm"},
    "design": {"base", "paper", "laws", "control", "swarm", "design"},
    "record": {"base", "paper", "swarm", "design", "record"},
    "sim": {"base", "paper", "laws", "control", "swarm", "design", "record", "sim"},
    "net": {"base", "paper", "laws", "control", "swarm", "net"},
    "ros": {"base", "paper", "control", "swarm", "ros"},
    "host": {"base", "paper", "laws", "control", "swarm", "net", "host"},
    "agents": {"base", "paper", "laws", "control", "swarm", "net", "ros", "agents"},
    "world": {"base", "paper", "laws", "control", "swarm", "design", "net", "record", "world"},
    "tune": {"base", "paper", "laws", "control", "swarm", "design", "record", "sim", "tune"},
    "launch": {"base", "paper", "laws", "control", "swarm", "design", "record", "sim", "net", "host", "ros",
               "launch"},
    "cluster": {"base", "paper", "laws", "control", "swarm", "design", "record", "sim", "net", "host", "ros",
                "launch", "cluster"},
    "bench": {"base", "paper", "laws", "control", "swarm", "design", "record", "sim", "net", "host", "launch",
              "cluster", "bench"},
    "cli": {"base", "paper", "laws", "control", "swarm", "design", "record", "sim", "net", "host", "tune", "launch",
            "cluster", "bench", "ros", "cli"},
    "api": {"base", "paper", "laws", "control", "swarm", "design", "record", "sim"},  # zswarm/__init__
}


#: The layer of a project module whose package is in no layer: the check fails on it (closed, not open).
UNLAYERED = "no layer"


def layer(module: str) -> str | None:
    """The layer of a project module (:data:`UNLAYERED` for a zswarm package missing from ALLOWED), or
    None for anything outside the project."""
    if module in BASE:
        return "base"
    top, _, rest = module.partition(".")
    if top in ("agents", "world"):
        return top
    if top != "zswarm":
        return None
    name = rest.split(".")[0]
    return name if name in ALLOWED else UNLAYERED


def imports(path: Path, module: str) -> list[tuple[int, str]]:
    """Every module ``path`` imports (at any depth: lazy imports count), resolved to full names."""
    tree = ast.parse(path.read_text(), str(path))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1] + ([base] if base else []))
            for a in node.names:  # `from zswarm.sim import simulator` imports zswarm.sim.simulator
                full = f"{base}.{a.name}"
                out.append((node.lineno, full if layer(full) is not None and _is_module(full) else base))
    return out


def _is_module(name: str) -> bool:
    rel = Path(*name.split("."))
    return (ROOT / rel).is_dir() or (ROOT / rel).with_suffix(".py").is_file()


def project_modules() -> list[tuple[str, Path]]:
    out = []
    for top in ("zswarm", "agents", "world"):
        for path in sorted((ROOT / top).rglob("*.py")):
            rel = path.relative_to(ROOT).with_suffix("")
            parts = list(rel.parts[:-1]) if rel.name == "__init__" else list(rel.parts)
            out.append((".".join(parts), path))
    return out


def violations(modules: list[tuple[str, Path]]) -> list[str]:
    bad = []
    for module, path in modules:
        own = "api" if module == "zswarm" else layer(module)
        if module == "zswarm.__main__":
            own = "cli"
        if own == UNLAYERED:
            bad.append(f"{path}: {module} is in no layer: give its package a row of ALLOWED here and of "
                       "docs/architecture.md")
            continue
        for line, target in imports(path, module):
            theirs = layer(target)
            if theirs is None or own is None:
                continue
            if theirs == UNLAYERED:
                bad.append(f"{path}:{line}: {own} imports {target}, which is in no layer")
                continue
            if theirs == "api":
                theirs = "base"
            if theirs not in ALLOWED[own]:
                bad.append(f"{path}:{line}: {own} imports {target} ({theirs})")
    return bad


def test_every_import_respects_the_layers():
    modules = project_modules()
    assert len(modules) > 40  # the check sees the whole tree
    assert violations(modules) == []


@pytest.mark.parametrize("where,line", [
    ("world/world.py", "from zswarm.sim.simulator import simulate"),
    ("zswarm/swarm/metrics.py", "from zswarm.net import messages"),
    ("zswarm/sim/simulator.py", "from zswarm.net.keys import Keys"),
    ("zswarm/net/bridge.py", "import zswarm.sim.channel"),
    ("zswarm/record/replay.py", "from zswarm.cli.replay import run_replay"),
    ("agents/agent.py", "from zswarm.record import swarm_log"),
    ("zswarm/paper/params.py", "from zswarm.cli import main"),
    ("zswarm/tune/search.py", "from zswarm.net.runspec import RunSpec"),
    ("zswarm/sim/batch.py", "from zswarm.tune.space import Space"),
    ("zswarm/launch/plan.py", "from zswarm.cli.launch import build_parser"),
    ("zswarm/launch/supervisor.py", "from zswarm.bench.net import start_routers"),
    ("zswarm/bench/net.py", "from zswarm.cli import bench_net"),
    ("zswarm/tune/pipeline.py", "from zswarm.launch.run_once import run_once"),
])
def test_the_check_catches_an_import_against_the_layers(tmp_path, where, line):
    """The same check on a copy of a module with one forbidden import added fails."""
    module = where[:-3].replace("/", ".")
    copy = tmp_path / Path(where).name
    copy.write_text((ROOT / where).read_text() + f"\n\ndef _sneaky():\n    {line}\n")
    assert violations([(module, copy)]) != []
    assert violations([(module, ROOT / where)]) == []


def test_a_package_without_a_layer_fails_the_check(tmp_path):
    """A new folder (say a swarm-of-swarms layer) that nobody gave a layer is caught, both as a module
    and as something another module imports; the same module is accepted once its package has a layer."""
    module = tmp_path / "host.py"
    module.write_text("from zswarm.host.procs import Children\n")
    assert any("zswarm.fleets.host is in no layer" in v for v in violations([("zswarm.fleets.host", module)]))
    user = tmp_path / "supervisor.py"
    user.write_text("def _start():\n    from zswarm.fleets.host import Host\n")
    assert any("which is in no layer" in v for v in violations([("zswarm.launch.supervisor", user)]))
    ALLOWED["fleets"] = {"base", "model", "net", "host", "fleets"}
    try:
        assert violations([("zswarm.fleets.host", module)]) == []
    finally:
        del ALLOWED["fleets"]


#: The most lines a command module may hold: a command reads its arguments and reports; the work is in
#: the layers below it.
CLI_MAX_LINES = 150


def oversized(paths: list[Path]) -> list[str]:
    """The command modules (zswarm/cli/) over :data:`CLI_MAX_LINES` lines."""
    return [f"{p}: {n} lines" for p in paths if (n := len(p.read_text().splitlines())) > CLI_MAX_LINES]


def circles(modules: list[tuple[str, Path]]) -> list[list[str]]:
    """Every circle of imports between project modules (lazy imports count: they only hide one), as the
    modules of each strongly connected group of more than one."""
    names = {m for m, _ in modules}
    graph = {m: sorted({t for _, t in imports(p, m) if t in names and t != m}) for m, p in modules}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    out = []

    def visit(v: str) -> None:  # Tarjan's strongly connected components
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            group = []
            while True:
                w = stack.pop()
                group.append(w)
                if w == v:
                    break
            if len(group) > 1:
                out.append(sorted(group))

    for v in graph:
        if v not in index:
            visit(v)
    return out


def cli_modules() -> list[Path]:
    return sorted((ROOT / "zswarm" / "cli").glob("*.py"))


def test_no_two_modules_import_each_other():
    assert circles(project_modules()) == []


def test_every_command_module_is_small():
    assert len(cli_modules()) > 10
    assert oversized(cli_modules()) == []


def test_the_checks_catch_a_circle_and_a_big_command(tmp_path):
    """A copy of zswarm/launch/plan.py that imports the supervisor back makes a circle; a command module
    of 151 lines is caught."""
    modules = project_modules()
    plan = tmp_path / "plan.py"
    plan.write_text((ROOT / "zswarm/launch/plan.py").read_text()
                    + "\n\ndef _back():\n    from zswarm.launch.supervisor import Launch\n")
    looped = [(m, plan if m == "zswarm.launch.plan" else p) for m, p in modules]
    assert any({"zswarm.launch.plan", "zswarm.launch.supervisor"} <= set(group) for group in circles(looped))
    big = tmp_path / "big.py"
    big.write_text("\n".join(["x = 1"] * (CLI_MAX_LINES + 1)) + "\n")
    small = tmp_path / "small.py"
    small.write_text("\n".join(["x = 1"] * CLI_MAX_LINES) + "\n")
    assert oversized([big, small]) == [f"{big}: {CLI_MAX_LINES + 1} lines"]


@pytest.mark.parametrize("modules", ["agents.main, agents.agent, agents.free", "world.main, world.world"])
def test_the_processes_do_not_import_rerun_until_they_record(modules):
    """The agent never imports Rerun, the world only when it records (a 100-agent swarm cannot carry
    tens of megabytes of it per process)."""
    import subprocess

    code = (f"import sys, {modules}; "
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('rerun', 'pyarrow')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]", out.stdout
