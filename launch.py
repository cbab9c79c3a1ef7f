"""Launch a zswarm run: a Zenoh router, the world and N agent processes, on one machine or several.

    python launch.py                                   # the demo: 10 agents chase a moving prey, 30 s
    python launch.py --agents 20 --scenario static-goal --record sg.rrd
    python launch.py --role router,world --listen tcp/0.0.0.0:7447 --agents 20      # machine A
    python launch.py --role agents --connect tcp/A:7447 --ids 10-19 --agents 20     # machine B
    python launch.py sweep --scenario static-goal --latency 0,100ms --dropout 0,0.3 --out sweep/

At the end, or on Ctrl-C, the agents are stopped first, then the world (which flushes the recording
and writes the summary), then the router; every child is reaped.
"""

from __future__ import annotations

import argparse
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Sequence

from zswarm.cli_util import Parser, UsageError, run_main
from zswarm.procs import Children, free_port, port_in_use, wait_for_port
from zswarm.recording import check_writable
from zswarm.runspec import CLOCKS, add_fault_args, faults_from_args

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


def parse_kill(text: str) -> tuple[int, float]:
    try:
        k, t = text.split("@")
        out = int(k), float(t)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected K@T, e.g. 3@10 (got {text!r})") from None
    if out[0] < 1 or out[1] < 0:
        raise argparse.ArgumentTypeError(f"expected K >= 1 and T >= 0 (got {text!r})")
    return out


def parse_outage(text: str) -> tuple[float, float]:
    try:
        t, d = (float(v) for v in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected T:S, e.g. 10:5 (got {text!r})") from None
    if t < 0 or d <= 0:
        raise argparse.ArgumentTypeError(f"expected T >= 0 and S > 0 (got {text!r})")
    return t, d


def parse_crash(text: str) -> tuple[float, float | None]:
    """``T`` (kill the world at T for good) or ``T:S`` (and start a new one S seconds later)."""
    if ":" in text:
        return parse_outage(text)
    try:
        t = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected T or T:S, e.g. 10 or 10:3 (got {text!r})") from None
    if not t >= 0:
        raise argparse.ArgumentTypeError(f"expected T >= 0 (got {text!r})")
    return t, None


def build_parser() -> Parser:
    p = Parser(prog="launch.py", description="Start a zswarm run: router, world and agents.")
    p.add_argument("--agents", type=int, default=None, help="number of agents N (default: the scenario's)")
    p.add_argument("--scenario", default="moving-prey", help="scenario name or .toml file (default moving-prey)")
    p.add_argument("--duration", type=float, default=30.0, help="simulated seconds (default 30)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--set", dest="assignments", action="append", default=[], metavar="NAME=VALUE")
    p.add_argument("--potential", choices=("additive", "multiplicative"), default=None)
    p.add_argument("--clock", choices=CLOCKS, default="free")
    p.add_argument("--time-scale", type=float, default=1.0)
    p.add_argument("--run", default=None, help="run id (default: run-SEED-TIME)")
    p.add_argument("--record", type=Path, default=Path("run.rrd"), help="recording (default run.rrd)")
    p.add_argument("--summary", type=Path, default=None, help="summary JSON (default: beside the recording)")
    p.add_argument("--trajectory", type=Path, default=None, help="observed positions per step (.npz)")
    p.add_argument("--role", type=parse_roles, default=list(ROLES),
                   help="what this machine runs: router,world,agents (default all three)")
    p.add_argument("--connect", default=None, metavar="ENDPOINT",
                   help="router to join when this machine runs no router, e.g. tcp/10.0.0.1:7447")
    p.add_argument("--listen", default=None, metavar="ENDPOINT",
                   help="router endpoint (default tcp/127.0.0.1:FREE_PORT)")
    p.add_argument("--ids", type=parse_ids, default=None, help="agent ids this machine runs, e.g. 10-19")
    p.add_argument("--secure", type=Path, default=None, metavar="DIR",
                   help="TLS with access control: use the certificates and configs in DIR ('zswarm certs DIR'; "
                        "made there if DIR has none); endpoints become tls/...")
    p.add_argument("--config", type=Path, default=None, metavar="FILE",
                   help="a full Zenoh configuration (json5) for the world and the agents; --connect overrides "
                        "its endpoints")
    p.add_argument("--router-config", type=Path, default=None, metavar="FILE",
                   help="a full Zenoh configuration (json5) for the router; --listen overrides its endpoints")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--kill", type=parse_kill, default=None, metavar="K@T",
                   help="SIGKILL K agents, chosen with the seed, T seconds after the start")
    p.add_argument("--restart-after", type=float, default=None, metavar="S",
                   help="restart the killed agents S seconds later (they rejoin at their spawn position)")
    p.add_argument("--world-outage", type=parse_outage, default=None, metavar="T:S",
                   help="freeze the world (SIGSTOP) at T for S seconds: no prey, no obstacle answers")
    p.add_argument("--world-crash", type=parse_crash, default=None, metavar="T[:S]",
                   help="kill the world (SIGKILL) at T; with :S start a new one S seconds later with --resume "
                        "(it recovers the run from the recording and writes the next segment), without, "
                        "end the run there (the recording is repaired and the summary recomputed)")
    add_fault_args(p)
    return p


