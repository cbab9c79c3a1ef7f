"""The safety filter (zswarm.control.safety): exact, closest, and safe where the law alone is not."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from zswarm.control import safety as sf
from zswarm.swarm.scenarios import get_scenario

quadprog = pytest.importorskip("quadprog")


def _random_problem(rng: np.random.Generator, dims: int):
    """One agent at the origin, a crowd of neighbours and obstacles close by, random data ages."""
    s = sf.Safety(distance=0.1, clearance=0.05, v_max=1.0, period=0.05, sensing_radius=1.0)
    k = int(rng.integers(0, 9))
    psi = rng.normal(size=(k, dims))
    psi *= (rng.uniform(0.02, 0.6, size=k) / np.linalg.norm(psi, axis=1))[:, None]
    age = rng.choice([0.0, 0.05, 0.2, 0.5], size=k)
    m = int(rng.integers(0, 3))
    psi_o = rng.normal(size=(m, dims))
    radius_o = rng.uniform(0.0, 0.3, size=m)
    psi_o *= ((radius_o + rng.uniform(0.0, 0.4, size=m)) / np.linalg.norm(psi_o, axis=1))[:, None]
    r = sf.rows(s, 1, np.zeros(k, dtype=np.intp), psi, age, np.zeros(m, dtype=np.intp), psi_o, radius_o)
    u_hat = rng.normal(size=(1, dims))
    u_hat *= rng.uniform(0.0, 1.0) / np.linalg.norm(u_hat)
    return r, u_hat


def _quadprog(u_hat: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """min 1/2 |u|^2 - u^.u  s.t.  a u <= b   (quadprog: C^T x >= c0)."""
    dims = len(u_hat)
    if len(a) == 0:
        return u_hat.copy()
    return quadprog.solve_qp(np.eye(dims), u_hat, -a.T, -b)[0]


def aged(age: float, expected: float, took: float) -> bool:
    """An age measured against the wall clock: ``expected`` when it was set up, plus at most the ``took``
    seconds that passed until it was measured (12 ms once, on a machine beside two busy loops)."""
    return expected - 1e-6 <= age <= expected + took + 1e-6


@pytest.mark.parametrize("dims", [2, 3])
def test_the_filtered_command_satisfies_every_row_and_is_the_solvers_optimum(dims):
    rng = np.random.default_rng(dims)
    active = 0
    for _ in range(400):
        r, u_hat = _random_problem(rng, dims)
        u = sf.project(u_hat, r.agent, r.a, r.b)
        assert np.all(r.a @ u[0] - r.b <= 1e-9), "a returned command violates a row"
        assert np.linalg.norm(u) <= np.linalg.norm(u_hat) + 1e-12  # the speed limit holds
        want = _quadprog(u_hat[0], r.a, r.b)
        assert np.allclose(u[0], want, atol=1e-8), (u, want)
        active += not np.allclose(u, u_hat)
    assert active > 100, "the cases must make the filter act"


def test_many_agents_at_once_equal_one_at_a_time():
    rng = np.random.default_rng(7)
    problems = [_random_problem(rng, 2) for _ in range(300)]
    agent = np.concatenate([np.full(len(r.agent), i) for i, (r, _) in enumerate(problems)])
    a = np.concatenate([r.a for r, _ in problems])
    b = np.concatenate([r.b for r, _ in problems])
    u_hat = np.concatenate([u for _, u in problems])
    together = sf.project(u_hat, agent, a, b)
    alone = np.concatenate([sf.project(u, r.agent, r.a, r.b) for r, u in problems])
    assert np.allclose(together, alone, atol=1e-12)


def test_stale_data_inflates_the_margin_and_data_past_the_bound_brakes():
    s = sf.Safety(distance=0.1, clearance=0.05, v_max=1.0, period=0.05, sensing_radius=1.0)
    psi = np.array([[0.12, 0.0]])  # the neighbour 0.12 to the left; the agent heads straight at it
    u_hat = np.array([[-1.0, 0.0]])
    fresh = sf.apply(u_hat, sf.rows(s, 1, np.zeros(1, np.intp), psi, np.array([0.0]), np.zeros(0, np.intp),
                                    np.zeros((0, 2)), np.zeros(0)))
    old = sf.apply(u_hat, sf.rows(s, 1, np.zeros(1, np.intp), psi, np.array([0.05]), np.zeros(0, np.intp),
                                  np.zeros((0, 2)), np.zeros(0)), detour=False)
    any_side = sf.apply(u_hat, sf.rows(s, 1, np.zeros(1, np.intp), psi, np.array([0.3]), np.zeros(0, np.intp),
                                       np.zeros((0, 2)), np.zeros(0)))
    past = sf.apply(u_hat, sf.rows(s, 1, np.zeros(1, np.intp), psi, np.array([s.max_age + 0.01]),
                                   np.zeros(0, np.intp), np.zeros((0, 2)), np.zeros(0)))
    # fresh: D' = 0.1 and it may close half of the 0.02 gap in one period (0.2/s); 0.05 s old: D' = 0.15,
    # no gap, it may not come closer at all; 0.3 s old: it may be on any side (0.3 > 0.12), it brakes
    assert fresh.command[0] == pytest.approx([-0.5 * 0.02 / 0.05, 0.0]) and fresh.acted[0]
    assert old.command[0] == pytest.approx([0.0, 0.0]) and old.acted[0] and old.stalled[0]
    assert past.braked[0] and np.all(past.command == 0.0)
    assert any_side.braked[0] and np.all(any_side.command == 0.0)
    assert not fresh.braked[0] and not old.braked[0]


def test_stale_rows_hold_for_every_direction_the_data_allow():
    """A neighbour 0.2 away heard 0.05 s ago may be anywhere within 0.05 of where it was heard: the
    filtered command closes no true gap beyond the row's share, whichever of those places it is at."""
    s = sf.Safety(distance=0.1, clearance=0.05, v_max=1.0, period=0.05, sensing_radius=1.0)
    rng = np.random.default_rng(3)
    for dims in (2, 3):
        for _ in range(300):
            psi = rng.normal(size=dims)
            psi *= rng.uniform(0.12, 0.4) / np.linalg.norm(psi)
            age = rng.uniform(0.0, 0.1)
            r = sf.rows(s, 1, np.zeros(1, np.intp), psi[None], np.array([age]), np.zeros(0, np.intp),
                        np.zeros((0, dims)), np.zeros(0))
            u = sf.apply(rng.uniform(-1, 1, size=(1, dims)), r).command[0]
            b = 0.5 / s.period * max(np.linalg.norm(psi) - s.margin(age), 0.0)
            for _ in range(20):  # where j may truly be: within v tau of where it was heard
                e = rng.normal(size=dims)
                e *= s.v_max * age * rng.uniform() ** (1 / dims) / np.linalg.norm(e)
                true = psi + e
                assert true @ u / np.linalg.norm(true) >= -b - 1e-9


