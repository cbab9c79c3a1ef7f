"""The one control step: its batch of one, with its plain-float shortcut (what an agent process calls
twenty times a second), equals its batched form (what both simulators call) for every registered law,
every body and both dimensions, with and without the safety filter: the command, the filter's verdict
and the body's next state, to 1e-12. A shortcut that disagrees fails here (the break checks below)."""

from __future__ import annotations

import math
import zlib

import numpy as np
import pytest

from zswarm.control import safety as sf
from zswarm.control import one_filter
from zswarm.control import step as control
from zswarm.control.step import BodyState, Guard, control_step
from zswarm.laws.contract import Observations
from zswarm.laws.registry import BUILTIN
from zswarm.swarm.scenarios import get_scenario

from test_law_conformance import random_observation

SCENARIO = {2: "moving-prey", 3: "moving-prey-3d"}
BODIES = {2: ("point", "unicycle", "double-integrator"), 3: ("point", "double-integrator")}
CASES = [(law, dims, body, safety) for law in BUILTIN for dims in (2, 3) for body in BODIES[dims]
         for safety in ("off", "barrier")] + [(law, dims, "point+inertia", "barrier") for law in BUILTIN for dims in (2, 3)]


def _guard(rng: np.random.Generator, obs, dims: int, inertia: bool = False) -> list[tuple]:
    """What the filter guards against: the law's neighbours (some aged), one more it does not use, and now
    and then one just ahead, straight in the way (the filter acts, stalls, detours). ``inertia``: each
    with a velocity and an acceleration bound (a double integrator's, or inf: a point among them)."""
    look = lambda: float(rng.choice([0.0, 0.25]))  # noqa: E731 - a point body's, or a unicycle's
    out = [(tuple(n.position.tolist()), float(rng.choice([0.0, 0.0, 0.1, 0.4])), look()) for n in obs.neighbours]
    out.append((tuple((obs.position + rng.uniform(-0.4, 0.4, dims)).tolist()), float(rng.choice([0.0, 0.05])),
                look()))
    if rng.random() < 0.5:
        ahead = obs.target - obs.position
        out.append((tuple((obs.position + rng.uniform(0.1, 0.14) * ahead / np.linalg.norm(ahead)).tolist()), 0.0,
                    look()))
    if inertia:
        out = [(p, age, 0.0, tuple(rng.uniform(-0.6, 0.6, dims).tolist()), float(rng.choice([2.0, np.inf])))
               for p, age, _ in out]
    return out


def disagreement(law: str, dims: int, body: str, safety: str, cases: int = 40) -> tuple[float, int]:
    """The largest difference between the batch of one and the batched form over ``cases`` random steps
    (two steps made alike, so a law's state evolves alike in both), and how many steps the filter changed.
    ``body`` "point+inertia": a point body among double integrators (a mixed swarm's)."""
    among = body == "point+inertia"
    body = "point" if among else body
    scenario = get_scenario(SCENARIO[dims], {"law": law, "body": body})
    one = control_step([scenario], safety=safety, agents=[0])
    batched = control_step([scenario], safety=safety, agents=[0])
    rng = np.random.default_rng(zlib.crc32(repr((law, dims, body, safety)).encode()))
    worst, acted = 0.0, 0
    for _ in range(cases):
        obs = random_observation(rng, dims, scenario.params.swarm.sensing_radius, 0)
        guarded = _guard(rng, obs, dims, inertia=among or body == "double-integrator")
        brake = bool(rng.random() < 0.05)
        heading = float(rng.uniform(-np.pi, np.pi)) if body == "unicycle" else None
        got = one.one(tuple(obs.position.tolist()), tuple(obs.velocity.tolist()), heading,
                      [(tuple(n.position.tolist()), tuple(n.velocity.tolist()), n.age) for n in obs.neighbours],
                      [(*o.centre.tolist(), o.radius) for o in obs.obstacles], tuple(obs.target.tolist()), guarded, brake)
        state = BodyState(obs.position[None, None], obs.velocity[None, None], np.array([[np.nan if heading is None
                                                                                       else heading]]))
        want = batched(Observations.stack([[obs]]), Guard.of_one(guarded, dims, brake), state)
        flag = 0 if got.acted is None else got.acted.flag
        if want.filtered is not None:
            assert flag == int(want.filtered.flags()[0]), (law, dims, body, flag)
            acted += flag > 0
        else:
            assert got.acted is None
        diffs = [np.subtract(got.command, want.command[0, 0]), np.subtract(got.position, want.state.position[0, 0]),
                 np.subtract(got.velocity, want.state.velocity[0, 0])]
        if heading is not None:
            diffs.append([got.heading - want.state.heading[0, 0]])
        worst = max(worst, *(float(np.abs(d).max()) for d in diffs))
    return worst, acted


@pytest.mark.parametrize("law,dims,body,safety", CASES)
def test_the_batch_of_one_is_the_batched_step(law, dims, body, safety):
    worst, acted = disagreement(law, dims, body, safety)
    assert worst <= 1e-12
    if safety == "barrier":
        assert acted >= 5  # the cases exercise the filter