def run_args(args: argparse.Namespace, run: str) -> list[str]:
    out = ["--run", run, "--scenario", args.scenario, "--seed", str(args.seed), "--clock", args.clock,
           "--time-scale", str(args.time_scale)]
    for a in args.assignments:
        out += ["--set", a]
    if args.agents is not None:
        out += ["--set", f"n_agents={args.agents}"]
    if args.potential:
        out += ["--potential", args.potential]
    out += ["--latency", args.latency, "--jitter", args.jitter, "--dropout", str(args.dropout),
            "--burst", str(args.burst), "--distance-loss", str(args.distance_loss)]
    return out


def _endpoint_host_port(endpoint: str) -> tuple[str, int]:
    try:
        proto, rest = endpoint.split("/", 1)
        host, port = rest.rsplit(":", 1)
        return host.strip("[]"), int(port)
    except ValueError:
        raise UsageError(f"endpoint {endpoint!r} must look like tcp/HOST:PORT (or tls/HOST:PORT)") from None


def _validate(args: argparse.Namespace) -> tuple[str, int]:
    """Check everything a child would reject, before any child starts. Returns the agent count."""
    from zswarm.params import parse_assignments
    from zswarm.scenarios import get_scenario

    overrides = parse_assignments(args.assignments)
    if args.agents is not None:
        if args.agents < 1:
            raise UsageError(f"--agents must be >= 1 (got {args.agents})")
        overrides["n_agents"] = args.agents
    scenario = get_scenario(args.scenario, overrides)
    faults_from_args(args)
    if not args.duration > 0:
        raise UsageError(f"--duration must be > 0 (got {args.duration})")
    if "world" in args.role:
        for path in (args.record, args.summary, args.trajectory):
            if path is not None:
                check_writable(path)
    if "router" not in args.role and args.connect is None:
        raise UsageError("without the router role, give --connect tcp/HOST:PORT of the router")
    for flag, endpoint in (("--listen", args.listen), ("--connect", args.connect)):
        if endpoint is not None:
            _endpoint_host_port(endpoint)
            if args.secure is not None and not endpoint.startswith("tls/"):
                raise UsageError(f"with --secure, {flag} must be a tls/HOST:PORT endpoint (got {endpoint!r})")
    for flag, path in (("--config", args.config), ("--router-config", args.router_config)):
        if path is not None:
            if args.secure is not None:
                raise UsageError(f"{flag} and --secure both set the Zenoh configuration; give one")
            from zswarm.transport import zenoh_config

            zenoh_config(None, config=path)  # a missing or unreadable file fails here, not in a child
    if args.secure is not None:
        from zswarm.security import is_secure_dir

        if args.secure.exists() and not args.secure.is_dir():
            raise UsageError(f"--secure {args.secure} is not a directory")
        if args.secure.is_dir() and any(args.secure.iterdir()) and not is_secure_dir(args.secure):
            raise UsageError(f"--secure {args.secure} has no router/world/agent .json5 configs; "
                             f"make them with: zswarm certs {args.secure}")
        if "agents" in args.role and is_secure_dir(args.secure):
            from zswarm.security import agent_config, agent_name

            ids = args.ids if args.ids is not None else range(scenario.n_agents)
            own = [i for i in ids if agent_config(args.secure, i).name == f"{agent_name(i)}.json5"]
            if own and len(own) < len(ids):
                lacking = sorted(set(ids) - set(own))
                raise UsageError(f"--secure {args.secure} gives agents their own identities, but none to agent "
                                 f"{lacking[0]}{' and others' if len(lacking) > 1 else ''}; remake it with: "
                                 f"zswarm certs {args.secure} --force --agents {max(ids) + 1}")
    return scenario.name, scenario.n_agents


