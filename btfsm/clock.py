"""Explicit time for the runtime and trace replay: no wall-clock reads anywhere.

>>> c = Clock(10, 5); c.time
0.5
"""
from __future__ import annotations

__all__ = ["Clock"]


class Clock:
    """Explicit time: ``tick`` counts ticks, ``time`` is ``tick / rate`` seconds."""

    __slots__ = ("rate", "tick")

    def __init__(self, rate: float, tick: int = 0):
        self.rate, self.tick = float(rate), tick

    @property
    def time(self) -> float:
        return self.tick / self.rate
