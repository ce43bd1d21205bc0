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

Each class declares once what is true of its node type (docs/nodes.md, "How to add a node
type"): its fields with their types and defaults, each field's kind in a model file
(``file_field``: how ``btfsm.files`` reads and writes it, and its JSON Schema), its
child-count rule (``arity``), its names in BehaviorTree.CPP (``btcpp``, and ``library``
when a node library rather than BT.CPP itself has it) and py_trees (``pytrees``). The
file key of a node type is its class name (``NODE_TYPES``). The file tables, the schema,
the importers' and exporters' name maps and the child-count checks all read these.

>>> tree = ReactiveFallback("root", [Condition("done", "count >= 3"), Action("work")])
>>> [n.name for n in walk(tree)]
['root', 'done', 'work']
"""
from __future__ import annotations

from dataclasses import Field, dataclass, field, fields
from typing import Any, ClassVar, Iterator, Mapping, Optional, Sequence, cast

from .errors import ModelError
from .expr import Expr, ExprLike, as_expr
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
    "FILE_KINDS", "file_field", "file_fields", "arity_text", "arity_allows", "check_arity", "check_bounds", "register", "names_in", "btcpp_tags",
]

#: What a node field holds in a model file; ``btfsm.files`` reads, writes and describes
#: (JSON Schema) each kind in one place. ``opt_``: null allowed (the default).
FILE_KINDS = ("int", "opt_int", "bool", "opt_bool", "string", "names", "expr", "opt_expr", "effects",
              "outcomes", "args", "duration", "params")
#: When a field is written to a model file: ``changed`` (its value is not the default),
#: ``always``, or ``not_name`` (its value is not the node's name, which is the default)
WRITES = ("changed", "always", "not_name")


def file_field(kind: str, default: Any = None, *, required: bool = False, write: str = "changed",
               btcpp: Optional[str] = None, btcpp_none: Optional[int] = None, at_least: Optional[int] = None,
               what: Optional[str] = None, doc: Optional[str] = None, schema: "Optional[dict[str, Any]]" = None,
               after: Optional[str] = None) -> Any:
    """A node field (a dataclass field) with what is true of it in files and other engines.

    ``kind``: one of ``FILE_KINDS``; ``required``: a model file must give it; ``write``:
    one of ``WRITES``; ``btcpp``: its XML attribute (port) in BehaviorTree.CPP or the node
    library of the class; ``btcpp_none``: the BT.CPP value that stands for None;
    ``at_least``: the smallest value a model may give (checked when the model compiles);
    ``what``: what a string names, for messages; ``doc``: its description in the JSON
    Schema, ``schema``: more JSON Schema keywords for its value (``minLength``...);
    ``after``: files list it after that field instead of in the class's order (the
    constructor's positional order stays as it was)."""
    assert kind in FILE_KINDS and write in WRITES, (kind, write)
    meta = {"file": kind, "required": required, "write": write, "btcpp": btcpp, "btcpp_none": btcpp_none,
            "at_least": at_least, "what": what, "doc": doc, "schema": schema or {}, "after": after}
    return field(default=default, metadata=meta)


def file_fields(cls: "type[Node]") -> "tuple[Field[Any], ...]":
    """The fields of node type ``cls`` that a model file holds besides the name, the
    children and the child (in the order files write them)."""
    out = [f for f in fields(cls) if "file" in f.metadata]
    for f in [f for f in out if f.metadata["after"]]:
        out.remove(f)
        out.insert(next(i for i, g in enumerate(out) if g.name == f.metadata["after"]) + 1, f)
    return tuple(out)


def arity_text(cls: "type[Node]") -> str:
    """The child-count rule of ``cls`` in words: "2 or 3 children", "exactly 2 children".

    >>> arity_text(IfThenElse), arity_text(RecoveryNode), arity_text(Inverter)
    ('2 or 3 children', 'exactly 2 children', 'exactly one child')
    """
    lo, hi = cls.arity
    if (lo, hi) == (1, 1):
        return "exactly one child"
    if hi is None:
        return f"at least {lo} child{'' if lo == 1 else 'ren'}"
    if lo == hi:
        return f"exactly {lo} child{'' if lo == 1 else 'ren'}"
    return f"{lo} or {hi} children" if hi == lo + 1 else f"{lo} to {hi} children"


def arity_allows(cls: "type[Node]", count: int) -> bool:
    """Whether a node of type ``cls`` may have ``count`` children (its ``arity``)."""
    lo, hi = cls.arity
    return lo <= count and (hi is None or count <= hi)


def check_arity(node: "Node") -> None:
    """ModelError (``tree.NAME``) unless ``node`` has as many children as its type allows."""
    count = len(node.children_of())
    if not arity_allows(type(node), count):
        raise ModelError(f"tree.{node.name}", f"{type(node).__name__} needs {arity_text(type(node))}, got {count}")


def check_bounds(node: "Node") -> None:
    """ModelError (``tree.NAME.FIELD``) for a field below its ``at_least`` bound."""
    for f in file_fields(type(node)):
        low = f.metadata["at_least"]
        if low is not None and getattr(node, f.name) < low:
            raise ModelError(f"tree.{node.name}.{f.name}", f"must be at least {low}")


def btcpp_tags(library: Optional[str], kind: type) -> "dict[str, tuple[str, dict[str, tuple[str, Any]]]]":
    """BT.CPP tag -> (btfsm type key, {XML attribute: (btfsm field, default)}) for the node
    types of ``kind`` (``Composite`` or ``Decorator``) that BehaviorTree.CPP has
    (``library`` None) or a node library has (``"nav2"``): the importers' tables.
    ``default``: the value BT.CPP assumes when the attribute is absent.

    >>> btcpp_tags(None, Decorator)["RetryUntilSuccessful"]
    ('Retry', {'num_attempts': ('attempts', 1)})
    """
    out: "dict[str, tuple[str, dict[str, tuple[str, Any]]]]" = {}
    for key, cls in NODE_TYPES.items():
        if cls.btcpp and cls.library == library and issubclass(cls, kind):
            ports = {f.metadata["btcpp"]: (f.name, f.default if f.metadata["btcpp_none"] is None else f.metadata["btcpp_none"])
                     for f in file_fields(cls) if f.metadata["btcpp"]}
            out[cls.btcpp] = (key, ports)
    return out


def names_in(engine: str) -> "dict[str, str]":
    """btfsm node type -> its name in ``engine`` ("btcpp" or "pytrees"), for the types
    that have one.

    >>> names_in("btcpp")["Retry"], names_in("pytrees")["ForceSuccess"]
    ('RetryUntilSuccessful', 'FailureIsSuccess')
    """
    return {name: getattr(cls, engine) for name, cls in NODE_TYPES.items() if getattr(cls, engine)}


@dataclass(frozen=True)
class Node:
    """A tree node. Subclasses declare (class attributes): ``arity``, the (least, most)
    number of children (None: no upper bound); ``btcpp``, the BehaviorTree.CPP XML tag of
    the type when BT.CPP (or the node ``library``, such as ``nav2``) has a node with the
    same rules; ``pytrees``, the py_trees name."""

    name: str

    arity: ClassVar["tuple[int, Optional[int]]"] = (0, 0)
    btcpp: ClassVar[Optional[str]] = None
    library: ClassVar[Optional[str]] = None
    pytrees: ClassVar[Optional[str]] = None
    #: how ``btfsm show`` draws the type, when not by its name
    glyph: ClassVar[Optional[str]] = None

    def children_of(self) -> "tuple[Node, ...]":
        return ()


@dataclass(frozen=True)
class Composite(Node):
    children: Sequence[Node] = ()  # a tuple once built

    arity: ClassVar["tuple[int, Optional[int]]"] = (0, None)

    def __post_init__(self) -> None:
        object.__setattr__(self, "children", tuple(self.children))

    def children_of(self) -> "tuple[Node, ...]":
        return cast("tuple[Node, ...]", self.children)  # a tuple once built


class ReactiveSequence(Composite):
    """Ticks children from the first on every tick; fails or runs with the first child that does."""

    glyph = "->"
    btcpp = "ReactiveSequence"
    pytrees = "Sequence(memory=False)"


class MemorySequence(Composite):
    """Resumes at the child that was running; starts again from the first after a result."""

    glyph = "->*"
    btcpp = "Sequence"
    pytrees = "Sequence(memory=True)"


class ReactiveFallback(Composite):
    """Ticks children from the first on every tick; succeeds or runs with the first that does."""

    glyph = "?"
    btcpp = "ReactiveFallback"
    pytrees = "Selector(memory=False)"


class MemoryFallback(Composite):
    """Resumes at the child that was running; starts again from the first after a result."""

    glyph = "?*"
    btcpp = "Fallback"
    pytrees = "Selector(memory=True)"


class SequenceWithMemory(Composite):
    """BehaviorTree.CPP's ``SequenceWithMemory``: like ``MemorySequence``, but a FAILURE
    keeps the index (the failed child is ticked again next time) and halting keeps it too."""

    btcpp = "SequenceWithMemory"


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

    btcpp = "Parallel"
    pytrees = "Parallel"

    success_threshold: "int | None" = file_field("opt_int", None, btcpp="success_count", btcpp_none=-1)
    failure_threshold: int = file_field("int", 1, btcpp="failure_count")
    synchronise: bool = file_field("opt_bool", False, doc="a child that succeeded is not ticked again until the "
                                                          "parallel returns (py_trees synchronise)")
    selected: Sequence[str] = file_field("names", (), what="children",
                                             doc="SUCCESS once these children all succeeded (py_trees SuccessOnSelected)")

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "selected", tuple(self.selected))


