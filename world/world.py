"""The world: hosts the obstacles and the prey, and observes (never steers) the swarm.

It answers obstacle queries with only the obstacles within the asked radius, moves and publishes the
prey, and subscribes to every pose only to log and measure: live metrics with the simulator's code,
a Rerun recording with the simulator's blueprint, and a summary JSON at the end.
"""

from __future__ import annotations

import asyncio
import json
import math
import os
import sys
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from zswarm import messages as msg
from zswarm import prey as prey_motion
from zswarm.design import epsilon
from zswarm.metrics import Summary, step_metrics
from zswarm.runspec import RunSpec
from zswarm.sim import Simulator, metric_context, simulate, versions
from zswarm.transport import Bridge


@dataclass
class Observed:
    pose: msg.Pose
    received: float


@dataclass
class WorldState:
    poses: dict[int, Observed] = field(default_factory=dict)
    by_step: dict[int, dict[int, msg.Pose]] = field(default_factory=dict)
    alive: set[int] = field(default_factory=set)
    stats: dict[int, msg.Stats] = field(default_factory=dict)
    departures: list[dict[str, Any]] = field(default_factory=list)
    arrivals: list[dict[str, Any]] = field(default_factory=list)
    rejected: dict[str, int] = field(default_factory=dict)
    received: int = 0


def _ratio(a: float, b: float) -> float | None:
    return a / b if b else None


