"""What every Ray process zswarm starts is told, so that it stays on the cluster's own network.

Ray, by default, contacts the outside: a head node's dashboard process POSTs usage statistics to Ray's
server (and a "disabled" ping even when statistics are off), every head asks the cloud metadata
addresses (169.254.169.254, metadata.google.internal) which cloud it runs on unless
``~/ray_bootstrap_config.yaml`` exists, and a node finds "its" address by a UDP connect towards
8.8.8.8 (Ray 2.60's ``_common/usage/usage_lib.py``, ``dashboard/modules/usage_stats/usage_stats_head.py``,
``_private/services.py``). :func:`offline_env` switches each of these off or points it at loopback,
gives the run its own ``RAY_TMPDIR`` and ``HOME`` (holding the bootstrap file), and turns Ray's memory
monitor off (it kills workers at 95 % of host memory: a swarm's agents are not Ray's to kill).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import MutableMapping

from zswarm.ports import LOOPBACK

#: The environment of every Ray process (driver, nodes, workers), before ``import ray``.
OFFLINE = {
    "RAY_USAGE_STATS_ENABLED": "0",
    "RAY_USAGE_STATS_PROMPT_ENABLED": "0",
    "RAY_USAGE_STATS_REPORT_URL": f"http://{LOOPBACK}:9/",  # discard: nothing listens, nothing leaves
    "RAY_memory_monitor_refresh_ms": "0",
    "RAY_process_group_cleanup_enabled": "1",  # a dead worker's process group (its routers, agents) goes too
    "RAY_kill_child_processes_on_worker_exit": "1",
    "RAY_DISABLE_DOCKER_CPU_WARNING": "1",
    "RAY_ENABLE_UV_RUN_RUNTIME_ENV": "0",
    "RAY_BACKEND_LOG_LEVEL": "error",  # not a warning per process that its probe of 8.8.8.8 found no route
}

#: A node's failure is noticed within about a second (Ray's defaults: about 15 s for a killed raylet,
#: 65 s for one whose packets are lost).
SYSTEM_CONFIG = {
    "health_check_initial_delay_ms": 0,
    "health_check_period_ms": 200,
    "health_check_timeout_ms": 300,
    "health_check_failure_threshold": 3,
}

#: The object store of a node started here: about the smallest Ray accepts (zswarm sends nothing through it).
OBJECT_STORE_BYTES = 80 * 1024 * 1024

#: Ray's cluster launcher writes this file on a head; its presence skips the cloud-metadata probe.
BOOTSTRAP = "ray_bootstrap_config.yaml"


def offline_env(run_dir: Path | None, env: MutableMapping[str, str] | None = None) -> MutableMapping[str, str]:
    """Set, in ``env`` (default ``os.environ``), everything :data:`OFFLINE` says (values the user set win);
    for a cluster started here (``run_dir`` given), also ``RAY_TMPDIR`` to ``run_dir/ray`` and ``HOME`` to
    ``run_dir/home`` (with a bootstrap file). A driver joining a cluster keeps its own: the head it joins
    was started by ``ray start`` with the settings docs/cluster.md gives. Returns ``env``."""
    env = os.environ if env is None else env
    for key, value in OFFLINE.items():
        env.setdefault(key, value)
    if run_dir is None:
        return env
    home = run_dir / "home"
    home.mkdir(parents=True, exist_ok=True)
    (home / BOOTSTRAP).write_text("# written by zswarm: no cloud here, so Ray need not ask for one\n"
                                  "provider: {type: local}\n")
    env["HOME"] = str(home)
    tmp = run_dir / "ray"
    tmp.mkdir(parents=True, exist_ok=True)
    env.setdefault("RAY_TMPDIR", str(tmp))
    env["ZSWARM_RAY_RUN"] = str(run_dir)  # what zswarm.cluster.reaper finds a local cluster's processes by
    return env
