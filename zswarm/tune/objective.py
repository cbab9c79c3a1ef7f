"""What ``zswarm tune`` minimizes, and how a generation of candidates is simulated in one batch.

Each candidate runs on K seeds (the spawn and, under faults, the channel), all candidates and seeds of
a generation together in the batched simulator (:mod:`zswarm.sim.batch`). A run scores its capture
time, or the duration plus ``miss_penalty`` when it never catches the prey. A candidate's objective is
the mean score over its seeds, unless one of its runs is disqualified (two agents closer than 2 d^r,
an agent touching an obstacle, or coming closer to one than d_m^ro): then it ranks after every
qualified set, ordered by how many runs were disqualified. A set that fails the design checks is never
simulated and ranks after all of those (:data:`INFEASIBLE` + its violation).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from zswarm.swarm.faults import FaultModel
from zswarm.paper.params import Params
from zswarm.paper.potentials import Combination
from zswarm.swarm.scenarios import Scenario
from zswarm.sim.batch import Member, simulate_batch
from zswarm.swarm.tally import Outcome

INFEASIBLE = 1e6


@dataclass(frozen=True)
class Task:
    """The runs every candidate is judged on."""

    scenario: Scenario
    seeds: tuple[int, ...]
    faults: FaultModel = FaultModel()
    combination: Combination | None = None
    miss_penalty: float = 30.0
    safety: str = "off"  # apf: its guidelines keep it apart; another law runs behind the filter, as it is deployed

    @property
    def steps(self) -> int:
        return self.scenario.steps

    @property
    def duration(self) -> float:
        return self.scenario.steps * self.scenario.dt

    def members(self, params: Params, seeds: tuple[int, ...] | None = None) -> list[Member]:
        scenario = self.scenario.with_params(params)
        return [Member(scenario, s, dataclasses.replace(self.faults, seed=s) if self.faults.active else None,
                       self.combination, self.safety) for s in (seeds or self.seeds)]


def disqualified(collisions: int, contacts: int, clearance: float | None, params: Params) -> str | None:
    """Why a run does not count (a simulated or a distributed one), or None."""
    if collisions:
        return f"{collisions} collision(s)"
    if contacts:
        return f"{contacts} obstacle contact(s)"
    if clearance is not None and clearance < params.margins.d_m_ro:
        return f"clearance {clearance:.3g} < d_m^ro = {params.margins.d_m_ro:g}"
    return None


def run_score(outcome: Outcome, task: Task) -> float:
    """Capture time, or the duration plus the miss penalty."""
    return outcome.capture_time if outcome.capture_time is not None else task.duration + task.miss_penalty


def objective(outcomes: list[Outcome], params: Params, task: Task) -> tuple[float, list[str | None]]:
    """(objective, disqualification of each run); see the module doc."""
    reasons = [disqualified(o.collisions, o.obstacle_collisions, o.min_obstacle_clearance, params) for o in outcomes]
    bad = sum(r is not None for r in reasons)
    if bad:
        worst = task.duration + task.miss_penalty
        return 10.0 * worst + bad / len(outcomes), reasons
    return sum(run_score(o, task) for o in outcomes) / len(outcomes), reasons


def evaluate(task: Task, candidates: list[Params], seeds: tuple[int, ...] | None = None
             ) -> list[tuple[float, list[Outcome], list[str | None]]]:
    """Simulate every candidate on every seed in one batch; (objective, outcomes, reasons) each."""
    if not candidates:
        return []
    seeds = seeds or task.seeds
    members = [m for params in candidates for m in task.members(params, seeds)]
    outcomes = simulate_batch(members, task.steps).outcomes
    k = len(seeds)
    out = []
    for c, params in enumerate(candidates):
        mine = outcomes[c * k:(c + 1) * k]
        value, reasons = objective(mine, params, task)
        out.append((value, mine, reasons))
    return out


def describe() -> dict[str, Any]:
    """The objective in words, for the tune's result."""
    return {"objective": {"definition": "mean over the tuning seeds of the capture time (duration + miss penalty when the prey "
                         "is not caught)",
            "disqualifies": "any collision (agents closer than 2 d^r), obstacle contact, or clearance below d_m^ro",
            "rejects": "any set that fails zswarm design (Props 1-5, formation, contact, swarm squeeze) is "
                        "never simulated"}}