class World:
    def __init__(self, spec: RunSpec, bridge: Bridge, record: Path | None, summary_path: Path | None,
                 trajectory: Path | None = None, argv: list[str] | None = None, resume: bool = False) -> None:
        self.spec, self.bridge, self.keys = spec, bridge, spec.keys
        self.scenario = spec.scenario
        self.reference = Simulator(self.scenario, spec.seed, spec.combination)  # its field, not its state
        self.centers, self.radii = self.scenario.obstacle_arrays()
        p = self.scenario.params.swarm
        self.max_step = 3.0 * p.v_max * self.scenario.dt  # as the agents judge it
        self.prey = np.array(self.scenario.prey_start, dtype=float)
        self.state = WorldState()
        self.summary = Summary(capture_radius=self.scenario.capture_radius,
                               epsilon=epsilon(self.scenario.params.potential, self.scenario.n_agents))
        self.ctx = metric_context(self.scenario, self.reference.obstacles)
        self.record_path, self.summary_path, self.trajectory_path = record, summary_path, trajectory
        self.argv = argv or sys.argv
        self.rec = None
        self.trail: deque[np.ndarray] = deque(maxlen=400)  # the prey's recent path, as drawn
        self.traj: list[np.ndarray] = []
        self.traj_prey: list[np.ndarray] = []
        self.pose_arrived = asyncio.Event()
        self.stop = asyncio.Event()
        self.started_wall = time.time()
        self.all_alive_after: float | None = None
        self.sent = 0
        self.resume = resume
        self.segment = 0  # which recording segment this world writes (> 0: it was restarted)
        self.resumed_from: dict[str, Any] | None = None

    # --- what the world answers and hears -------------------------------------------------------------

    def answer_obstacles(self, params: dict[str, str]) -> list[tuple[str, bytes]]:
        """Obstacles whose boundary lies within r of (x, y): what an agent there can sense."""
        try:
            x, y, r = float(params["x"]), float(params["y"]), float(params["r"])
        except (KeyError, ValueError):
            return []
        if not all(math.isfinite(v) for v in (x, y, r)) or r < 0:
            return []
        if len(self.centers):
            gap = np.linalg.norm(self.centers - np.array([x, y]), axis=1) - self.radii
            keep = gap <= r
        else:
            keep = np.zeros(0, dtype=bool)
        payload = msg.encode(msg.Obstacles(tuple(map(tuple, self.centers[keep].tolist())),
                                           tuple(self.radii[keep].tolist())))
        return [(self.keys.obstacles, payload)]

    def handle(self, item: tuple[str, str, bytes, bool]) -> None:
        tag, key, payload, deleted = item
        st = self.state
        if tag == "alive":
            who = self.keys.agent_of(key)
            if who is None:
                return
            event = {"id": who, "t": round(self.sim_time(), 6), "wall": round(time.time() - self.started_wall, 3)}
            if deleted:
                st.alive.discard(who)
                st.poses.pop(who, None)
                st.departures.append(event)
                self._log_event(f"agent {who} departed")
            else:
                st.alive.add(who)
                st.arrivals.append(event)
                if self.all_alive_after is None and len(st.alive) >= self.scenario.n_agents:
                    self.all_alive_after = time.time() - self.started_wall
            return
        st.received += 1
        try:
            m = msg.decode(payload)
        except msg.DecodeError as exc:
            if exc.reason not in st.rejected:
                print(f"world: rejected a message on {key} ({exc}); further '{exc.reason}' rejections "
                      f"are only counted", file=sys.stderr, flush=True)
                self._log_event(f"rejected message: {exc}")
            st.rejected[exc.reason] = st.rejected.get(exc.reason, 0) + 1
            return
        if tag == "pose" and isinstance(m, msg.Pose) and self.keys.agent_of(key) == m.id:
            old = st.poses.get(m.id)
            elapsed = (time.time() - old.received) / self.spec.period + 2.0 if old is not None and m.step < 0 else None
            if old is not None and m.seq > old.pose.seq and msg.implausible_jump(old.pose, m, self.max_step, elapsed):
                st.rejected["jump"] = st.rejected.get("jump", 0) + 1
                return
            if old is None or msg.supersedes(old.pose, m):
                st.poses[m.id] = Observed(m, time.time())
            if m.step >= 0:
                st.by_step.setdefault(m.step, {})[m.id] = m
            self.pose_arrived.set()
        elif tag == "stats" and isinstance(m, msg.Stats) and self.keys.agent_of(key) == m.id:
            st.stats[m.id] = m
        else:
            st.rejected["kind"] = st.rejected.get("kind", 0) + 1

    # --- one observed step ----------------------------------------------------------------------------

    step_index = 0  # world ticks so far (the recording's "step" timeline)
    t = 0.0  # simulated time: k dt in lockstep, wall time x time scale in free mode

    def sim_time(self) -> float:
        return self.t

    def observe(self, poses: dict[int, msg.Pose]) -> dict[str, float] | None:
        """Metrics and logging of the swarm as it is now (poses of the live agents)."""
        ids = np.array(sorted(poses), dtype=np.int64)
        if len(ids) == 0:
            return None
        pos = np.array([[poses[i].x, poses[i].y] for i in ids])
        vel = np.array([[poses[i].vx, poses[i].vy] for i in ids])
        u, _ = self.reference.potential_and_velocity(pos, self.prey)
        metrics, colliding, contacts = step_metrics(pos, vel, self.prey, self.ctx, float(u.sum()))
        self.summary.add(self.sim_time(), metrics, ids[colliding] if len(colliding) else colliding, contacts)
        self._keep_trajectory(ids, pos, self.prey)
        if self.rec is not None:
            from zswarm import swarm_log

            swarm_log.set_time(self.rec, self.step_index, self.sim_time())
            self.trail.append(self.prey.copy())
            swarm_log.log_swarm(self.rec, self.sim_time(), ids, pos, vel)
            swarm_log.log_prey(self.rec, self.prey, np.array(self.trail))
            swarm_log.log_metrics(self.rec, {**metrics, "agents_alive": float(len(self.state.alive))})
        return metrics

    def _keep_trajectory(self, ids: np.ndarray, pos: np.ndarray, prey: np.ndarray) -> None:
        """One row of the --trajectory file: positions by agent id (NaN for the absent)."""
        if self.trajectory_path is None:
            return
        full = np.full((self.scenario.n_agents, 2), np.nan)
        inside = ids < self.scenario.n_agents
        full[ids[inside]] = pos[inside]
        self.traj.append(full)
        self.traj_prey.append(prey.copy())

    def advance_prey(self, poses: dict[int, msg.Pose], dt: float) -> None:
        pos = np.array([[p.x, p.y] for _, p in sorted(poses.items())]).reshape(-1, 2)
        self.prey = prey_motion.step(self.scenario.prey, self.prey, dt, pos)

    def publish(self, key: str, payload: bytes) -> None:
        self.bridge.session.put(key, payload)
        self.sent += 1

    def _log_event(self, text: str) -> None:
        if self.rec is not None:
            import rerun as rr

            from zswarm import swarm_log

            swarm_log.set_time(self.rec, self.step_index, self.sim_time())
            self.rec.log("run/events", rr.TextLog(text))

    # --- the clocks ------------------------------------------------------------------------------------

    async def wait_for_agents(self, timeout: float) -> None:
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout
        while len(self.state.alive) < self.scenario.n_agents and loop.time() < deadline and not self.stop.is_set():
            await asyncio.sleep(0.05)
        if len(self.state.alive) < self.scenario.n_agents:
            print(f"world: {len(self.state.alive)} of {self.scenario.n_agents} agents alive after "
                  f"{timeout:g} s; starting anyway", file=sys.stderr, flush=True)

    async def run_free(self, steps: int, progress: float) -> None:
        """Tick at the agents' rate; simulated time follows the wall clock, so a slow world tick
        stretches the prey's step instead of slowing its time down."""
        loop = asyncio.get_running_loop()
        period, duration = self.spec.period, steps * self.scenario.dt
        next_tick = loop.time()
        start = next_tick - self.t / self.spec.time_scale  # a restarted world goes on from its t
        last_print = -math.inf
        self.late_ticks = 0
        while not self.stop.is_set():
            live = {i: o.pose for i, o in self.state.poses.items() if i in self.state.alive}
            self.publish(self.keys.prey, msg.encode(msg.Prey(self.step_index, time.time(), -1,
                                                             float(self.prey[0]), float(self.prey[1]))))
            metrics = self.observe(live)
            last_print = self._progress(metrics, steps, progress, last_print)
            if self.t >= duration - 1e-9:
                break
            next_tick += period
            try:
                await asyncio.wait_for(self.stop.wait(), max(next_tick - loop.time(), 0.0))
            except asyncio.TimeoutError:
                pass
            if loop.time() - next_tick > 0.5 * period:
                self.late_ticks += 1
            t_new = min((loop.time() - start) * self.spec.time_scale, duration)
            self.advance_prey(live, t_new - self.t)
            self.t = t_new
            self.step_index += 1

    async def run_lockstep(self, steps: int, progress: float, step_timeout: float) -> None:
        loop = asyncio.get_running_loop()
        last_print = -math.inf
        self.missed_poses = 0
        while self.step_index <= steps and not self.stop.is_set():
            k = self.step_index
            self.publish(self.keys.tick, msg.encode(msg.Tick(k, time.time(), float(self.prey[0]),
                                                             float(self.prey[1]))))
            deadline = loop.time() + step_timeout
            while not self.stop.is_set():
                have = self.state.by_step.get(k, {})
                missing = self.state.alive - set(have)
                if not missing or loop.time() > deadline:
                    self.missed_poses += len(missing)
                    break
                self.pose_arrived.clear()
                try:
                    await asyncio.wait_for(self.pose_arrived.wait(), deadline - loop.time())
                except asyncio.TimeoutError:
                    pass
            poses = {i: p for i, p in self.state.by_step.pop(k, {}).items() if i in self.state.alive}
            metrics = self.observe(poses)
            last_print = self._progress(metrics, steps, progress, last_print)
            if k == steps:
                break
            self.advance_prey(poses, self.scenario.dt)
            self.step_index += 1
            self.t = self.step_index * self.scenario.dt
            for old in [s for s in self.state.by_step if s < k - 2]:
                del self.state.by_step[old]

    def _progress(self, metrics, steps: int, every: float, last: float) -> float:
        now = time.time()
        if every <= 0 or now - last < every:
            return last
        t, total = self.sim_time(), steps * self.scenario.dt
        d = metrics["centroid_goal_distance"] if metrics else float("nan")
        cap = self.summary.capture_time()
        print(f"t={t:7.2f}/{total:.1f} s  agents {len(self.state.alive)}/{self.scenario.n_agents}  "
              f"centroid-prey {d:6.3f}  " + (f"captured at {cap:.2f} s" if cap is not None else "not captured"),
              flush=True)
        return now

    # --- start and end --------------------------------------------------------------------------------

    def open_recording(self) -> None:
        if self.record_path is None:
            return
        from zswarm import swarm_log
        from zswarm.recording import open_recording
        from zswarm.replay import segment_path

        path = self.record_path
        if self.resume and path.exists():
            self.recover()
            path = segment_path(path, self.segment)
        extra = (("agents alive", ("agents_alive",)),)
        self.rec = open_recording(path, "zswarm-world", swarm_log.blueprint(extra), recording_id=self.spec.run)
        swarm_log.log_config(self.rec, self.config())
        swarm_log.log_obstacles(self.rec, self.centers, self.radii)
        self.rec.flush()  # on disk before anything can go wrong: a successor reads the run's identity here
        if self.resumed_from is not None:
            self._log_event(f"world restarted: segment {self.segment} continues after step "
                            f"{self.resumed_from['step']} (t = {self.resumed_from['t']:.2f} s)")

    def recover(self) -> None:
        """A restarted world: read what the previous worlds recorded (every segment; a killed
        writer's file is read up to its last complete chunk), fold it into the summary, and go on
        from the last recorded step, time and prey position. Their files are never touched."""
        from zswarm.cli_util import UsageError
        from zswarm.replay import fold_frames, load_run, segments
        from zswarm.salvage import seal

        for part in segments(self.record_path):
            if seal(part):
                print(f"world: {part} had no footer (its world was killed); rewritten whole", flush=True)
        prior = load_run(self.record_path, require_states=False)
        if prior.config.get("run") != self.spec.run:
            raise UsageError(f"--resume: {self.record_path} records run {prior.config.get('run')!r}, not "
                             f"{self.spec.run!r}; give the same --run or another --record")
        self.segment = len(prior.segments)
        if not prior.frames:  # its predecessor died before its first step: start from the beginning
            self.resumed_from = {"segment": self.segment, "step": -1, "t": 0.0, "frames_recovered": 0}
            return
        fold_frames(self.summary, prior.frames, self.reference, self.ctx)
        last = prior.frames[-1]
        self.step_index, self.t = last.step + 1, last.t
        if last.prey is not None:
            self.prey = last.prey.copy()
        self.trail.extend(f.prey for f in prior.frames[-400:] if f.prey is not None)
        for f in prior.frames:
            self._keep_trajectory(f.ids, f.positions, f.prey if f.prey is not None else np.full(2, np.nan))
        self.resumed_from = {"segment": self.segment, "step": last.step, "t": last.t,
                             "frames_recovered": len(prior.frames)}
        print(f"world: resuming run {self.spec.run!r} after step {last.step} (t = {last.t:.2f} s) from "
              f"{len(prior.segments)} segment(s); writing segment {self.segment}", flush=True)

    def config(self) -> dict[str, Any]:
        s = self.spec
        return {"run": s.run, "scenario": s.scenario.name, "seed": s.seed, "potential": s.combination,
                "clock": s.clock, "time_scale": s.time_scale, "n_agents": s.scenario.n_agents,
                "scenario_definition": s.scenario.to_dict(), "versions": versions(), "argv": self.argv,
                "segment": self.segment, "resumed_from": self.resumed_from}

    def transport_summary(self) -> dict[str, Any]:
        stats = list(self.state.stats.values())
        ages = msg.merge([s.age_hist for s in stats])
        lat = msg.merge([s.latency_hist for s in stats])
        ticks = sum(s.ticks for s in stats)
        late = sum(s.late_ticks for s in stats)
        rejected: dict[str, int] = dict(self.state.rejected)
        for s in stats:
            for k, v in s.rejected.items():
                rejected[k] = rejected.get(k, 0) + v
        return {
            "clock": self.spec.clock, "run": self.spec.run,
            "agents_reporting": len(stats),
            "messages_sent": sum(s.sent for s in stats) + self.sent,
            "messages_received": sum(s.received for s in stats) + self.state.received,
            "messages_rejected": sum(rejected.values()), "rejected_by_reason": rejected,
            "pose_age_ms": {"p50": msg.percentile(ages, 0.5), "p99": msg.percentile(ages, 0.99)},
            "pose_latency_ms": {"p50": msg.percentile(lat, 0.5), "p99": msg.percentile(lat, 0.99)},
            "poses_received": sum(lat.values()),
            "ticks": ticks, "late_ticks": late, "on_time_ratio": (1 - late / ticks) if ticks else None,
            "startup_s": self.all_alive_after,
            "departures": self.state.departures,
            "requested_faults": self.spec.faults.requested(),
            "observed_dropout": _ratio(sum((s.extra or {}).get("seq_lost", 0.0) for s in stats),
                                       sum((s.extra or {}).get("seq_lost", 0.0) + (s.extra or {}).get("seq_received", 0.0)
                                           for s in stats)),
            "observed_latency_ms": msg.percentile(lat, 0.5),
            "heard": {str(s.id): list(s.heard) for s in stats},
            "neighbour_departures": {str(s.id): {str(k): v for k, v in (s.departed or {}).items()} for s in stats},
            "neighbour_returns": {str(s.id): {str(k): v for k, v in (s.returned or {}).items()} for s in stats},
            "missed_lockstep_poses": getattr(self, "missed_poses", 0),
            "world_late_ticks": getattr(self, "late_ticks", 0), "world_ticks": self.step_index + 1,
            "world_segments": self.segment + 1, "resumed_from": self.resumed_from,
        }

    def finish(self, steps: int) -> dict[str, Any]:
        header = {"scenario": self.scenario.name, "n_agents": self.scenario.n_agents, "seed": self.spec.seed,
                  "potential": self.spec.combination, "duration": self.t,
                  "steps": self.step_index, "dt": self.scenario.dt}
        result = {**header, **self.summary.result(), **self.transport_summary()}
        ref = simulate(self.scenario, self.spec.seed, combination=self.spec.combination,
                       duration=max(self.t, self.scenario.dt)).summary
        result["reference"] = {k: ref[k] for k in ("capture_time", "collisions", "final_components",
                                                   "min_pair_distance", "final_centroid_goal_distance",
                                                   "min_obstacle_clearance")}
        result["vs_reference"] = {k: (None if result[k] is None or ref[k] is None else result[k] - ref[k])
                                  for k in result["reference"]}
        if self.rec is not None:
            from zswarm import swarm_log
            from zswarm.recording import close_recording

            swarm_log.log_summary(self.rec, result)
            close_recording(self.rec)
        if self.trajectory_path is not None and self.traj:
            np.savez(self.trajectory_path, positions=np.array(self.traj), prey=np.array(self.traj_prey),
                     dt=self.scenario.dt)
        if self.summary_path is not None:
            tmp = Path(f"{self.summary_path}.tmp")
            tmp.write_text(json.dumps(result, indent=2, sort_keys=True))
            os.replace(tmp, self.summary_path)
        return result
