"""The transport latency, timed on one neighbour's poses heard through a subscription stamped on arrival.

Poses reach an agent through ring channels, which carry no arrival time. One neighbour's poses, the
nearest one heard within the subscription radius and holding a liveliness token, are heard a second
time through a stamped subscription: one publish -> router -> subscriber trip, the path every
neighbour's pose takes. Its poses reach the agent's session for the cells anyway, so the router sends
nothing more. Not the agent's own pose: Zenoh hands a publication to a subscriber of the same session
directly, without the router, so an echo would time the session, not the transport.
"""

from __future__ import annotations

from agents.counters import Counters
from zswarm.net import messages as msg
from zswarm.net.bridge import Bridge
from zswarm.net.keys import Keys
from zswarm.net.poses import PoseTable


class LatencyProbe:
    def __init__(self, keys: Keys, body, reach: float, neighbours: PoseTable, alive: set[int],
                 counters: Counters) -> None:
        self.keys, self.body, self.reach = keys, body, reach
        self.neighbours, self.alive, self.counters = neighbours, alive, counters
        self.probe: tuple[int, object] | None = None  # the neighbour probed, and its subscription

    def heard(self, payload: bytes, received: float) -> None:
        """A pose of the probed neighbour with its arrival time. The same bytes reach the agent through
        its cells too, where they are taken in, and rejected and counted if bad."""
        try:
            m = msg.decode(payload)
        except msg.DecodeError:
            return
        if isinstance(m, msg.Pose):
            self.counters.add(self.counters.latency, (received - m.stamp) * 1000.0)

    def follow(self, bridge: Bridge) -> None:
        """Keep probing the nearest neighbour for as long as it stays within reach and alive."""
        if self.probe is not None:
            who, sub = self.probe
            nb = self.neighbours.get(who)
            if who in self.alive and nb is not None and self.body.distance(nb.latest) <= self.reach:
                return
            bridge.unsubscribe(sub)
            self.probe = None
        best: tuple[float, int] | None = None
        for who, nb in self.neighbours.entries.items():
            d = self.body.distance(nb.latest)
            if d <= self.reach and who in self.alive and (best is None or d < best[0]):
                best = (d, who)
        if best is not None:
            self.probe = (best[1], bridge.subscribe(self.keys.any_cell_pose(best[1]), "probe", stamped=True))