@pytest.mark.parametrize("detour", [False, True])
def test_fresh_data_keeps_a_head_on_pair_apart_in_discrete_time(detour):
    """Two agents driven straight at each other's start at full speed: apart by D_s at every step,
    exactly. Without the detour they stall face to face for good (the symmetric deadlock); with it both
    turn right, slide past each other and reach the other's start."""
    s = sf.Safety(distance=0.1, clearance=0.05, v_max=1.0, period=0.05, sensing_radius=1.0)
    goals = np.array([[0.6, 0.0], [0.0, 0.0]])
    p = goals[::-1].copy()
    closest, stalled = np.inf, 0
    for _ in range(100):
        u_hat = goals - p
        u_hat *= np.minimum(1.0, 1.0 / np.maximum(np.linalg.norm(u_hat, axis=1), 1e-12))[:, None]
        psi = np.array([p[0] - p[1], p[1] - p[0]])
        r = sf.rows(s, 2, np.array([0, 1]), psi, np.zeros(2), np.zeros(0, np.intp), np.zeros((0, 2)), np.zeros(0))
        done = sf.apply(u_hat, r, detour=detour)
        p = p + s.period * done.command
        closest = min(closest, float(np.linalg.norm(p[0] - p[1])))
        stalled += int(done.stalled.sum())
    assert closest >= s.distance - 1e-12
    assert 0.6 - 2 * 1.0 * 0.05 * 100 < s.distance  # without the filter they would pass through each other
    left = np.linalg.norm(p - goals, axis=1)
    if detour:
        assert np.all(left < 0.01) and stalled < 10
    else:
        assert np.all(left > 0.2) and stalled > 150


def test_a_unicycle_filters_its_lookahead_point_with_the_radius_grown():
    params = get_scenario("moving-prey").params
    plain, ahead = sf.safety_for(params, 0.05), sf.safety_for(params, 0.05, lookahead=0.25)
    assert ahead.distance == pytest.approx(plain.distance + 0.5)
    assert ahead.clearance == pytest.approx(plain.clearance + 0.25)
    blind = sf.safety_for(dataclasses.replace(params, swarm=dataclasses.replace(params.swarm, sensing_radius=0.099)), 0.05)
    assert blind.max_age < 0  # it cannot sense far enough: a binding neighbour, however fresh, brakes it
    r = sf.rows(blind, 1, np.zeros(1, np.intp), np.array([[0.095, 0.0]]), np.array([0.01]), np.zeros(0, np.intp),
                np.zeros((0, 2)), np.zeros(0))
    assert r.stale[0]


def test_bad_mode_is_one_line():
    with pytest.raises(ValueError, match="off, barrier"):
        sf.parse_mode("orca")


def test_the_batched_simulator_filters_each_run_as_the_reference_does_alone():
    """One implementation: a batch mixing filtered, unfiltered and filtered-under-faults runs; each run
    is the run simulate() makes alone (1e-9 at every step), with the same interventions. The paper's
    law crushes goal-near-obstacle's 8 agents into collisions; the filter leaves none."""
    from zswarm.swarm.faults import FaultModel
    from zswarm.sim.batch import Member, simulate_batch
    from zswarm.sim.simulator import simulate

    scenario = get_scenario("goal-near-obstacle")
    members = [Member(scenario, 0, safety="barrier"), Member(scenario, 1, safety="off"),
               Member(scenario, 2, FaultModel(latency=0.2, dropout=0.3, seed=2), safety="barrier")]
    steps = 200
    res = simulate_batch(members, steps, keep_trajectory=True)
    for r, m in enumerate(members):
        alone = simulate(m.scenario, m.seed, duration=steps * scenario.dt, keep_trajectory=True, faults=m.faults,
                         safety=m.safety)
        assert np.max(np.abs(res.trajectory[:, r] - alone.trajectory)) < 1e-9
        assert res.outcomes[r].collisions == alone.summary["collisions"]
        assert res.outcomes[r].safety_interventions == alone.summary.get("safety_interventions", 0)
    assert res.outcomes[1].collisions > 0 and res.outcomes[0].collisions == res.outcomes[2].collisions == 0
    assert res.outcomes[0].safety_interventions > 0 and res.outcomes[2].safety_interventions > 0


