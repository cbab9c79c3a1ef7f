"""Rerun logging of a swarm run: used by the simulator and by the world process.

One batched entity per kind (the viewer slows down with hundreds of entities): all agents are one
``Points2D``, all velocities one ``Arrows2D``. Positions are also logged as float64 ``AnyValues``
(``Points2D`` stores float32), so that metrics can be recomputed exactly from a recording.

A 3-D run (positions with three columns) is logged with the 3-D archetypes (``Points3D``,
``Arrows3D``, ``LineStrips3D``; obstacles are spheres) into a 3-D view, with a ``z`` state column
beside ``x`` and ``y``; the plots are the same.
"""

from __future__ import annotations

import json
import time
from typing import Any, Callable, Final, Iterable

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

MAP: Final = "map"
AGENTS: Final = "map/agents"
VELOCITIES: Final = "map/velocities"
HEADINGS: Final = "map/headings"  # a body with a heading (zswarm.control.body): where each one faces
SENSING: Final = "map/sensing"
SAFETY: Final = "map/safety"  # where the safety filter acted this step (zswarm.control.safety)
#: acted (orange), stalled (red), braked on old data (purple); messages.SAFETY_FLAGS 1..3
SAFETY_COLOURS: Final = {1: (255, 160, 40), 2: (230, 40, 40), 3: (160, 60, 220)}
SAFETY_LABELS: Final = {1: "filtered", 2: "stalled", 3: "braked"}
SENSING_GRAPH: Final = "map/sensing_graph"  # an edge between every two agents within the sensing radius
OBSTACLES: Final = "map/obstacles"
PREY: Final = "map/prey"
PREY_TRAIL: Final = "map/prey_trail"
STATE: Final = "state/agents"  # float64 x, y, vx, vy, id (and heading, for a headed body) per agent
PREY_STATE: Final = "state/prey"
METRICS: Final = "metrics"
THRESHOLDS: Final = "thresholds"
NETWORK: Final = "network"
EVENTS: Final = "run/events"
CONFIG: Final = "run/config"
SUMMARY: Final = "run/summary"
TIMELINE: Final = "sim_time"

#: How long a heading stroke is drawn (map units).
HEADING_LENGTH: Final = 0.3

#: The lines a reader measures the metrics against (``SwarmObserver.thresholds``), by plot.
THRESHOLD_NAMES = {"capture_radius": "capture radius", "collision_distance": "2 d^r (collision)",
                   "d_m_ro": "d_m^ro (Prop 2)", "epsilon": "epsilon (Prop 3)"}
PLOTS = (("distance to prey", ("mean_goal_distance", "centroid_goal_distance", "capture_radius")),
         ("safety and spacing", ("min_pair_distance", "median_nearest", "min_obstacle_clearance", "collision_distance",
                                "d_m_ro")),
         ("cohesion and components", ("cohesion", "components", "epsilon")),
         ("order and union", ("order", "union")),
         ("energy (eq 35; the Lyapunov trace of the paper's interaction)", ("energy",)))


def _kind(positions: Any, two: Any, three: Any) -> Any:
    """The archetype for points of this dimension: ``three`` for 3-D, else ``two``."""
    return three if np.shape(positions)[-1] == 3 else two


def _points(positions: np.ndarray, **kw: Any) -> Any:
    return _kind(positions, rr.Points2D, rr.Points3D)(positions, **kw)


