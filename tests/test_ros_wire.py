"""The ROS 2 wire, checked against implementations that are not ours: rosbags' message types and
RIHS01 hashes, Zenoh's own serializer for rmw_zenoh's attachment, rmw_zenoh's documented key example,
and CDR bytes laid out by hand from the CDR rules."""

from __future__ import annotations

import math
import struct

import pytest
import zenoh.ext as zx
from hypothesis import given, settings
from hypothesis import strategies as st

from zswarm.errors import UsageError
from zswarm.ros.graph import node_token, topic_token
from zswarm.ros.motion import Odom, odometry, read_pose, read_twist, twist
from zswarm.ros.robot_sim import SimRobot
from zswarm.ros.robots import ODOMETRY, POSE_STAMPED, TWIST, Robot, load_robots
from zswarm.ros.wire import Attachment, Route, WireError

JAZZY = Route("rmw_zenoh", "jazzy")


def test_the_key_of_a_topic_is_rmw_zenohs():
    # rmw_zenoh's docs/design.md: "0/chatter/std_msgs::msg::dds_::String_/RIHS01_df668c74..."
    assert JAZZY.key("/chatter", "std_msgs/msg/String") == (
        "0/chatter/std_msgs::msg::dds_::String_/RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18")
    assert Route("rmw_zenoh", "humble", 7).key("/robot0/cmd_vel/", TWIST) == (
        "7/robot0/cmd_vel/geometry_msgs::msg::dds_::Twist_/TypeHashNotSupported")
    assert Route("ros2dds").key("/robot0/cmd_vel", TWIST) == "robot0/cmd_vel"
    assert Route("ros2dds", bridge_namespace="/site1").key("/robot0/odom", ODOMETRY) == "site1/robot0/odom"


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 2**62), st.integers(0, 2**62), st.binary(min_size=16, max_size=16))
def test_the_attachment_is_what_zenohs_own_serializer_writes(sequence, stamp, gid):
    ours = Attachment(sequence, stamp, gid).encode()
    theirs = zx.z_serialize((zx.Int64(sequence), zx.Int64(stamp), gid)).to_bytes()
    assert ours == theirs and len(ours) == 33
    assert Attachment.decode(theirs) == Attachment(sequence, stamp, gid)


@pytest.mark.parametrize("data", [None, b"", b"\x00" * 32, b"\x00" * 16 + b"\x0f" + b"\x00" * 16])
def test_a_sample_without_rmw_zenohs_attachment_is_refused(data):
    with pytest.raises(WireError) as err:
        Attachment.decode(data)
    assert err.value.reason == "attachment"


def test_a_twist_is_cdr_little_endian_as_laid_out_by_hand():
    """Encapsulation header 00 01 00 00, then six float64 (two Vector3), 8-aligned from after the header."""
    assert twist(JAZZY, 0.5, -1.25) == b"\x00\x01\x00\x00" + struct.pack("<6d", 0.5, 0, 0, 0, 0, -1.25)
    assert read_twist(JAZZY, b"\x00\x01\x00\x00" + struct.pack("<6d", 0.3, 9, 9, 9, 9, 2.0)) == (0.3, 2.0)
    assert read_twist(JAZZY, b"\x00\x00\x00\x00" + struct.pack(">6d", 0.3, 0, 0, 0, 0, 2.0)) == (0.3, 2.0)  # big endian


def test_odometry_round_trips_through_rosbags():
    odom = Odom(1.5, -2.0, 2.9, 0.4, -0.7, 1234.5)
    payload = odometry(JAZZY, odom, "robot0/odom", "robot0/base_footprint")
    m = JAZZY.types()  # decoded by rosbags itself, field by field
    raw = JAZZY.decode(ODOMETRY, payload)
    assert isinstance(raw, m[ODOMETRY]) and raw.child_frame_id == "robot0/base_footprint"
    assert read_pose(JAZZY, ODOMETRY, payload) == pytest.approx(odom)