@dataclass(frozen=True)
class ParallelAll(Composite):
    """BehaviorTree.CPP's ``ParallelAll``: ticks the children that have not finished until all
    have; then FAILURE if at least ``max_failures`` failed, else SUCCESS."""

    btcpp = "ParallelAll"

    max_failures: int = file_field("int", 1, btcpp="max_failures")


class IfThenElse(Composite):
    """Two or three children: the first is the condition; SUCCESS runs the second, FAILURE
    the third (or returns FAILURE with two children). The branch chosen is kept while it
    runs (the condition is not ticked again until the branch finishes)."""

    arity = (2, 3)
    btcpp = "IfThenElse"


class WhileDoElse(Composite):
    """Two or three children: the condition (the first) is ticked every tick; SUCCESS ticks
    the second (halting the third), FAILURE the third (halting the second) or returns
    FAILURE with two children."""

    arity = (2, 3)
    btcpp = "WhileDoElse"


class PipelineSequence(Composite):
    """Nav2's ``PipelineSequence``: ticks every child from the first on every tick; a child
    that returns RUNNING before the furthest child reached so far is left running and the
    next one is ticked (earlier stages keep running while later ones work). FAILURE halts
    every child; all SUCCESS halts every child and succeeds (docs/semantics.md 8.3)."""

    btcpp, library = "PipelineSequence", "nav2"


