"""The transport latency, timed on the nearest live neighbour's poses heard a second time through a
subscription stamped on arrival, :data:`ON_S` seconds in every :data:`EVERY_S` (docs/architecture.md,
"An agent's tick"). Not the agent's own pose: Zenoh hands it to a subscriber of the same session
without the router."""

from __future__ import annotations

from agents.counters import Counters
from zswarm.net import messages as msg
from zswarm.net.bridge import Bridge
from zswarm.net.keys import Keys
from zswarm.net.poses import PoseTable


ON_S = 1.0
EVERY_S = 5.0


class LatencyProbe:
    def __init__(self, keys: Keys, body, reach: float, neighbours: PoseTable, alive: set[int],
                 counters: Counters) -> None:
        self.keys, self.body, self.reach = keys, body, reach
        self.neighbours, self.alive, self.counters = neighbours, alive, counters
        self.probe: tuple[int, object] | None = None  # the neighbour probed, and its subscription
        self.first: float | None = None  # when it was first asked to follow (the windows count from it)

    def heard(self, payload: bytes, received: float) -> None:
        """A pose of the probed neighbour with its arrival time. The same bytes reach the agent through
        its cells too, where they are taken in, and rejected and counted if bad. Between windows nothing
        is timed: a pose Zenoh was still handing over when the subscription closed is let go."""
        if self.probe is None:
            return
        try:
            m = msg.decode(payload)
        except msg.DecodeError:
            return
        if isinstance(m, msg.Pose):
            self.counters.add(self.counters.latency, (received - m.stamp) * 1000.0)

    def listening(self, now: float) -> bool:
        """Within a window (the first opens at the first call)."""
        if self.first is None:
            self.first = now
        return (now - self.first) % EVERY_S < ON_S

    def follow(self, bridge: Bridge, now: float) -> None:
        """Within a window, probe the nearest neighbour for as long as it stays within reach and alive;
        between windows, hold no subscription."""
        window = self.listening(now)
        if self.probe is not None:
            who, sub = self.probe
            nb = self.neighbours.get(who)
            if window and who in self.alive and nb is not None and self.body.distance(nb.latest) <= self.reach:
                return
            bridge.unsubscribe(sub)
            self.probe = None
        if not window:
            return
        best: tuple[float, int] | None = None
        for who, nb in self.neighbours.entries.items():
            d = self.body.distance(nb.latest)
            if d <= self.reach and who in self.alive and (best is None or d < best[0]):
                best = (d, who)
        if best is not None:
            self.probe = (best[1], bridge.subscribe(self.keys.any_cell_pose(best[1]), "probe", stamped=True))