def test_the_design_report_says_what_the_filter_guarantees():
    from zswarm.design.guidelines import check
    from zswarm.design.text import render

    point = check(get_scenario("moving-prey").params, swarm=False, dt=0.05)
    assert point.safety["holds"] and point.safety["max_age"] == pytest.approx((1.0 - 0.1 * (1 + sf.HAIR)) / 1.0)
    assert "safety" not in point.failures()  # a guarantee of the filter, not a check the set must pass
    assert "Safety     holds" in render(point)
    # a double integrator: both braking distances at full speed (0.25 each at accel 2) come off the age bound
    drone = check(get_scenario("moving-prey", {"body": "double-integrator"}).params, swarm=False, dt=0.05)
    assert drone.safety["max_age"] == pytest.approx(point.safety["max_age"] - 0.5) and "Safety     holds" in render(drone)
    slow = check(get_scenario("moving-prey", {"body": "double-integrator", "accel": 0.9}).params, swarm=False, dt=0.05)
    assert not slow.safety["holds"] and "leaves -0.2111 beyond both" in slow.safety["detail"]  # 1 - 0.1 - 2 (1/1.8)


def test_time_scale_auto_picks_the_pace_the_machine_can_hold(monkeypatch):
    import argparse

    from zswarm.launch import plan

    def args(**kw):
        base = dict(time_scale="auto", clock="free", role=["router", "world", "agents"], scenario="large-swarm",
                    assignments=[], agents=100, ids=None)
        return argparse.Namespace(**{**base, **kw})

    a = args()
    note = plan.auto_time_scale(a, 2)
    assert a.time_scale == 0.25 and "auto picked 0.25" in note  # 100 agents at 40 Hz need 4 x half of 2 cores
    a = args(agents=10, scenario="moving-prey")
    assert plan.auto_time_scale(a, 2) is None and a.time_scale == 1.0  # the demo fits: real time, nothing said
    a = args(time_scale=0.5)
    assert plan.auto_time_scale(a, 2) is None and a.time_scale == 0.5  # an explicit pace wins
    a = args(clock="lockstep")
    assert plan.auto_time_scale(a, 2) is None and a.time_scale == 1.0
    a = args(agents=500, scenario="moving-prey")  # too many to start in time: left to the refusal
    assert plan.auto_time_scale(a, 2) is None and a.time_scale == 1.0
    a = args()  # a cluster's cores: 100 agents on 16 of them run at real time
    assert plan.auto_time_scale(a, 16) is None and a.time_scale == 1.0


def test_bench_safety_puts_the_filter_beside_the_law_alone():
    import json

    from conftest import run_cli

    res = run_cli("-m", "zswarm", "bench", "safety", "--scenarios", "goal-near-obstacle", "--seeds", "1",
                  "--modes", "off,barrier", "--bodies", "point,double-integrator", "--workers", "1", "--json",
                  timeout=120)
    assert res.returncode == 0, res.stderr
    for body in ("point", "double-integrator"):  # a body with inertia behind its own rows (S4)
        rows = {r["mode"]: r for r in json.loads(res.stdout)["rows"] if r["body"] == body}
        assert rows["off"]["collisions"] > 0 and rows["barrier"]["collisions"] == 0
        assert rows["barrier"]["stalled_ticks"] > 0  # held at the goal against a law that would crush it
        assert rows["barrier"]["us_per_agent_step"] > 0 and rows["off"]["us_per_agent_step"] > 0
    bad = run_cli("-m", "zswarm", "bench", "safety", "--modes", "rvo3", timeout=60)
    assert bad.returncode == 2 and "--modes are off, barrier, orca" in bad.stderr