@pytest.mark.parametrize("payload,reason", [
    (b"\x01\x02\x03\x04" + b"\x00" * 48, "header"),  # not CDR
    (b"", "header"),
    (b"\x00\x01\x00\x00" + b"\x00" * 10, "cdr"),  # too short for a Twist
    (b"\x00\x01\x00\x00" + struct.pack("<6d", math.nan, 0, 0, 0, 0, 0), "cdr"),
])
def test_malformed_or_foreign_cdr_is_refused_with_a_reason(payload, reason):
    with pytest.raises(WireError) as err:
        read_twist(JAZZY, payload)
    assert err.value.reason == reason


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=200))
def test_no_bytes_make_the_decoder_raise_anything_but_a_wire_error(data):
    for msgtype in (TWIST, ODOMETRY):
        try:
            read_twist(JAZZY, data) if msgtype == TWIST else read_pose(JAZZY, msgtype, data)
        except WireError:
            pass


def test_odom_frames_turn_into_the_world_and_back():
    r = Robot(0, "/r", (1.0, -2.0, 0.7))
    x, y, yaw = r.to_world(0.5, 0.25, -2.0)
    assert r.to_odom(x, y, yaw) == pytest.approx((0.5, 0.25, -2.0))
    assert r.to_world(0.0, 0.0, 0.0) == pytest.approx((1.0, -2.0, 0.7))


def test_a_stand_in_robot_obeys_its_limits_and_stops_when_commands_stop():
    robot = SimRobot(Robot(0, "/r", max_linear=0.5, max_angular=2.0), JAZZY, Odom(0, 0, 0), cmd_timeout=0.25)
    robot.take(twist(JAZZY, 3.0, 0.0), now=10.0)
    assert robot.inputs(10.1) == (0.5, 0.0)  # clipped to max_linear
    robot.take(twist(JAZZY, 0.5, 2.0), now=10.0)
    u, omega = robot.inputs(10.1)  # the outer wheel would exceed 0.5 m/s: both slowed, curvature kept
    assert max(abs(u - omega * 0.08), abs(u + omega * 0.08)) == pytest.approx(0.5) and omega / u == pytest.approx(4.0)
    assert robot.inputs(10.26) == (0.0, 0.0)  # 0.26 s after the last command: stopped
    robot.take(b"\x00\x01\x00\x00garbage", now=11.0)
    assert robot.rejected == {"cdr": 1} and robot.commands == 2


def test_a_stand_in_robot_starved_of_cpu_pauses_rather_than_leaps():
    """Once behind its schedule (its thread starved), the stand-in robots' loop does not make up the
    steps it missed in a burst: the robot would cover the missed time at once, and the agent that
    follows its odometry would send a pose farther from its last than it can go (refused as a jump)."""
    import time

    import zenoh

    from zswarm.net.config import zenoh_config
    from zswarm.ros.robot_sim import run

    robot = SimRobot(Robot(0, "/r", max_linear=0.5, max_angular=2.0), JAZZY, Odom(0, 0, 0), cmd_timeout=1e9)
    robot.take(twist(JAZZY, 0.5, 0.0), now=time.time())
    seen: list[tuple[float, float]] = []
    step = robot.step
    robot.step = lambda dt, now: seen.append((time.monotonic(), step(dt, now).x)) or robot.pose

    class Starving:  # the loop's wait: the 5th sleeps 0.4 s (a starved thread) instead of 0.02
        calls = 0

        def is_set(self) -> bool:
            return self.calls >= 30

        def wait(self, timeout: float) -> bool:
            self.calls += 1
            time.sleep(0.4 if self.calls == 5 else timeout)
            return False

    with zenoh.open(zenoh_config("peer", listen=[])) as session:
        run(session, JAZZY, [robot], 50.0, Starving())
    # between any two steps, at most what 0.5 m/s covers in the wall time between them, give or take two
    # steps' timing: no burst of the steps missed (that would be 0.4 s, 0.2 m, at once)
    assert max(x1 - x0 - 0.5 * (t1 - t0) for k, (t0, x0) in enumerate(seen) for t1, x1 in seen[k + 1:]) <= 0.02


