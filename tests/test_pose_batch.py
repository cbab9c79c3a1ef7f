"""The world's batched table of poses (zswarm.net.pose_batch) accepts exactly what the per-pose table
(zswarm.net.poses) accepts, for the same reasons, and ends holding the same latest pose of each agent."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from zswarm.net import messages as msg
from zswarm.net.pose_batch import REASON, PoseArrays
from zswarm.net.poses import PoseTable

MAX_STEP, PERIOD = 0.3, 0.05

pose = st.tuples(
    st.integers(0, 4),                                  # the agent
    st.sampled_from([0, 0, 0, 0, 1]),                   # 1: sent under another agent's key
    st.integers(0, 12) | st.just(1500),                 # seq (1500: far ahead, then a "restart" below it)
    st.sampled_from([-1, -1, 0, 1, 2, 5]),              # lockstep step, or -1
    st.floats(-3, 3), st.floats(-3, 3), st.floats(-3, 3),
    st.floats(-1, 1), st.floats(-1, 1),
    st.floats(0.0, 0.5),                                # how far the sender's stamp is behind the batch's clock
    st.sampled_from([None, None, 0.5]),                 # a heading (2-D only)
)


@settings(max_examples=400, deadline=None)
@given(batches=st.lists(st.lists(pose, min_size=1, max_size=6), min_size=1, max_size=8), dims=st.sampled_from([2, 3]))
def test_a_batch_is_accepted_as_its_poses_one_by_one(batches, dims):
    table, arrays = PoseTable(MAX_STEP, PERIOD), PoseArrays(MAX_STEP, PERIOD, dims)
    now = 100.0
    for batch in batches:
        now += 0.05
        poses, keys = [], []
        for who, other_key, seq, step, x, y, z, vx, vy, lag, heading in batch:
            extra = dict(z=z, vz=0.25) if dims == 3 else dict(heading=heading)
            poses.append(msg.Pose(who, seq, now - lag, step, x, y, vx, vy, **extra))
            keys.append((who + other_key) % 5)
        alone = [table.accept(key, p, now) for key, p in zip(keys, poses)]
        # as the world takes them: runs of one record size, in arrival order
        payloads = [msg.encode(p) for p in poses]
        together, start = [], 0
        for end in range(1, len(payloads) + 1):
            if end == len(payloads) or len(payloads[end]) != len(payloads[start]):
                rows, ok = msg.decode_pose_records(payloads[start:end])
                assert ok.all()
                codes = arrays.accept(np.array(keys[start:end]), rows, now)
                together += [REASON.get(c) for c in codes.tolist()]
                start = end
        assert together == alone
    held = table.latest()
    ids, rows = arrays.latest()
    assert sorted(held) == ids.tolist()
    for who, r in zip(ids.tolist(), rows.tolist()):
        p, e = held[who], table.get(who)
        assert (arrays.seq[r], arrays.step[r], arrays.stamp[r], arrays.received[r]) == (p.seq, p.step, p.stamp, e.received)
        assert tuple(arrays.position[r]) == p.position and tuple(arrays.velocity[r]) == p.velocity
        assert (p.heading is None and np.isnan(arrays.heading[r])) or arrays.heading[r] == p.heading


def test_a_forgotten_agent_is_no_longer_held_and_starts_afresh():
    arrays = PoseArrays(MAX_STEP, PERIOD, 2)
    first = msg.decode_pose_records([msg.encode(msg.Pose(7, 5, 1.0, -1, 0.0, 0.0, 0.0, 0.0))])[0]
    far = msg.decode_pose_records([msg.encode(msg.Pose(7, 6, 1.05, -1, 9.0, 0.0, 0.0, 0.0))])[0]
    assert arrays.accept(np.array([7]), first, 1.0).tolist() == [0]
    assert arrays.accept(np.array([7]), far, 1.05).tolist() == [2]  # an impossible jump
    arrays.forget(7)
    assert arrays.latest()[0].tolist() == []
    assert arrays.accept(np.array([7]), far, 1.1).tolist() == [0]  # back, anywhere: a new agent
    assert arrays.latest({7, 8})[0].tolist() == [7] and arrays.latest({8})[0].tolist() == []


def test_ids_far_apart_take_a_row_each_not_an_array_to_the_largest():
    """A pose may name any id up to MAX_ID (a rogue one too): the table grows by agents heard, not by ids."""
    arrays = PoseArrays(MAX_STEP, PERIOD, 2)
    big = [msg.encode(msg.Pose(who, 1, 1.0, -1, float(k), 0.0, 0.0, 0.0)) for k, who in enumerate((msg.MAX_ID, 3, 70))]
    rows, ok = msg.decode_pose_records(big)
    assert arrays.accept(np.array([msg.MAX_ID, 3, 70]), rows, 1.0).tolist() == [0, 0, 0]
    assert len(arrays.known) <= 64
    ids, at = arrays.latest()
    assert ids.tolist() == [3, 70, msg.MAX_ID] and arrays.position[at, 0].tolist() == [1.0, 2.0, 0.0]


def test_an_empty_table_holds_no_one():
    """A world that heard no pose yet observes an empty swarm (it does not fail)."""
    arrays = PoseArrays(MAX_STEP, PERIOD, 3)
    assert arrays.latest()[0].tolist() == [] and arrays.latest({0, 1})[0].tolist() == []
    assert arrays.position.shape[1] == 3

