"""``zswarm export RUN.rrd --mcap RUN.mcap``: read back with an MCAP/ROS 2 reader that is not ours
(Foxglove's ``mcap`` and ``mcap-ros2-support``), the positions equal the recording's to 1e-9."""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np
import pytest

from conftest import run_cli
from zswarm.swarm.scenarios import get_scenario
from zswarm.record.replay import load_run, recompute
from zswarm.sim.simulator import simulate


def read_mcap(path) -> dict[str, list]:
    """Every message of ``path``, decoded by mcap-ros2-support, by topic: (log time ns, message)."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    out: dict[str, list] = defaultdict(list)
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages():
            assert channel.message_encoding == "cdr" and schema.encoding == "ros2msg"
            out[channel.topic].append((message.log_time, decoded))
    return out


@pytest.mark.parametrize("scenario,overrides", [("moving-prey", {"body": "unicycle"}), ("moving-prey-3d", {})])
def test_an_exported_run_reads_back_equal_to_its_recording(tmp_path, scenario, overrides):
    rec, out = tmp_path / "run.rrd", tmp_path / "run.mcap"
    simulate(get_scenario(scenario, overrides), 0, duration=2.0, record=rec)
    res = run_cli("-m", "zswarm", "export", str(rec), "--mcap", str(out), cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    run = load_run(rec)
    topics = read_mcap(out)
    dims = run.frames[0].positions.shape[1]
    n = len(run.frames[0].ids)
    assert {f"/swarm/agent_{i}/pose" for i in range(n)} <= set(topics) and "/swarm/prey" in topics
    for i in range(n):
        poses = topics[f"/swarm/agent_{i}/pose"]
        assert len(poses) == len(run.frames)
        got = np.array([[m.pose.position.x, m.pose.position.y, m.pose.position.z][:dims] for _, m in poses])
        want = np.stack([f.positions[list(f.ids).index(i)] for f in run.frames])
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-9)
        assert [t for t, _ in poses] == [round(f.t * 1e9) for f in run.frames]
        assert all(m.header.frame_id == "world" for _, m in poses)
        if overrides.get("body") == "unicycle":  # the orientation is the robot's heading
            yaw = [2.0 * math.atan2(m.pose.orientation.z, m.pose.orientation.w) for _, m in poses]
            heading = [f.headings[list(f.ids).index(i)] for f in run.frames]
            assert np.allclose(np.angle(np.exp(1j * (np.array(yaw) - heading))), 0.0, atol=1e-9)
    prey = np.array([[m.point.x, m.point.y, m.point.z][:dims] for _, m in topics["/swarm/prey"]])
    np.testing.assert_allclose(prey, np.stack([f.prey for f in run.frames]), rtol=0, atol=1e-9)
    (_, markers), = topics["/swarm/obstacles"]
    centers, radii = get_scenario(scenario, overrides).obstacle_arrays()
    assert len(markers.markers) == len(radii) and all(m.type == (2 if dims == 3 else 3) for m in markers.markers)
    np.testing.assert_allclose([m.scale.x / 2 for m in markers.markers], radii)
    distance = [m.data for _, m in topics["/swarm/metrics/centroid_goal_distance"]]
    assert len(distance) == len(run.frames)
    assert min(d for _, m in topics["/swarm/metrics/min_pair_distance"] for d in [m.data]) == pytest.approx(
        recompute(run)["min_pair_distance"], abs=1e-12)


def test_export_refuses_to_overwrite_and_names_what_is_missing(tmp_path):
    out = tmp_path / "x.mcap"
    out.write_bytes(b"")
    res = run_cli("-m", "zswarm", "export", str(tmp_path / "none.rrd"), "--mcap", str(out), cwd=tmp_path)
    assert res.returncode == 2 and "exists; give another path or --force" in res.stderr
    res = run_cli("-m", "zswarm", "export", str(tmp_path / "none.rrd"), "--mcap", str(tmp_path / "y.mcap"), cwd=tmp_path)
    assert res.returncode == 2 and "does not exist" in res.stderr and "Traceback" not in res.stderr


def test_export_to_a_folder_it_may_not_write_is_one_line(tmp_path):
    """A new user's 33-line double traceback: now one line, exit 2, before the recording is read."""
    res = run_cli("-m", "zswarm", "export", str(tmp_path / "none.rrd"), "--mcap", "/sys/run.mcap", cwd=tmp_path)
    lines = res.stderr.strip().splitlines()
    assert res.returncode == 2 and len(lines) == 1 and "cannot write /sys/run.mcap" in lines[0], res.stderr