def test_an_agent_guards_against_late_neighbours_and_quiet_ones_that_cannot_have_left():
    """agents.sensing: a neighbour heard late is kept with its age (plus one period); one from which
    nothing came for the staleness limit longer than from the one heard last has gone quiet: let go if
    it can have left the agent's cells, still guarded against (its poses lost) if it cannot have; a
    neighbour last heard beyond the sensing radius is not guarded against, unless its pose is so old
    that it may be within the radius by now."""
    import time

    from agents.sensing import Body, Sensing
    from zswarm.net import messages as msg
    from zswarm.net.runspec import RunSpec

    spec = RunSpec(scenario_name="moving-prey")
    sensing = Sensing(spec, 0, Body(0.0, 0.0), probe_latency=False)
    now = time.time()
    heard = {1: ((0.3, 0.0), 0.20, now - 0.01),   # late (sent 0.2 s ago) but still arriving
             2: ((0.0, 0.4), 0.02, now - 0.01),   # fresh
             3: ((-0.4, 0.0), 2.00, now - 2.0),   # nothing from it for 2 s: quiet, and it can have left
             6: ((0.0, -0.3), 0.60, now - 0.6),   # quiet 0.6 s, but 0.3 + 0.65 < 1.1 (R + 2 v dt): lost, not gone
             4: ((3.0, 0.0), 0.02, now - 0.01),   # beyond the sensing radius (1.0)
             5: ((0.0, -1.3), 0.40, now - 0.01)}  # beyond it, but 0.45 s old at v_max 1: may be 0.85 away
    for who, (p, age, received) in heard.items():
        pose = msg.Pose(who, 1, now - age, -1, *p, 0.0, 0.0)
        assert sensing.neighbours.accept(who, pose, received) is None
        sensing.membership.alive.add(who)
    got = dict((p, a) for p, a, _ in sensing.sense(None, 0.5, 1.0, 0.05)[1])
    took = time.time() - now
    assert set(got) == {(0.3, 0.0), (0.0, 0.4), (0.0, -1.3), (0.0, -0.3)}
    assert aged(got[(0.0, -0.3)], 0.65, took)  # guarded with its whole age
    assert aged(got[(0.3, 0.0)], 0.25, took)  # its age, plus one control period
    assert aged(got[(0.0, 0.4)], 0.07, took)
    half = dict((p, a) for p, a, _ in sensing.sense(None, 0.5, 0.5, 0.05)[1])
    assert aged(half[(0.3, 0.0)], 0.15, 0.5 * (time.time() - now))  # simulated seconds: at half pace, half the age
    # the law uses every fresh one within the sensing radius, with its age, not the quiet nor the far
    near = {p: a for p, _, a in sensing.sense(None, 0.5, 1.0, 0.05)[0]}
    assert set(near) == {(0.3, 0.0), (0.0, 0.4)}
    took = time.time() - now
    assert aged(near[(0.3, 0.0)], 0.20, took) and aged(near[(0.0, 0.4)], 0.02, took)  # no period added: the law's age
    sensing.membership.alive.discard(1)  # its token has not come yet: its poses say it is there, so it is guarded
    poses, guarded = sensing.sense(None, 0.5, 1.0, 0.05)  # one pass, as an agent's tick
    positions = [p for p, _, _ in poses]
    assert (0.3, 0.0) in {p for p, _, _ in guarded}
    assert (0.3, 0.0) not in positions  # the law waits for its token
    assert (0.3, 0.0) not in [p for p, _, _ in sensing.sense(None, 0.5, guard=False)[0]]
    # it departed (its token went) just after its newest pose: no neighbour of the law's, but its body holds
    # there, one control period old, however long ago that pose was sent, until it is heard again
    for who in (1, 4, 3):  # 4: beyond the sensing radius, not guarded; 3: heard last 2 s before it went
        sensing.handle(("alive", spec.keys.alive(who), b"", True, time.time()))
    time.sleep(0.05)
    poses, guarded = sensing.sense(None, 0.5, 1.0, 0.05)
    took = time.time() - now
    assert (0.3, 0.0) not in [p for p, _, _ in poses]
    assert [a for p, a, _ in guarded if p == (0.3, 0.0)] == [0.05] and (3.0, 0.0) not in {p for p, _, _ in guarded}
    # one heard last long before its token went (it was frozen, or this agent was, while the others went
    # on) may be anywhere its age allows: guarded with that whole age
    assert [aged(a, 2.05, took) for p, a, _ in guarded if p == (-0.4, 0.0)] == [True]
    # its token back (a link that went and came) before any pose of it: its body is still there
    sensing.handle(("alive", spec.keys.alive(3), b"", False, time.time()))
    assert (-0.4, 0.0) in {p for p, _, _ in sensing.sense(None, 0.5, 1.0, 0.05)[1]}
    back = msg.encode(msg.Pose(1, 2, time.time(), -1, 0.35, 0.0, 0.0, 0.0))
    sensing.handle(("pose", spec.keys.pose((0, 0), 1), back, False, time.time()))
    guarded = {p for p, _, _ in sensing.sense(None, 0.5, 1.0, 0.05)[1]}
    assert (0.35, 0.0) in guarded and (0.3, 0.0) not in guarded  # heard again, before its token: where it is
    sensing.handle(("alive", spec.keys.alive(1), b"", False, time.time()))  # a member again: by its poses
    poses, guarded = sensing.sense(None, 0.5, 1.0, 0.05)
    assert [p for p, _, _ in guarded].count((0.35, 0.0)) == 1 and (0.35, 0.0) in [p for p, _, _ in poses]
    # lockstep: the step's poses, exact for that step (none here), and the departed bodies where they are
    assert sensing.sense(7, 0.5, 1.0, 0.05)[1] == [((-0.4, 0.0), 0.0, 0.0)]


def test_under_a_common_delay_a_quiet_neighbour_deep_inside_stays_guarded_in_agents_and_simulators():
    """When everything arrives seconds late (a machine far behind), each pose's age says nothing about
    whether a quiet neighbour can have left: had it stayed in the cells, its poses would have come
    through the same delay as the others'. So it counts as gone only if its newest position plus what
    it can have moved *beyond the freshest neighbour's age* reaches past the cells: agents
    (``Sensing.sense``) and simulators (``BatchChannel.known``) alike. On its whole age
    (2.65 s at v_max 1) the neighbour 0.3 away would be let go; it is guarded."""
    import time

    from agents.sensing import Body, Sensing
    from zswarm.swarm.faults import FaultModel
    from zswarm.net import messages as msg
    from zswarm.net.runspec import RunSpec
    from zswarm.sim.batch_channel import BatchChannel

    spec = RunSpec(scenario_name="moving-prey")  # R = 1, v_max = 1, dt = 0.05: cells reach 1.1
    swarm = spec.scenario.params.swarm
    assert (swarm.sensing_radius, swarm.v_max, spec.scenario.dt) == (1.0, 1.0, 0.05)
    sensing = Sensing(spec, 0, Body(0.0, 0.0), probe_latency=False)
    now = time.time()
    late = {1: ((0.5, 0.0), 2.0, now - 0.01),   # 2 s late, still arriving: the common delay
            2: ((0.0, -0.3), 2.6, now - 0.6),   # quiet 0.6 s longer, deep inside: lost, not gone
            3: ((-0.9, 0.0), 4.0, now - 2.0)}   # quiet 2 s longer, 0.9 + 2.0 > 1.1: can have left
    for who, (p, age, received) in late.items():
        assert sensing.neighbours.accept(who, msg.Pose(who, 1, now - age, -1, *p, 0.0, 0.0), received) is None
        sensing.membership.alive.add(who)
    got = {p: a for p, a, _ in sensing.sense(None, 0.5, 1.0, 0.05)[1]}
    took = time.time() - now
    assert set(got) == {(0.5, 0.0), (0.0, -0.3)}
    assert aged(got[(0.0, -0.3)], 2.65, took)  # guarded with its whole age

    channel = BatchChannel(4, [FaultModel()], 0.05, np.array([1.0]), np.array([1.0]))
    k = 100
    for who, ((x, y), age, received) in late.items():  # the same poses, sent and received at the same steps
        channel.belief_stamp[0, 0, who] = k - int(round(age / 0.05))
        channel.belief_received[0, 0, who] = k - int(round((now - received) / 0.05))
        channel.belief_pos[0, 0, who] = (x, y)
    positions = np.array([[[0.0, 0.0], [0.5, 0.0], [0.0, -0.3], [-2.5, 0.0]]])  # 3 has left the cells
    channel.history[0, k % channel.slots, :4] = positions[0]  # where the member tokens say they are
    mask, _, ages = channel.known(k, positions)
    assert mask[0, 0].tolist() == [False, True, True, False]
    assert ages[0, 0, 2] == pytest.approx(2.6)