@dataclass(frozen=True)
class RecoveryNode(Composite):
    """Nav2's ``RecoveryNode`` (two children): the first child's FAILURE runs the second
    (the recovery); the recovery's SUCCESS ticks the first again, at most ``retries``
    times, all within one tick when nothing runs (docs/semantics.md 8.3)."""

    arity = (2, 2)
    btcpp, library = "RecoveryNode", "nav2"

    retries: int = file_field("int", 1, btcpp="number_of_retries", at_least=0)


@dataclass(frozen=True)
class RoundRobin(Composite):
    """Nav2's ``RoundRobin``: ticks one child at a time starting at the one after the child
    that last finished; SUCCESS on the first child that succeeds (the position is kept for
    the next run), FAILURE when every child failed in a row. Without ``wrap_around`` (Nav2's
    default) reaching the end of the children ends the run with FAILURE, even when the last
    child succeeded (docs/semantics.md 8.3)."""

    btcpp, library = "RoundRobin", "nav2"

    wrap_around: bool = file_field("bool", False, btcpp="wrap_around")


@dataclass(frozen=True)
class Decorator(Node):
    child: "Node | None" = None

    arity: ClassVar["tuple[int, Optional[int]]"] = (1, 1)

    def children_of(self) -> "tuple[Node, ...]":
        # a decorator built without a child holds None here: Model refuses it ("missing or not a node")
        return (cast(Node, self.child),)


class Inverter(Decorator):
    """SUCCESS <-> FAILURE; RUNNING unchanged."""

    glyph = "NOT"
    btcpp = "Inverter"
    pytrees = "Inverter"


