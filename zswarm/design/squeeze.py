"""A swarm squeezed against an obstacle (Fig 10): a brute-force check of what Props 4 and 5 promise.

Props 3-5 reason about one pair, or bound forces one at a time. A swarm adds up N - 1 attractions on
every agent, and the goal's pull presses the whole swarm against an obstacle that lies on its way
(Fig 10, the case Prop 4 is about). With soft (bounded) repulsion the sum can squeeze neighbours far
closer than the pair spacing d^f, or onto each other. This module runs exactly that case with the full
control law (eq 36, speed limit, sensing radius, interaction): N agents start in a disc (in 3-D, a ball) 1 behind a
point obstacle that sits on the straight line to a static goal, where the goal pulls hardest
(l_g/sqrt2 from it, at least 1), and it records the closest any two agents and any agent and the
obstacle come during the run.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from functools import lru_cache

import numpy as np

from zswarm.cache import kept
from zswarm.control.step import BodyState, Stepped, control_step
from zswarm.laws.contract import Observations
from zswarm.paper.neighbours import ObstacleIndex, pairs_within
from zswarm.paper.params import Params
from zswarm.swarm.prey import PreyMotion
from zswarm.swarm.scenario import Obstacle, Scenario
from zswarm.swarm.tally import OutcomeTally, Sensed, drive


@dataclass(frozen=True)
class Squeeze:
    n_agents: int
    min_pair_distance: float  # over the whole run
    min_obstacle_distance: float  # over the whole run
    final_median_nearest: float
    final_groups: int  # groups of the sensing graph at the end


def _disc(n: int, spacing: float) -> np.ndarray:
    """``n`` points evenly filling a disc of radius spacing sqrt(n)/1.5 (Vogel's sunflower spiral: no two
    closer than about 0.9 spacing), so no pair starts in contact."""
    k = np.arange(n) + 0.5
    radius = spacing * math.sqrt(n) / 1.5
    r, theta = radius * np.sqrt(k / n), k * math.pi * (3.0 - math.sqrt(5.0))
    return np.column_stack([r * np.cos(theta), r * np.sin(theta)])


def _ball(n: int, spacing: float) -> np.ndarray:
    """``n`` points filling a ball at about ``spacing`` apart: a cubic lattice of that pitch, the ``n``
    nearest its centre (the 3-D counterpart of :func:`_disc`)."""
    side = int(math.ceil(n ** (1.0 / 3.0))) + 2
    axis = spacing * (np.arange(side) - (side - 1) / 2.0)
    grid = np.stack(np.meshgrid(axis, axis, axis, indexing="ij"), axis=-1).reshape(-1, 3)
    order = np.argsort(np.einsum("ij,ij->i", grid, grid), kind="stable")
    return grid[order[:n]]


def squeeze_scenario(params: Params, n: int, seed: int = 2006, duration: float = 60.0, dt: float = 0.05) -> Scenario:
    """The squeeze as a scenario: ``n`` agents of the set (the paper's law, multiplicative, in point
    bodies) in a disc (a ball) 1 behind a point obstacle on the line to a static goal at the origin, where
    the goal pulls hardest (|psi_g| = l_g/sqrt2, eq 8's peak; at least 1 away): the press of Fig 10 at its
    strongest, whatever the goal's range."""
    reach = max(1.0, params.potential.l_g / math.sqrt(2.0))
    if params.swarm.dimensions == 2:
        x = _disc(n, 0.5) + np.array([-reach - 1.0 - 0.5 * math.sqrt(n) / 1.5, 0.0])
    else:
        x = _ball(n, 0.5) + np.array([-reach - 1.0 - 0.5 * math.ceil(n ** (1.0 / 3.0)) / 2.0, 0.0, 0.0])
    x = x + np.random.default_rng(seed).uniform(-0.02, 0.02, x.shape)  # no exact symmetry
    own = params.with_values({"n_agents": n, "law": "apf", "body": "point", "groups": ""})
    d = params.swarm.dimensions
    return Scenario("squeeze", "a swarm pressed against an obstacle by the goal (Fig 10)", own,
                    (Obstacle(-reach, 0.0),), (0.0,) * d, PreyMotion("static"), (-1.0,) * d + (1.0,) * d,
                    tuple(map(tuple, x)), duration, dt, "multiplicative", True, 1e-9)


class _Pressed:
    """The squeeze stepped through the one control step and loop (:class:`zswarm.swarm.tally.Engine`,
    a batch of one), every agent sensing exactly."""

    def __init__(self, scenario: Scenario) -> None:
        self.scenario, self.dt, self.step_index = scenario, scenario.dt, 0
        self.control = control_step([scenario])
        x = np.array(scenario.starts, dtype=float)
        self.state = BodyState(x[None], np.zeros_like(x)[None], np.full((1, len(x)), np.nan))
        self.obstacles = ObstacleIndex(*scenario.obstacle_arrays(), scenario.params.swarm.sensing_radius)
        self.prey = np.zeros((1, len(x[0])))
        self._found: tuple | None = None

    @property
    def positions(self) -> np.ndarray:
        return self.state.position

    def _near(self) -> tuple[np.ndarray, ...]:
        """(i, j) within the sensing radius and the sensed obstacles (agent, obstacle), once a step."""
        key, x = self.state.position, self.state.position[0]
        if self._found is None or self._found[0] is not key:
            self._found = (key, *pairs_within(x, self.scenario.params.swarm.sensing_radius), *self.obstacles.sensed(x))
        return self._found[1:]

    def command(self) -> Stepped:
        x, v = self.state.position[0], self.state.velocity[0]
        i, j, a, m = self._near()
        obs = Observations.of_swarm(x, v, np.zeros_like(x), self.scenario.params.swarm.v_max, self.dt,
                                    np.zeros((len(x), 0)), (i, j), (a, self.obstacles.centers[m], self.obstacles.radii[m]),
                                    velocities=self.control.hears_velocities)
        return self.control(obs, None, self.state)

    def advance(self, stepped: Stepped) -> None:
        self.state, self.step_index = stepped.state, self.step_index + 1

    def sensed(self) -> Sensed:
        return Sensed.of_pairs(self.state.position[0], *self._near(), self.obstacles)

    def safety_counts(self) -> np.ndarray:
        return np.zeros((1, 3), dtype=np.int64)


@lru_cache(maxsize=512)
def squeeze(params: Params, n: int, seed: int = 2006, duration: float = 60.0, dt: float = 0.05) -> Squeeze:
    """``n`` agents of the set ``params`` (its potentials, sensing radius, speed and interaction) pressed
    against the obstacle (:func:`squeeze_scenario`): the one step loop and tally of every simulation, kept on
    disk between commands (:mod:`zswarm.cache`)."""
    scenario = squeeze_scenario(params, n, seed, duration, dt)

    def run() -> dict:
        engine = _Pressed(scenario)
        tally = OutcomeTally(1, n, dt, np.array([scenario.capture_radius]), np.array([params.swarm.robot_radius]))
        drive(engine, scenario.steps, tally)
        o = tally.outcomes(engine.safety_counts())[0]
        return asdict(Squeeze(
            n_agents=n, min_pair_distance=float(o.min_pair_distance),
            min_obstacle_distance=math.inf if o.min_obstacle_clearance is None else float(o.min_obstacle_clearance),
            final_median_nearest=math.inf if o.final_median_nearest is None else float(o.final_median_nearest),
            final_groups=int(o.final_components)))

    # what the run depends on: the scenario (its set, the law and body fixed above, the starts) and the steps
    key = repr((scenario.params, scenario.starts, scenario.steps, dt))
    return Squeeze(**kept("squeeze", key, run))
