"""Printing measured figures: a figure a run did not produce prints as ``n/a``, never a traceback."""

from __future__ import annotations


def figure(value: float | None, spec: str = ".3g") -> str:
    """``format(value, spec)``, or ``n/a`` for a figure that was not measured (None)."""
    return "n/a" if value is None else format(value, spec)