class ForceSuccess(Decorator):
    """RUNNING unchanged, anything else SUCCESS."""

    btcpp = "ForceSuccess"
    pytrees = "FailureIsSuccess"


class ForceFailure(Decorator):
    """RUNNING unchanged, anything else FAILURE."""

    btcpp = "ForceFailure"
    pytrees = "SuccessIsFailure"


@dataclass(frozen=True)
class Retry(Decorator):
    """Up to ``attempts`` tries: a FAILURE with tries left returns RUNNING and the child
    starts again on the next tick."""

    btcpp = "RetryUntilSuccessful"
    pytrees = "Retry"

    attempts: int = file_field("int", 1, btcpp="num_attempts", at_least=1)


@dataclass(frozen=True)
class Repeat(Decorator):
    """Runs the child to SUCCESS ``times`` times (RUNNING in between); FAILURE stops it."""

    btcpp = "Repeat"
    pytrees = "Repeat"

    times: int = file_field("int", 1, btcpp="num_cycles", at_least=1)


class KeepRunningUntilFailure(Decorator):
    """Child SUCCESS -> RUNNING, FAILURE -> FAILURE, RUNNING -> RUNNING (py_trees'
    ``SuccessIsRunning`` and ``Repeat(num_success=-1)`` too)."""

    btcpp = "KeepRunningUntilFailure"
    pytrees = "SuccessIsRunning"


class FailureIsRunning(Decorator):
    """py_trees' ``FailureIsRunning``: child FAILURE -> RUNNING (the child starts afresh
    next tick), SUCCESS -> SUCCESS, RUNNING -> RUNNING."""

    pytrees = "FailureIsRunning"


class RunningIsFailure(Decorator):
    """py_trees' ``RunningIsFailure``: child RUNNING -> FAILURE (the running child is
    halted), SUCCESS -> SUCCESS, FAILURE -> FAILURE."""

    pytrees = "RunningIsFailure"


class RunningIsSuccess(Decorator):
    """py_trees' ``RunningIsSuccess``: child RUNNING -> SUCCESS (the running child is
    halted), SUCCESS -> SUCCESS, FAILURE -> FAILURE."""

    pytrees = "RunningIsSuccess"


@dataclass(frozen=True)
class RunOnce(Decorator):
    """Ticks the child until it finishes once; afterwards returns that status without
    ticking it (``then_skip=False``). ``then_skip=True`` (BehaviorTree.CPP's default) would
    return SKIPPED, which btfsm does not model: the model is refused when compiled."""

    btcpp = "RunOnce"

    then_skip: bool = file_field("bool", True, write="always", btcpp="then_skip")


@dataclass(frozen=True)
class Guard(Decorator):
    """Checks ``condition`` before every tick of the child; when false, halts the child
    and returns FAILURE (py_trees' EternalGuard)."""

    pytrees = "EternalGuard"

    condition: ExprLike = file_field("expr", None, required=True)  # an Expr once built

    def __post_init__(self) -> None:
        object.__setattr__(self, "condition", as_expr(self.condition))


@dataclass(frozen=True)
class Effects(Decorator):
    """Applies effects when the child starts, succeeds, fails or is halted
    (BehaviorTree.CPP's ``_onSuccess`` / ``_onFailure`` / ``_onHalted`` scripts)."""

    on_start: EffectsLike = file_field("effects", ())  # each a tuple of (var, Expr) once built
    on_success: EffectsLike = file_field("effects", ())
    on_failure: EffectsLike = file_field("effects", ())
    on_halt: EffectsLike = file_field("effects", ())

    def __post_init__(self) -> None:
        for f in ("on_start", "on_success", "on_failure", "on_halt"):
            object.__setattr__(self, f, effects_of(getattr(self, f)))


@dataclass(frozen=True)
class SubTree(Decorator):
    """BehaviorTree.CPP's ``<SubTree ID="tree_id">``: returns its child's status. Under
    ``semantics: btcpp`` it resets its child whenever the child finishes (BT.CPP 4's
    SubTreeNode), so a stateful leaf at the subtree's root keeps no old status
    (docs/semantics.md section 8.1). ``tree_id``: the ``<BehaviorTree>`` ID (default: the
    node's name); the export writes one ``<BehaviorTree>`` per ID."""

    tree_id: str = file_field("string", "", write="not_name", what="a BehaviorTree ID", schema={"minLength": 1},
                              doc="the BehaviorTree.CPP <BehaviorTree> ID (default: the node's name)")

    def __post_init__(self) -> None:
        if not self.tree_id:
            object.__setattr__(self, "tree_id", self.name)


