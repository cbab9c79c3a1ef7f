"""A run's plan: everything ``zswarm run`` was asked to do, checked before any process starts.

:func:`plan_from_args` turns the command line (:func:`zswarm.cli.launch.build_parser`) into a
:class:`Plan`, refusing in one line what a child would reject later: an unplaceable swarm, more agent
processes than the memory holds, a set that fails its design under ``--require-design``, bad
endpoints, configs or secure directories. :class:`zswarm.launch.supervisor.Launch` carries it out.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

from zswarm.control.step import control_step
from zswarm.launch import chaos
from zswarm.args import id_ranges
from zswarm.errors import UsageError
from zswarm.files import check_run_files
from zswarm.paper.params import parse_assignments
from zswarm.swarm.scenarios import get_scenario
from zswarm.net.config import endpoint_host_port
from zswarm.net.runspec import RunSpec, spec_from_args
from zswarm.record.live import Viewer, viewer_from_args

if TYPE_CHECKING:
    from zswarm.ros.robots import RobotsFile


@dataclass(frozen=True)
class Plan:
    """Everything ``zswarm run`` was asked to do, checked: the run itself and where its parts run."""

    spec: RunSpec
    roles: tuple[str, ...]
    routers: int
    ids: tuple[int, ...]  # the agents this machine runs
    record: Path
    summary: Path
    trajectory: Path | None
    connect: str | None
    listen: str | None
    secure: Path | None
    config: Path | None
    router_config: Path | None
    quiet: bool
    fork: bool
    kill: tuple[int, float] | None
    restart_after: float | None
    pauses: tuple[chaos.Pause, ...]  # --pause, and --world-outage as the world's
    world_crash: tuple[float, float | None] | None
    viewer: Viewer = Viewer()
    design: dict | None = None
    robots: Path | None = None  # a robots file: the agents it names drive ROS 2 robots
    notes: tuple[str, ...] = ()  # said at start: where the recording goes, which agents drive robots
    connect_timeout: float | None = None  # how long the world and agents retry their router (their default 15 s)
    tracks: Path | None = None  # each agent writes the poses it sent here; judged at the end
    migrate_every: float | None = None  # move agents between routers (nodes) every this many run seconds
    end_after_capture: float | None = None  # the world ends the run this many run seconds after the capture


def plan_from_args(args: argparse.Namespace, cores: int | None = None, memory_mib: float | None = None) -> Plan:
    """Check everything a child would reject, before any child starts. ``cores`` and ``memory_mib``: what
    the agents have (default: this machine's; a cluster run passes its nodes' sum)."""
    if args.agents is not None and args.agents < 1:
        raise UsageError(f"--agents must be >= 1 (got {args.agents})")
    where = "this machine" if cores is None else "the cluster"
    cores = cores or available_cores()
    pace_note = auto_time_scale(args, cores)
    spec = spec_from_args(args, run=f"run-{args.seed}-{int(time.time())}",
                          extra={"n_agents": args.agents} if args.agents is not None else None)
    n = spec.scenario.n_agents
    ids = tuple(args.ids if args.ids is not None else range(n))
    if ids and max(ids) >= n:
        raise UsageError(f"--ids {id_ranges(sorted(ids))} goes beyond the run's agents 0-{n - 1} (--agents {n}): "
                         f"give ids below {n}, or --agents {max(ids) + 1}")
    if "agents" in args.role:
        check_capacity(len(ids), args.fork, memory_mib)
    spec.scenario.check_placement()  # every agent would fail to place itself, one by one
    # every group's law loaded and probed, and the filter checked: refused here, in one line
    control_step([spec.scenario], [spec.combination], spec.safety, probe=True)
    files_note = ""
    if "world" in args.role:
        args.record, args.summary, files_note = run_files(args.record, args.summary, args.force)
        check_run_files(args.record, args.summary, args.trajectory)
    elif args.record is None:
        args.record = Path("run.rrd")  # not written here: the world's machine records
    if "router" not in args.role and args.connect is None:
        raise UsageError("without the router role, give --connect tcp/HOST:PORT of the router")
    for flag, endpoint in (("--listen", args.listen), ("--connect", args.connect)):
        if endpoint is not None:
            endpoint_host_port(endpoint)
            if args.secure is not None and not endpoint.startswith("tls/"):
                raise UsageError(f"with --secure, {flag} must be a tls/HOST:PORT endpoint (got {endpoint!r})")
    for flag, path in (("--config", args.config), ("--router-config", args.router_config)):
        if path is not None:
            if args.secure is not None:
                raise UsageError(f"{flag} and --secure both set the Zenoh configuration; give one")
            from zswarm.net.certs import check_config_files
            from zswarm.net.config import zenoh_config

            zenoh_config(None, config=path)  # a missing or unreadable file fails here, not in a child
            check_config_files(path)  # and so do the TLS files it names
    if not 1 <= args.routers <= 64:
        raise UsageError(f"--routers must be between 1 and 64 (got {args.routers})")
    if args.routers > 1 and "router" not in args.role:
        raise UsageError("--routers K starts K routers: give the router role too (or leave --role alone)")
    if "agents" in args.role and args.connect is None and args.routers > max(len(ids), 1):
        raise UsageError(f"--routers {args.routers} for {len(ids)} agents leaves at least "
                         f"{args.routers - len(ids)} routers with no agent; give --routers {len(ids)} or fewer")
    if args.routers > 1 and args.secure is not None:
        from zswarm.net.security import is_secure_dir, meshes

        if is_secure_dir(args.secure) and not meshes(args.secure):
            raise UsageError(f"the routers of {args.secure} do not let each other forward (made by an older zswarm): "
                             "make the directory again with zswarm certs, or give an empty one")
    if args.connect_timeout is not None and not 0 < args.connect_timeout <= 3600:
        raise UsageError(f"--connect-timeout must be between 0 and 3600 seconds (got {args.connect_timeout})")
    if args.restart_after is not None and not args.restart_after >= 0:
        raise UsageError(f"--restart-after must be >= 0 (got {args.restart_after})")
    check_migration(args, spec)
    run_s = spec.steps * spec.scenario.dt
    pauses = tuple(args.pause or ())
    if pauses and args.cluster is not None:
        raise UsageError(f"--pause {pauses[0]}: a cluster's processes run on its nodes; pause one machine's "
                         "processes without --cluster")
    chaos.check(args.kill, args.restart_after, args.world_outage, args.world_crash, args.migrate_every, len(ids),
                args.role, run_s, run_s / spec.time_scale, cluster=args.cluster is not None, pauses=pauses,
                names=process_names(args.role, args.routers, ids))
    if args.world_outage is not None:
        pauses = (chaos.Pause("world", *args.world_outage), *pauses)
    tracks = tracks_folder(args.tracks)
    viewer = viewer_from_args(args) if "world" in args.role else Viewer()
    if (viewer.spawn or viewer.serve) and args.world_crash is not None and args.world_crash[1] is not None:
        raise UsageError("--world-crash T:S restarts the world; watch it with --connect to a viewer of your own "
                         "(--spawn and --serve live in the world process)")
    if args.secure is not None:
        check_secure_dir(args.secure, args.role, ids)
    if "agents" in args.role and spec.clock == "free" and \
            pace_load(len(ids), spec.scenario.dt, spec.time_scale, cores) > HOPELESS:
        raise UsageError(pace_warning(len(ids), spec.scenario.dt, spec.time_scale, cores, refused=True, where=where))
    robots = None if args.robots is None else robots_note(check_robots(args.robots, spec), args.robots, ids)
    design = None  # after every flag and file is checked: the swarm check simulates for a second or more
    if "world" in args.role or args.require_design:
        design = judge_design(spec, args.require_design)
    notes = [note for note in (files_note, pace_note, robots) if note]
    if args.secure is None:
        notes.append(OPEN_RUN)
    if "agents" in args.role and spec.clock == "free":  # last: a usage error above comes alone
        line = pace_warning(len(ids), spec.scenario.dt, spec.time_scale, cores, where=where)
        if line:
            print(f"warning: {line}", file=sys.stderr, flush=True)
    return Plan(spec=spec, roles=tuple(args.role), routers=args.routers, ids=ids, record=args.record,
                summary=args.summary or args.record.with_suffix(".json"), trajectory=args.trajectory,
                connect=args.connect, listen=args.listen, secure=args.secure, config=args.config,
                router_config=args.router_config, quiet=args.quiet, fork=args.fork, kill=args.kill, restart_after=args.restart_after,
                pauses=pauses, world_crash=args.world_crash, viewer=viewer, design=design,
                robots=args.robots, notes=tuple(notes), connect_timeout=args.connect_timeout,
                tracks=tracks, migrate_every=args.migrate_every, end_after_capture=args.end_after_capture)


def process_names(roles: Sequence[str], routers: int, ids: Sequence[int]) -> list[str]:
    """The names the launcher gives this machine's processes (``--pause`` names one)."""
    from zswarm.net.security import router_name

    return ([*(router_name(k) for k in range(routers))] if "router" in roles else []) + \
        (["world"] if "world" in roles else []) + ([f"agent-{i}" for i in ids] if "agents" in roles else [])


