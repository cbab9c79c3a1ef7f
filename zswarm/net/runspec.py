"""One specification of a run: what every process of it must agree on, parsed and written in one place.

The world and every agent are started with the same run arguments (``--run --scenario --seed --set
... --clock --time-scale --duration`` and the faults); each derives what it needs from them (an agent:
its own start position and the control law; the world: obstacles, prey, metrics), so no process hands
another its state. :func:`add_run_args` declares those arguments (for every program, ``zswarm run``
included), :func:`spec_from_args` is the only place that reads them, and :meth:`RunSpec.to_argv` the
only place that writes a spec back into a child's command line:
``spec_from_args(parse(spec.to_argv())) == spec`` for every valid spec.
"""

from __future__ import annotations

import argparse
import math
import dataclasses
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, Literal

from zswarm.args import add_law_arg, add_param_args, loss_probability, safety_mode_arg, seed_arg, sim_seconds
from zswarm.errors import UsageError
from zswarm.swarm.faults import FaultModel, parse_duration
from zswarm.paper.neighbours import subscription_radius
from zswarm.paper.params import parse_assignments
from zswarm.paper.potentials import COMBINATIONS, Combination
from zswarm.control.safety import MODES
from zswarm.swarm.scenarios import Scenario, get_scenario
from zswarm.net.keys import Keys, check_run_id

#: An agent leaves once nothing (prey, ticks) has come from its world for this long after its clock started
#: (``--world-timeout``; a world still waiting for its agents sends nothing): the world ended or died and
#: no final tick reached it. A world fault the launcher stages is shorter.
WORLD_SILENT_S = 30.0
#: Zenoh's lease: a process silent this long is taken for gone by its router, and its liveliness token goes
#: (a pause shorter than this is a pause: docs/experiments.md). An agent gives up a robot silent as long.
LEASE_S = 10.0

Clock = Literal["free", "lockstep"]
CLOCKS: tuple[Clock, ...] = ("free", "lockstep")
DEFAULT_RUN = "demo"


@dataclass(frozen=True)
class RunSpec:
    """A run: its id, the scenario (a registered name or a .toml path) with parameter overrides, the
    seed, the obstacle-goal combination (None: the scenario's), the clock and pace, the duration
    (None: the scenario's) and the injected faults (seeded by the run's seed)."""

    run: str = DEFAULT_RUN
    scenario_name: str = "moving-prey"
    overrides: tuple[tuple[str, float | int | str], ...] = ()
    seed: int = 0
    potential: Combination | None = None
    clock: Clock = "free"
    time_scale: float = 1.0
    duration: float | None = None
    faults: FaultModel = field(default_factory=FaultModel)
    safety: str = "barrier"

    def __post_init__(self) -> None:
        check_run_id(self.run)
        if self.safety not in MODES:
            raise UsageError(f"--safety must be one of {', '.join(MODES)} (got {self.safety!r})")
        if not isinstance(self.seed, int) or not 0 <= self.seed < 2**63:
            raise UsageError(f"--seed must be an integer in [0, 2^63) (got {self.seed!r})")
        if self.clock not in CLOCKS:
            raise UsageError(f"--clock must be one of {', '.join(CLOCKS)} (got {self.clock!r})")
        if self.potential is not None and self.potential not in COMBINATIONS:
            raise UsageError(f"--potential must be one of {', '.join(COMBINATIONS)} (got {self.potential!r})")
        if not 0 < self.time_scale < 1e3:
            raise UsageError(f"--time-scale must be in (0, 1000) (got {self.time_scale})")
        if self.duration is not None and not 0 < self.duration < float("inf"):
            raise UsageError(f"--duration must be a finite number > 0 (got {self.duration})")
        if self.faults.seed != self.seed:
            object.__setattr__(self, "faults", dataclasses.replace(self.faults, seed=self.seed))
        object.__setattr__(self, "overrides", tuple(sorted(dict(self.overrides).items())))

    @cached_property
    def scenario(self) -> Scenario:
        return get_scenario(self.scenario_name, dict(self.overrides))

    @property
    def combination(self) -> Combination:
        return self.potential or self.scenario.combination

    @property
    def keys(self) -> Keys:
        return Keys(self.run, cell_size=self.scenario.params.swarm.sensing_radius, dims=self.scenario.dimensions)

    @property
    def subscription_radius(self) -> float:
        """R + 2 v_max dt: an agent listens to the cells this disc about it meets, so whoever can
        enter its sensing disc by the next step is already heard."""
        swarm = self.scenario.params.swarm
        return subscription_radius(swarm.sensing_radius, swarm.v_max, self.scenario.dt)

    @property
    def period(self) -> float:
        """Wall seconds between control ticks in free mode."""
        return self.scenario.dt / self.time_scale

    @property
    def steps(self) -> int:
        """World ticks in the run (after the initial one)."""
        return int(round((self.duration if self.duration is not None else self.scenario.duration)
                         / self.scenario.dt))

    def with_overrides(self, **values: float | int) -> RunSpec:
        return dataclasses.replace(self, overrides=(*self.overrides, *values.items()))

    def describe(self) -> dict[str, Any]:
        """What the run was asked to do, as plain data (the recording's ``run/config``)."""
        return {"run": self.run, "scenario": self.scenario.name, "seed": self.seed, "potential": self.combination,
                "clock": self.clock, "time_scale": self.time_scale, "n_agents": self.scenario.n_agents,
                "duration": self.steps * self.scenario.dt, "faults": self.faults.requested(), "safety": self.safety,
                "scenario_definition": self.scenario.to_dict()}

    def to_argv(self) -> list[str]:
        """The run arguments that :func:`spec_from_args` turns back into this spec."""
        out = ["--run", self.run, "--scenario", self.scenario_name, "--seed", str(self.seed),
               "--clock", self.clock, "--time-scale", repr(self.time_scale), "--safety", self.safety]
        for name, value in self.overrides:
            out += ["--set", f"{name}={value}" if isinstance(value, str) else f"{name}={value!r}"]
        if self.potential is not None:
            out += ["--potential", self.potential]
        if self.duration is not None:
            out += ["--duration", repr(self.duration)]
        f = self.faults
        out += ["--latency", f"{f.latency!r}s", "--jitter", f"{f.jitter!r}s", "--dropout", repr(f.dropout),
                "--burst", repr(f.burst), "--distance-loss", repr(f.distance_loss)]
        return out