def test_a_sender_that_never_announced_itself_and_fell_silent_is_not_guarded_for_ever():
    """A hostile peer published poses of an agent nobody announced (id 999, no liveliness token) amid
    the swarm for 10 s; an agent that later came near the last of them braked beside it for the rest
    of the run (27 s, a loaded CI): with no one else in reach, nothing told its silence apart from
    loss. A token can come seconds after the poses, so a token-less sender is guarded while it keeps
    publishing or for TOKEN_GRACE seconds after its first pose, and not once it has been silent
    beyond both."""
    import time

    from agents.guard import TOKEN_GRACE
    from agents.sensing import Body, Sensing
    from zswarm.net import messages as msg
    from zswarm.net.runspec import RunSpec

    spec = RunSpec(scenario_name="moving-prey")  # R = 1, v_max = 1
    sensing = Sensing(spec, 0, Body(0.0, 0.0), probe_latency=False)
    now = time.time()
    long_ago = now - TOKEN_GRACE - 1.0

    def hear(who, p, first, last):
        assert sensing.neighbours.accept(who, msg.Pose(who, 1, first, -1, *p, 0.0, 0.0), first) is None
        if last != first:
            assert sensing.neighbours.accept(who, msg.Pose(who, 2, last, -1, *p, 0.0, 0.0), last) is None

    guarded = lambda: {p for p, _, _ in sensing.sense(None, 0.5, 1.0, 0.05)[1]}  # noqa: E731
    hear(999, (0.4, 0.0), long_ago, long_ago + 0.2)  # made up long ago, silent since, no one else heard
    assert guarded() == set()
    sensing.membership.alive.add(999)  # had its token come: alone, its silence cannot be told from loss: guarded
    assert guarded() == {(0.4, 0.0)}
    sensing.membership.alive.discard(999)
    hear(7, (0.0, 0.4), long_ago, now - 0.01)  # its token late for seconds, but it keeps publishing
    hear(8, (-0.4, 0.0), now - 0.3, now - 0.3)  # first heard 0.3 s ago: its token may still come
    assert guarded() == {(0.0, 0.4), (-0.4, 0.0)}