def blueprint(extra_plots: Iterable[tuple[str, tuple[str, ...]]] = (), network: bool = False,
              arena: tuple[float, float, float, float] | None = None, dimensions: int = 2) -> rrb.Blueprint:
    """The map beside the metric plots (each with its threshold lines); ``network``: a third column with
    the transport figures and the run's events (the world's recordings). ``arena`` (x_min, y_min, x_max,
    y_max): what the map frames when it opens (the scenario's :meth:`~zswarm.swarm.scenario.Scenario.arena`).
    ``dimensions`` 3: the map is a 3-D view."""
    def path(name: str) -> str:
        return f"{THRESHOLDS}/{name}" if name in THRESHOLD_NAMES else f"{METRICS}/{name}"

    plots = [rrb.TimeSeriesView(name=title, origin="/", contents=[path(name) for name in names])
             for title, names in (*PLOTS, *extra_plots)]
    plots.append(rrb.TimeSeriesView(name="safety filter: agents filtered, stalled, braked", origin="/",
                                    contents=[f"safety/{name}" for name in SAFETY_LABELS.values()]))
    side = [rrb.Vertical(*plots)]
    if network:
        side.append(rrb.Vertical(
            rrb.TimeSeriesView(name="network: latency and data age p50/p99 (ms)", origin="/",
                               contents=[f"{NETWORK}/latency_p50_ms", f"{NETWORK}/latency_p99_ms",
                                         f"{NETWORK}/age_p50_ms", f"{NETWORK}/age_p99_ms"]),
            rrb.TimeSeriesView(name="network: poses/s, rejected, late ticks, agents alive", origin="/",
                               contents=[f"{NETWORK}/poses_per_s", f"{NETWORK}/rejected", f"{NETWORK}/late_ticks",
                                         f"{NETWORK}/agents_alive"]),
            rrb.TextLogView(origin=EVENTS, name="events"),
            row_shares=[2, 2, 1]))
    return rrb.Blueprint(
        rrb.Horizontal(
            (rrb.Spatial3DView(origin=MAP, name="swarm", eye_controls=_eye(arena)) if dimensions == 3 else
             rrb.Spatial2DView(origin=MAP, name="swarm", visual_bounds=None if arena is None else
                               rrb.VisualBounds2D(x_range=[arena[0], arena[2]], y_range=[arena[1], arena[3]]))),
            *side,
            column_shares=[3, 2, 2] if network else [3, 2],
        ),
        rrb.TimePanel(expanded=False),
        collapse_panels=True,
    )


def _eye(arena: tuple[float, ...] | None) -> rrb.EyeControls3D | None:
    """A 3-D map's camera: looking at the arena's centre from its front-left, above, far enough back to
    hold all of it (spawn, obstacles, the prey's path) in the frame."""
    if arena is None or len(arena) != 6:
        return None
    lo, hi = np.array(arena[:3]), np.array(arena[3:])
    centre, size = (lo + hi) / 2.0, float(np.linalg.norm(hi - lo))
    position = centre + size * np.array([-0.45, -0.75, 0.45])
    return rrb.EyeControls3D(kind=rrb.Eye3DKind.Orbital, position=position.tolist(), look_target=centre.tolist(),
                             eye_up=[0.0, 0.0, 1.0])


def log_config(rec: rr.RecordingStream, config: dict[str, Any]) -> None:
    """What the run was asked to do (scenario, parameters, seed, versions), as static data."""
    text = json.dumps(config, indent=2, sort_keys=True, default=str)
    rec.log(CONFIG, rr.TextDocument(f"```json\n{text}\n```", media_type=rr.MediaType.MARKDOWN),
            rr.AnyValues(config_json=text), static=True)


def log_obstacles(rec: rr.RecordingStream, centers: np.ndarray, radii: np.ndarray) -> None:
    if len(centers):
        rec.log(OBSTACLES, _points(centers, radii=np.maximum(radii, 0.03), colors=(150, 150, 150)), static=True)


def set_time(rec: rr.RecordingStream, step: int, t: float, series: Series | None = None) -> None:
    rec.set_time("step", sequence=step)
    rec.set_time(TIMELINE, duration=t)
    if series is not None:
        series.at(step, t)


class Labels:
    """Which agents the map's points were last labelled for. Their labels, class ids and radius are
    logged when the set of agents changes, their positions every step: the viewer shows, at every
    instant, the newest of each component (a partial update), so the map is the same, and a recorder
    does not turn every id into text at every step (at N = 1000: 368 us a step against 45 for the
    positions alone)."""

    def __init__(self) -> None:
        self.ids: np.ndarray | None = None

    def due(self, ids: np.ndarray) -> bool:
        """The agents (in this order) differ from those labelled last: label them now."""
        if self.ids is not None and np.array_equal(self.ids, ids):
            return False
        self.ids = np.array(ids, copy=True)
        return True


