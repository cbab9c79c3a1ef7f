"""Stand-in robots for ``tests/test_robots.py``, in a process of their own, so that a test can freeze
them (SIGSTOP) as a starved machine would. ``python tests/robot_driver.py ENDPOINT ROBOTS.toml N`` drives
them at 50 Hz; ``stop`` on stdin (or its end) ends it; then each robot's command count and rejections
are printed as one JSON line."""
from __future__ import annotations

import json
import sys
import threading

import numpy as np

from zswarm.net.config import open_session, zenoh_config
from zswarm.ros import robot_sim
from zswarm.ros.robots import load_robots
from zswarm.swarm.scenarios import get_scenario


def main() -> int:
    endpoint, path, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
    fleet = load_robots(path)
    scenario = get_scenario("moving-prey", {"n_agents": n})
    spawn = scenario.initial_positions(np.random.default_rng(0))
    robots = [robot_sim.SimRobot(r, fleet.route, robot_sim.start_pose(r, tuple(spawn[r.id]), scenario.prey_start))
              for r in fleet.robots]
    stop = threading.Event()

    def orders() -> None:
        for line in sys.stdin:
            if line.split()[:1] == ["stop"]:
                break
        stop.set()

    threading.Thread(target=orders, daemon=True).start()
    with open_session(zenoh_config("client", [endpoint]), "robots", retry_for=30.0) as session:
        print("ready", flush=True)
        robot_sim.run(session, fleet.route, robots, 50.0, stop)
    print(json.dumps([{"commands": r.commands, "rejected": r.rejected} for r in robots]), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
