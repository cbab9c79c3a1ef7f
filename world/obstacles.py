"""The world's obstacle service: each agent learns only the obstacles it can sense."""

from __future__ import annotations

import math

import numpy as np

from zswarm.net import messages as msg


class ObstacleService:
    """Answers ``obstacles?x=..;y=..;r=..`` with the obstacles whose boundary lies within r of (x, y).

    Runs on a Zenoh thread: it reads only the immutable arrays it was built with."""

    def __init__(self, centers: np.ndarray, radii: np.ndarray, reply_key: str) -> None:
        self.centers, self.radii, self.reply_key = centers, radii, reply_key

    def answer(self, params: dict[str, str]) -> list[tuple[str, bytes]]:
        try:
            x, y, r = float(params["x"]), float(params["y"]), float(params["r"])
        except (KeyError, ValueError):
            return []
        if not all(math.isfinite(v) for v in (x, y, r)) or r < 0:
            return []
        if len(self.centers):
            keep = np.linalg.norm(self.centers - np.array([x, y]), axis=1) - self.radii <= r
        else:
            keep = np.zeros(0, dtype=bool)
        payload = msg.encode(msg.Obstacles(tuple(map(tuple, self.centers[keep].tolist())),
                                           tuple(self.radii[keep].tolist())))
        return [(self.reply_key, payload)]