def log_swarm(series: Series, t: float, ids: np.ndarray, positions: np.ndarray,
              velocities: np.ndarray, sensing_radius: float | None = None,
              headings: np.ndarray | None = None, stamps: np.ndarray | None = None,
              labels: Labels | None = None) -> None:
    """Agents (with id labels), their velocity arrows, optional sensing discs and exact float64 state;
    ``headings`` (radians, NaN where none): a short white arrow from each agent the way it faces.
    ``labels``: the recording's :class:`Labels` (without one, every step carries them). Kept in
    ``series`` and sent with its next columns, but for a step whose labels are due: logged at once."""
    points = _kind(positions, rr.Points2D, rr.Points3D)
    if labels is None or labels.due(ids):
        series.rec.log(AGENTS, _points(positions, radii=0.05, labels=[str(int(i)) for i in ids], class_ids=ids,
                                       show_labels=len(ids) <= 30))
    else:
        series.put(AGENTS, points, positions=positions)
    series.put(VELOCITIES, _kind(positions, rr.Arrows2D, rr.Arrows3D), origins=positions, vectors=velocities)
    if sensing_radius is not None:
        series.put(SENSING, points, positions=positions,
                   style=lambda: points.from_fields(radii=sensing_radius, colors=(120, 160, 255, 25)))
    state = {}
    if headings is not None:
        has = np.isfinite(headings)
        facing = HEADING_LENGTH * np.column_stack([np.cos(headings[has]), np.sin(headings[has])])
        series.put(HEADINGS, rr.Arrows2D, origins=positions[has], vectors=facing,
                   style=lambda: rr.Arrows2D.from_fields(colors=(240, 240, 240), radii=0.012))
        state["heading"] = np.asarray(headings, dtype=np.float64)
    if stamps is not None:  # a free-clock world: when each agent sent the pose it holds (wall seconds)
        state["stamp"] = np.asarray(stamps, dtype=np.float64)
    if positions.shape[1] == 3:
        state["z"] = positions[:, 2].astype(np.float64)
        state["vz"] = velocities[:, 2].astype(np.float64)
    series.put(STATE, rr.AnyValues, prompt=True, t=np.array([t], dtype=np.float64), id=np.asarray(ids, dtype=np.int64),
               x=positions[:, 0].astype(np.float64), y=positions[:, 1].astype(np.float64),
               vx=velocities[:, 0].astype(np.float64), vy=velocities[:, 1].astype(np.float64), **state)


def log_safety(series: Series, positions: np.ndarray, flags: np.ndarray, radius: float) -> None:
    """A translucent halo of twice ``radius`` (the body's radius: two halos overlap well before two
    agents touch) under each agent whose command the filter changed this step, coloured by what it
    did (:data:`SAFETY_COLOURS`: filtered, stalled, braked); the count of each as a time series."""
    flags = np.asarray(flags, dtype=int)
    acted = flags > 0
    colours = np.array([(*SAFETY_COLOURS[int(f)], 150) for f in flags[acted]], dtype=np.uint8).reshape(-1, 4)
    points = _kind(positions, rr.Points2D, rr.Points3D)
    extra = {"draw_order": 5.0} if np.shape(positions)[-1] == 2 else {}  # under the agents (rerun's default 30)
    series.put(SAFETY, points, positions=positions[acted], colors=colours,
               style=lambda: points.from_fields(radii=2.0 * radius, **extra))
    for f, name in SAFETY_LABELS.items():
        series.add(f"safety/{name}", float(np.sum(flags == f)))


