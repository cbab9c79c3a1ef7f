"""Which neighbours an agent's law may use, and which its safety filter guards it against, at a tick.

One pass over the poses it holds (:class:`zswarm.net.poses.PoseTable`), by its liveliness and member
tokens (:mod:`agents.membership`): the law takes the members heard recently enough; the filter keeps
clear of every neighbour that may be within the sensing radius by now, including the silent ones that
cannot have left and the bodies of the departed ones, with the age of what it knows of each
(docs/safety.md).
"""

from __future__ import annotations

import math
import time

from zswarm.control.step import tracked_point

#: How long the safety filter waits for the liveliness token of a sender whose poses it hears (tokens
#: can come seconds after the poses on a loaded machine) before a silent one stops counting.
TOKEN_GRACE = 5.0


Near = tuple[tuple[float, ...], tuple[float, ...], float]  # a neighbour as its law takes it: position, velocity, age


def choose(s: Sensing, step: int | None, staleness: float, time_scale: float = 1.0, period: float = 0.0,
           lookahead: float = 0.0, guard: bool = True) -> tuple[list[Near], list[tuple[tuple[float, ...], float, float]]]:
    """What the law and the safety filter may use now, from one pass over the neighbours it holds
    (an agent does this every tick): ``(poses, guarded)``.

    *near* (the law's neighbours): of the agents that hold a liveliness token, the step-k pose
    (lockstep, ``step`` k) or the newest, if received within ``staleness`` seconds (free, ``step``
    None), within the sensing radius, as (position, velocity, age: 0 in lockstep, where the step's
    poses are exact). The age is recorded here too, at the moment it is used.

    *guarded* (the safety filter's rows, empty unless ``guard``): (where the filter acts on it, age
    in simulated seconds, its look-ahead) of every neighbour not seen departing, with or without its token. A
    neighbour whose token has not come yet counts (its poses prove it is there; under load a token
    can come seconds after them), unless its token has not come in :data:`TOKEN_GRACE` seconds
    since its first pose and nothing came from it for ``staleness`` seconds: a sender that never
    announced itself and fell silent is no member of the swarm (a hostile peer's made-up agent
    would hold an agent braking beside it). Of those, the ones whose newest pose may
    be within the sensing radius by now (no farther beyond it than v_max times its age), less the
    ones that have gone quiet and can have left (:meth:`_guarded`); and where each departed neighbour's
    body holds (:func:`_remains`).

    Lockstep: the step-k poses, exact for step k (age 0). Free: the newest pose, its age from its
    stamp scaled by ``time_scale``, plus one control period ``period`` (a neighbour on its own timer
    may have stepped once more than the age says: ticks that catch up on a late one come closer
    together). ``lookahead``: a unicycle's tracked point ahead of its axle, from the heading."""
    now, b, entries = time.time(), s.body, s.neighbours.entries
    radius, v, alive, departed = s.radius, s.v_max, s.membership.alive, s.counters.departed
    c = s.counters
    near: list[Near] = []
    heard = []
    # over what is heard: the least time since a neighbour was heard, the least age, the least delay
    quiet_min = age_min = lag_min = math.inf
    for who, nb in entries.items():
        pose = nb.latest if step is None else nb.by_step.get(step)
        if pose is None:
            continue
        quiet = now - nb.received
        member = who in alive
        if not member and not (guard and who not in departed
                               and (now - nb.first <= TOKEN_GRACE or quiet <= staleness)):
            continue
        d = b.distance(pose)
        if member and d <= radius and (step is not None or quiet <= staleness):
            c.add(c.ages, (now - pose.stamp) * 1000.0)
            near.append((pose.position, pose.velocity, 0.0 if step is not None else max(now - pose.stamp, 0.0) * time_scale))
        if guard:
            age = 0.0 if step is not None else max(now - pose.stamp, 0.0) * time_scale + period
            if d - v * age <= radius:
                lag = nb.received - pose.stamp
                heard.append((pose, age, quiet, d, lag))
                quiet_min, age_min, lag_min = min(quiet_min, quiet), min(age_min, age), min(lag_min, lag)
    kept = _remains(s, step, period, lookahead, now, time_scale) if guard else []
    if not heard:
        return near, kept
    return near, _guarded(s, heard, (quiet_min, age_min, lag_min), step, staleness, lookahead) + kept


