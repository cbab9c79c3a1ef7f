"""Every registered law's two forms agree: the single form (one agent's observation) and the batched
form (runs x agents, neighbours and obstacles padded and masked) to 1e-12 on random observations in
2-D and 3-D, with per-agent state carried through. A law added to the registry is tested here without
a line more."""

from __future__ import annotations

import numpy as np
import pytest

from zswarm.laws.contract import Neighbour, Obstacle, Observation, Observations
from zswarm.laws.registry import BUILTIN, bind
from zswarm.swarm.scenarios import get_scenario

SCENARIO = {2: "moving-prey", 3: "moving-prey-3d"}


def random_observation(rng: np.random.Generator, dims: int, radius: float, state_size: int) -> Observation:
    """An agent with 0-6 neighbours and 0-3 obstacles about it, some beyond the sensing radius."""
    me = rng.uniform(-3, 3, dims)
    neighbours = tuple(Neighbour(me + rng.uniform(-1.3, 1.3, dims) * radius, rng.uniform(-1, 1, dims),
                                 float(rng.uniform(0, 0.4))) for _ in range(rng.integers(0, 7)))
    obstacles = tuple(Obstacle(me + rng.uniform(-1.5, 1.5, dims) * radius, float(rng.choice([0.0, 0.3])))
                      for _ in range(rng.integers(0, 4)))
    state = np.concatenate([me + rng.uniform(-0.2, 0.2, dims), [float(rng.integers(0, 2))]])[:state_size] \
        if state_size else np.zeros(0)
    return Observation(me, rng.uniform(-1, 1, dims), neighbours, obstacles, me + rng.uniform(-4, 4, dims),
                       1.0, 0.05, state)


@pytest.mark.parametrize("dims", [2, 3])
@pytest.mark.parametrize("name", list(BUILTIN))
def test_single_and_batched_forms_agree(name: str, dims: int) -> None:
    scenario = get_scenario(SCENARIO[dims], {"law": name, "interaction": "scalable"} if name == "apf" and dims == 2
                            else {"law": name})
    law = bind(scenario)
    rng = np.random.default_rng(7 + dims)
    radius = scenario.params.swarm.sensing_radius
    rows = [[random_observation(rng, dims, radius, law.state_size) for _ in range(5)] for _ in range(4)]
    batch = Observations.stack(rows)
    assert law.has_batch
    v_batch, s_batch = law.law.batch(batch) if law.state_size else (law.law.batch(batch), None)
    moved = 0
    for r, row in enumerate(rows):
        for i, obs in enumerate(row):
            v, s = law.decide(obs)
            np.testing.assert_allclose(v_batch[r, i], v, rtol=0, atol=1e-12)
            if law.state_size:
                np.testing.assert_allclose(s_batch[r, i], s, rtol=0, atol=1e-12)
            moved += float(np.abs(v).sum()) > 0
    assert moved > 10  # the law does something on these observations


@pytest.mark.parametrize("name", list(BUILTIN))
def test_a_batched_form_that_ignores_its_mask_fails_the_check(name: str) -> None:
    """The padding the batch holds is visible to a law that reads it unmasked: the check above would
    catch a batched form that forgets a mask (shown by unmasking the neighbours here)."""
    scenario = get_scenario("moving-prey", {"law": name})
    law = bind(scenario)
    rng = np.random.default_rng(3)
    rows = [[random_observation(rng, 2, 1.0, law.state_size) for _ in range(6)]]
    batch = Observations.stack(rows)
    if not (~batch.neighbour_mask).any():
        pytest.skip("no padding drawn")
    unmasked = batch.replace(neighbour_mask=np.ones_like(batch.neighbour_mask),
                             neighbour_position=np.where(batch.neighbour_mask[..., None], batch.neighbour_position,
                                                         batch.position[..., None, :] + 0.3))
    out = law.law.batch(unmasked)
    v = out[0] if law.state_size else out
    single = np.array([law.decide(o)[0] for o in rows[0]])
    assert np.abs(v[0] - single).max() > 1e-6