def check_migration(args: argparse.Namespace, spec: RunSpec) -> None:
    """``--migrate-every S``: what moving agents between routers needs."""
    every = args.migrate_every
    if every is None:
        return
    if not every >= 1.0:
        raise UsageError(f"--migrate-every must be at least 1 second of the run (got {every:g})")
    if spec.clock != "free":
        raise UsageError("--migrate-every runs on the free clock only (a lockstep step waits for every agent's pose)")
    if args.routers < 2 and args.cluster is None:
        raise UsageError("--migrate-every moves agents between routers: give --routers K (K >= 2) or --cluster")
    if set(args.role) != {"router", "world", "agents"}:
        raise UsageError("--migrate-every needs every role here (the launcher asks the world where its agents are)")
    if args.robots is not None:
        raise UsageError("--migrate-every with --robots is not supported: a robot's agent stays beside its robot")


def tracks_folder(folder: Path | None) -> Path | None:
    """``--tracks DIR``: made if missing; one that holds an earlier run's tracks is refused."""
    if folder is None:
        return None
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"--tracks {folder}: cannot make the folder ({exc.strerror})") from None
    if any(folder.glob("agent-*.npy")):
        raise UsageError(f"--tracks {folder} holds an earlier run's tracks: give an empty folder")
    return folder.resolve()


