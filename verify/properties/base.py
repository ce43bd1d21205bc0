"""What every property module shares: the ``Result`` of a property, the ``Context`` that
explores the model and each FSM once, and vectorised expression evaluation over states.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from ..explore import DEFAULT_MAX_STATES, Budget, explore, explore_fsm

if TYPE_CHECKING:
    from btfsm.expr import Expr
    from btfsm.model import Model

    from ..search import Progress
    from ..system import TransitionSystem

__all__ = ["Result", "Context", "evaluate", "columns_of", "budget_hit"]


@dataclass
class Result:
    """The verdict of one property."""

    name: str
    holds: "bool | None"
    counterexample: Any = None  # a btfsm.verify.counterexample.Counterexample, or None
    notes: list[str] = field(default_factory=list)
    info: dict[str, Any] = field(default_factory=dict)
    seconds: float = 0.0
    not_applicable: "str | None" = None  # why the model gives this property nothing to check

    @property
    def verdict(self) -> str:
        """``holds``, ``violated``, ``undecided`` or ``not-applicable``."""
        if self.not_applicable is not None:
            return "not-applicable"
        return {True: "holds", False: "violated", None: "undecided"}[self.holds]

    def to_json(self) -> dict[str, Any]:
        out = {"name": self.name, "holds": self.holds, "verdict": self.verdict,
               "counterexample": self.counterexample.to_json() if self.counterexample is not None else None,
               "notes": list(self.notes), "info": self.info, "seconds": round(self.seconds, 6)}
        if self.not_applicable is not None:
            out["why"] = self.not_applicable
        return out


class Context:
    """The model under check and its explorations (each done once, on demand)."""

    def __init__(self, model: Model, *, max_states: "int | None" = DEFAULT_MAX_STATES,
                 progress: "Callable[[str, int, int, float], Any] | None" = None, engine: str = "auto",
                 max_transitions: "int | None" = None, max_seconds: "float | None" = None,
                 goal_level: str = "open") -> None:
        self.model = model
        self.goal_level = goal_level  # goal-reachability: "open" (each FSM alone) or "tree"
        self.max_states = max_states
        self.max_transitions = max_transitions
        self.clock = Budget(max_seconds=max_seconds)  # one time budget for every exploration of the check
        self.engine = engine
        self.progress = progress
        self._model_ts: "TransitionSystem | None" = None
        self._fsm_ts: dict[str, TransitionSystem] = {}
        self.systems: "list[TransitionSystem | SystemSummary]" = []
        # set by ``btfsm.verify.report.check``: no property still to run reads the model-level
        # system, so ``done_with_model`` may let it go (the check's peak memory is then one
        # system, not two); a Context used directly keeps every system
        self.model_needed = True
        self._model_summary: "tuple[int, bool] | None" = None  # (n_transitions, complete) of a released model system

    def model_ts(self) -> TransitionSystem:
        """The whole model's transition system."""
        if self._model_ts is None:
            if self._model_summary is not None:
                raise RuntimeError("the model-level system was released; a later property needs it (schedule bug)")
            self._model_ts = explore(self.model, max_states=self.max_states, max_transitions=self.max_transitions,
                                     max_seconds=self._seconds_left(), progress=self._progress("model"),
                                     engine=self.engine)
            self.systems.append(self._model_ts)
        return self._model_ts

    def model_size(self) -> "tuple[int, bool]":
        """``(transitions, complete)`` of the model-level system (explored if needed), also
        after it was released."""
        if self._model_summary is not None:
            return self._model_summary
        ts = self.model_ts()
        return ts.n_transitions, ts.complete

    def done_with_model(self) -> None:
        """Let the model-level system go when no property still to run reads it (its
        figures stay in ``systems``, as a ``SystemSummary``)."""
        if self.model_needed or self._model_ts is None:
            return
        ts = self._model_ts
        self._model_summary = (ts.n_transitions, ts.complete)
        self.systems[self.systems.index(ts)] = SystemSummary.of(ts)
        self._model_ts = None

    def fsm_ts(self, name: str) -> TransitionSystem:
        """FSM ``name`` as an open system."""
        ts = self._fsm_ts.get(name)
        if ts is None:
            ts = self._fsm_ts[name] = explore_fsm(self.model, name, max_states=self.max_states,
                                                  max_transitions=self.max_transitions,
                                                  max_seconds=self._seconds_left(),
                                                  progress=self._progress(f"fsm {name}"), engine=self.engine)
            self.systems.append(ts)
        return ts

    def _seconds_left(self) -> "float | None":
        c = self.clock
        return None if c.max_seconds is None else max(c.max_seconds - c.elapsed(), 0.0)

    def _progress(self, what: str) -> "Progress | None":
        progress = self.progress
        if progress is None:
            return None
        return lambda states, transitions, seconds: progress(what, states, transitions, seconds)


