"""Behavior-tree node types: immutable, named, and checked when the model is built.

Composites: ``ReactiveSequence``, ``MemorySequence``, ``SequenceWithMemory``,
``ReactiveFallback``, ``MemoryFallback``, ``Parallel``, ``ParallelAll``, ``IfThenElse`` and
``WhileDoElse``. Decorators: ``Inverter``, ``ForceSuccess``, ``ForceFailure``, ``Retry``,
``Repeat``, ``KeepRunningUntilFailure``, ``RunOnce``, ``Guard``, ``Effects``, ``SubTree``
(BehaviorTree.CPP's SubTree node: the tree of another ``<BehaviorTree>``) and py_trees'
``FailureIsRunning``, ``RunningIsFailure``, ``RunningIsSuccess``. Leaves: ``Condition``,
``Action`` and ``SkillRequest``. Their tick rules are in docs/semantics.md and in exactly
one implementation, ``btfsm.semantics``.

Name mapping to other libraries (the rules differ in places: docs/semantics.md sections 2
and 8 state every difference; ``Model.semantics`` selects an engine's rules):

================== =============================== ==========================
btfsm              py_trees 2.x                    BehaviorTree.CPP 4.x
================== =============================== ==========================
ReactiveSequence   ``Sequence(memory=False)``      ``ReactiveSequence``
MemorySequence     ``Sequence(memory=True)``       ``Sequence``
ReactiveFallback   ``Selector(memory=False)``      ``ReactiveFallback``
MemoryFallback     ``Selector(memory=True)``       ``Fallback``
Parallel           ``Parallel`` (policies: below)  ``Parallel``
SequenceWithMemory                                 ``SequenceWithMemory``
ParallelAll                                        ``ParallelAll``
IfThenElse                                         ``IfThenElse``
WhileDoElse                                        ``WhileDoElse``
SubTree                                            ``SubTree``
================== =============================== ==========================

The reactive rows and py_trees' ``SuccessOnOne``/``SuccessOnSelected`` hold exactly under
``semantics="pytrees"`` (docs/semantics.md section 8.2; ``btfsm.interop.pytrees`` converts
both ways): ``Parallel(synchronise=s)`` is ``SuccessOnAll(synchronise=s)``,
``success_threshold=1`` is ``SuccessOnOne()``, ``selected=names`` is ``SuccessOnSelected``.

>>> tree = ReactiveFallback("root", [Condition("done", "count >= 3"), Action("work")])
>>> [n.name for n in walk(tree)]
['root', 'done', 'work']
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Iterator, Mapping, Sequence, cast

from .expr import ExprLike, as_expr
from .primitives import EffectsLike, Outcome, effects_of
from .timing import duration_of

__all__ = [
    "Node", "Composite", "Decorator", "Leaf",
    "ReactiveSequence", "MemorySequence", "ReactiveFallback", "MemoryFallback", "Parallel",
    "SequenceWithMemory", "ParallelAll", "IfThenElse", "WhileDoElse",
    "Inverter", "ForceSuccess", "ForceFailure", "Retry", "Repeat", "Guard", "Effects",
    "KeepRunningUntilFailure", "RunOnce", "SubTree", "FailureIsRunning", "RunningIsFailure", "RunningIsSuccess",
    "PipelineSequence", "RecoveryNode", "RoundRobin",
    "Condition", "Action", "SkillRequest", "walk", "NODE_TYPES",
]


@dataclass(frozen=True)
class Node:
    name: str

    def children_of(self) -> tuple:
        return ()


@dataclass(frozen=True)
class Composite(Node):
    children: Sequence[Node] = ()  # a tuple once built

    def __post_init__(self):
        object.__setattr__(self, "children", tuple(self.children))

    def children_of(self) -> tuple:
        return cast("tuple[Node, ...]", self.children)  # a tuple once built


class ReactiveSequence(Composite):
    """Ticks children from the first on every tick; fails or runs with the first child that does."""


class MemorySequence(Composite):
    """Resumes at the child that was running; starts again from the first after a result."""


class ReactiveFallback(Composite):
    """Ticks children from the first on every tick; succeeds or runs with the first that does."""


class MemoryFallback(Composite):
    """Resumes at the child that was running; starts again from the first after a result."""


class SequenceWithMemory(Composite):
    """BehaviorTree.CPP's ``SequenceWithMemory``: like ``MemorySequence``, but a FAILURE
    keeps the index (the failed child is ticked again next time) and halting keeps it too."""


@dataclass(frozen=True)
class Parallel(Composite):
    """Ticks every child each tick; SUCCESS at ``success_threshold`` successes (default: all),
    FAILURE at ``failure_threshold`` failures or when success became impossible.
    A negative threshold counts from the end, as in BehaviorTree.CPP (-1: all children).

    ``synchronise``: a child that succeeded is not ticked again (it counts as a success)
    until the parallel returns or is halted (py_trees' ``synchronise=True``).
    ``selected``: names of children: SUCCESS once every one of them succeeded, instead of
    a threshold (py_trees' ``SuccessOnSelected``); a selected child's failure makes
    success impossible."""

    success_threshold: "int | None" = None
    failure_threshold: int = 1
    synchronise: bool = False
    selected: Sequence[str] = ()

    def __post_init__(self):
        super().__post_init__()
        object.__setattr__(self, "selected", tuple(self.selected))


@dataclass(frozen=True)
class ParallelAll(Composite):
    """BehaviorTree.CPP's ``ParallelAll``: ticks the children that have not finished until all
    have; then FAILURE if at least ``max_failures`` failed, else SUCCESS."""

    max_failures: int = 1


class IfThenElse(Composite):
    """Two or three children: the first is the condition; SUCCESS runs the second, FAILURE
    the third (or returns FAILURE with two children). The branch chosen is kept while it
    runs (the condition is not ticked again until the branch finishes)."""


class WhileDoElse(Composite):
    """Two or three children: the condition (the first) is ticked every tick; SUCCESS ticks
    the second (halting the third), FAILURE the third (halting the second) or returns
    FAILURE with two children."""


class PipelineSequence(Composite):
    """Nav2's ``PipelineSequence``: ticks every child from the first on every tick; a child
    that returns RUNNING before the furthest child reached so far is left running and the
    next one is ticked (earlier stages keep running while later ones work). FAILURE halts
    every child; all SUCCESS halts every child and succeeds (docs/semantics.md 8.3)."""


@dataclass(frozen=True)
class RecoveryNode(Composite):
    """Nav2's ``RecoveryNode`` (two children): the first child's FAILURE runs the second
    (the recovery); the recovery's SUCCESS ticks the first again, at most ``retries``
    times, all within one tick when nothing runs (docs/semantics.md 8.3)."""

    retries: int = 1


@dataclass(frozen=True)
class RoundRobin(Composite):
    """Nav2's ``RoundRobin``: ticks one child at a time starting at the one after the child
    that last finished; SUCCESS on the first child that succeeds (the position is kept for
    the next run), FAILURE when every child failed in a row. Without ``wrap_around`` (Nav2's
    default) reaching the end of the children ends the run with FAILURE, even when the last
    child succeeded (docs/semantics.md 8.3)."""

    wrap_around: bool = False


@dataclass(frozen=True)
class Decorator(Node):
    child: "Node | None" = None

    def children_of(self) -> tuple:
        return (self.child,)


class Inverter(Decorator):
    """SUCCESS <-> FAILURE; RUNNING unchanged."""


class ForceSuccess(Decorator):
    """RUNNING unchanged, anything else SUCCESS."""


class ForceFailure(Decorator):
    """RUNNING unchanged, anything else FAILURE."""


@dataclass(frozen=True)
class Retry(Decorator):
    """Up to ``attempts`` tries: a FAILURE with tries left returns RUNNING and the child
    starts again on the next tick."""

    attempts: int = 1


@dataclass(frozen=True)
class Repeat(Decorator):
    """Runs the child to SUCCESS ``times`` times (RUNNING in between); FAILURE stops it."""

    times: int = 1


class KeepRunningUntilFailure(Decorator):
    """Child SUCCESS -> RUNNING, FAILURE -> FAILURE, RUNNING -> RUNNING (py_trees'
    ``SuccessIsRunning`` and ``Repeat(num_success=-1)`` too)."""


class FailureIsRunning(Decorator):
    """py_trees' ``FailureIsRunning``: child FAILURE -> RUNNING (the child starts afresh
    next tick), SUCCESS -> SUCCESS, RUNNING -> RUNNING."""


class RunningIsFailure(Decorator):
    """py_trees' ``RunningIsFailure``: child RUNNING -> FAILURE (the running child is
    halted), SUCCESS -> SUCCESS, FAILURE -> FAILURE."""


class RunningIsSuccess(Decorator):
    """py_trees' ``RunningIsSuccess``: child RUNNING -> SUCCESS (the running child is
    halted), SUCCESS -> SUCCESS, FAILURE -> FAILURE."""


@dataclass(frozen=True)
class RunOnce(Decorator):
    """Ticks the child until it finishes once; afterwards returns that status without
    ticking it (``then_skip=False``). ``then_skip=True`` (BehaviorTree.CPP's default) would
    return SKIPPED, which btfsm does not model: the model is refused when compiled."""

    then_skip: bool = True


@dataclass(frozen=True)
class Guard(Decorator):
    """Checks ``condition`` before every tick of the child; when false, halts the child
    and returns FAILURE (py_trees' EternalGuard)."""

    condition: ExprLike = None  # type: ignore[assignment]  # an Expr once built

    def __post_init__(self):
        object.__setattr__(self, "condition", as_expr(self.condition))


@dataclass(frozen=True)
class Effects(Decorator):
    """Applies effects when the child starts, succeeds, fails or is halted
    (BehaviorTree.CPP's ``_onSuccess`` / ``_onFailure`` / ``_onHalted`` scripts)."""

    on_start: EffectsLike = ()  # each a tuple of (var, Expr) once built
    on_success: EffectsLike = ()
    on_failure: EffectsLike = ()
    on_halt: EffectsLike = ()

    def __post_init__(self):
        for f in ("on_start", "on_success", "on_failure", "on_halt"):
            object.__setattr__(self, f, effects_of(getattr(self, f)))


@dataclass(frozen=True)
class SubTree(Decorator):
    """BehaviorTree.CPP's ``<SubTree ID="tree_id">``: returns its child's status. Under
    ``semantics: btcpp`` it resets its child whenever the child finishes (BT.CPP 4's
    SubTreeNode), so a stateful leaf at the subtree's root keeps no old status
    (docs/semantics.md section 8.1). ``tree_id``: the ``<BehaviorTree>`` ID (default: the
    node's name); the export writes one ``<BehaviorTree>`` per ID."""

    tree_id: str = ""

    def __post_init__(self):
        if not self.tree_id:
            object.__setattr__(self, "tree_id", self.name)


@dataclass(frozen=True)
class Leaf(Node):
    pass


@dataclass(frozen=True)
class Condition(Leaf):
    """SUCCESS when the expression holds, else FAILURE. Never RUNNING."""

    expr: ExprLike = None  # type: ignore[assignment]  # an Expr once built

    def __post_init__(self):
        object.__setattr__(self, "expr", as_expr(self.expr))


@dataclass(frozen=True)
class Action(Leaf):
    """Runs a primitive. ``primitive`` names one declared in the model; ``outcomes`` declares
    it inline instead (under ``primitive`` or, when that is empty, the node's name).
    ``args`` are constants handed to the implementation."""

    primitive: str = ""
    outcomes: "Sequence[Any] | None" = None
    args: "Mapping[str, Any] | Sequence[Any]" = ()
    duration: "tuple | None" = None  # (min, max) seconds at this node; default: the primitive's

    def __post_init__(self):
        object.__setattr__(self, "duration", duration_of(self.duration, f"tree.{self.name}.duration"))
        if not self.primitive:
            object.__setattr__(self, "primitive", self.name)
        if self.outcomes is not None:
            object.__setattr__(self, "outcomes", tuple(o if isinstance(o, Outcome) else Outcome(**o) for o in self.outcomes))
        object.__setattr__(self, "args", _pairs(self.args))


@dataclass(frozen=True)
class SkillRequest(Leaf):
    """The paper's execution node: ticks FSM ``fsm`` toward ``goal`` with ``params``.

    ``pre``: when false the request returns FAILURE without ticking the FSM.
    ``post``: a contract that must hold whenever the skill reports SUCCESS (the runtime
    records a violation event; ``btfsm check`` proves it or shows a counterexample).
    Halting the request withdraws its goal from the FSM.
    """

    fsm: str = ""
    goal: str = ""
    params: "Mapping[str, Any] | Sequence[Any]" = ()
    pre: "ExprLike | None" = None  # an Expr once built
    post: "ExprLike | None" = None

    def __post_init__(self):
        object.__setattr__(self, "params", tuple((str(k), as_expr(x)) for k, x in _pairs(self.params)))
        for f in ("pre", "post"):
            val = getattr(self, f)
            object.__setattr__(self, f, None if val is None else as_expr(val))


def _pairs(x) -> tuple:
    if not x:
        return ()
    return tuple(sorted(x.items())) if hasattr(x, "items") else tuple(tuple(p) for p in x)


def walk(node: Node) -> Iterator[Node]:
    """Pre-order traversal of a (sub)tree."""
    stack = [node]
    while stack:
        n = stack.pop()
        yield n
        stack.extend(reversed(n.children_of()))


NODE_TYPES = {cls.__name__: cls for cls in (
    ReactiveSequence, MemorySequence, ReactiveFallback, MemoryFallback, Parallel,
    SequenceWithMemory, ParallelAll, IfThenElse, WhileDoElse, PipelineSequence, RecoveryNode, RoundRobin,
    Inverter, ForceSuccess, ForceFailure, Retry, Repeat, KeepRunningUntilFailure, RunOnce, Guard, Effects, SubTree,
    Condition, Action, SkillRequest, FailureIsRunning, RunningIsFailure, RunningIsSuccess)}