def log_prey(series: Series, prey: np.ndarray, trail: np.ndarray) -> None:
    points = _kind(prey, rr.Points2D, rr.Points3D)
    series.put(PREY, points, positions=np.asarray(prey, dtype=float)[None],
               style=lambda: points.from_fields(radii=0.08, colors=(255, 60, 60), labels=["prey"]))
    if len(trail) > 1:
        strips = _kind(prey, rr.LineStrips2D, rr.LineStrips3D)
        series.put(PREY_TRAIL, strips, strips=[np.asarray(trail, dtype=float)],
                   style=lambda: strips.from_fields(colors=(255, 120, 120)))
    z = {"z": np.array([prey[2]], np.float64)} if len(prey) == 3 else {}
    series.put(PREY_STATE, rr.AnyValues, prompt=True, x=np.array([prey[0]], np.float64),
               y=np.array([prey[1]], np.float64), **z)


class Series:
    """The rows of a run's steps, kept and sent as columns: the scalar series (its metrics, their
    threshold lines, the safety filter's counts: :meth:`add`) and the map's and the state's components
    (:meth:`put`). One ``send_columns`` call per entity every ``every`` steps or ``seconds`` of wall
    time, whichever comes first, not one ``log`` call per entity and step: a call costs 100-300 us,
    and a step has about eight entities and twenty scalars (docs/cluster.md, "What a node costs"). The
    rows are the same ones, on the ``step`` and ``sim_time`` timelines (not on the logger's own
    ``log_time``); what never changes in an entity (a colour, a radius) is logged once, static. The
    ``prompt`` entities (the agents' and the prey's exact states, from which a run is replayed and a
    replacement world resumes) are sent every ``prompt_seconds``: a world killed outright loses no more
    of them than the recording's own buffer held. ``live`` (a viewer watches): the map and the states
    are logged as each step comes, the scalars still kept. :meth:`flush` before the recording closes
    (:func:`~zswarm.record.recording.close_recording` does not know of it)."""

    def __init__(self, rec: rr.RecordingStream, live: bool = False, every: int = 50, seconds: float = 1.0,
                 prompt_seconds: float = 0.2) -> None:
        self.rec, self.live, self.every, self.seconds, self.prompt_seconds = rec, live, every, seconds, prompt_seconds
        self.rows: dict[str, tuple[list[int], list[float], list[float]]] = {}
        self.parts: dict[str, tuple[Any, bool, list[int], list[float], dict[str, list[Any]]]] = {}
        self.step, self.t, self.kept = 0, 0.0, 0
        self.sent_at = self.prompt_at = time.monotonic()

    def at(self, step: int, t: float) -> None:
        """The step the next rows belong to; what was kept is sent first when it is due."""
        if self.kept:
            now = time.monotonic()
            if self.kept >= self.every or now - self.sent_at >= self.seconds:
                self.flush()
            elif now - self.prompt_at >= self.prompt_seconds:
                self.flush(prompt_only=True)
        self.step, self.t = step, t
        self.kept += 1

    def add(self, path: str, value: float) -> None:
        steps, times, values = self.rows.setdefault(path, ([], [], []))
        steps.append(self.step)
        times.append(self.t)
        values.append(float(value))

    def put(self, path: str, kind: Any, style: Callable[[], Any] | None = None, prompt: bool = False,
            **components: Any) -> None:
        """This step's row of entity ``path``: ``kind`` (an archetype) holds its ``components``, each a
        batch (an array of rows, or a list); ``style``: makes the entity's components that never
        change, logged once, static, when it is first put; ``prompt``: sent every ``prompt_seconds``."""
        part = self.parts.get(path)
        if part is None:
            if style is not None:
                self.rec.log(path, style(), static=True)
            part = self.parts[path] = (kind, prompt, [], [], {})
        if self.live:  # at the recording's time, which set_time has moved to this step
            self.rec.log(path, kind(**components) if kind is rr.AnyValues else kind.from_fields(**components))
            return
        _, _, steps, times, batches = part
        steps.append(self.step)
        times.append(self.t)
        for name, batch in components.items():
            batches.setdefault(name, []).append(batch)

    def flush(self, prompt_only: bool = False) -> None:
        """Send what was kept (``prompt_only``: the prompt entities' rows only)."""
        indexes: dict[tuple[int, ...], list[Any]] = {}  # the same steps' time columns, made once

        def send(path: str, steps: list[int], times: list[float], columns: list[Any]) -> None:
            key = tuple(steps)
            if key not in indexes:
                indexes[key] = [rr.TimeColumn("step", sequence=steps), rr.TimeColumn(TIMELINE, duration=times)]
            self.rec.send_columns(path, indexes=indexes[key], columns=columns)

        if not prompt_only:
            for path, (steps, times, values) in self.rows.items():
                send(path, steps, times, rr.Scalars.columns(scalars=values))
            self.rows.clear()
        for path, (kind, prompt, steps, times, batches) in self.parts.items():
            if not steps or (prompt_only and not prompt):
                continue
            groups: dict[tuple[int, ...], dict[str, Any]] = {}  # the components whose rows have the same lengths
            for name, rows in batches.items():
                flat = np.concatenate(rows) if isinstance(rows[0], np.ndarray) else [x for row in rows for x in row]
                groups.setdefault(tuple(len(row) for row in rows), {})[name] = flat
            send(path, steps, times, [column for lengths, group in groups.items()
                                      for column in (kind.columns(**group) if all(n == 1 for n in lengths) else
                                                     kind.columns(**group).partition(list(lengths)))])
            steps.clear()
            times.clear()
            batches.clear()
        self.prompt_at = time.monotonic()
        if not prompt_only:
            self.kept = 0
            self.sent_at = self.prompt_at