def test_a_quiet_neighbour_whose_member_token_is_in_the_cells_is_guarded_whatever_its_silence():
    """Loss near the edge of the cells: every pose of a neighbour lost for seconds while the others
    come through. By its silence and its distance it can have left; its member token (a liveliness
    token in the cell it is in, which pose loss does not touch) says it is still in a cell the agent
    listens to, so it stays guarded with its whole age, and is let go once the token leaves (or the
    agent stops listening to that cell): agents and simulators alike. Tokens already in a cell the
    agent starts to listen to come as answers to a question, which can be older than a live change;
    until every such answer is in, a silent neighbour whose token it has not heard stays guarded (it
    may sit in one of those cells: an agent drove through a frozen neighbour's place)."""
    import time

    from agents.sensing import Body, Sensing
    from zswarm.swarm.faults import FaultModel
    from zswarm.net import messages as msg
    from zswarm.net.runspec import RunSpec
    from zswarm.sim.batch_channel import BatchChannel

    spec = RunSpec(scenario_name="moving-prey")  # R = 1, v_max = 1, dt = 0.05: cells reach 1.1
    keys = spec.keys
    sensing = Sensing(spec, 0, Body(0.0, 0.0), probe_latency=False)
    now = time.time()
    heard = {1: ((0.5, 0.0), 0.02, now - 0.01),   # heard all along
             3: ((-0.9, 0.0), 2.0, now - 2.0)}    # quiet 2 s near the edge: can have left
    for who, (p, age, received) in heard.items():
        assert sensing.neighbours.accept(who, msg.Pose(who, 1, now - age, -1, *p, 0.0, 0.0), received) is None
        sensing.membership.alive.add(who)
    guarded = lambda: {p: a for p, a, _ in sensing.sense(None, 0.5, 1.0, 0.05)[1]}  # noqa: E731
    assert set(guarded()) == {(0.5, 0.0)}
    cell = keys.cell(-0.9, 0.0)
    sensing.handle(("in", keys.member(cell, 3), b"", False, now))  # a cell it does not listen to
    assert set(guarded()) == {(0.5, 0.0)}
    sensing.membership.listen_to([cell, keys.cell(0.0, 0.0)], [])
    # who sits in the cells it has just begun to listen to is not known yet: 3's token may be there
    assert set(guarded()) == {(0.5, 0.0), (-0.9, 0.0)} and 3 not in sensing.membership.members
    for c in (cell, keys.cell(0.0, 0.0)):  # the answers came: nobody there
        sensing.handle(("in-answered", keys.cell_members(c), b"", False, now))
    # but no sign that it left the cell it was heard in: still guarded, and its token there asked about
    assert set(guarded()) == {(0.5, 0.0), (-0.9, 0.0)} and sensing.membership.doubted == {3: {cell}}
    sensing.handle(("in-gone", keys.member(cell, 3), b"", True, now + 1.0))  # the ask: nobody holds it
    assert set(guarded()) == {(0.5, 0.0)}
    sensing.handle(("in", keys.member(cell, 3), b"", False, now))
    sensing.handle(("in", keys.member(keys.cell(0.0, 0.0), 0), b"", False, now))  # its own: ignored
    assert set(guarded()) == {(0.5, 0.0), (-0.9, 0.0)} and 0 not in sensing.membership.members
    assert aged(guarded()[(-0.9, 0.0)], 2.05, time.time() - now)  # its whole age: 2 s, and a tick ahead
    sensing.handle(("in", keys.member(cell, 3), b"", True, now))  # it left that cell
    assert set(guarded()) == {(0.5, 0.0)}
    sensing.handle(("in", keys.member(cell, 3), b"", False, now))
    sensing.membership.listen_to([], [cell])  # the agent stopped listening to it
    assert set(guarded()) == {(0.5, 0.0)}
    # a cell it starts to listen to: who sits there already comes as an answer, which counts only where
    # no live change of the same token came first (an answer can be older than a live removal)
    sensing.membership.listen_to([cell], [])
    sensing.handle(("in", keys.member(cell, 3), b"", True, now))  # live: it left
    sensing.handle(("in-now", keys.member(cell, 3), b"", False, now))  # the older answer: ignored
    assert set(guarded()) == {(0.5, 0.0), (-0.9, 0.0)}  # until the whole answer is in
    sensing.handle(("in-answered", keys.cell_members(cell), b"", False, now))
    assert set(guarded()) == {(0.5, 0.0)}
    sensing.membership.listen_to([], [cell])
    sensing.membership.listen_to([cell], [])
    sensing.handle(("in-now", keys.member(cell, 3), b"", False, now))  # nothing live since: it is there
    assert set(guarded()) == {(0.5, 0.0), (-0.9, 0.0)}

    channel = BatchChannel(4, [FaultModel(latency=0.1)], 0.05, np.array([1.0]), np.array([1.0]))
    k = 100
    channel.belief_stamp[0, 0, 1], channel.belief_pos[0, 0, 1] = k, (0.5, 0.0)
    channel.belief_stamp[0, 0, 3], channel.belief_pos[0, 0, 3] = k - 40, (-0.9, 0.0)  # quiet 2 s
    channel.belief_received[0, 0, [1, 3]] = k, k - 40
    positions = np.array([[[0.0, 0.0], [0.5, 0.0], [5.0, 5.0], [-0.9, 0.0]]])
    for then, three in ((k - 2, (-0.9, 0.0)), (k, (-3.0, 0.0))):  # tokens lag by the latency (2 steps)
        channel.history[0, then % channel.slots, :4] = [*positions[0, :3], three]
    assert channel.known(k, positions)[0][0, 0].tolist() == [False, True, False, True]  # 0.1 s ago: in
    channel.history[0, (k - 2) % channel.slots, 3] = (-3.0, 0.0)
    assert channel.known(k, positions)[0][0, 0].tolist() == [False, True, False, False]


def test_a_quiet_neighbour_whose_poses_came_through_a_slower_path_is_given_that_delay_before_it_is_let_go():
    """The quiet rule assumes a neighbour that stayed would be heard through the delay the others are
    heard through. A router that reads some senders seconds late (measured: a starved router, agents
    walking into neighbours they had let go, docs/safety.md) breaks that: a neighbour whose newest pose
    arrived later after it was sent than the promptest one's is given that extra delay before its
    silence counts, and no longer: a neighbour that really left is let go once its silence outlasts it."""
    import time

    from agents.sensing import Body, Sensing
    from zswarm.net import messages as msg
    from zswarm.net.runspec import RunSpec

    spec = RunSpec(scenario_name="moving-prey")  # R = 1, v_max = 1, dt = 0.05: cells reach 1.1
    sensing = Sensing(spec, 0, Body(0.0, 0.0), probe_latency=False)
    now = time.time()
    # who: (position, sent s ago, received s ago); each quiet one is near the edge and can have left
    heard = {1: ((0.5, 0.0), 0.11, 0.01),   # prompt: its poses come through 0.1 s
             3: ((-0.9, 0.0), 5.0, 2.0),    # quiet 2 s, but its newest pose took 3 s: still there?
             4: ((0.0, 0.9), 2.1, 2.0),     # quiet 2 s, through the same 0.1 s as the others: left
             5: ((0.0, -0.9), 6.0, 3.5)}    # took 2.5 s, quiet 3.5 s: longer than its extra delay
    for who, (p, sent, received) in heard.items():
        assert sensing.neighbours.accept(who, msg.Pose(who, 1, now - sent, -1, *p, 0.0, 0.0), now - received) is None
        sensing.membership.alive.add(who)
    got = {p: a for p, a, _ in sensing.sense(None, 0.5, 1.0, 0.05)[1]}
    took = time.time() - now
    assert set(got) == {(0.5, 0.0), (-0.9, 0.0)}
    assert aged(got[(-0.9, 0.0)], 5.05, took)  # guarded with its whole age

    # the simulators let them go by the same rule, in steps (their tokens far outside the cells)
    from zswarm.swarm.faults import FaultModel
    from zswarm.sim.batch_channel import BatchChannel

    channel, k = BatchChannel(6, [FaultModel()], 0.05, np.array([1.0]), np.array([1.0])), 200
    for who, (p, sent, received) in heard.items():
        channel.belief_stamp[0, 0, who] = k - int(round(sent / 0.05))
        channel.belief_received[0, 0, who] = k - int(round(received / 0.05))
        channel.belief_pos[0, 0, who] = p
    positions = np.zeros((1, 6, 2))
    positions[0, 1:] = 50.0
    channel.history[0, k % channel.slots, :6] = positions[0]
    assert np.flatnonzero(channel.known(k, positions)[0][0, 0]).tolist() == [1, 3]


