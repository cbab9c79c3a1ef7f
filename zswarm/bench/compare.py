"""``zswarm bench net --compare REF``: this tree's agents against a git ref's, run alternately on the
same machine in the same hour, each figure a median over the runs (docs/benchmarks.md)."""

from __future__ import annotations

import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any, Callable

from zswarm.errors import UsageError

#: The figures compared: (label, how to read it from one run of ``bench net --json``, its format).
FIGURES: tuple[tuple[str, Callable[[dict[str, Any]], Any], str], ...] = (
    ("agent CPU per tick (ms)", lambda r: r["cpu_ms_per_tick_agent"], ".3f"),
    ("pose latency p50 (ms)", lambda r: r["latency_ms"]["p50"], ".2f"),
    ("pose latency p99 (ms)", lambda r: r["latency_ms"]["p99"], ".2f"),
    ("startup (s)", lambda r: r["startup_s"], ".2f"),
    ("PSS per agent (MB)", lambda r: r["pss_mb_per_agent"], ".2f"),
    ("ticks on time", lambda r: r["on_time_ratio"], ".4f"),
)


#: The clone this package runs from: this tree's side of a comparison, and where the ref is checked out from.
HERE = Path(__file__).resolve().parents[2]


def checkout(ref: str, folder: Path, repo: Path = HERE) -> str:
    """``ref`` checked out (detached) in ``folder``, from ``repo``; returns its commit. UsageError in one
    line where there is no repository or no such ref."""
    found = subprocess.run(["git", "-C", str(repo), "rev-parse", "--verify", "--quiet", f"{ref}^{{commit}}"],
                           capture_output=True, text=True)
    if found.returncode != 0:
        where = "is no git checkout" if not (repo / ".git").exists() else f"has no commit {ref!r}"
        raise UsageError(f"--compare {ref}: {repo} {where} (--compare needs zswarm installed from a clone)")
    commit = found.stdout.strip()
    subprocess.run(["git", "-C", str(repo), "worktree", "add", "--detach", "--force", str(folder), commit],
                   check=True, capture_output=True)
    return commit


def run_at(tree: Path, argv: list[str]) -> dict[str, Any]:
    """One ``zswarm bench net --json`` of the tree at ``tree`` (this interpreter, that tree's code first)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tree), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}
    done = subprocess.run([sys.executable, "-m", "zswarm", "bench", "net", "--json", *argv], cwd=tree, env=env,
                          capture_output=True, text=True)
    if done.returncode != 0 or not done.stdout.strip():
        last = (done.stderr.strip().splitlines() or ["no output"])[-1]
        raise RuntimeError(f"bench net in {tree} exited {done.returncode}: {last}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def compare(ref: str, runs: int, argv: list[str], say: Callable[[str], None] = print) -> dict[str, Any]:
    """``runs`` alternating pairs (the ref, then this tree) of ``bench net`` with ``argv``; the medians."""
    with tempfile.TemporaryDirectory(prefix="zswarm-compare-") as tmp:
        folder = Path(tmp) / "ref"
        commit = checkout(ref, folder)
        try:
            results: dict[str, list[dict[str, Any]]] = {"ref": [], "this": []}
            for k in range(runs):
                for side, tree in (("ref", folder), ("this", HERE)):
                    results[side].append(run_at(tree, argv))
                    say(f"run {k + 1}/{runs} {side} done")
        finally:
            subprocess.run(["git", "-C", str(HERE), "worktree", "remove", "--force", str(folder)], capture_output=True)
    table = {label: {side: statistics.median(read(r) for r in rs) for side, rs in results.items()}
             for label, read, _ in FIGURES}
    return {"ref": ref, "commit": commit, "runs": runs, "medians": table,
            "each": {label: {side: [read(r) for r in rs] for side, rs in results.items()} for label, read, _ in FIGURES}}


def table(out: dict[str, Any]) -> str:
    """The comparison as a Markdown table: each figure's median at the ref and here, and each run's."""
    rows = [f"| figure | {out['ref']} ({out['commit'][:7]}) | this tree | each run (ref; this) |", "|---|---|---|---|"]
    for label, _, fmt in FIGURES:
        med, each = out["medians"][label], out["each"][label]
        runs = "; ".join(", ".join(format(v, fmt) for v in each[side]) for side in ("ref", "this"))
        rows.append(f"| {label} | {format(med['ref'], fmt)} | {format(med['this'], fmt)} | {runs} |")
    return "\n".join(rows)