@dataclass(frozen=True)
class Leaf(Node):
    pass


@dataclass(frozen=True)
class Condition(Leaf):
    """SUCCESS when the expression holds, else FAILURE. Never RUNNING."""

    expr: ExprLike = file_field("expr", None, required=True)  # an Expr once built

    def __post_init__(self) -> None:
        object.__setattr__(self, "expr", as_expr(self.expr))


@dataclass(frozen=True)
class Action(Leaf):
    """Runs a primitive. ``primitive`` names one declared in the model; ``outcomes`` declares
    it inline instead (under ``primitive`` or, when that is empty, the node's name).
    ``args`` are constants handed to the implementation."""

    primitive: str = file_field("string", "", write="not_name", what="a primitive name")
    outcomes: "Sequence[Any] | None" = file_field("outcomes", None, after="args")  # Outcomes once built
    args: "Mapping[str, Any] | Sequence[Any]" = file_field("args", ())  # (name, value) pairs once built
    #: (min, max) seconds at this node; default: the primitive's
    duration: "tuple[float, float | None] | None" = file_field("duration", None)

    def __post_init__(self) -> None:
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

    fsm: str = file_field("string", "", required=True, write="always", what="an FSM name",
                          schema={"pattern": "^[A-Za-z_][A-Za-z0-9_]*$"})
    goal: str = file_field("string", "", required=True, write="always", what="a goal name", schema={"minLength": 1})
    params: "Mapping[str, Any] | Sequence[Any]" = file_field("params", ())  # (name, Expr) pairs once built
    pre: "ExprLike | None" = file_field("opt_expr", None)  # an Expr once built
    post: "ExprLike | None" = file_field("opt_expr", None)

    def __post_init__(self) -> None:
        object.__setattr__(self, "params", tuple((str(k), as_expr(x)) for k, x in _pairs(self.params)))
        for f in ("pre", "post"):
            val = getattr(self, f)
            object.__setattr__(self, f, None if val is None else as_expr(val))


def _pairs(x: Any) -> "tuple[Any, ...]":
    if not x:
        return ()
    return tuple(sorted(x.items())) if hasattr(x, "items") else tuple(tuple(p) for p in x)


def walk(node: Node) -> Iterator[Node]:
    """Pre-order traversal of a (sub)tree."""
    stack: "list[Node]" = [node]
    while stack:
        n = stack.pop()
        yield n
        stack.extend(reversed(n.children_of()))


#: file key (the class name) -> node type, in the order files and messages list them
NODE_TYPES: "dict[str, type[Node]]" = {cls.__name__: cls for cls in (
    ReactiveSequence, MemorySequence, ReactiveFallback, MemoryFallback, Parallel,
    SequenceWithMemory, ParallelAll, IfThenElse, WhileDoElse, PipelineSequence, RecoveryNode, RoundRobin,
    Inverter, ForceSuccess, ForceFailure, Retry, Repeat, KeepRunningUntilFailure, RunOnce, Guard, Effects, SubTree,
    Condition, Action, SkillRequest, FailureIsRunning, RunningIsFailure, RunningIsSuccess)}


def register(cls: "type[Node]") -> "type[Node]":
    """Add a node type to ``NODE_TYPES`` (usable as a class decorator): model files then
    read and write it, and the schema describes it. Its tick rule is registered in
    ``btfsm.semantics`` (``rule``); docs/nodes.md walks through a whole new node type."""
    if not (isinstance(cls, type) and issubclass(cls, (Composite, Decorator, Leaf))):
        raise TypeError(f"{cls!r} is not a Composite, Decorator or Leaf node class")
    if NODE_TYPES.get(cls.__name__, cls) is not cls:
        raise ValueError(f"a node type named {cls.__name__} exists already")
    NODE_TYPES[cls.__name__] = cls
    return cls