def _remains(s: Sensing, step: int | None, period: float, lookahead: float, now: float,
             time_scale: float) -> list[tuple]:
    """The safety filter's rows for the departed neighbours within the sensing radius: a neighbour whose
    liveliness token went is no member of the swarm, but its body has not gone with it. One that stopped
    at its newest pose (sent just before its token went: :data:`agents.sensing.HELD_WITHIN`; its process
    ended, or a robot at its command timeout) holds there, one control period old, until it is heard
    again. One heard last long before (it was frozen, or this agent was, or cut off, while the others went
    on) is guarded with its pose's whole age: this agent brakes near it until it hears again
    (docs/safety.md)."""
    out = []
    for pose in s.remains.values():
        if step is not None:
            age = 0.0
        elif pose.id in s.held:
            age = period
        else:
            age = max(now - pose.stamp, 0.0) * time_scale + period
        if s.body.distance(pose) - s.v_max * age <= s.radius:
            out.append(_row(s, pose, age, lookahead))
    return out


def _row(s: Sensing, pose, age: float, lookahead: float) -> tuple:
    """The filter's row of a neighbour: (its tracked point, age, look-ahead: a unicycle's alone carries a
    heading), and, where the run has bodies with inertia, its velocity and acceleration bound (by its id's
    group in the run's scenario, which every agent knows; the least of the run's for an id outside it)."""
    row = (tracked_point(pose.position, pose.heading, lookahead), age, lookahead if pose.heading is not None else 0.0)
    if s.accels is None:
        return row
    accel = s.accels[pose.id] if 0 <= pose.id < len(s.accels) else min(s.accels)
    return (*row, pose.velocity, accel)


def _guarded(s: Sensing, heard: list, least: tuple[float, float, float], step: int | None, staleness: float,
         lookahead: float) -> list[tuple[tuple[float, ...], float, float]]:
    """The safety filter's rows from ``heard`` (pose, age, seconds since it was heard, distance,
    delay it came through): the neighbours that may be within its radius (:meth:`sense`); ``least``:
    the least time since heard, age and delay over them.

    One from which nothing came for ``staleness`` wall seconds longer than from the one heard last
    has gone *quiet*: it has left the cells this agent listens to, or its poses are being lost. One
    whose member token is in one of those cells is there (tokens travel on Zenoh's control plane,
    which pose loss does not touch): its silence is loss, and it stays guarded against. Otherwise it
    is let go only if it can have left: if its newest pose plus what it can have moved while the
    others were still heard (its age beyond the freshest neighbour's: had it stayed, its poses would
    have come through the same delay as theirs) reaches past the subscription disc (the cells cover
    at least that disc about this agent). One deep inside cannot have left: its silence is loss, and
    it stays guarded against where it may be (``docs/safety.md``). That premise holds only for a
    neighbour whose poses came through no slower a path than the others': one whose newest pose
    arrived later after it was sent than the promptest neighbour's by some extra delay is given that
    extra before its silence counts (a router that reads some senders seconds late made them fall
    silent while they were there, and neighbours walked into them). One without a member token is let
    go only on a sign that it left: its token seen to leave the cell it was heard in (a live removal, or
    an ask that found nobody holds it there), and the answer to who sits in every listened cell in (a
    cell just entered, or asked while its router was frozen, may hold it); until then it stays guarded
    and its token in that cell is asked about. ``lookahead``: a unicycle's tracked point ahead of its
    axle, from the heading."""
    v, cells = s.v_max, s.subscription_radius
    left = least[0] + staleness
    fresh = least[1]  # the delay every pose heard now has come through
    path = least[2]  # the shortest delay a newest pose came through
    out = []
    for pose, age, quiet, d, lag in heard:
        # its silence counts only beyond its own path's extra delay: a sender whose poses queue
        # (a router that reads it late) falls silent while it is still there
        if step is None and quiet - max(lag - path, 0.0) > left and d + v * (age - fresh) > cells:
            m = s.membership
            if pose.id in m.members:  # guarded on its member token alone: that token is asked about
                m.doubted[pose.id] = set(m.members[pose.id])
            else:
                cell = s.keys.cell(*pose.position)
                if cell not in m.listening or ((pose.id, cell) in m.gone_from and m.settled):
                    continue  # it left the cell it was heard in, and is in no other it listens to
                m.doubted[pose.id] = {cell}  # no sign it left: guarded, and its token there asked about
        out.append(_row(s, pose, age, lookahead))
    return out