def log_metrics(series: Series, metrics: dict[str, float], thresholds: dict[str, float] | None = None) -> None:
    """The step's metrics, and the threshold lines beside them (with every step, so they grow with a
    live run)."""
    for name, value in metrics.items():
        if np.isfinite(value):
            series.add(f"{METRICS}/{name}", value)
    for name, value in (thresholds or {}).items():
        if np.isfinite(value):
            series.add(f"{THRESHOLDS}/{name}", value)


def log_threshold_styles(rec: rr.RecordingStream, thresholds: dict[str, float]) -> None:
    """Thin grey lines, named for what they are; and the safety filter's counts in the colours of its
    rings on the map."""
    for name in thresholds:
        rec.log(f"{THRESHOLDS}/{name}", rr.SeriesLines(names=THRESHOLD_NAMES.get(name, name), widths=1.0,
                                                       colors=(160, 160, 160)), static=True)
    for flag, name in SAFETY_LABELS.items():
        rec.log(f"safety/{name}", rr.SeriesLines(names=f"agents {name}", colors=SAFETY_COLOURS[flag]), static=True)


def log_sensing_graph(series: Series, positions: np.ndarray, radius: float) -> None:
    """Who senses whom: a segment between every two agents within ``radius`` (a split swarm shows as
    separate graphs)."""
    from zswarm.paper.neighbours import pairs_within

    i, j = pairs_within(positions, radius)
    keep = i < j
    segments = np.stack([positions[i[keep]], positions[j[keep]]], axis=1)
    strips = _kind(positions, rr.LineStrips2D, rr.LineStrips3D)
    series.put(SENSING_GRAPH, strips, strips=segments,
               style=lambda: strips.from_fields(colors=(110, 150, 220, 110), radii=0.006))


def log_network(rec: rr.RecordingStream, figures: dict[str, float | None]) -> None:
    for name, value in figures.items():
        if value is not None and np.isfinite(value):
            rec.log(f"{NETWORK}/{name}", rr.Scalars(value))


def log_event(rec: rr.RecordingStream, text: str, level: str = "INFO") -> None:
    rec.log(EVENTS, rr.TextLog(text, level=level))


def log_summary(rec: rr.RecordingStream, summary: dict[str, Any]) -> None:
    text = json.dumps(summary, indent=2, sort_keys=True)
    rec.log(SUMMARY, rr.TextDocument(f"```json\n{text}\n```", media_type=rr.MediaType.MARKDOWN),
            rr.AnyValues(summary_json=text), static=True)
