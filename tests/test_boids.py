"""``boids`` as Reynolds' steering rules are written (Shiffman's *Nature of Code*, "Flocking"): two edge
cases where a looser reading brakes or steers where the reference rule does nothing."""

from __future__ import annotations

import numpy as np

from zswarm.laws.contract import Neighbour, Observation, Observations
from zswarm.laws.registry import bind
from zswarm.swarm.scenarios import get_scenario


def _boids(**weights: float):
    """The bound boids law of moving-prey with the given weights (the other rules' weights 0)."""
    settings = {f"law.w_{k}": 0.0 for k in ("sep", "ali", "coh", "tgt")}
    settings.update({f"law.w_{k}": v for k, v in weights.items()})
    return bind(get_scenario("moving-prey", {"law": "boids", **settings}))


def _obs(law, neighbours: list[tuple[np.ndarray, np.ndarray]], velocity=(0.3, 0.1)) -> Observation:
    me = np.array([1.0, 2.0])
    return Observation(me, np.array(velocity), tuple(Neighbour(p, v, 0.0) for p, v in neighbours), (),
                       me + np.array([5.0, 0.0]), law.context.v_max, law.context.dt)


def test_separation_pushes_that_cancel_steer_nothing() -> None:
    """Four neighbours in a square about the agent, inside R_sep: the pushes sum to zero, and the rule
    steers only when the summed push has a length (it does not brake the agent to a stop)."""
    law = _boids(sep=1.5)
    r_sep = law.law.units.scaled(law.law.params.r_sep, "length")
    square = [np.array([1.0, 2.0]) + 0.4 * r_sep * np.array(d) for d in ((1, 1), (1, -1), (-1, 1), (-1, -1))]
    obs = _obs(law, [(p, np.zeros(2)) for p in square])
    v, _ = law.decide(obs)
    np.testing.assert_allclose(v, obs.velocity, rtol=0, atol=1e-12)
    v_batch, _ = law.decide_batch(Observations.stack([[obs]]))
    np.testing.assert_allclose(v_batch[0, 0], obs.velocity, rtol=0, atol=1e-12)
    one_side = _obs(law, [(p, np.zeros(2)) for p in square[:3]])  # the case steers once the pushes do not cancel
    assert np.abs(law.decide(one_side)[0] - one_side.velocity).max() > 1e-3


def test_a_neighbour_at_the_agents_own_position_counts_in_neither_alignment_nor_cohesion() -> None:
    law = _boids(ali=1.0, coh=1.0)
    here = _obs(law, [(np.array([1.0, 2.0]), np.array([-0.5, 0.4]))])
    np.testing.assert_allclose(law.decide(here)[0], here.velocity, rtol=0, atol=1e-12)
    near = _obs(law, [(np.array([1.0, 2.05]), np.array([-0.5, 0.4]))])  # a hair away, it counts
    assert np.abs(law.decide(near)[0] - near.velocity).max() > 1e-3