def test_a_law_whose_shortcut_disagrees_fails_the_check(monkeypatch):
    """apf's plain-float single form off by one part in a thousand: the check sees it."""
    import zswarm.laws.apf as apf

    real = apf._velocity_2d
    monkeypatch.setattr(apf, "_velocity_2d", lambda *a: tuple(1.001 * c for c in real(*a)))
    assert disagreement("apf", 2, "point", "off")[0] > 1e-6


def test_a_filter_whose_shortcut_disagrees_fails_the_check(monkeypatch):
    """The filter's float shortcuts letting every command through: the check sees each."""
    monkeypatch.setattr(control, "filter_floats", lambda s, p, v, a, u_hat, *rest: (u_hat, None))
    with pytest.raises(AssertionError):
        disagreement("boids", 2, "point", "barrier")
    with pytest.raises(AssertionError):
        disagreement("boids", 2, "double-integrator", "barrier")


@pytest.mark.parametrize("dims", [2, 3])
def test_the_float_filter_is_the_vectorized_filter(dims):
    """The filter's shortcut on its own, case by case against rows + apply: stalls, detours and brakes."""
    rng = np.random.default_rng(10 + dims)
    s = sf.Safety(distance=0.1, clearance=0.05, v_max=1.0, period=0.05, sensing_radius=1.0)
    acted = braked = detours = 0
    for case in range(400):
        point = rng.uniform(-1, 1, size=dims)
        k, m = int(rng.integers(0, 7)), int(rng.integers(0, 3))
        q = point + rng.uniform(-0.5, 0.5, size=(k, dims))
        u_hat = rng.uniform(-0.7, 0.7, size=dims)
        if case >= 300 and k:  # a neighbour just ahead, straight in the way: stalls, and detours
            q[0] = point + rng.uniform(0.1, 0.12) * (u_hat + rng.normal(0, 0.05, dims)) / np.linalg.norm(u_hat)
        age = rng.choice([0.0, 0.0, 0.0, 0.0, 0.1, 0.4, 1.0], size=k)
        if case >= 300:
            age[:] = 0.0
        centres = point + rng.uniform(-0.6, 0.6, size=(m, dims))
        radii = rng.uniform(0, 0.2, size=m)
        own, theirs = float(rng.choice([0.0, 0.05])), rng.choice([0.0, 0.05], size=k)  # look-aheads
        got, done = one_filter.filter_floats(s, tuple(point), (0.0,) * dims, math.inf, tuple(u_hat),
                                           [(tuple(x), float(a), float(t)) for x, a, t in zip(q, age, theirs)],
                                           [(*c, r) for c, r in zip(centres.tolist(), radii.tolist())], own)
        rows = sf.rows(s, 1, np.zeros(k, np.intp), point - q, age, np.zeros(m, np.intp), point - centres, radii,
                       sf.widening(own + theirs), sf.widening(np.full(m, own)))
        want = sf.apply(u_hat[None], rows)
        np.testing.assert_allclose(got, want.command[0], atol=1e-12)
        assert (done.flag if done is not None else 0) == int(want.flags()[0])
        acted += bool(want.acted[0])
        braked += bool(want.braked[0])
        detours += not np.allclose(sf.apply(u_hat[None], rows, detour=False).command, want.command)
    assert acted > 50 and braked > 5 and detours > 10, (acted, braked, detours)


@pytest.mark.parametrize("dims", [2, 3])
def test_a_body_that_stops_at_once_among_bodies_with_inertia_takes_the_detour_in_both_forms(dims):
    """A point agent guarded against double integrators: (S4)'s rows, their braking distances kept.
    Stalled by one just ahead, it turns right as it does among points, batched and in floats alike."""
    rng = np.random.default_rng(20 + dims)
    s = sf.Safety(distance=0.1, clearance=0.05, v_max=1.0, period=0.05, sensing_radius=1.0)
    detours = 0
    for _ in range(200):
        point, u_hat = rng.uniform(-1, 1, size=dims), rng.uniform(-0.7, 0.7, size=dims)
        k = int(rng.integers(1, 5))
        q = point + rng.uniform(-0.5, 0.5, size=(k, dims))
        q[0] = point + rng.uniform(0.1, 0.15) * (u_hat + rng.normal(0, 0.05, dims)) / np.linalg.norm(u_hat)
        vel, age = rng.uniform(-0.1, 0.1, size=(k, dims)), rng.choice([0.0, 0.0, 0.05], size=k)
        got, done = one_filter.filter_floats(s, tuple(point), (0.0,) * dims, math.inf, tuple(u_hat),
                                           [(tuple(x), float(a), 0.0, tuple(w), 1.5) for x, a, w in zip(q, age, vel)],
                                           [])
        inertia = sf.Inertia(np.zeros((1, dims)), np.array([math.inf]), sf.neighbour_stop(vel, age, 1.5, s.v_max))
        rows = sf.rows(s, 1, np.zeros(k, np.intp), point - q, age, np.zeros(0, np.intp), np.zeros((0, dims)),
                       np.zeros(0), inertia=inertia)
        want = sf.apply(u_hat[None], rows)
        np.testing.assert_allclose(got, want.command[0], atol=1e-12)
        assert (done.flag if done is not None else 0) == int(want.flags()[0])
        plain = sf.project(u_hat[None], rows.agent, rows.a, rows.b)
        detours += not want.braked[0] and not np.allclose(plain, want.command)
    assert detours > 20, detours