def test_poses_that_waited_in_a_queue_are_not_refused_as_jumps_but_a_forged_leap_is():
    """zswarm.net.poses: after a queue, a burst brings an old pose and, at once, a much later one (the
    poses between were lost). The receiver's clock since the old pose was *sent* bounds how far the
    agent went; counted from when it was taken in, the true pose would be refused as a jump."""
    from zswarm.net import messages as msg
    from zswarm.net.poses import PoseTable

    table, now = PoseTable(max_step=3.0 * 0.05, period=0.05), 1000.0
    old = msg.Pose(1, 10, now - 2.0, -1, 0.0, 0.0, 1.0, 0.0)  # sent 2 s ago, taken in now
    assert table.accept(1, old, now) is None
    later = msg.Pose(1, 50, now - 0.01, -1, 1.9, 0.0, 1.0, 0.0)  # 40 ticks on, 1.9 farther: it could
    assert table.accept(1, later, now + 0.001) is None
    forged = msg.Pose(1, 10**6, now, -1, 500.0, 0.0, 0.0, 0.0)  # a huge sequence number buys no leap
    assert table.accept(1, forged, now + 0.002) == "jump"


def test_a_member_token_nobody_holds_any_longer_is_asked_about_and_let_go():
    """The filter guards a silent neighbour whose member token is in a cell it listens to. Once, the
    token's removal never reached an agent (it had taken the token in from its question on entering
    the cell), and the agent braked beside where that neighbour was last heard for as long as it
    stayed (35 s, the CI failure of the hostile flood). A token the filter relies on alone is now
    asked about again, over real Zenoh sessions here: one nobody holds is let go, one that is held
    stays, and a live change that comes after the question wins over its answer."""
    import time

    import zenoh

    from agents.outreach import Outreach
    from agents.sensing import Body, Sensing
    from conftest import free_port
    from zswarm.net import messages as msg
    from zswarm.net.bridge import Bridge
    from zswarm.net.config import zenoh_config
    from zswarm.net.runspec import RunSpec

    spec = RunSpec(run="asked", scenario_name="moving-prey")  # R = 1, v_max = 1: cells reach 1.1
    keys = spec.keys
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with zenoh.open(zenoh_config("peer", listen=[endpoint])) as holder, \
            zenoh.open(zenoh_config("peer", connect=[endpoint])) as session:
        sensing = Sensing(spec, 0, Body(0.0, 0.0), probe_latency=False)
        bridge = Bridge(session, None, deliver=sensing.handle, batch=True, channels=True)
        reach = Outreach(sensing, bridge)
        now = time.time()
        at = {1: (0.5, 0.0), 3: (-0.9, 0.0), 4: (0.0, -0.95)}
        for who, p in at.items():
            age = 0.02 if who == 1 else 2.0  # 1 heard all along; 3 and 4 quiet for 2 s near the edge
            assert sensing.neighbours.accept(who, msg.Pose(who, 1, now - age, -1, *p, 0.0, 0.0), now - age) is None
            sensing.membership.alive.add(who)
        cells = {who: keys.cell(*p) for who, p in at.items()}
        sensing.membership.listen_to(sorted(set(cells.values())), [])
        token = holder.liveliness().declare_token(keys.member(cells[4], 4))  # 4 is still there
        for who in (3, 4):  # both came in as answers on entering the cells; 3's removal never came
            sensing.handle(("in-now", keys.member(cells[who], who), b"", False, now))
        for cell in set(cells.values()):
            sensing.handle(("in-answered", keys.cell_members(cell), b"", False, now))
        guarded = lambda: {p for p, _, _ in sensing.sense(None, 0.5, 1.0, 0.05)[1]}  # noqa: E731
        assert guarded() == {at[1], at[3], at[4]} and set(sensing.membership.doubted) == {3, 4}
        time.sleep(0.5)  # the holder's token has reached the other session
        reach.check_members(time.time())
        deadline = time.monotonic() + 10.0
        while 3 in sensing.membership.members and time.monotonic() < deadline:
            bridge.drain()
            time.sleep(0.05)
        assert 3 not in sensing.membership.members and sensing.membership.members[4] == {cells[4]}
        assert guarded() == {at[1], at[4]}
        # asked again no sooner than MEMBER_CHECK_S; a live change after a question wins over its answer
        asked = time.time()
        sensing.handle(("in", keys.member(cells[3], 3), b"", False, asked + 0.1))
        sensing.handle(("in-gone", keys.member(cells[3], 3), b"", True, asked))
        assert sensing.membership.members[3] == {cells[3]}
        token.undeclare()
        bridge.close()


