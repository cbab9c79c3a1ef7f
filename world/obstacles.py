"""The world's obstacle service: each agent learns only the obstacles it can sense."""

from __future__ import annotations

import math
import sys

import numpy as np

from zswarm.net import messages as msg


class ObstacleService:
    """Answers ``obstacles?x=..;y=..;r=..`` (``;z=..`` too in a 3-D run) with the obstacles whose
    boundary lies within r of the point.

    The answer carries the run's dimension. A query of the other dimension (a 2-D agent in a 3-D run,
    or the reverse) is answered at z = 0 (or with z left out), so the agent learns it is in the wrong
    run and refuses to join; the world says so once on stderr.

    Runs on a Zenoh thread: it reads only the immutable arrays it was built with (and sets one flag)."""

    def __init__(self, centers: np.ndarray, radii: np.ndarray, reply_key: str, dims: int = 2) -> None:
        self.centers, self.radii, self.reply_key, self.dims = centers.reshape(-1, dims), radii, reply_key, dims
        self.foreign_seen = False

    def answer(self, params: dict[str, str]) -> list[tuple[str, bytes]]:
        try:
            point = [float(params[a]) for a in "xyz"[:self.dims] if a in params or a != "z"]
            r = float(params["r"])
        except (KeyError, ValueError):
            return []
        if not all(math.isfinite(v) for v in (*point, r)) or r < 0:
            return []
        if ("z" in params) != (self.dims == 3):
            self._foreign()
            point = (point + [0.0])[:self.dims]
        if len(self.centers):
            keep = np.linalg.norm(self.centers - np.array(point), axis=1) - self.radii <= r
        else:
            keep = np.zeros(0, dtype=bool)
        payload = msg.encode(msg.Obstacles(tuple(map(tuple, self.centers[keep].tolist())),
                                           tuple(self.radii[keep].tolist()), self.dims))
        return [(self.reply_key, payload)]

    def _foreign(self) -> None:
        if not self.foreign_seen:
            self.foreign_seen = True
            other = 5 - self.dims
            print(f"world: a {other}-D agent asked this {self.dims}-D run for obstacles; it is told so and will "
                  "not join (start every process of a run with the same --scenario)", file=sys.stderr, flush=True)
