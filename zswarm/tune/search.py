"""The search of ``zswarm tune``: CMA-ES (the ``cma`` package) over a :class:`~zswarm.tune.space.Space`.

Each generation CMA-ES proposes ``popsize`` points. Each is judged against the design guidelines
first (:mod:`zswarm.tune.feasibility`); one that fails is ranked by how far it fails and never
simulated, so a start outside the allowed region is walked into it. The others are simulated together
(:func:`zswarm.tune.objective.evaluate`) and ranked by the objective. ``budget`` counts simulated
candidates; the last generation simulates only what the budget leaves. Everything is recorded in a
:class:`~zswarm.tune.history.History`, which also answers for whatever a resumed search already did.
Deterministic for a given seed: CMA-ES draws from a generator seeded by it, and the simulations are
seeded by the task's seeds.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from zswarm.errors import UsageError
from zswarm.tune.feasibility import judge
from zswarm.tune.history import History
from zswarm.tune.objective import INFEASIBLE, Task, evaluate
from zswarm.tune.space import Space


@dataclass(frozen=True)
class Settings:
    budget: int  # simulated candidates
    seed: int = 0
    popsize: int | None = None  # None: CMA-ES's default, 4 + 3 ln(dimension)
    sigma0: float = 0.3  # initial step, in ln units (about 35 %)
    waived: frozenset[str] = frozenset()
    #: a search that has found nothing to simulate after this many design checks stops and says so
    max_checks_unfeasible: int = 1500
    max_checks_per_eval: int = 40  # and any search after budget x this many checks

    @property
    def cma_seed(self) -> int:
        # cma seeds numpy's legacy generator with it; 0 would mean "from the clock"
        return int(np.random.SeedSequence([self.seed, 0xC3A]).generate_state(1)[0]) % (2**31 - 1) + 1


@dataclass
class Progress:
    evaluated: int = 0
    budget: int = 0
    checked: int = 0
    rejected: int = 0
    generation: int = 0
    best: float | None = None
    started: float = field(default_factory=time.monotonic)
    computed: int = 0  # simulated in this process (not replayed from a history): what the ETA is based on

    @property
    def eta(self) -> float | None:
        """Seconds left at this process's pace (design checks and simulations together)."""
        if not self.computed:
            return None
        return (time.monotonic() - self.started) / self.computed * max(self.budget - self.evaluated, 0)


@dataclass
class SearchResult:
    records: list[dict[str, Any]]  # every candidate in the order judged
    stop: str
    progress: Progress

    @property
    def evaluated(self) -> list[dict[str, Any]]:
        return [r for r in self.records if "objective" in r]

    @property
    def closest(self) -> dict[str, Any] | None:
        """The candidate nearest to passing the design checks (for a search that found none)."""
        return min(self.records, key=lambda r: r["violation"]) if self.records else None

    @property
    def best(self) -> dict[str, Any] | None:
        """The simulated candidate with the lowest objective (the first of equals)."""
        done = self.evaluated
        return min(done, key=lambda r: r["objective"]) if done else None


def _same(a: list[float], b: np.ndarray) -> bool:
    return len(a) == len(b) and all(float(x) == float(y) for x, y in zip(a, b))


def search(space: Space, task: Task, history: History, settings: Settings,
           on_progress: Callable[[Progress], None] = lambda p: None) -> SearchResult:
    import cma

    lower, upper = space.bounds
    options = {"seed": settings.cma_seed, "bounds": [list(lower), list(upper)], "verbose": -9,
               "verb_log": 0, "verb_disp": 0, "tolfun": 0.0, "tolfunhist": 0.0, "tolflatfitness": 10**9}
    if settings.popsize:
        options["popsize"] = settings.popsize
    es = cma.CMAEvolutionStrategy(list(space.start), settings.sigma0, options)
    progress = Progress(budget=settings.budget)
    records: list[dict[str, Any]] = []
    max_checks = settings.budget * settings.max_checks_per_eval
    stop = "budget"
    gen = 0
    while True:
        if progress.evaluated >= settings.budget:
            break
        if progress.evaluated == 0 and progress.checked >= settings.max_checks_unfeasible:
            stop = f"no candidate passed the design checks in {progress.checked} tries"
            break
        if progress.checked >= max_checks:
            stop = f"design checks exhausted ({progress.checked}, {max_checks} allowed for this budget)"
            break
        if es.stop():
            stop = "CMA-ES converged: " + ", ".join(sorted(es.stop()))
            break
        xs = es.ask()
        generation = [_judged(history, space, settings, gen, slot, x, progress) for slot, x in enumerate(xs)]
        waiting = [r for r in generation if r["feasible"] and "objective" not in r]
        room = settings.budget - progress.evaluated - sum("objective" in r for r in generation)
        todo = waiting[:max(room, 0)]
        if todo:
            results = evaluate(task, [space.params(np.array(r["x"])) for r in todo])
            progress.computed += len(todo)
            for r, (value, outcomes, reasons) in zip(todo, results):
                r.update(objective=float(value), runs=[{**o.to_dict(), "seed": s, "disqualified": why}
                                                for o, s, why in zip(outcomes, task.seeds, reasons)])
                history.add(r)
        records += generation
        progress.evaluated += sum("objective" in r for r in generation)
        progress.generation = gen + 1
        scored = [r["objective"] for r in records if "objective" in r]
        progress.best = min(scored) if scored else None
        on_progress(progress)
        if len(todo) < len(waiting):
            break  # the budget ran out inside this generation: it cannot be told to CMA-ES
        es.tell(xs, [r.get("objective", INFEASIBLE + r["violation"]) for r in generation])
        gen += 1
    return SearchResult(records, stop, progress)


def _judged(history: History, space: Space, settings: Settings, gen: int, slot: int, x: np.ndarray,
            progress: Progress) -> dict[str, Any]:
    """The design verdict of one candidate, from the history when it has it."""
    progress.checked += 1
    old = history.get(gen, slot)
    if old is not None:
        if not _same(old["x"], x):
            raise UsageError(f"{history.path} does not belong to this search (generation {gen} differs); "
                             "give another --out")
        progress.rejected += not old["feasible"]
        return dict(old)
    verdict = judge(space.params(x), settings.waived)
    record = {"gen": gen, "slot": slot, "x": [float(v) for v in x], "values": space.values(x),
              "violation": verdict.violation, "failures": list(verdict.failures),
              "feasible": verdict.violation == 0.0}
    progress.rejected += not record["feasible"]
    history.add(record)
    return record
