"""A recorded run as ROS 2 messages in an MCAP file, to play in Foxglove or with ``ros2 bag play``.

Topics (frame ``world``; time stamps are the run's simulated time, from 0):

- ``/swarm/agent_<ID>/pose`` geometry_msgs/msg/PoseStamped, every step: where the agent was, facing its
  heading where its body has one, else the way it moved (at rest: the identity);
- ``/swarm/prey`` geometry_msgs/msg/PointStamped, every step;
- ``/swarm/obstacles`` visualization_msgs/msg/MarkerArray, once: a cylinder (2-D) or a sphere (3-D) each;
- ``/swarm/metrics/<NAME>`` std_msgs/msg/Float64, every step: the observer's metrics, recomputed from the
  recording as ``zswarm replay`` does.

The bag is written by rosbags (MCAP storage, CDR, the type definitions of ``distro``), then the one
``.mcap`` file is kept.
"""

from __future__ import annotations

import math
import shutil
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from zswarm.swarm.observer import SwarmObserver
from zswarm.swarm.scenario import Scenario
from zswarm.ros.motion import quaternion
from zswarm.ros.wire import typestore

POSE, POINT, MARKERS, FLOAT = ("geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/PointStamped",
                               "visualization_msgs/msg/MarkerArray", "std_msgs/msg/Float64")


class _Messages:
    """Builders of the few message kinds the export writes, from one distro's types."""

    def __init__(self, distro: str) -> None:
        self.t = typestore(distro).types

    def header(self, ns: int) -> Any:
        stamp = self.t["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
        return self.t["std_msgs/msg/Header"](stamp=stamp, frame_id="world")

    def point(self, p: np.ndarray) -> Any:
        return self.t["geometry_msgs/msg/Point"](x=float(p[0]), y=float(p[1]), z=float(p[2]) if len(p) > 2 else 0.0)

    def pose(self, p: np.ndarray, yaw: float | None) -> Any:
        return self.t["geometry_msgs/msg/Pose"](position=self.point(p), orientation=quaternion(self.t, yaw))

    def marker(self, ns: int, k: int, center: np.ndarray, radius: float, dims: int) -> Any:
        t = self.t
        m = t["visualization_msgs/msg/Marker"]
        d = 2.0 * radius
        return m(header=self.header(ns), ns="obstacles", id=k, type=m.SPHERE if dims == 3 else m.CYLINDER,
                 action=m.ADD, pose=self.pose(center, None),
                 scale=t["geometry_msgs/msg/Vector3"](x=d, y=d, z=d if dims == 3 else 0.1),
                 color=t["std_msgs/msg/ColorRGBA"](r=0.6, g=0.6, b=0.6, a=1.0),
                 lifetime=t["builtin_interfaces/msg/Duration"](sec=0, nanosec=0), frame_locked=False, points=[],
                 colors=[], texture_resource="",
                 texture=t["sensor_msgs/msg/CompressedImage"](header=self.header(ns), format="", data=np.zeros(0, np.uint8)),
                 uv_coordinates=[], text="", mesh_resource="",
                 mesh_file=t["visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, np.uint8)),
                 mesh_use_embedded_materials=False)


def facing(heading: float | None, velocity: np.ndarray) -> float | None:
    """The yaw a pose is drawn with: the heading, else the direction of motion (None at rest)."""
    if heading is not None and math.isfinite(heading):
        return float(heading)
    return math.atan2(velocity[1], velocity[0]) if float(np.hypot(velocity[0], velocity[1])) > 1e-9 else None


def export_mcap(run: Any, scenario: Scenario, observer: SwarmObserver, out: Path,
                distro: str = "jazzy") -> dict[str, int]:
    """Write ``run`` (a :class:`zswarm.record.replay.RunRecord` of ``scenario``; ``observer`` a fresh
    one of it, which recomputes the metrics) to ``out`` (an .mcap file); returns the messages per topic."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    store, build = typestore(distro), _Messages(distro)
    counts: dict[str, int] = {}
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / "bag"
        with Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
            links: dict[str, Any] = {}

            def put(topic: str, msgtype: str, message: Any, ns: int) -> None:
                if topic not in links:
                    links[topic] = writer.add_connection(topic, msgtype, typestore=store)
                writer.write(links[topic], ns, store.serialize_cdr(message, msgtype))
                counts[topic] = counts.get(topic, 0) + 1

            centers, radii = scenario.obstacle_arrays()
            ns0 = int(round(run.frames[0].t * 1e9)) if run.frames else 0
            markers = [build.marker(ns0, k, c, float(r), scenario.dimensions) for k, (c, r) in enumerate(zip(centers, radii))]
            put("/swarm/obstacles", MARKERS, store.types[MARKERS](markers=markers), ns0)
            for f in run.frames:
                ns = int(round(f.t * 1e9))
                for k, agent in enumerate(f.ids.tolist()):
                    heading = None if f.headings is None else float(f.headings[k])
                    pose = build.pose(f.positions[k], facing(heading, f.velocities[k]))
                    put(f"/swarm/agent_{agent}/pose", POSE, store.types[POSE](header=build.header(ns), pose=pose), ns)
                if f.prey is not None:
                    put("/swarm/prey", POINT, store.types[POINT](header=build.header(ns), point=build.point(f.prey)), ns)
                metrics = observer.observe(f.t, f.ids, f.positions, f.velocities, f.prey)
                for name, value in sorted(metrics.items()):
                    if isinstance(value, (int, float)) and math.isfinite(value):
                        put(f"/swarm/metrics/{name}", FLOAT, store.types[FLOAT](data=float(value)), ns)
        written = next(bag.glob("*.mcap"))
        out.parent.mkdir(parents=True, exist_ok=True)
        shutil.move(str(written), out)
    return counts