def _launch(argv: Sequence[str] | None) -> int:
    args = build_parser().parse_args(argv)
    _, n = _validate(args)
    args.started_at = time.time()
    run = args.run or f"run-{args.seed}-{int(time.time())}"
    if args.summary is None:
        args.summary = args.record.with_suffix(".json")
    endpoint = args.connect
    configs = _secure_configs(args, n)
    if "router" in args.role:
        endpoint = args.listen or f"{'tls' if configs else 'tcp'}/127.0.0.1:{free_port()}"
        host, port = _endpoint_host_port(endpoint)
        if port_in_use(host if host not in ("0.0.0.0", "::") else "127.0.0.1", port):
            raise UsageError(f"port {port} on {host} is already in use; pick another with --listen")
    kids = Children()
    interrupted = False

    def on_signal(signum, _frame) -> None:
        nonlocal interrupted
        interrupted = True
        raise KeyboardInterrupt

    signal.signal(signal.SIGTERM, on_signal)
    try:
        if "router" in args.role:
            router = kids.spawn("router", ["-m", "zswarm.router", "--listen", endpoint,
                                           *configs.get("router", [])], stdout=subprocess.DEVNULL)
            host, port = _endpoint_host_port(endpoint)
            if not wait_for_port("127.0.0.1" if host in ("0.0.0.0", "::") else host, port, 10.0, router):
                raise UsageError(f"the router did not start on {endpoint} (port taken? address not local?)")
        common = run_args(args, run) + ["--connect", endpoint]
        args.agent_args = common + configs.get("agent", [])
        world = None
        if "world" in args.role:
            args.world_args = ["-m", "world", *common, *configs.get("world", []), "--record", str(args.record),
                               "--summary", str(args.summary), "--duration", str(args.duration),
                               "--progress", "0" if args.quiet else "2"]
            if args.trajectory is not None:
                args.world_args += ["--trajectory", str(args.trajectory)]
            world = spawn_world(kids, args)
        if "agents" in args.role:
            for i in args.ids if args.ids is not None else range(n):
                kids.spawn(f"agent-{i}", ["-m", "agents", "--id", str(i), *agent_args(args, i)],
                           stdout=subprocess.DEVNULL)
        if not args.quiet:
            print(f"launch: run {run!r}, {len(kids.named('agent'))} agent processes, router {endpoint}",
                  flush=True)
        return _supervise(kids, world, args)
    except KeyboardInterrupt:
        print("launch: stopping (agents, then the world, then the router)", file=sys.stderr, flush=True)
        kids.stop_all()
        worlds = kids.named("world")
        _salvage(args, worlds[-1] if worlds else None)
        _report(args, None)
        return 130 if not interrupted else 143
    finally:
        kids.stop_all()


def agent_args(args: argparse.Namespace, agent: int) -> list[str]:
    """Agent ``agent``'s arguments; under --secure, its own identity's config if DIR has one."""
    if args.secure is None:
        return args.agent_args
    from zswarm.security import agent_config

    return [*args.agent_args, "--config", str(agent_config(args.secure, agent))]


