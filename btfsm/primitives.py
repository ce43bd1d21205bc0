"""Primitives: named robot operations with their declared outcomes and effects.

A primitive is what an Action leaf or an FSM state runs. The model declares every outcome
it may have (a status plus effects on world variables); the checker explores all of them,
and the runtime asks an implementation (bound by name) which one happened.

>>> p = Primitive("dock", (running(), success(battery=100)))
>>> [o.name for o in p.outcomes]
['running', 'success']
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Sequence, Union

from .expr import as_expr
from .status import Status
from .timing import duration_of

__all__ = ["Outcome", "Primitive", "success", "failure", "running", "effects_of", "PASS"]


#: what ``effects_of`` accepts: a mapping ``var -> expression`` or ``(var, expression)`` pairs
EffectsLike = Union[Mapping[str, Any], Sequence[Any]]


def effects_of(effects: EffectsLike) -> tuple:
    """Normalise effects given as a mapping or pairs into ``((var, Expr), ...)``."""
    if not effects:
        return ()
    items = effects.items() if hasattr(effects, "items") else effects
    return tuple((str(name), as_expr(value)) for name, value in items)


@dataclass(frozen=True)
class Outcome:
    """One declared result of a primitive: a status, its effects, and a name."""

    status: "Status | str"  # a Status once built
    effects: EffectsLike = ()  # a tuple of (var, Expr) once built
    name: str = ""

    def __post_init__(self):
        object.__setattr__(self, "status", Status.parse(self.status))
        object.__setattr__(self, "effects", effects_of(self.effects))
        if not self.name:
            object.__setattr__(self, "name", self.status.name.lower())


def success(name: str = "", **effects) -> Outcome:
    return Outcome(Status.SUCCESS, effects_of(effects), name)


def failure(name: str = "", **effects) -> Outcome:
    return Outcome(Status.FAILURE, effects_of(effects), name)


def running(name: str = "", **effects) -> Outcome:
    return Outcome(Status.RUNNING, effects_of(effects), name)


@dataclass(frozen=True)
class Primitive:
    """A named operation and the outcomes the model allows it; ``duration``: how long one
    run takes, ``(min, max)`` seconds (docs/semantics.md section 6.1), None: any time."""

    name: str
    outcomes: Sequence[Outcome] = (Outcome(Status.SUCCESS),)  # a tuple once built
    duration: "tuple | None" = None  # (min, max or None) seconds of one run (btfsm.timing)

    def __post_init__(self):
        object.__setattr__(self, "outcomes", tuple(self.outcomes))
        object.__setattr__(self, "duration", duration_of(self.duration, f"primitives.{self.name}.duration"))

    def statuses(self) -> frozenset:
        return frozenset(o.status for o in self.outcomes)


PASS = Primitive("pass")  # what a state without a primitive runs: one instant SUCCESS
