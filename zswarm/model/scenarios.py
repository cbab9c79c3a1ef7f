"""The registered scenarios (``zswarm scenarios``), scenarios from TOML files
(:func:`load_scenario_file`, format in docs/simulation.md), and :func:`get_scenario`, which builds
either with parameter overrides. What a scenario is: :mod:`zswarm.model.scenario`."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Callable

import numpy as np

from zswarm.errors import UsageError
from zswarm.files import read_toml
from zswarm.model.params import DEFAULT_PARAMS, ParamError, validate
from zswarm.model.prey import PreyMotion
from zswarm.model.scenario import Box, Obstacle, Scenario, spawn_positions

__all__ = ["SCENARIOS", "Box", "Obstacle", "Scenario", "get_scenario", "load_scenario_file", "spawn_positions"]


def goal_near_obstacle() -> Scenario:
    angles = np.linspace(0.0, 2.0 * np.pi, 9)[:-1] + np.pi / 8
    starts = tuple((float(1.2 * math.cos(a)), float(1.2 * math.sin(a))) for a in angles)
    return Scenario(
        name="goal-near-obstacle",
        description="Figs 3-6: goal (0,0) beside a point obstacle at (-0.1,0); 8 agents around it move "
                    "on their own (no formation term). Additive: trapped; multiplicative: reach the goal.",
        params=DEFAULT_PARAMS.with_values({"n_agents": 8}),
        obstacles=(Obstacle(-0.1, 0.0, 0.0),),
        starts=starts, duration=40.0, formation=False, capture_radius=0.2,
    )


#: Fig 13's obstacles are not given in the text. This layout puts a large obstacle on the swarm's
#: straight path to the goal and two smaller ones off its flanks, nearer the goal: the swarm splits to
#: pass the large one and the two streams thread between the three before they meet at the goal.
FIG13_OBSTACLES = (Obstacle(-1.6, 0.0, 0.5), Obstacle(-0.6, 1.3, 0.25), Obstacle(-0.6, -1.3, 0.25))
#: Fig 14 (moving target): the two flank obstacles only. With the large blocker the prey, which
#: circles near the goal, often pulls the swarm into the blocker's shadow, where it waits (Remark 1).
FIG14_OBSTACLES = FIG13_OBSTACLES[1:]
#: Local sensing: a radius below the gap the large obstacle opens, so the two streams lose sight of
#: each other (the split) and meet again at the goal (the regroup).
FIG13_SENSING_RADIUS = 0.9


def static_goal() -> Scenario:
    return Scenario(
        name="static-goal",
        description="Fig 13: 10 agents spawned left of x=-2 reach a static goal at (0,0) through "
                    "circular obstacles; the swarm splits to pass them and regroups at the goal.",
        params=DEFAULT_PARAMS.with_values({"sensing_radius": FIG13_SENSING_RADIUS}),
        obstacles=FIG13_OBSTACLES, spawn=(-4.0, -1.2, -2.6, 1.2), duration=60.0,
    )


def moving_prey_blocked() -> Scenario:
    """Fig 14's layout with the large blocking obstacle kept (the three obstacles of Fig 13)."""
    return Scenario(
        name="moving-prey-blocked",
        description="Fig 14 with the blocker: the prey circles near (0.5, 0) behind a large obstacle on the "
                    "swarm's way and two flank obstacles; 10 agents from left of x=-2 split, pass and regroup.",
        params=DEFAULT_PARAMS.with_values({"sensing_radius": 1.0}),
        obstacles=FIG13_OBSTACLES, spawn=(-4.0, -1.2, -2.6, 1.2),
        prey=PreyMotion(kind="circle", speed=0.15, center=(0.5, 0.0), radius=0.5), duration=60.0,
    )


def moving_prey(kind: str = "circle") -> Callable[[], Scenario]:
    motions = {
        "circle": PreyMotion(kind="circle", speed=0.15, center=(0.5, 0.0), radius=0.5),
        "straight": PreyMotion(kind="straight", speed=0.1, heading_deg=90.0),
        "evasive": PreyMotion(kind="evasive", speed=0.2, sense_radius=1.0, bounds=(-5.0, -3.0, 3.0, 3.0)),
    }

    def make() -> Scenario:
        return Scenario(
            name="moving-prey" if kind == "circle" else f"moving-prey-{kind}",
            description=f"Fig 14: the prey starts at (0,0) and moves ({kind}) slower than v_max; "
                        "10 agents from left of x=-2 chase it between two obstacles.",
            params=DEFAULT_PARAMS.with_values({"sensing_radius": 1.0}),
            obstacles=FIG14_OBSTACLES, spawn=(-4.0, -1.2, -2.6, 1.2), prey=motions[kind], duration=60.0,
        )

    return make


def narrow_passage() -> Scenario:
    return Scenario(
        name="narrow-passage",
        description="Two close obstacles with a gap narrower than twice d_0^ro on the way to the goal: "
                    "the second local-minimum case the paper names (Section 3.2).",
        params=DEFAULT_PARAMS.with_values({"n_agents": 5, "sensing_radius": 1.5}),
        obstacles=(Obstacle(-1.0, 0.45, 0.2), Obstacle(-1.0, -0.45, 0.2)),
        spawn=(-3.5, -0.5, -2.5, 0.5), duration=40.0,
    )


