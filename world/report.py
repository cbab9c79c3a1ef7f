"""The transport half of a run's summary: what the agents' stats and the world itself counted."""

from __future__ import annotations

from typing import Any, Callable

from zswarm.net import histogram
from zswarm.net import messages as msg
from zswarm.net.poses import Rejections


def _ratio(a: float, b: float) -> float | None:
    return a / b if b else None


def transport_summary(stats: list[msg.Stats], world_rejected: dict[str, int]) -> dict[str, Any]:
    """Traffic, rejections, latency and age percentiles, ticks on time, observed loss and who heard
    whom, merged over every agent's latest stats message (and the world's own rejections)."""
    ages = histogram.merge([s.age_hist for s in stats])
    lat = histogram.merge([s.latency_hist for s in stats])
    ticks = sum(s.ticks for s in stats)
    late = sum(s.late_ticks for s in stats)
    rejected: dict[str, int] = dict(world_rejected)
    for s in stats:
        for k, v in s.rejected.items():
            rejected[k] = rejected.get(k, 0) + v
    lost = sum(s.health.seq_lost for s in stats)
    counted = sum(s.health.seq_lost + s.health.seq_received for s in stats)
    poses = sum(s.health.poses for s in stats)
    return {
        "agents_reporting": len(stats),
        "agents_final_reports": sum(1 for s in stats if s.final),
        # an agent without one is counted from its last periodic stats (up to its last second), marked so
        "agents_without_final_report": sorted(s.id for s in stats if not s.final),
        **({"counted_without_final_report": "from their last periodic stats"} if any(not s.final for s in stats)
           else {}),
        "messages_sent": sum(s.sent for s in stats),
        "messages_received": sum(s.received for s in stats),
        "messages_rejected": sum(rejected.values()), "rejected_by_reason": rejected,
        "pose_age_ms": {"p50": histogram.percentile(ages, 0.5), "p99": histogram.percentile(ages, 0.99)},
        "pose_latency_ms": {"p50": histogram.percentile(lat, 0.5), "p99": histogram.percentile(lat, 0.99)},
        "poses_received": poses,
        # the share of those sent from another router (each pose names its sender's), and how many
        # agents took in one: measured pose by pose, wherever each agent ran at the time
        "cross_router_share": _ratio(float(sum(s.health.crossed for s in stats)), float(poses)),
        "cross_router_heard": sum(1 for s in stats if s.health.crossed),
        "safety_interventions": sum(s.health.interventions for s in stats),
        "safety_stalled_ticks": sum(s.health.stalled_ticks for s in stats),
        "safety_braked_ticks": sum(s.health.braked_ticks for s in stats),
        "safety_stalled_agents": sum(1 for s in stats if s.health.stalled_long),
        "ticks": ticks, "late_ticks": late, "on_time_ratio": (1 - late / ticks) if ticks else None,
        "skipped_ticks": sum(s.health.skipped_ticks for s in stats),  # free clock: let go by late agents
        "observed_dropout": _ratio(float(lost), float(counted)),
        "observed_latency_ms": histogram.percentile(lat, 0.5),
        "heard": {str(s.id): list(s.heard) for s in stats},
        "heard_poses": {str(s.id): {str(j): n for j, n in zip(s.heard, s.heard_poses)} for s in stats},
        "neighbour_departures": {str(s.id): {str(k): v for k, v in (s.departed or {}).items()} for s in stats},
        "neighbour_returns": {str(s.id): {str(k): v for k, v in (s.returned or {}).items()} for s in stats},
    }


class StatsBook:
    """The agents' stats messages, kept raw and decoded only when read.

    Every agent re-sends its cumulative counters and histograms once a second; decoding and
    validating each on arrival cost a 100-agent world more than all the poses it observes. Only the
    newest message of each agent matters: the messages are decoded when read (the end-of-run wait, the
    summary), and a message that does not decode is counted as rejected and the agent's last good one
    kept. The newest by arrival, except that a final report is replaced only by a message with more
    ticks: the agent's last periodic message, with as many ticks, is batched and its final report
    express, so the final one can arrive first; and an agent moved to another node
    (``--migrate-every``) carries its counts on in another process, whose messages take another path,
    so the last one its old process sent can arrive after the new one's final report. (An agent killed
    and restarted starts its counts anew and sent no final report: its new messages replace the old.)
    """

    def __init__(self, agent_of: Callable[[str], int | None], rejected: Rejections) -> None:
        self.agent_of, self.rejected = agent_of, rejected
        self.raw: dict[int, list[tuple[str, bytes]]] = {}
        self.good: dict[int, msg.Stats] = {}

    def add(self, key: str, payload: bytes) -> int | None:
        """Keep one stats message; returns its agent's id where it is a final report (to acknowledge)."""
        who = self.agent_of(key)
        if who is None:
            self.rejected.add("kind")
        elif len(payload) > msg.MAX_PAYLOAD:
            self.rejected.add("size", f"on {key}: {len(payload)} bytes")
        else:
            pending = self.raw.setdefault(who, [])
            pending.append((key, payload))
            if len(pending) > 8:  # read every few seconds; never a backlog however long the run
                self.get(who)
            return who if msg.is_final_report(payload) else None
        return None

    def get(self, who: int) -> msg.Stats | None:
        for key, payload in self.raw.pop(who, ()):
            try:
                m = msg.decode(payload)
            except msg.DecodeError as exc:
                self.rejected.add(exc.reason, f"on {key}: {exc}")
                continue
            if not isinstance(m, msg.Stats) or m.id != who:
                self.rejected.add("kind")
                continue
            held = self.good.get(who)
            if held is None or not held.final or m.ticks > held.ticks:
                self.good[who] = m
        return self.good.get(who)

    def final(self, who: int) -> bool:
        s = self.get(who)
        return s is not None and s.final

    def all(self) -> list[msg.Stats]:
        return [s for s in (self.get(w) for w in sorted({*self.raw, *self.good})) if s is not None]
