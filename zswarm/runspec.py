"""What every process of a run must agree on: run id, scenario, seed, parameters, clock and pace.

The world and every agent are started with the same ``--run --scenario --seed --set ...``; each
derives what it needs (an agent: its own start position and the control law; the world: obstacles,
prey, metrics) from that, so no process hands another its state.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass

from zswarm.cli_util import UsageError, add_param_args
from zswarm.faults import FaultModel, parse_duration
from zswarm.params import parse_assignments
from zswarm.potentials import COMBINATIONS, Combination
from zswarm.scenarios import Scenario, get_scenario
from zswarm.transport import Keys, check_run_id

CLOCKS = ("free", "lockstep")


def add_run_args(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("run")
    group.add_argument("--run", default="demo", help="run id: namespaces every key (default demo)")
    group.add_argument("--scenario", default="moving-prey", help="scenario name or .toml file")
    group.add_argument("--seed", type=int, default=0, help="random seed of the run (default 0)")
    add_param_args(group)
    group.add_argument("--potential", choices=COMBINATIONS, default=None,
                       help="obstacle-goal combination (default: the scenario's)")
    group.add_argument("--clock", choices=CLOCKS, default="free",
                       help="free: each agent on its own timer; lockstep: the world ticks (default free)")
    group.add_argument("--time-scale", type=float, default=1.0,
                       help="simulated seconds per wall second in free mode (default 1: dt=0.05 s at 20 Hz)")
    add_fault_args(parser)


def add_fault_args(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("faults (applied by every receiving agent, seeded by --seed)")
    group.add_argument("--latency", default="0", help="fixed delay of every incoming message, e.g. 100ms")
    group.add_argument("--jitter", default="0", help="uniform jitter around the delay, e.g. 20ms")
    group.add_argument("--dropout", type=float, default=0.0, help="loss probability in [0, 1)")
    group.add_argument("--burst", type=float, default=0.0,
                       help="mean loss-burst length (Gilbert-Elliott); 0: independent losses")
    group.add_argument("--distance-loss", type=float, default=0.0,
                       help="pose loss probability at the sensing radius, growing with distance squared")


def faults_from_args(args: argparse.Namespace) -> FaultModel:
    try:
        return FaultModel(latency=parse_duration(args.latency), jitter=parse_duration(args.jitter),
                          dropout=args.dropout, burst=args.burst, distance_loss=args.distance_loss,
                          seed=args.seed)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


@dataclass(frozen=True)
class RunSpec:
    run: str
    scenario: Scenario
    seed: int
    combination: Combination
    clock: str
    time_scale: float
    faults: FaultModel = FaultModel()

    @property
    def keys(self) -> Keys:
        return Keys(self.run, cell_size=self.scenario.params.swarm.sensing_radius)

    @property
    def period(self) -> float:
        """Wall seconds between control ticks in free mode."""
        return self.scenario.dt / self.time_scale


def spec_from_args(args: argparse.Namespace) -> RunSpec:
    if not (args.time_scale > 0 and args.time_scale < 1e3):
        raise UsageError(f"--time-scale must be in (0, 1000) (got {args.time_scale})")
    scenario = get_scenario(args.scenario, parse_assignments(args.assignments))
    return RunSpec(run=check_run_id(args.run), scenario=scenario, seed=args.seed,
                   combination=args.potential or scenario.combination, clock=args.clock,
                   time_scale=args.time_scale, faults=faults_from_args(args))