def run_files(record: Path | None, summary: Path | None, force: bool) -> tuple[Path, Path, str]:
    """The recording and summary a run writes, and what to say about them at start. Nothing an earlier
    run left is overwritten without ``--force``: the default (no ``--record``) takes run.rrd, or the
    first of run-2.rrd, run-3.rrd, ... whose recording and summary are both free; an explicit path that
    holds a file is refused."""
    if record is None and summary is None and not force:
        for k in range(1, 10_000):
            candidate = Path("run.rrd" if k == 1 else f"run-{k}.rrd")
            if not candidate.exists() and not candidate.with_suffix(".json").exists():
                note = "" if k == 1 else f"recording to {candidate} (run.rrd is an earlier run's; --record to choose)"
                return candidate, candidate.with_suffix(".json"), note
        raise UsageError("run.rrd to run-9999.rrd are all taken: give --record FILE.rrd")
    record = record or Path("run.rrd")
    summary = summary or record.with_suffix(".json")
    for flag, path in (("--record", record), ("--summary", summary)):
        if path.is_file() and not force:  # a directory there: check_run_files says what is wrong
            raise UsageError(f"{path} exists (an earlier run's): give --force to overwrite it, or another {flag}")
    return record, summary, ""


def robots_note(robots: RobotsFile, path: Path, ids: Sequence[int]) -> str:
    """Which of this machine's agents drive a robot of the file, and which keep a simulated body."""
    named = {r.id for r in robots.robots}
    driving = [i for i in ids if i in named]
    simulated = [i for i in ids if i not in named]
    line = (f"robots ({path}): agents {id_ranges(driving)} drive ROS 2 robots" if driving else
            f"robots ({path}): none of this machine's agents is named there: every agent keeps a simulated body")
    if driving and simulated:
        line += f"; agents {id_ranges(simulated)} keep a simulated body"
    return line


