"""The body check: which guarantees assume the paper's point body, and whether a real body's lag fits.

Every other check of the design report (Props 1-5, the pair spacing, contact, the swarm squeeze, the
time step) is about the paper's agent, "the omni-directional robot without nonholonomic constraints",
which moves exactly as commanded: the point body of :mod:`zswarm.control.body`. Another body moves
differently, and what it adds is a lag between where the law wants an agent and where it is:

- a ``unicycle`` steers the point ``lookahead`` (l) ahead of its axle, so its axle may be l from where
  the law's point is; two of them 2 l closer than the law's points are;
- a ``double-integrator`` needs v_max^2 / (2 accel) to stop from full speed, against the law's
  immediate stop.

A pair resting at the spacing d^f has d^f - 2 d^r between its bodies. The check holds when the body's
lag fits in that slack: 2 l < d^f - 2 d^r, or v_max^2 / (2 accel) < d^f - 2 d^r. It is a rule of
thumb, not a proof: ``zswarm bench bodies`` measures what the bodies cost.
"""

from __future__ import annotations

from typing import Any

from zswarm.paper.params import Params

#: The checks of the design report that assume the point body.
POINT_CHECKS = ("Props 1-5", "formation", "contact", "swarm", "time step")


def body_check(params: Params, spacing: float | None) -> dict[str, Any]:
    """The body row of the design report (``spacing``: the pair spacing d^f, None when unstable)."""
    b, s = params.body, params.swarm
    kind = b.body
    slack = None if spacing is None else spacing - 2.0 * s.robot_radius
    if kind == "point":
        return {"holds": True, "body": kind, "lag": 0.0, "slack": slack,
                "detail": "the paper's body (moves as commanded): every check above is for it"}
    if kind == "unicycle":
        lag, what = 2.0 * b.lookahead, f"2 lookahead = {2.0 * b.lookahead:.4g} (its axle trails the point it steers)"
        extra = f"; it turns no tighter than v_max/turn_rate = {s.v_max / b.turn_rate:.4g}"
    else:
        lag = s.v_max ** 2 / (2.0 * b.accel)
        what = f"its stopping distance v_max^2/(2 accel) = {lag:.4g}"
        extra = f"; it takes v_max/accel = {s.v_max / b.accel:.4g} s to stop"
    holds = slack is not None and lag < slack
    room = ("no stable spacing" if slack is None else
            f"{'<' if holds else '>='} d^f - 2 d^r = {slack:.4g}")
    return {"holds": holds, "body": kind, "lag": lag, "slack": slack,
            "detail": f"{kind}: {what} {room}{extra}; the checks above ({', '.join(POINT_CHECKS)}) assume "
                      f"the point body"}
