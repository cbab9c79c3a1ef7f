"""Collisions judged at one instant (zswarm.swarm.timed_contacts): the free clock's judge counts two
agents only where they were closer than 2 d^r at the same time, on the senders' clock."""

from __future__ import annotations

import math

import numpy as np

from zswarm.swarm.timed_contacts import TimedContacts, judge_tracks

D = 0.2  # the collision distance 2 d^r


def feed(judge: TimedContacts, who: int, poses: list[tuple[float, tuple[float, ...]]], seq0: int = 1) -> None:
    """Each pose taken in as soon as it was sent."""
    for k, (stamp, point) in enumerate(poses):
        judge.add(who, seq0 + k, stamp, point, received=stamp)


def line(x0: float, x1: float, t0: float, t1: float, steps: int, y: float = 0.0) -> list[tuple[float, tuple]]:
    return [(t0 + (t1 - t0) * k / steps, (x0 + (x1 - x0) * k / steps, y)) for k in range(steps + 1)]


def test_poses_that_overlap_only_across_time_are_not_a_collision() -> None:
    """Agent 0 leaves x = 0 at t = 0 and agent 1 reaches it at t = 1: their stale and fresh poses
    overlap in a snapshot (what the world's latest-pose view compares), but never at one instant."""
    judge = TimedContacts(D)
    feed(judge, 0, line(0.0, 1.0, 0.0, 1.0, 10))
    feed(judge, 1, line(-5.0, 0.0, 0.0, 1.0, 10))
    judge.judge(now=1.0)
    judge.judge(now=2.0)
    assert judge.collisions == 0
    stale_0, fresh_1 = (0.0, 0.0), (0.0, 0.0)
    assert math.dist(stale_0, fresh_1) < D  # the snapshot's pair, for contrast
    assert judge.closest is not None and judge.closest > D


def test_a_contact_at_one_instant_counts_once_per_onset() -> None:
    judge = TimedContacts(D)
    feed(judge, 0, [(0.1 * k, (0.0, 0.0)) for k in range(31)])
    # agent 1 comes within 0.1 at t = 0.9, stays until t = 1.5, leaves, and comes back at t = 2.5
    path = [(0.1 * k, (1.0 if k < 9 else 0.1 if k <= 15 else 1.0 if k < 25 else 0.05, 0.0)) for k in range(31)]
    feed(judge, 1, path)
    onsets = judge.judge(now=3.0)
    assert judge.collisions == 2
    assert [round(o.stamp, 6) for o in onsets] == [0.9, 2.5]
    assert onsets[0].i == 0 and onsets[0].j == 1 and math.isclose(onsets[0].distance, 0.1)
    assert judge.result()["collisions_at_one_time"] == 2


def test_the_judge_waits_for_a_lagging_agent_and_judges_the_instant_right() -> None:
    """Agent 1's poses arrive late. Judged before they are in, an instant would pair agent 0's fresh
    pose with agent 1's old one; the judge holds the instant back until both are in."""
    judge = TimedContacts(D, silence=5.0)
    a = line(0.0, 2.0, 0.0, 2.0, 20)  # agent 0 walks along y = 0
    b = [(t, (x, 0.05)) for t, (x, _) in line(0.0, 2.0, 0.0, 2.0, 20)]  # agent 1 walks beside it, 0.05 away
    feed(judge, 0, a)
    feed(judge, 1, b[:3])  # only agent 1's first poses are in, and more are on their way
    judge.judge(now=2.0)
    assert judge.judged is not None and math.isclose(judge.judged, 0.2)  # held back to what both sent
    feed(judge, 1, b[3:], seq0=4)
    judge.judge(now=2.1)
    assert judge.collisions == 1  # one contact, from the start, never broken
    assert math.isclose(judge.judged, 2.0) and math.isclose(judge.closest, 0.05)


def test_a_silent_agent_holds_its_last_pose() -> None:
    """A starved agent does not tick, so it does not move: once nothing has come from it for
    ``silence`` seconds the judge stops waiting for it and holds its last pose; an agent walking into
    it collides. Before that, the judge waits."""
    judge = TimedContacts(D, silence=1.0)
    feed(judge, 1, [(0.0, (0.0, 0.0)), (0.1, (0.0, 0.0))])
    feed(judge, 0, line(-3.0, 0.0, 0.0, 3.0, 30))
    judge.judge(now=1.0)
    assert judge.judged is not None and math.isclose(judge.judged, 0.1)
    judge.judge(now=3.0)
    assert judge.collisions == 1
    assert judge.onsets[0].stamp > 2.5


def test_an_agent_that_left_is_judged_only_up_to_its_last_pose() -> None:
    judge = TimedContacts(D)
    feed(judge, 1, [(0.0, (0.0, 0.0)), (1.0, (0.0, 0.0))])
    judge.leave(1)
    feed(judge, 0, line(-3.0, 0.0, 0.0, 3.0, 30))
    judge.judge(now=3.0)
    assert judge.collisions == 0
    assert 1 not in judge.tracks  # dropped once judged past