def check_robots(path: Path, spec: RunSpec) -> RobotsFile:
    """A robots file every agent can use (:func:`zswarm.ros.robots.robots_for_run`)."""
    from zswarm.ros.robots import robots_for_run

    return robots_for_run(path, spec.scenario.name, spec.scenario.dimensions, spec.clock, spec.time_scale)


#: Memory an agent process holds, with margin (PSS in docs/benchmarks.md: 10-12 MB forked, 22-25 MB not).
AGENT_MIB = {True: 16, False: 32}


def available_mib() -> float | None:
    """MemAvailable from /proc/meminfo, in MiB (None where there is no such file)."""
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) / 1024.0
    except (OSError, ValueError, IndexError):
        return None
    return None


def check_capacity(n_local: int, fork: bool, have: float | None = None) -> None:
    """Refuse, before anything starts, a number of agent processes this machine (or a cluster's ``have``
    MiB) cannot hold."""
    where = "this machine has" if have is None else "the cluster has"
    need, have = n_local * AGENT_MIB[fork], have or available_mib()
    if have is not None and need > have:
        raise UsageError(f"{n_local} agent processes need about {need / 1024:,.0f} GiB of memory "
                         f"({AGENT_MIB[fork]} MiB each{', forked' if fork else ''}) and {where} "
                         f"{have / 1024:.1f} GiB available; run fewer agents, or "
                         + ("spread them over machines (zswarm run --cluster, docs/cluster.md)" if where.startswith("this")
                            else "add nodes"))


#: CPU an agent's control step takes (ms): 0.5-0.8 on bench-field (docs/benchmarks.md), more in a dense swarm.
AGENT_TICK_MS = 1.0
#: The share of the machine the agents may use in real time; the router, the world and the OS need the rest.
AGENT_SHARE = 0.5


def available_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


#: A run asking for more than this many times the CPU its agents can have is refused: its agents could
#: not even all start before the run ended (500 agents of moving-prey on 2 cores, 10 times over: 70 s to
#: fork them, the world starting with a fifth of them, the rest failing after it was gone).
HOPELESS = 4.0


def pace_load(n_local: int, dt: float, time_scale: float, cores: int) -> float:
    """How many times over its agents' share of this machine a free-clock run's control steps are."""
    need = n_local * (time_scale / dt) * AGENT_TICK_MS / 1000.0  # cores, for the control steps alone
    return need / (AGENT_SHARE * cores)


def pace_warning(n_local: int, dt: float, time_scale: float, cores: int, refused: bool = False,
                 where: str = "this machine") -> str | None:
    """A free-clock run whose agents need more CPU than the machine has falls behind: the agents' ticks
    come late and are skipped, so the swarm moves slower than asked (its poses still arrive fresh: the
    agents share one scheduling group, ``agents.fleet``). The warning names a time scale that fits
    (measured: large-swarm, 100 agents at dt = 0.025 on 2 cores: 0.25 on time, 0.5 not);
    ``refused``: the line of a run refused for needing more than :data:`HOPELESS` times that."""
    load = pace_load(n_local, dt, time_scale, cores)
    if load <= 1.0:
        return None
    budget = AGENT_SHARE * cores
    need = load * budget
    fits = math.floor(20.0 * time_scale * budget / need) / 20.0
    advice = f"--time-scale {fits:g}" if fits >= 0.05 else "fewer agents on this machine (--ids)"
    what = (f"more than {HOPELESS:g} times what it can step: the agents could not all start in time; give {advice}"
            if refused else f"its agents will tick late and the swarm move slower than asked; use {advice}")
    return (f"{n_local} agents stepping {time_scale / dt:g} times a second need about {need:.2g} cores "
            f"({AGENT_TICK_MS:g} ms a step) and {where} has {cores}: {what}")