@pytest.mark.parametrize("text,needle", [
    ('route = "dds"\n[[robot]]\nid = 0\nnamespace = "/r0"\n', "route must be one of"),
    ('distro = "iron"\n[[robot]]\nid = 0\nnamespace = "/r0"\n', "distro must be one of"),
    ('route = "rmw_zenoh"\n', "no [[robot]] entries"),
    ('[[robot]]\nid = 0\nnamespace = "r0"\n', "namespace must be a ROS namespace"),
    ('[[robot]]\nid = 0\nnamespace = "/r0"\n[[robot]]\nid = 0\nnamespace = "/r1"\n', "two robots have id 0"),
    ('[[robot]]\nid = 0\nnamespace = "/r0"\nmax_linear = -1\n', "max_linear must be a number"),
    ('[[robot]]\nid = 0\nnamespace = "/r0"\nodom_origin = [1, 2]\n', "odom_origin must be [x, y, yaw]"),
    ('[[robot]]\nid = 0\nnamespace = "/r0"\nspeed = 2\n', "unknown field 'speed'"),
    ("[[robot\n", "is not valid TOML"),
])
def test_a_bad_robots_file_is_one_line(tmp_path, text, needle):
    f = tmp_path / "robots.toml"
    f.write_text(text)
    with pytest.raises(UsageError, match=None) as err:
        load_robots(f)
    assert needle in str(err.value) and "\n" not in str(err.value) and str(f) in str(err.value)


def test_liveliness_tokens_are_rmw_zenohs_documented_examples():
    """rmw_zenoh's docs/design.md: the listener node, its subscription and the talker's publisher."""
    zid, domain2 = "aac3178e146ba6f1fc6e6a4085e77f21", Route("rmw_zenoh", "jazzy", 2)
    assert node_token(domain2, zid, 0, "/", "listener") == f"@ros2_lv/2/{zid}/0/0/NN/%/%/listener"
    hash_ = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
    assert topic_token(domain2, zid, 0, 10, "MS", "/", "listener", "/chatter", "std_msgs/msg/String") == (
        f"@ros2_lv/2/{zid}/0/10/MS/%/%/listener/%chatter/std_msgs::msg::dds_::String_/{hash_}/::,10:,:,:,,")
    talker = "8b20917502ee955ac4476e0266340d5c"
    assert topic_token(domain2, talker, 0, 10, "MP", "/", "talker", "/chatter", "std_msgs/msg/String",
                       "::,7:,:,:,,") == (
        f"@ros2_lv/2/{talker}/0/10/MP/%/%/talker/%chatter/std_msgs::msg::dds_::String_/{hash_}/::,7:,:,:,,")
    # a namespaced node: every '/' inside a name is a '%'
    assert topic_token(JAZZY, zid, 0, 1, "MP", "/robot0", "zswarm_agent_0", "/robot0/cmd_vel", TWIST).split("/")[6:10] == [
        "%", "%robot0", "zswarm_agent_0", "%robot0%cmd_vel"]


def test_a_pose_stamped_topic_gives_the_pose_without_speeds():
    t = JAZZY.types()
    q = t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(0.6), w=math.cos(0.6))
    pose = t["geometry_msgs/msg/Pose"](position=t["geometry_msgs/msg/Point"](x=2.0, y=-1.0, z=0.0), orientation=q)
    header = t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=3, nanosec=500_000_000), frame_id="map")
    payload = JAZZY.encode(POSE_STAMPED, t[POSE_STAMPED](header=header, pose=pose))
    assert read_pose(JAZZY, POSE_STAMPED, payload) == pytest.approx(Odom(2.0, -1.0, 1.2, 0.0, 0.0, 3.5))
    robot = Robot(0, "/r0", pose_topic="/mocap/r0/pose")
    assert (robot.odom, robot.pose_type, robot.cmd_vel) == ("/mocap/r0/pose", POSE_STAMPED, "/r0/cmd_vel")