def test_gaps_and_late_poses_are_counted_and_three_dimensions_work() -> None:
    judge = TimedContacts(D)
    judge.add(0, 1, 0.0, (0.0, 0.0, 0.0), received=0.0)
    judge.add(0, 4, 0.3, (0.0, 0.0, 0.05), received=0.3)  # seq 2 and 3 never came
    judge.add(1, 1, 0.0, (1.0, 0.0, 0.0), received=0.0)
    judge.add(1, 2, 0.3, (0.0, 0.0, 0.0), received=0.3)
    judge.judge(now=0.3)
    assert judge.gaps == 2 and judge.collisions == 1
    judge.add(0, 2, 0.1, (0.0, 0.0, 0.0), received=0.4)  # stamped before the judged instant: too late
    assert judge.late == 1
    assert judge.result()["poses_too_late_to_judge"] == 1


def test_a_restarted_sender_starts_a_new_track() -> None:
    judge = TimedContacts(D)
    feed(judge, 0, line(0.0, 1.0, 0.0, 1.0, 10), seq0=5000)
    judge.add(0, 1, 1.5, (9.0, 9.0), received=1.5)  # counts from 1 again: a new process, anywhere
    assert judge.tracks[0].stamps == [1.5] and judge.gaps == 0


def test_the_agents_own_tracks_are_judged_exactly() -> None:
    """judge_tracks: complete tracks (what each agent sent), judged window by window; the counts are the
    ones the incremental judge gives the same poses, and a restarted process continues its agent."""
    a = np.array([(t, x, 0.0) for t, (x, _) in line(0.0, 2.0, 0.0, 2.0, 40)])
    b = np.array([(t, x, 0.05) for t, (x, _) in line(3.0, 1.0, 0.0, 2.0, 40)])  # meets agent 0 at x = 1.5, t = 1.5
    c = np.array([(t, 9.0, 9.0) for t in np.linspace(0.0, 2.0, 41)])
    c2 = np.array([(t, 2.0, 0.0) for t in np.linspace(2.5, 3.0, 11)])  # agent 2 restarted on agent 0's last spot
    out = judge_tracks([(0, a), (1, b), (2, c), (2, c2)], D)
    assert out["collisions"] == 1 and out["processes"] == 4 and out["poses"] == 41 * 3 + 11
    assert out["onsets"][0]["agents"] == [0, 1] and 1.4 < out["onsets"][0]["stamp"] < 1.5
    assert math.isclose(out["closest"], 0.05, abs_tol=1e-9)
    assert out["judged_s"] == 3.0  # agent 0 left at t = 2: no contact with the restarted agent 2 after


def test_a_contact_across_a_lost_pose_is_uncertain_not_a_collision() -> None:
    """Agent 1's poses 2-10 never came: at the instants between its poses 1 and 11 its position is not
    known (it may have been anywhere a few steps away), so a contact there is counted as uncertain;
    the same contact with every pose in is a collision."""
    def run(lost: bool) -> TimedContacts:
        judge = TimedContacts(D)
        feed(judge, 0, [(0.1 * k, (0.05, 0.0)) for k in range(11)])  # agent 0 sits 0.05 from agent 1's start
        ones = [(0.1 * k, (0.0, 0.0) if k == 0 else (1.0, 0.0)) for k in range(11)]  # agent 1 left at once
        for k, (stamp, point) in enumerate(ones):
            if not (lost and 1 <= k <= 9):
                judge.add(1, k + 1, stamp, point, received=stamp)
        judge.judge(now=2.0)
        return judge

    whole, holed = run(lost=False), run(lost=True)
    assert whole.collisions == 1 and whole.uncertain == 0  # at t = 0, both poses exact
    assert holed.collisions == 1 and holed.uncertain == 0  # t = 0 is agent 1's own stamp: still exact
    assert holed.gaps == 9
    # agent 0's stamps between 0 and 1 s find agent 1 held at the origin, across its lost poses: the
    # contact continues there without a new onset; make it a fresh one by parting them first
    judge = TimedContacts(D)
    feed(judge, 0, [(0.1 * k, (0.05, 0.0) if k != 1 else (5.0, 0.0)) for k in range(11)])
    judge.add(1, 1, 0.0, (0.0, 0.0), received=0.0)
    judge.add(1, 10, 1.0, (1.0, 0.0), received=1.0)  # seq 2-9 lost: where was it at 0.2-0.9 s?
    judge.judge(now=2.0)
    assert judge.collisions == 1 and judge.uncertain == 1  # the onset at 0.2 s is not counted as certain
    assert judge.result()["uncertain_contacts_at_one_time"] == 1


def test_a_run_where_no_pair_came_near_says_how_near_at_least() -> None:
    """No pair within twice the collision distance at one instant: the closest is not walked, and the
    summary says it was at least that far (a bare null beside a real min_pair_distance read as missing)."""
    judge = TimedContacts(D)
    feed(judge, 0, line(0.0, 0.0, 0.0, 1.0, 10))
    feed(judge, 1, line(3.0, 3.0, 0.0, 1.0, 10))
    judge.judge(now=1.0)
    out = judge.result()
    assert out["closest_at_one_time"] is None and out["closest_at_one_time_at_least"] == 2 * D
    near = TimedContacts(D)
    feed(near, 0, line(0.0, 0.0, 0.0, 1.0, 10))
    feed(near, 1, line(0.3, 0.3, 0.0, 1.0, 10))
    near.judge(now=1.0)
    assert near.result()["closest_at_one_time"] == 0.3 and near.result()["closest_at_one_time_at_least"] is None