def auto_time_scale(args: argparse.Namespace, cores: int) -> str | None:
    """``--time-scale auto`` (the default of ``zswarm run``): the pace this machine can hold for its
    agents (:func:`pace_load` at most 1), at most real time, in steps of 0.05; lockstep, runs without
    agents here, and runs too large for this machine even to start in time (refused later) take 1. Sets ``args.time_scale``; returns what it picked, to say at start."""
    if args.time_scale != "auto":
        return None
    args.time_scale = 1.0
    if args.clock != "free" or "agents" not in args.role:
        return None
    scenario = get_scenario(args.scenario, {**parse_assignments(args.assignments),
                                            **({"n_agents": args.agents} if args.agents is not None else {})})
    n = len(args.ids) if args.ids is not None else scenario.n_agents
    load = pace_load(n, scenario.dt, 1.0, cores)
    if load <= 1.0 or load > HOPELESS:  # beyond HOPELESS the run is refused below, naming a pace that fits
        return None
    args.time_scale = max(math.floor(20.0 / load) / 20.0, 0.05)
    return (f"time scale: auto picked {args.time_scale:g} (real time would need {load:.2g} times the CPU "
            f"{n} agents can have on {cores} cores; --time-scale 1 runs at real time, the safety filter keeping "
            f"it safe on stale data)")


#: What a run without --secure says at its start (zswarm.net.poses.Contest says what is left to an attacker).
OPEN_RUN = ("open run: any program that reaches its router can join it; --secure DIR lets in only the run's own "
            "processes (docs/running.md, Secure runs)")


def design_command(spec: RunSpec) -> str:
    """The command that explains a run's design verdict."""
    sets = " ".join(f"--set {k}={v}" for k, v in spec.overrides)
    return f"zswarm design --scenario {spec.scenario_name}" + (f" {sets}" if sets else "")


def judge_design(spec: RunSpec, required: bool) -> dict:
    """The design verdict of the set the run will use; one line when it fails, or when the law has no
    guidelines (then whether the filter is on), or (with ``required``) a usage error before anything
    starts."""
    from zswarm.design.guidelines import judged

    result, line = judged(spec.scenario.params, spec.scenario.dt, design_command(spec), required, spec.safety)
    if line is not None:
        print(line, file=sys.stderr, flush=True)
    return result


def check_secure_dir(directory: Path, roles: Sequence[str], ids: Sequence[int]) -> None:
    """``--secure DIR``: an empty or new DIR, which the run makes (where it can write); or one that holds
    every config this machine's roles use (``zswarm certs`` made it, or its ``--bundle`` for this machine),
    each naming files of DIR that are there and sound (:func:`zswarm.net.certs.check_config_files`).
    UsageError in one line otherwise, before anything starts."""
    from zswarm.net.certs import check_config_files
    from zswarm.net.security import agent_config, agent_name

    if directory.exists() and not directory.is_dir():
        raise UsageError(f"--secure {directory} is not a directory")
    if not directory.exists() or not any(directory.iterdir()):  # zswarm makes it: it must be able to
        try:
            directory.mkdir(parents=True, exist_ok=True)
            probe = directory / ".zswarm-probe"
            probe.write_bytes(b"")
            probe.unlink()
        except OSError as exc:
            raise UsageError(f"--secure {directory}: cannot write the keys there ({exc.strerror or exc}); give a "
                             "directory of yours") from None
        return
    needed = {role: directory / f"{role}.json5" for role in ("router", "world") if role in roles}
    needed.update({f"agent {i}": agent_config(directory, i) for i in (ids if "agents" in roles else ())})
    for role, config in needed.items():
        if not config.is_file():
            raise UsageError(f"--secure {directory} has no {config.name}, which this machine's {role} needs: make "
                             f"the folder with zswarm certs {directory}, or on the machine with the CA a bundle for "
                             f"this one with zswarm certs DIR --bundle OUT --names NAME,... (docs/running.md)")
    own = [i for i in ids if agent_config(directory, i).name == f"{agent_name(i)}.json5"]
    if own and len(own) < len(ids):
        lacking = sorted(set(ids) - set(own))
        raise UsageError(f"--secure {directory} gives agents their own identities, but none to agent "
                         f"{lacking[0]}{' and others' if len(lacking) > 1 else ''}; remake it with: "
                         f"zswarm certs {directory} --force --agents {max(ids) + 1}")
    for config in dict.fromkeys(needed.values()):
        check_config_files(config, directory)
