"""``zswarm run`` (and ``python launch.py``): a Zenoh router, the world and N agent processes, on one
machine or several.

    zswarm run                                        # the demo: 10 agents chase a moving prey
    zswarm run --agents 20 --scenario static-goal --record sg.rrd
    zswarm run --role router,world --listen tcp/0.0.0.0:7447 --agents 20      # machine A
    zswarm run --role agents --connect tcp/A:7447 --ids 10-19 --agents 20     # machine B

The run's own arguments are every process's (:mod:`zswarm.net.runspec`); the rest say where the
processes run, what is recorded and which crashes to stage. At the end, or on Ctrl-C, the agents are
stopped first, then the world (which flushes the recording and writes the summary), then the router;
every child is reaped.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Sequence

from zswarm.args import Parser, ZenohEndpoint, agent_count, positive_seconds, router_count, run_main, seconds
from zswarm.launch.chaos import parse_crash, parse_kill, parse_outage, parse_pause
from zswarm.net.runspec import add_run_args
from zswarm.record.live import add_viewer_args

ROLES = ("router", "world", "agents")


def parse_ids(text: str) -> list[int]:
    ids: list[int] = []
    try:
        for part in text.split(","):
            lo, sep, hi = part.partition("-")
            ids.extend(range(int(lo), int(hi) + 1) if sep else [int(lo)])
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected ids like 0-9 or 3,5,7 (got {text!r})") from None
    if not ids or min(ids) < 0:
        raise argparse.ArgumentTypeError(f"expected non-negative ids (got {text!r})")
    return ids


def parse_roles(text: str) -> list[str]:
    roles = [r.strip() for r in text.split(",") if r.strip()]
    bad = [r for r in roles if r not in ROLES]
    if bad or not roles:
        raise argparse.ArgumentTypeError(f"roles are {', '.join(ROLES)} (comma-separated); got {text!r}")
    return roles


def build_parser(prog: str = "zswarm run") -> Parser:
    p = Parser(prog=prog, description="Start a zswarm run: router, world and agents.")
    add_run_args(p, run_help="run id: namespaces every key (default: run-SEED-TIME)")
    p.set_defaults(time_scale="auto")
    p.add_argument("--agents", type=agent_count, default=None,
                   help="number of agents N (default: the scenario's; same as --set n_agents=N)")
    p.add_argument("--record", type=Path, default=None,
                   help="recording (default run.rrd, or run-2.rrd, run-3.rrd, ... when an earlier run's is there)")
    p.add_argument("--force", action="store_true",
                   help="overwrite the recording and summary an earlier run left at --record / --summary")
    p.add_argument("--summary", type=Path, default=None, help="summary JSON (default: beside the recording)")
    p.add_argument("--trajectory", type=Path, default=None, help="observed positions per step (.npz)")
    p.add_argument("--tracks", type=Path, default=None, metavar="DIR",
                   help="each agent writes every pose it sent into DIR; at the end the run's collisions are "
                        "judged from them at one instant, exactly (summary: tracks)")
    p.add_argument("--role", type=parse_roles, default=list(ROLES),
                   help="what this machine runs: router,world,agents (default all three)")
    p.add_argument("--connect", action=ZenohEndpoint, append=False, default=None, metavar="ENDPOINT",
                   help="the Zenoh router to join when this machine runs no router, e.g. tcp/10.0.0.1:7447 (a "
                        "Rerun viewer is --viewer)")
    add_viewer_args(p)
    p.add_argument("--listen", action=ZenohEndpoint, append=False, default=None, metavar="ENDPOINT",
                   help="router endpoint (default tcp/127.0.0.1:FREE_PORT)")
    p.add_argument("--connect-timeout", type=seconds, default=None, metavar="S",
                   help="how long the world and the agents retry a router that does not answer before they give "
                        "up (default 15 s; machines started by hand must start within it)")
    p.add_argument("--routers", type=router_count, default=1, metavar="K",
                   help="run K routers meshed together (the 2nd..Kth join the first) and spread the agents "
                        "over them, agent i on router i mod K (default 1). With --role router and --connect, "
                        "this machine's router joins the router at --connect")
    p.add_argument("--ids", type=parse_ids, default=None, help="agent ids this machine runs, e.g. 10-19")
    p.add_argument("--secure", type=Path, default=None, metavar="DIR",
                   help="TLS with access control: use the certificates and configs in DIR ('zswarm certs DIR'; "
                        "made there if DIR has none); endpoints become tls/...")
    p.add_argument("--config", type=Path, default=None, metavar="FILE",
                   help="a full Zenoh configuration (json5) for the world and the agents; --connect overrides "
                        "its endpoints")
    p.add_argument("--router-config", type=Path, default=None, metavar="FILE",
                   help="a full Zenoh configuration (json5) for the router; --listen overrides its endpoints")
    p.add_argument("--robots", type=Path, default=None, metavar="FILE.toml",
                   help="drive ROS 2 robots: the agents this file names take their pose from their robot's "
                        "odometry and command it (docs/robots.md; try it with zswarm robot-sim)")
    p.add_argument("--end-after-capture", type=positive_seconds, default=None, metavar="S",
                   help="end the run S simulated seconds after the prey is caught (default: at --duration)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--require-design", action="store_true",
                   help="refuse to start (exit 2) when the set this run would use fails zswarm design")
    p.add_argument("--no-fork", dest="fork", action="store_false",
                   help="start every agent as a fresh Python process instead of forking it from one that "
                        "imported the agent program once (slower to start, more memory; same behaviour)")
    p.add_argument("--cluster", default=None, metavar="ADDRESS|auto|local[:K]",
                   help="run the whole swarm over a Ray cluster (pip install -e \".[cluster]\"): HOST:PORT of its "
                        "head, auto, local (this machine as one node) or local:K (K nodes here); a router and a "
                        "share of the agents on every node, the world and the recording here (docs/cluster.md)")
    p.add_argument("--cluster-insecure-ok", action="store_true",
                   help="with --cluster ADDRESS: run on a head that has token authentication off, which is refused "
                        "otherwise; the summary then says \"ray_auth\": \"off\"")
    p.add_argument("--placement", default="space", choices=("space", "round-robin"),
                   help="with --cluster: agents that start near each other share a node (space, default) or "
                        "ids are dealt in turn (round-robin)")
    p.add_argument("--migrate-every", type=positive_seconds, default=None, metavar="S",
                   help="free clock, with --routers K or --cluster: every S seconds of the run, split the swarm "
                        "anew by space and move each agent whose router (node) changes there, make-before-break "
                        "(docs/cluster.md)")
    p.add_argument("--kill", type=parse_kill, default=None, metavar="K@T",
                   help="SIGKILL K agents, chosen with the seed, T seconds after the start")
    p.add_argument("--restart-after", type=seconds, default=None, metavar="S",
                   help="restart the killed agents S seconds later (they rejoin at their spawn position); with "
                        "--cluster, also the agents of a node that was lost, on the surviving nodes")
    p.add_argument("--pause", type=parse_pause, action="append", default=None, metavar="WHAT@T:S",
                   help="freeze a process (SIGSTOP) at T for S seconds, then let it go on (SIGCONT), as a "
                        "starved or swapped-out machine does: WHAT is world, router, router-K or agent-ID "
                        "(a robot's bridge is its agent); repeatable (docs/experiments.md)")
    p.add_argument("--world-outage", type=parse_outage, default=None, metavar="T:S",
                   help="--pause world@T:S: no prey, no obstacle answers")
    p.add_argument("--world-crash", type=parse_crash, default=None, metavar="T[:S]",
                   help="kill the world (SIGKILL) at T; with :S start a new one S seconds later with --resume "
                        "(it recovers the run from the recording and writes the next segment), without, "
                        "end the run there (the recording is repaired and the summary recomputed)")
    return p


def _launch(argv: Sequence[str] | None, prog: str) -> int:
    from zswarm.launch.plan import plan_from_args
    from zswarm.launch.supervisor import Launch

    args = build_parser(prog).parse_args(argv)
    if args.cluster is not None:
        from zswarm.cluster.run import cluster_run

        return cluster_run(args)
    return Launch(plan_from_args(args)).run()


def main(argv: Sequence[str] | None = None, prog: str = "zswarm run") -> int:
    return run_main(lambda a: _launch(a, prog), argv, prog=prog)