def large_swarm(n_agents: int = 300) -> Scenario:
    """Hundreds of agents crossing an obstacle field; the area grows with N (constant density)."""
    density = 1.5  # agents per unit area at spawn
    side = math.sqrt(n_agents / density)
    rng = np.random.default_rng(20061)  # the obstacle layout is part of the scenario, not the run
    n_obs = max(3, n_agents // 20)
    xs = rng.uniform(0.5, 0.5 + side, n_obs)
    ys = rng.uniform(-side / 2, side / 2, n_obs)
    obstacles = tuple(Obstacle(float(x), float(y), 0.3) for x, y in zip(xs, ys))
    params = DEFAULT_PARAMS.with_values({"n_agents": n_agents, "sensing_radius": 1.5, "l_g": side,
                                         "c_g": side / 2.0})
    params = params.with_values({"c_o": 3.0 * params.potential.c_g})
    return Scenario(
        name="large-swarm",
        description="A large swarm (N from --set n_agents) crossing a field of obstacles to a goal on "
                    "the far side; spawn area and obstacle field grow with N.",
        params=params, obstacles=obstacles, prey_start=(1.0 + 1.5 * side, 0.0),
        spawn=(-side, -side / 2, 0.0, side / 2), duration=40.0,
    )


def bench_field(n_agents: int = 50) -> Scenario:
    """Transport benchmark: agents spread at constant density (0.5 per unit area) over a square that
    grows with N, sensing radius 1; the prey is far away, so each agent only keeps its formation."""
    side = math.sqrt(n_agents / 0.5)
    return Scenario(
        name="bench-field",
        description="Transport benchmark: N agents at constant density, prey out of reach.",
        params=DEFAULT_PARAMS.with_values({"n_agents": n_agents, "sensing_radius": 1.0}),
        prey_start=(1000.0, 0.0), spawn=(-side / 2, -side / 2, side / 2, side / 2), duration=15.0,
    )


SCENARIOS: dict[str, Callable[[], Scenario]] = {
    "goal-near-obstacle": goal_near_obstacle,
    "static-goal": static_goal,
    "moving-prey": moving_prey("circle"),
    "moving-prey-straight": moving_prey("straight"),
    "moving-prey-evasive": moving_prey("evasive"),
    "moving-prey-blocked": moving_prey_blocked,
    "narrow-passage": narrow_passage,
    "large-swarm": large_swarm,
    "bench-field": bench_field,
}


def get_scenario(name: str, overrides: dict[str, Any] | None = None) -> Scenario:
    """A registered scenario (or a TOML file path), with parameter overrides applied.

    For ``large-swarm`` an ``n_agents`` override rebuilds the scenario at that size.
    """
    try:  # checked before anything is built from them (large-swarm grows with n_agents)
        overrides = {k: validate(k, v) for k, v in (overrides or {}).items()}
    except ParamError as exc:
        raise UsageError(str(exc)) from None
    if name.endswith(".toml"):
        scenario = load_scenario_file(Path(name))
    elif name in SCENARIOS:
        if name in ("large-swarm", "bench-field") and "n_agents" in overrides:
            scenario = (large_swarm if name == "large-swarm" else bench_field)(int(overrides["n_agents"]))
        else:
            scenario = SCENARIOS[name]()
    else:
        raise UsageError(f"unknown scenario {name!r}; known: {', '.join(SCENARIOS)} (or a .toml file)")
    if scenario.starts and "n_agents" in overrides:
        raise UsageError(f"scenario {scenario.name} has fixed start positions; n_agents cannot be set")
    try:
        return scenario.with_params(scenario.params.with_values(overrides))
    except ValueError as exc:
        raise UsageError(str(exc)) from None


_TOP_KEYS = {"name", "description", "params", "obstacles", "prey_start", "prey", "spawn", "starts",
             "duration", "dt", "combination", "formation", "capture_radius"}


def load_scenario_file(path: Path) -> Scenario:
    """Read a scenario from TOML (see README); every mistake is a one-line :class:`UsageError`."""
    data = read_toml(path, "scenario file")
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise UsageError(f"scenario file {path}: unknown keys {sorted(unknown)}; allowed: {sorted(_TOP_KEYS)}")
    try:
        kw: dict[str, Any] = {k: v for k, v in data.items() if k not in {"params", "obstacles", "prey"}}
        kw.setdefault("name", Path(path).stem)
        kw.setdefault("description", f"loaded from {path}")
        for key in ("prey_start", "spawn"):
            if key in kw:
                kw[key] = tuple(float(v) for v in kw[key])
        if "starts" in kw:
            kw["starts"] = tuple((float(x), float(y)) for x, y in kw["starts"])
        kw["params"] = DEFAULT_PARAMS.with_values(data.get("params", {}))
        kw["obstacles"] = tuple(Obstacle(float(o["x"]), float(o["y"]), float(o.get("radius", 0.0)))
                                for o in data.get("obstacles", []))
        prey = dict(data.get("prey", {}))
        for key in ("center", "bounds"):
            if key in prey:
                prey[key] = tuple(float(v) for v in prey[key])
        kw["prey"] = PreyMotion(**prey)
        return Scenario(**kw)
    except ParamError as exc:
        raise UsageError(f"scenario file {path}: {exc}") from None
    except (TypeError, ValueError, KeyError) as exc:
        raise UsageError(f"scenario file {path}: {exc}") from None