def _inertial_loop(dims: int, n: int, delay: int, seed: int, braking: bool = True, steps: int = 120):
    """A closed loop of n double integrators (A = 2, v_max = 1, T = 0.05) and one obstacle, started at
    random inside the safe set (every gap wider than both braking distances), each agent commanded
    straight at its nearest neighbour at full speed half the time and at random otherwise, filtered by
    (S4) on what it heard ``delay`` steps ago (synchronous ticks, each age exact). Returns the least
    distance over every pair and step less D_s, the least obstacle clearance less D_o, and how many
    agent-steps braked."""
    from zswarm.control import body as bodies

    T, A, v_max = 0.05, 2.0, 1.0
    s = sf.Safety(distance=0.1, clearance=0.05, v_max=v_max, period=T, sensing_radius=3.0)
    spec = bodies.BodySpec("double-integrator", v_max, accel=A)
    rng = np.random.default_rng(seed)
    centre, radius = np.zeros(dims), 0.3
    while True:  # a start inside the safe set, crowded
        p = rng.uniform(-1.2, 1.2, size=(n, dims))
        v = rng.normal(size=(n, dims))
        v *= (rng.uniform(0, v_max, size=n) / np.linalg.norm(v, axis=1))[:, None]
        stop = sf.stopping(np.linalg.norm(v, axis=1), A)
        d = np.linalg.norm(p[:, None] - p[None], axis=-1) + np.eye(n) * 9
        clear = np.linalg.norm(p - centre, axis=1) - radius - s.clearance - stop
        if (d - s.distance - stop[:, None] - stop[None] > 0.02).all() and (clear > 0.02).all():
            break
    state = bodies.BodyState(p, v, np.full(n, np.nan))
    history = [state]
    ii, jj = np.nonzero(~np.eye(n, dtype=bool))
    least, least_o, braked = np.inf, np.inf, 0
    for k in range(steps):
        then = history[max(k - delay, 0)]
        age = np.full(len(ii), (k - max(k - delay, 0)) * T)
        near = np.argmin(np.linalg.norm(state.position[:, None] - state.position[None], axis=-1) + np.eye(n) * 9, axis=1)
        chase = state.position[near] - state.position
        chase *= (v_max / np.linalg.norm(chase, axis=1))[:, None]
        wild = rng.normal(size=(n, dims))
        u_hat = np.where((rng.uniform(size=n) < 0.5)[:, None], chase, wild / np.linalg.norm(wild, axis=1)[:, None])
        inertia = sf.Inertia(state.velocity, np.full(n, A),
                             sf.neighbour_stop(then.velocity[jj], age, A, v_max) if braking else 0.0)
        if not braking:
            inertia = sf.Inertia(state.velocity, np.full(n, np.inf), 0.0)
        r = sf.rows(s, n, ii, state.position[ii] - then.position[jj], age, np.arange(n),
                    state.position - centre, np.full(n, radius), inertia=inertia)
        done = sf.apply(u_hat, r)
        braked += int(done.braked.sum())
        state = bodies.step(spec, state, done.command, T)
        history.append(state)
        d = np.linalg.norm(state.position[:, None] - state.position[None], axis=-1) + np.eye(n) * 9
        least = min(least, d.min() - s.distance)
        least_o = min(least_o, (np.linalg.norm(state.position - centre, axis=1) - radius - s.clearance).min())
    return least, least_o, braked


@pytest.mark.parametrize("dims", [2, 3])
def test_bodies_with_inertia_stay_apart_on_data_of_any_age_and_collide_without_the_braking_term(dims):
    """(S4), the property: random crowded starts inside the safe set, every agent driven at its nearest
    neighbour or at random, on data up to 0.3 s old and on data older than the bound (the agent brakes):
    no pair comes within D_s and no agent within D_o of the obstacle, at any step. Without the braking
    terms (each body taken for one that stops at once, the point filter's rows) they collide."""
    for seed in range(6):
        for delay in (0, 2, 6):
            least, least_o, _ = _inertial_loop(dims, 6, delay, seed)
            assert least >= -1e-9 and least_o >= -1e-9, (seed, delay, least, least_o)
    least, _, braked = _inertial_loop(dims, 6, 40, 0)  # 2 s old: beyond the bound, it brakes
    assert least >= -1e-9 and braked > 0
    worst = min(_inertial_loop(dims, 6, 0, seed, braking=False)[0] for seed in range(6))
    assert worst < -0.01, worst


@pytest.mark.parametrize("dims", [2, 3])
def test_double_integrators_behind_the_filter_every_law_and_a_users_in_the_simulators(dims):
    """(S4) in the engines: 12 double integrators (accel 1.5: 0.33 to stop from full speed) of every
    registered law and a user's law file, in the reference simulator and in one batch of the batched
    simulator: no collision behind the filter. The point body's rows alone (no braking distance) let
    vasarhelyi's collide (the break check), and vasarhelyi's law alone collides."""
    from pathlib import Path

    from zswarm.laws.registry import BUILTIN
    from zswarm.sim.batch import Member, simulate_batch
    from zswarm.sim.simulator import simulate

    mine = str(Path(__file__).resolve().parents[1] / "examples" / "my_law.py") + ":seek"
    name = "moving-prey" if dims == 2 else "moving-prey-3d"
    scenarios = [get_scenario(name, {"law": law, "body": "double-integrator", "accel": 1.5, "n_agents": 12})
                 for law in (*BUILTIN, mine)]
    for scenario in scenarios:
        s = simulate(scenario, 0, duration=12.0, safety="barrier").summary
        assert s["collisions"] == 0, (scenario.params.law.law, s["collisions"])
    batch = simulate_batch([Member(s, 0, safety="barrier") for s in scenarios], int(12.0 / scenarios[0].dt))
    assert [o.collisions for o in batch.outcomes] == [0] * len(scenarios)
    alone = scenarios[list(BUILTIN).index("vasarhelyi")]
    assert simulate(alone, 0, duration=12.0, safety="off").summary["collisions"] > 0