def spawn_world(kids: Children, args: argparse.Namespace, resume: bool = False):
    """Start the world (``resume``: a replacement that records into the next segment)."""
    world = kids.spawn("world", args.world_args + (["--resume"] if resume else []), stdout=subprocess.PIPE)
    world.started = threading.Event()
    threading.Thread(target=_forward, args=(world, args.quiet), daemon=True).start()
    return world


def _secure_configs(args: argparse.Namespace, n_agents: int) -> dict[str, list[str]]:
    """``--config`` arguments of the router and the world: --config/--router-config as given, or for
    --secure DIR its files (made there if DIR has none: one identity per agent, see
    :func:`agent_args`)."""
    if args.secure is None:
        out = {}
        if args.config is not None:
            out["world"] = out["agent"] = ["--config", str(args.config)]
        if args.router_config is not None:
            out["router"] = ["--config", str(args.router_config)]
        return out
    from zswarm.security import is_secure_dir, write_secure_dir

    if not is_secure_dir(args.secure):
        write_secure_dir(args.secure, agents=n_agents)
        if not args.quiet:
            print(f"launch: made a CA, certificates (one per agent) and configs in {args.secure}", flush=True)
    return {role: ["--config", str(args.secure / f"{role}.json5")] for role in ("router", "world")}


def _forward(world, quiet: bool) -> None:
    """Pass the world's lines through, and note when its clock starts."""
    for line in world.proc.stdout:
        text = line.decode(errors="replace") if isinstance(line, bytes) else line
        if text.startswith("world: started"):
            world.started.set()
        if not quiet or text.startswith("world: done"):
            sys.stdout.write(text)
            sys.stdout.flush()


class Chaos:
    """The scheduled crashes and outages of a run (--kill, --restart-after, --world-outage,
    --world-crash). ``world`` is the current world process (a replacement after --world-crash)."""

    def __init__(self, kids: Children, world, args: argparse.Namespace) -> None:
        import numpy as np

        self.kids, self.world, self.args = kids, world, args
        self.t0 = time.monotonic()
        self.rng = np.random.default_rng([args.seed, 0xC0FFEE])
        self.killed: list[int] = []
        self.killed_at: float | None = None
        self.done: set[str] = set()
        self.expected: set[str] = set()
        self.clock_started = False

    @property
    def world_pending(self) -> bool:
        """A killed world is to be replaced."""
        crash = self.args.world_crash
        return bool(crash) and crash[1] is not None and "crash" in self.done and "resume" not in self.done

    def tick(self) -> None:
        """Times count from the start of the world's clock (or of the launch, without a world here)."""
        if self.world is not None and not self.clock_started:
            if not self.world.started.is_set():
                self.t0 = time.monotonic()
                return
            self.clock_started = True
        a, t = self.args, time.monotonic() - self.t0
        if a.world_crash and self.world is not None:
            at, after = a.world_crash
            if "crash" not in self.done and t >= at:
                self.world.proc.kill()
                self.world.proc.wait()
                self.done.add("crash")
                print(f"launch: killed the world at {t:.1f} s", file=sys.stderr, flush=True)
            if self.world_pending and t >= at + after:
                self.world = spawn_world(self.kids, a, resume=True)
                self.done.add("resume")
                print(f"launch: started a new world at {t:.1f} s (--resume)", file=sys.stderr, flush=True)
        if a.kill and "kill" not in self.done and t >= a.kill[1]:
            alive = [c for c in self.kids.named("agent") if c.alive()]
            chosen = self.rng.choice(len(alive), size=min(a.kill[0], len(alive)), replace=False)
            for k in sorted(chosen):
                alive[k].proc.kill()
                self.expected.add(alive[k].name)
                self.killed.append(int(alive[k].name.split("-")[1]))
            self.killed_at, _ = t, self.done.add("kill")
            print(f"launch: killed agents {sorted(self.killed)} at {t:.1f} s", file=sys.stderr, flush=True)
        if (a.restart_after is not None and self.killed_at is not None and "restart" not in self.done
                and t >= self.killed_at + a.restart_after):
            for i in self.killed:
                self.kids.spawn(f"agent-{i}", ["-m", "agents", "--id", str(i), *agent_args(a, i)],
                                stdout=subprocess.DEVNULL)
            self.done.add("restart")
            print(f"launch: restarted agents {sorted(self.killed)} at {t:.1f} s", file=sys.stderr, flush=True)
        if a.world_outage and self.world is not None:
            start, length = a.world_outage
            if "stop" not in self.done and t >= start:
                self.world.proc.send_signal(signal.SIGSTOP)
                self.done.add("stop")
                print(f"launch: world frozen at {t:.1f} s", file=sys.stderr, flush=True)
            if "cont" not in self.done and t >= start + length:
                self.world.proc.send_signal(signal.SIGCONT)
                self.done.add("cont")
                print(f"launch: world resumed at {t:.1f} s", file=sys.stderr, flush=True)


