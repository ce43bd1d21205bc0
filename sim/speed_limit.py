"""The proved limit belt speed of the ARIAC cell (issue 21.4): the fastest belt for which
the requirement ``reach`` (every detected belt part is reached within dt*) still holds,
found by bisection over the belt speed. ``btfsm sweep --limit-line`` prints it and draws
it beside the measured loss curve.

At belt speed v the pick window is dt*(v) = ``WINDOW_M`` / v (3.2 m of belt within the
arm's reach: 16 s at 0.2 m/s), and the arm's durations are derived from the ARIAC scene
with its belt at v (``btfsm.sim.durations.derive``: the belt pursuit depends on v).
``reach_at(variant, v)``: the worst first late response of ``reach`` in
``ariac.timed(variant(n_tray), timing, window=dt*(v))`` with the durations derived under
"no part lost yet" (``derive(..., no_loss=True)``; it decides ``reach`` when the arrivals'
30 s spacing exceeds dt*(v), docs/verification.md 2.1), else the worst case of the plain
derivation (property ``response``: the same verdict as ``btfsm check``), and whether it is
at most dt*(v). ``limit_speed`` bisects over a grid of speeds (multiples of
``step`` up to ``hi``), assuming that a belt slower than one that holds holds too (its
window is longer); it returns the fastest grid speed that holds whose next one fails, after
ceil(log2(n + 1)) checks for a grid of n speeds, whatever the predicate (with a predicate
that is not monotone, one such boundary; ``tests/test_scene_durations.py`` compares it with
a brute-force scan).

>>> limit_index(lambda i: i < 6, 10)
(5, {4: True, 7: False, 5: True, 6: False})
"""
from __future__ import annotations

import math
from typing import Callable, NamedTuple

__all__ = ["limit_index", "limit_speed", "reach_at", "Limit", "proved_limit", "FIRST_LATE"]


def limit_index(holds: Callable[[int], bool], n: int) -> tuple:
    """``(i, checked)``: the largest index in 0..n-1 with ``holds(i)`` and ``not holds(i +
    1)`` (-1: none holds, n - 1: all do), by bisection; ``checked``: {index: verdict} in the
    order they were checked."""
    lo, hi = -1, n  # holds(lo) (virtual), not holds(hi) (virtual)
    checked: dict = {}
    while hi - lo > 1:
        mid = (lo + hi) // 2
        checked[mid] = ok = bool(holds(mid))
        if ok:
            lo = mid
        else:
            hi = mid
    return lo, checked


def grid_speeds(hi: float, step: float) -> list:
    """The speeds ``step, 2 step, ...`` up to ``hi`` (m/s), rounded to 1e-6."""
    return [round(step * (i + 1), 6) for i in range(max(1, int(math.floor(hi / step + 1e-9))))]


class Limit(NamedTuple):
    """The result of a bisection: ``speed`` (m/s; None: not even the slowest grid speed
    holds), ``above`` (every grid speed up to ``hi`` holds: the limit is at least ``hi``),
    ``checks``: (speed, holds, figure s, window s[, what the figure is]) in the order checked."""

    variant: str
    speed: "float | None"
    above: bool
    step: float
    hi: float
    checks: tuple

    def describe(self) -> str:
        worst = {c[0]: c for c in self.checks}
        if self.speed is None:
            low = min(worst)
            return (f"below {self.step:g} m/s (at {low:g} m/s the "
                    f"{worst[low][4] if len(worst[low]) > 4 else 'worst case'} is {worst[low][2]:g} s > dt* "
                    f"{worst[low][3]:.4g} s)")
        w = worst.get(self.speed)
        text = f"{self.speed:g} m/s" + (f" ({w[4] if len(w) > 4 else 'worst case'} {w[2]:g} s <= dt* {w[3]:.4g} s)"
                                        if w else "")
        if self.above:
            return f"at least {text}: every speed up to {self.hi:g} m/s holds"
        nxt = worst.get(round(self.speed + self.step, 6))
        return text + (f"; at {nxt[0]:g} m/s {nxt[2]:g} s > {nxt[3]:.4g} s" if nxt else "")


def limit_speed(check: Callable[[float], tuple], hi: float, step: float, variant: str = "") -> Limit:
    """Bisection of ``check(speed) -> (holds, worst seconds, window seconds[, what the
    figure is])`` over the grid ``grid_speeds(hi, step)``."""
    speeds = grid_speeds(hi, step)
    seen: list = []

    def holds(i):
        ok, worst, window, *what = check(speeds[i])
        seen.append((speeds[i], bool(ok), worst, window, *what))
        return ok

    i, _ = limit_index(holds, len(speeds))
    return Limit(variant, None if i < 0 else speeds[i], i == len(speeds) - 1, step, hi, tuple(seen))


_TIMINGS: dict = {}  # (belt speed, no_loss) -> the derivation's data (the same for both variants: one arm FSM)
FIRST_LATE = "worst first late response (no part lost yet)"


def reach_at(variant: str, speed: float, n_tray: int = 2) -> tuple:
    """``(holds, seconds, dt* seconds, what the seconds are)`` of ``reach`` for ``variant``
    with the belt at ``speed`` m/s: durations derived from the ARIAC scene at that speed,
    dt* = WINDOW_M / v; the worst first late response under "no part lost yet" when the
    arrivals' spacing exceeds dt* (then it decides ``reach``), else the plain worst case."""
    from btfsm.errors import ModelError
    from btfsm.models import ariac
    from btfsm.timing import Response
    from btfsm.verify.explore import explore
    from btfsm.verify.properties.response import INF, ResponseBound

    from .durations import derive_ariac
    from .protocol import TrialSpec
    from .sweep import WINDOW_M
    from .trial import ariac_scene

    window = WINDOW_M / speed
    no_loss = window < ariac.ARRIVAL_MIN_INTERVAL
    if (speed, no_loss) not in _TIMINGS:
        scene = ariac_scene(TrialSpec("preemptive", 1, belt_speed=speed, pick_window=window))
        _TIMINGS[(speed, no_loss)] = derive_ariac(scene, no_loss=no_loss).to_data()
    model = ariac.timed({"preemptive": ariac.preemptive, "baseline": ariac.baseline}[variant](n_tray=n_tray),
                        timing=_TIMINGS[(speed, no_loss)], window=window)
    ts = explore(model)
    if not ts.complete:
        raise ModelError("limit", f"{model.name} at {speed:g} m/s: the exploration hit its budget")
    rb = ResponseBound(ts, next(r for r in model.responses if isinstance(r, Response) and r.name == "reach"))
    worst = rb.worst
    bound = rb.bound_ticks()
    if worst is None or bound is None:
        raise ModelError("limit", f"{model.name}: the trigger of 'reach' never occurs")
    what = "worst case"
    late = rb.first_late(bound) if no_loss else None
    if late is not None:
        worst, what = late[0], FIRST_LATE
    return worst <= bound, (math.inf if worst == INF else rb.seconds(worst)), window, what


def proved_limit(variant: str, hi: float, step: float = 0.005, n_tray: int = 2) -> Limit:
    """The proved limit belt speed of ``variant`` on the grid of ``step`` up to ``hi``."""
    return limit_speed(lambda v: reach_at(variant, v, n_tray), hi, step, variant)
