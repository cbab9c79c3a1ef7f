"""Duration histograms as the agents send them (0.5 ms bins, sparse): bin, merge, quantile.

An agent bins the age of the neighbour data it used and the one-way latency of the poses it heard
(:mod:`agents.counters`); its stats message carries the bins (:class:`zswarm.net.messages.Stats`,
at most ``MAX_HIST_BINS``); the world and the monitor merge them and read quantiles.
"""

from __future__ import annotations

from zswarm.net.messages import MAX_HIST_BINS

BIN_MS = 0.5


def to_bin(ms: float) -> int:
    """Histogram bin of a duration in milliseconds (0.5 ms bins, clamped to the last bin)."""
    return min(max(int(ms / BIN_MS), 0), MAX_HIST_BINS - 1)


def percentile(hist: dict[int, int], q: float) -> float | None:
    """The q-quantile (0..1) of a binned histogram, in milliseconds (bin centre); None if empty."""
    total = sum(hist.values())
    if total == 0:
        return None
    rank = q * (total - 1)
    seen = 0
    for b in sorted(hist):
        seen += hist[b]
        if seen > rank:
            return (b + 0.5) * BIN_MS
    return (max(hist) + 0.5) * BIN_MS


def merge(hists: list[dict[int, int]]) -> dict[int, int]:
    out: dict[int, int] = {}
    for h in hists:
        for b, c in h.items():
            out[b] = out.get(b, 0) + c
    return out