def _supervise(kids: Children, world, args: argparse.Namespace) -> int:
    """Wait for the world to finish (or, without a world, for the agents / for Ctrl-C)."""
    crashed: set[str] = set()
    chaos = Chaos(kids, world, args)
    while True:
        chaos.tick()
        world = chaos.world
        for c in kids.children:
            code = c.proc.poll()
            if (code not in (None, 0) and c.name not in crashed and c.name not in ("world", "router")
                    and c.name not in chaos.expected):
                crashed.add(c.name)
                print(f"launch: {c.name} exited with code {code}; the others carry on", file=sys.stderr,
                      flush=True)
        if world is not None and not world.alive() and not chaos.world_pending:
            break
        if world is None and "agents" in args.role and not any(c.alive() for c in kids.named("agent")):
            break
        router = kids.named("router")
        if router and not router[0].alive():
            print("launch: the router died; stopping the run", file=sys.stderr, flush=True)
            kids.stop_all()
            _salvage(args, world)
            _report(args, None)
            return 1
        time.sleep(0.1)
    if world is None:
        return 0
    Children.stop(kids.named("agent"), 5.0)  # they end on the world's final tick; this reaps them
    code = world.proc.returncode
    _salvage(args, world)
    _report(args, code)
    if "crash" in chaos.done and args.world_crash[1] is None:
        return 0  # the run ended where it was asked to (--world-crash T)
    return 0 if code == 0 else (2 if code == 2 else 1)


def _salvage(args: argparse.Namespace, world) -> None:
    """A world that died without writing its summary (killed, crashed) leaves a recording without a
    footer: repair it and recompute the summary from it, so every run ends with both."""
    if world is None or world.alive() or world.proc.returncode == 2 or not args.record.exists():
        return
    fresh = args.summary.exists() and args.summary.stat().st_mtime >= args.started_at
    if fresh and world.proc.returncode == 0:
        return
    from zswarm.cli_util import UsageError
    from zswarm.salvage import salvage_summary

    try:
        salvage_summary(args.record, args.summary)
        print(f"launch: the world ended with code {world.proc.returncode}; its recording was made whole and "
              f"the summary recomputed from it (\"salvaged\": true)", file=sys.stderr, flush=True)
    except UsageError as exc:
        print(f"launch: the world ended with code {world.proc.returncode} and its recording cannot be "
              f"salvaged: {exc}", file=sys.stderr, flush=True)


def _report(args: argparse.Namespace, code: int | None) -> None:
    if "world" not in args.role or args.quiet:
        return
    if args.record.exists():
        print(f"launch: recording {args.record} (open with: rerun {args.record}); summary {args.summary}",
              flush=True)


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if argv[:1] == ["sweep"]:
        from zswarm import sweep

        return run_main(sweep.main, argv[1:], prog="launch.py sweep")
    return run_main(_launch, argv, prog="launch.py")


if __name__ == "__main__":
    sys.exit(main())