@dataclass(frozen=True)
class SystemSummary:
    """What the report says of a system that was let go (``Context.done_with_model``)."""

    kind: str
    fsm: "str | None"
    n_states: int
    n_transitions: int
    complete: bool
    seconds: float
    stopped: "str | None"

    @classmethod
    def of(cls, ts: TransitionSystem) -> "SystemSummary":
        return cls(ts.kind, ts.fsm, ts.n_states, ts.n_transitions, ts.complete, ts.seconds, ts.stopped)


def evaluate(ts: TransitionSystem, expr: Expr) -> np.ndarray:
    """A boolean array: ``expr`` (a checked model expression) in every state of ``ts``,
    vectorised with numpy over int64 columns (only the columns it reads are built)."""
    from btfsm.expr import BOOL, compile_fn, to_numpy_source

    prog = ts.model.program
    if _constant_not(expr):  # numpy evaluates ``~True`` to -2: use the compiled predicate
        fn = compile_fn(expr, prog.scope, "predicate", BOOL)
        return np.fromiter((bool(fn(list(ts.full_state(i)))) for i in range(ts.n_states)), bool, ts.n_states)
    code = compile(to_numpy_source(expr, prog.scope), "<expression>", "eval")
    n = ts.n_states
    out = np.empty(n, bool)
    for a in range(0, max(n, 1), _SLICE):  # int64 columns a slice at a time: memory bounded at any size
        b = min(a + _SLICE, n)
        val = eval(code, {"__builtins__": {}, "np": np, "c": columns_of(ts, a, b)})  # noqa: S307 - generated from a checked AST
        arr = np.asarray(val)
        if arr.dtype != bool:
            arr = arr != 0
        out[a:b] = np.broadcast_to(arr, (b - a,))
    return out


_SLICE = 1 << 21  # states per slice of ``evaluate``


def _constant_not(expr: Expr) -> bool:
    """Does ``expr`` negate a sub-expression that reads no variable (a Python bool in numpy)?"""
    from btfsm.expr import BinOp, BoolOp, Call, Compare, IfElse, Unary, names_in

    if isinstance(expr, Unary):
        return (expr.op == "not" and not names_in(expr.arg)) or _constant_not(expr.arg)
    if isinstance(expr, (BoolOp, Call)):
        return any(_constant_not(a) for a in expr.args)
    if isinstance(expr, (Compare, BinOp)):
        return _constant_not(expr.left) or _constant_not(expr.right)
    if isinstance(expr, IfElse):
        return any(_constant_not(a) for a in (expr.cond, expr.then, expr.other))
    return False


class columns_of:
    """Lazy int64 state columns of a transition system, indexed by program slot (of the
    states ``a:b``, all by default)."""

    def __init__(self, ts: TransitionSystem, a: int = 0, b: "int | None" = None) -> None:
        self.ts, self.a, self.b = ts, a, b
        self.cache: dict[int, np.ndarray] = {}

    def __getitem__(self, slot: int) -> np.ndarray:
        col = self.cache.get(slot)
        if col is None:
            col = self.cache[slot] = self.ts.column(slot)[self.a:self.b].astype(np.int64)
        return col


def budget_hit(ts: TransitionSystem) -> str:
    """``"time budget hit"`` (or state, transition, ...) for an incomplete system."""
    from ..search import HIT_WORDS

    return f"{HIT_WORDS.get(getattr(ts, 'stopped', None) or '', 'state')} budget hit"