def add_run_args(parser: argparse.ArgumentParser, run_help: str = f"run id: namespaces every key "
                 f"(default {DEFAULT_RUN})") -> None:
    group = parser.add_argument_group("run")
    group.add_argument("--run", default=None, help=run_help)
    group.add_argument("--scenario", default="moving-prey", help="scenario name or .toml file (default moving-prey)")
    group.add_argument("--seed", type=seed_arg, default=0, help="random seed of the run (default 0)")
    add_param_args(group)
    add_law_arg(group)
    group.add_argument("--potential", choices=COMBINATIONS, default=None,
                       help="obstacle-goal combination (default: the scenario's)")
    group.add_argument("--clock", choices=CLOCKS, default="free",
                       help="free: each agent on its own timer; lockstep: the world ticks (default free)")
    group.add_argument("--time-scale", type=time_scale_arg, default=1.0,
                       help="simulated seconds per wall second in free mode (default 1: dt=0.05 s at 20 Hz; "
                            "zswarm run: auto, the pace this machine can hold)")
    group.add_argument("--duration", type=sim_seconds, default=None,
                       help="simulated time, e.g. 30 or 30s, 2min (default: the scenario's)")
    add_safety_arg(group)
    add_fault_args(parser)


def time_scale_arg(text: str) -> float | str:
    """A number, or ``auto`` (``zswarm run`` only: the launcher picks the pace, :mod:`zswarm.launch.plan`)."""
    if text.strip() == "auto":
        return "auto"
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"a number of simulated seconds per wall second, or auto (got {text!r})")


def time_scale_number(text: str) -> float:
    """``--time-scale`` where a command takes a number only (no ``auto``)."""
    value = time_scale_arg(text)
    if value == "auto" or not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a number of simulated seconds per wall second > 0, got {text!r}")
    return value


time_scale_arg.meaning = time_scale_number.meaning = "simulated seconds per wall second"  # type: ignore[attr-defined]


def add_fault_args(parser: argparse.ArgumentParser) -> None:
    group = parser.add_argument_group("faults (applied by every receiving agent, seeded by --seed)")
    group.add_argument("--latency", default="0", help="fixed delay of every incoming message, e.g. 100ms or 0.1s (a unit is required but for 0)")
    group.add_argument("--jitter", default="0", help="uniform jitter around the delay, e.g. 20ms (a unit is required but for 0)")
    group.add_argument("--dropout", type=loss_probability, default=0.0, help="loss probability in [0, 1)")
    group.add_argument("--burst", type=float, default=0.0,
                       help="mean loss-burst length (Gilbert-Elliott); 0: independent losses")
    group.add_argument("--distance-loss", type=float, default=0.0,
                       help="pose loss probability at the sensing radius, growing with distance squared")


def add_safety_arg(parser) -> None:
    parser.add_argument("--safety", type=safety_mode_arg, default=None, metavar="off|barrier",
                        help="barrier: every command passes the safety filter, robust to the age of each "
                             "neighbour's data (docs/safety.md); off: the law alone (default barrier)")


def safety_mode(asked: str | None) -> str:
    """The filter a run uses: as asked, or barrier (every body has its rows: docs/safety.md)."""
    return asked or "barrier"


def faults_from_args(args: argparse.Namespace) -> FaultModel:
    try:
        return FaultModel(latency=parse_duration(args.latency), jitter=parse_duration(args.jitter),
                          dropout=args.dropout, burst=args.burst, distance_loss=args.distance_loss,
                          seed=args.seed)
    except ValueError as exc:
        raise UsageError(str(exc)) from None


def spec_from_args(args: argparse.Namespace, run: str | None = None, extra: dict[str, float | int] | None = None
                   ) -> RunSpec:
    """The spec the parsed run arguments describe; ``run`` stands in for a missing ``--run`` and
    ``extra`` adds overrides (e.g. ``zswarm run --agents N``). The scenario is built here, so every
    mistake in it is reported before anything starts."""
    overrides = {**parse_assignments(args.assignments), **(extra or {})}
    if args.time_scale == "auto":
        raise UsageError("--time-scale auto is for zswarm run, which picks the pace; give a number here")
    spec = RunSpec(run=args.run or run or DEFAULT_RUN, scenario_name=args.scenario,
                   overrides=tuple(overrides.items()), seed=args.seed, potential=args.potential, clock=args.clock,
                   time_scale=args.time_scale, duration=args.duration, faults=faults_from_args(args),
                   safety=safety_mode(getattr(args, "safety", None)))
    spec.scenario  # noqa: B018 - built now: a mistake in it is said before anything starts
    return spec
