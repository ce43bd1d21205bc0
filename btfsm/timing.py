"""Time in a model: durations of primitives, spacing of environment events, and the
bounded-response requirements ``btfsm check --property response`` decides.

Seconds are the unit of every declaration; the model's ``tick_rate`` (Hz) turns them into
ticks (docs/semantics.md section 6.1):

* a **duration** ``(min, max)`` of a primitive use: the use answers a non-RUNNING outcome
  on its k-th tick of running only when ``lo <= k <= hi``, with ``lo = ceil(min * rate) + 1``
  and ``hi = ceil(max * rate) + 1`` (a use started by tick t whose work ends d seconds later
  is seen to end by the first tick at or after t/rate + d); ``max`` None: no upper bound.
* a **minimum interval** of an environment event: after it happens at tick t it is not
  enabled before tick ``t + ceil(min_interval * rate)``.

>>> duration_ticks((0.25, 1.0), 10.0)
(4, 11)
>>> duration_ticks((0, None), 10.0)
(1, None)
>>> interval_ticks(30.0, 10.0)
300
>>> Response("pick", "event:arrive", "held", 16).trigger_event
'arrive'
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from .errors import ModelError
from .expr import as_expr

__all__ = ["duration_of", "duration_ticks", "interval_ticks", "seconds_to_ticks", "Response", "responses_of"]

_EPS = 1e-9  # seconds that are a whole number of ticks stay that number (0.3 s * 10 Hz = 3, not 4)


def seconds_to_ticks(seconds: float, rate: float) -> int:
    """Whole ticks that cover ``seconds`` at ``rate`` Hz (rounded up)."""
    return max(0, math.ceil(seconds * rate - _EPS))


def duration_of(value, where: str) -> "tuple | None":
    """A duration as given in Python or a model file (``(min, max)``, ``[min, max]``,
    ``{"min": .., "max": ..}``, or one number for both) as ``(min, max or None)``, checked."""
    if value is None:
        return None
    if isinstance(value, dict):
        unknown = set(value) - {"min", "max"}
        if unknown:
            raise ModelError(where, f"unknown key(s) {sorted(unknown)} (expected min, max)")
        lo, hi = value.get("min", 0), value.get("max")
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        lo = hi = value
    elif isinstance(value, (list, tuple)) and len(value) == 2:
        lo, hi = value
    else:
        raise ModelError(where, "expected [min, max] seconds, {min: .., max: ..} or one number")
    for name, x in (("min", lo), ("max", hi)):
        if x is None and name == "max":
            continue
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not 0 <= x < math.inf:
            raise ModelError(where, f"{name} must be a finite number of seconds >= 0, got {x!r}")
    if hi is not None and hi < lo:
        raise ModelError(where, f"max ({hi:g} s) is below min ({lo:g} s)")
    return (float(lo), None if hi is None else float(hi))


def duration_ticks(duration, rate: float) -> tuple:
    """``(lo, hi)``: the ticks of running on which a use may end (1-based; hi None: no bound)."""
    lo, hi = duration
    return seconds_to_ticks(lo, rate) + 1, None if hi is None else seconds_to_ticks(hi, rate) + 1


def interval_ticks(seconds: float, rate: float) -> int:
    """Ticks an event waits after it happened before it is enabled again."""
    return seconds_to_ticks(seconds, rate)


@dataclass(frozen=True)
class Response:
    """Every time ``trigger`` occurs, ``response`` must hold within ``within`` seconds.

    ``trigger``: an expression (it occurs in every state where it holds) or ``event:NAME``
    (it occurs in the tick in which environment event NAME happens). ``response``: an
    expression. ``within``: seconds, or None to measure only (``btfsm bound``).
    ``trigger_text``, ``response_text``: the two as written (set when built); a model
    widens an expression that names a split state to its copies
    (``btfsm.positions.widen_to_copies``), and messages show what was written.

    >>> r = Response("r", "event:go", "arm.state == 'a'")
    >>> r.response_text, r.trigger_text
    ("arm.state == 'a'", 'event:go')
    """

    name: str
    trigger: Any  # an expression (text, then an Expr once built) or "event:<name>"
    response: Any  # an expression (an Expr once built)
    within: "float | None" = None
    trigger_text: str = field(default="", compare=False, repr=False)
    response_text: str = field(default="", compare=False, repr=False)

    def __post_init__(self):
        t = self.trigger
        if isinstance(t, str) and t.strip().startswith("event:"):
            object.__setattr__(self, "trigger", "event:" + t.strip()[len("event:"):].strip())
        else:
            object.__setattr__(self, "trigger", as_expr(t))
        object.__setattr__(self, "response", as_expr(self.response))
        if not self.response_text:
            object.__setattr__(self, "trigger_text", str(self.trigger))
            object.__setattr__(self, "response_text", str(self.response))
        w = self.within
        if w is not None and (isinstance(w, bool) or not isinstance(w, (int, float)) or not 0 <= w < math.inf):
            raise ModelError(f"responses.{self.name}.within", f"expected a finite number of seconds >= 0, got {w!r}")

    @property
    def trigger_event(self) -> "str | None":
        """The environment event name of an ``event:NAME`` trigger, else None."""
        t = self.trigger
        return t[len("event:"):] if isinstance(t, str) else None


def responses_of(x: Any) -> tuple:
    """Responses given as Response objects, or a mapping name -> {trigger, response, within}."""
    if not x:
        return ()
    if hasattr(x, "items"):
        out = []
        for name, spec in x.items():
            if isinstance(spec, Response):
                out.append(spec)
                continue
            if not isinstance(spec, dict):
                raise ModelError(f"responses.{name}", "expected a mapping with trigger, response and within")
            unknown = set(spec) - {"trigger", "response", "within"}
            if unknown:
                raise ModelError(f"responses.{name}", f"unknown key(s) {sorted(unknown)} (expected trigger, response, within)")
            for k in ("trigger", "response"):
                if k not in spec:
                    raise ModelError(f"responses.{name}", f"missing '{k}'")
            out.append(Response(str(name), spec["trigger"], spec["response"], spec.get("within")))
        return tuple(out)
    given = tuple(x)
    for r in given:
        if not isinstance(r, Response):
            raise ModelError("responses", f"not a Response: {r!r}")
    return given
