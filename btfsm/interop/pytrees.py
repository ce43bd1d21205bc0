"""py_trees 2.x in and out: a live py_trees tree as a btfsm model, a btfsm model as a
py_trees tree.

``from_pytrees(root, leaves=...)`` reads a tree of py_trees behaviours and returns a
``Model`` with ``semantics="pytrees"`` (docs/semantics.md section 8.2: the tick rules
of py_trees 2.6, proven against the real library in tests/test_peer_pytrees.py).
``to_pytrees(model, ...)`` builds the py_trees tree that behaves like ``model`` under
that profile; its leaves are made by a factory (default: ``AnswerBehaviour``, a stub that
asks a callable for each tick's status).

Node mapping (both directions):

=============================================== =========================================
py_trees 2.6                                    btfsm
=============================================== =========================================
``Sequence(memory=False)``                      ``ReactiveSequence``
``Sequence(memory=True)``                       ``MemorySequence``
``Selector(memory=False)``                      ``ReactiveFallback``
``Selector(memory=True)``                       ``MemoryFallback``
``Parallel(SuccessOnAll(synchronise=s))``       ``Parallel(synchronise=s)``
``Parallel(SuccessOnOne())``                    ``Parallel(success_threshold=1)``
``Parallel(SuccessOnSelected(cs, synchronise))`` ``Parallel(selected=names of cs, ...)``
``Inverter``                                    ``Inverter``
``FailureIsSuccess``                            ``ForceSuccess``
``SuccessIsFailure``                            ``ForceFailure``
``Retry(num_failures=k)``                       ``Retry(attempts=k)``
``Repeat(num_success=k)``, k >= 1               ``Repeat(times=k)``
``EternalGuard``                                ``Guard``
``PassThrough``, ``Count`` (read only)           the child itself (they change no status)
=============================================== =========================================

Everything else (``Timeout``: wall-clock time; ``OneShot``; ``RunningIsFailure`` and the
other status remaps; ``Repeat(-1)``) is refused with a ``ModelError`` naming the node.

>>> import py_trees
>>> root = py_trees.composites.Selector("root", memory=False, children=[
...     py_trees.behaviours.Failure(name="check"), py_trees.behaviours.Running(name="work")])
>>> model = from_pytrees(root)
>>> type(model.tree).__name__, [type(k).__name__ for k in model.tree.children]
('ReactiveFallback', ['Action', 'Action'])
>>> back = to_pytrees(model, answer=lambda name: "running")
>>> back.tick_once(); back.status.name
'RUNNING'
"""
from __future__ import annotations

import json
import os
import re
import warnings
from typing import Callable

try:
    import py_trees
except ImportError as exc:  # pragma: no cover - exercised only without py_trees
    raise ImportError("btfsm.interop.pytrees needs py_trees 2.x: pip install 'py_trees>=2.2' "
                      "(or the btfsm 'test' / 'bench' extras)") from exc

from ..bt import (Action, Condition, Effects, ForceFailure, ForceSuccess, Guard, Inverter,
                  MemoryFallback, MemorySequence, Node, Parallel, ReactiveFallback,
                  ReactiveSequence, Repeat, Retry, SkillRequest)
from ..errors import ModelError
from ..model import EnvChoice, EnvEvent, Model
from ..primitives import Outcome, Primitive
from ..status import Status
from ..world import Bool

__all__ = ["from_pytrees", "to_pytrees", "AnswerBehaviour", "PytreesImportWarning", "RunRecorder", "RUN_FORMAT"]

Common = py_trees.common
_TO_PT = {Status.RUNNING: Common.Status.RUNNING, Status.SUCCESS: Common.Status.SUCCESS,
          Status.FAILURE: Common.Status.FAILURE}
_FROM_PT = {v: k for k, v in _TO_PT.items()}


class PytreesImportWarning(UserWarning):
    """A py_trees leaf was modelled by an over-approximation (any status it may return)."""


# ====================================================================== btfsm -> py_trees

class AnswerBehaviour(py_trees.behaviour.Behaviour):
    """A py_trees leaf whose ``update`` returns ``answer(name)`` (a ``Status``, a status
    name or a py_trees status). When ``log`` is a list, the lifecycle is appended to it:
    ``("start", name)`` from ``initialise``, ``("tick", name, "SUCCESS")`` from ``update``,
    ``("halt", name)`` when the behaviour is stopped (``stop(INVALID)``) while RUNNING:
    the three leaf callbacks btfsm's step function reports (start, run, halt)."""

    def __init__(self, name: str, answer: Callable, log: "list | None" = None):
        super().__init__(name)
        self.answer, self.log = answer, log

    def initialise(self) -> None:
        if self.log is not None:
            self.log.append(("start", self.name))

    def update(self):
        st = _pt_status(self.answer(self.name), self.name)
        if self.log is not None:
            self.log.append(("tick", self.name, _FROM_PT[st].name))
        return st

    def terminate(self, new_status) -> None:
        if self.log is not None and new_status == Common.Status.INVALID and self.status == Common.Status.RUNNING:
            self.log.append(("halt", self.name))


def _pt_status(x, name):
    if isinstance(x, Common.Status):
        if x == Common.Status.INVALID:
            raise ValueError(f"{name}: a leaf's answer must be RUNNING, SUCCESS or FAILURE, not INVALID")
        return x
    return _TO_PT[Status.parse(x)]


def to_pytrees(model: Model, behaviours: "Callable | dict | None" = None,
               answer: "Callable | None" = None, log: "list | None" = None):
    """The py_trees tree of ``model.tree``; it ticks like the model under
    ``semantics="pytrees"`` (docs/semantics.md section 8.2).

    Leaves (``Action``, ``Condition``, ``SkillRequest``) come from ``behaviours``: a
    mapping {node name: py_trees behaviour} or a factory ``behaviours(node) ->
    behaviour``; a leaf it does not give is an ``AnswerBehaviour(name, answer, log)``.
    A ``Guard``'s condition becomes an ``EternalGuard`` whose condition is
    ``answer(guard name)`` (FAILURE or a false value: the guard is closed). A node with no
    py_trees counterpart (``Effects``, a ``Parallel`` threshold py_trees has no policy for)
    raises ``ModelError`` naming it."""
    if model.tree is None:
        raise ModelError("tree", "the model has no tree")

    def leaf(n):
        b = None
        if isinstance(behaviours, dict):
            b = behaviours.get(n.name)
        elif behaviours is not None:
            b = behaviours(n)
        if b is None:
            if answer is None:
                raise ModelError(f"tree.{n.name}", "no py_trees behaviour for this leaf: pass behaviours= or answer=")
            b = AnswerBehaviour(n.name, answer, log)
        return b

    def build(n: Node):
        where = f"tree.{n.name}"
        if isinstance(n, (Action, Condition, SkillRequest)):
            return leaf(n)
        if isinstance(n, (ReactiveSequence, MemorySequence, ReactiveFallback, MemoryFallback)):
            cls = py_trees.composites.Sequence if isinstance(n, (ReactiveSequence, MemorySequence)) else py_trees.composites.Selector
            return cls(n.name, memory=isinstance(n, (MemorySequence, MemoryFallback)), children=[build(c) for c in n.children])
        if isinstance(n, Parallel):
            kids = [build(c) for c in n.children]
            count = len(kids)
            if n.failure_threshold != 1:
                raise ModelError(where, f"py_trees' Parallel fails at the first failure; failure_threshold {n.failure_threshold} has no counterpart")
            if n.selected:
                chosen = [k for k, c in zip(kids, n.children) if c.name in n.selected]
                policy = Common.ParallelPolicy.SuccessOnSelected(chosen, synchronise=n.synchronise)
            elif n.success_threshold in (None, count):
                policy = Common.ParallelPolicy.SuccessOnAll(synchronise=n.synchronise)
            elif n.success_threshold == 1 and not n.synchronise:
                policy = Common.ParallelPolicy.SuccessOnOne()
            else:
                raise ModelError(where, f"py_trees has no Parallel policy for success_threshold {n.success_threshold} of {count}"
                                 + (" with synchronise" if n.synchronise else ""))
            return py_trees.composites.Parallel(n.name, policy=policy, children=kids)
        if isinstance(n, Guard):
            if answer is None:
                raise ModelError(where, "a Guard's condition needs answer= (asked with the guard's name)")
            name = n.name
            return py_trees.decorators.EternalGuard(name=name, child=build(n.child),
                                                    condition=lambda: _guard_open(answer(name), name))
        simple = {Inverter: py_trees.decorators.Inverter, ForceSuccess: py_trees.decorators.FailureIsSuccess,
                  ForceFailure: py_trees.decorators.SuccessIsFailure}
        for cls, pt in simple.items():
            if type(n) is cls:
                return pt(name=n.name, child=build(n.child))
        if isinstance(n, Retry):
            return py_trees.decorators.Retry(name=n.name, child=build(n.child), num_failures=n.attempts)
        if isinstance(n, Repeat):
            return py_trees.decorators.Repeat(name=n.name, child=build(n.child), num_success=n.times)
        if isinstance(n, Effects):
            raise ModelError(where, "Effects has no py_trees counterpart (py_trees behaviours write the blackboard in code)")
        raise ModelError(where, f"{type(n).__name__} has no py_trees counterpart")

    return build(model.tree)


def _guard_open(x, name) -> bool:
    if isinstance(x, (Status, str, Common.Status)):
        return _pt_status(x, name) != Common.Status.FAILURE
    return bool(x)


# ====================================================================== py_trees -> btfsm

_ANY = (Outcome(Status.SUCCESS), Outcome(Status.FAILURE), Outcome(Status.RUNNING))


def _outcomes_of(spec, where):
    """Outcomes from a leaves= entry: a Primitive, one status, or a list of statuses/Outcomes."""
    if isinstance(spec, Primitive):
        return tuple(spec.outcomes)
    if isinstance(spec, (str, Status, Outcome)):
        spec = [spec]
    try:
        items = list(spec)
    except TypeError:
        raise ModelError(where, f"leaves: expected a Primitive, a status or a list of statuses/Outcomes, got {type(spec).__name__}") from None
    out = []
    for x in items:
        if isinstance(x, Outcome):
            out.append(x)
        else:
            try:
                out.append(Outcome(Status.parse(x)))
            except ValueError as exc:
                raise ModelError(where, str(exc)) from None
    if not out:
        raise ModelError(where, "leaves: a leaf needs at least one outcome")
    return tuple(out)


def _builtin_outcomes(b):
    """The statuses a py_trees built-in leaf can return, or None when unknown."""
    B = py_trees.behaviours
    S = Status
    table = ((B.Success, (S.SUCCESS,)), (B.Failure, (S.FAILURE,)), (B.Running, (S.RUNNING,)),
             (B.Dummy, (S.RUNNING,)), (B.SuccessEveryN, (S.SUCCESS, S.FAILURE)),
             (B.Periodic, (S.RUNNING, S.SUCCESS, S.FAILURE)))
    for cls, sts in table:
        if isinstance(b, cls):
            return tuple(Outcome(s) for s in sts)
    if isinstance(b, B.TickCounter):
        return (Outcome(S.RUNNING), Outcome(_FROM_PT[b.completion_status]))
    if isinstance(b, B.StatusQueue):
        sts = {_FROM_PT[x] for x in list(b.queue) + [b.eventually] if x in _FROM_PT}
        return tuple(Outcome(s) for s in S if s in sts) or None
    return None


def from_pytrees(root, leaves: "dict | None" = None, name: "str | None" = None,
                 semantics: str = "pytrees") -> Model:
    """A btfsm ``Model`` of the py_trees tree under ``root``.

    ``leaves`` maps a leaf behaviour's name to its outcomes: a ``Primitive``, a status
    (``"success"``), or a list of statuses / ``Outcome`` objects (with effects on model
    variables, if the model is extended). py_trees' own finite leaves map without an entry
    (``Success``, ``Failure``, ``Running``, ``Dummy``; ``SuccessEveryN``, ``Periodic``,
    ``TickCounter`` and ``StatusQueue`` to the set of statuses they can return). Any other
    leaf may return any status (a ``PytreesImportWarning`` names it). An ``EternalGuard``'s
    condition (Python code) becomes a bool variable ``<guard>_open`` that the environment
    sets freely before each tick (an ``EnvChoice``), unless ``leaves`` maps the guard's name
    to an expression over those variables. Duplicate py_trees names get ``_2``, ``_3``...
    Nodes with no counterpart raise ``ModelError`` naming the node."""
    leaves = dict(leaves or {})
    used: dict = {}
    variables, environment = [], []

    def unique(label):
        k = used.get(label, 0) + 1
        used[label] = k
        return label if k == 1 else f"{label}_{k}"

    def ident(label):
        x = re.sub(r"\W", "_", label)
        return x if re.match(r"[A-Za-z_]", x) else f"g_{x}"

    def build(b) -> Node:
        nm = unique(b.name)
        where = f"tree.{nm}"
        C, D = py_trees.composites, py_trees.decorators
        if isinstance(b, (C.Sequence, C.Selector)):
            kids = [build(c) for c in b.children]
            if not kids:
                raise ModelError(where, f"an empty {type(b).__name__} has no btfsm counterpart")
            if isinstance(b, C.Sequence):
                return (MemorySequence if b.memory else ReactiveSequence)(nm, kids)
            return (MemoryFallback if b.memory else ReactiveFallback)(nm, kids)
        if isinstance(b, C.Parallel):
            kids = [build(c) for c in b.children]
            if not kids:
                raise ModelError(where, "an empty Parallel has no btfsm counterpart")
            pol, P = b.policy, Common.ParallelPolicy
            if isinstance(pol, P.SuccessOnAll):
                return Parallel(nm, kids, synchronise=pol.synchronise)
            if isinstance(pol, P.SuccessOnOne):
                return Parallel(nm, kids, success_threshold=1)
            if isinstance(pol, P.SuccessOnSelected):
                sel = tuple(k.name for k, c in zip(kids, b.children) if any(c is x for x in pol.children))
                if len(sel) != len(pol.children) or not sel:
                    raise ModelError(where, "SuccessOnSelected must select children of this parallel")
                return Parallel(nm, kids, selected=sel, synchronise=pol.synchronise)
            raise ModelError(where, f"unknown parallel policy {type(pol).__name__}")
        if isinstance(b, D.Decorator):
            if isinstance(b, (D.PassThrough, D.Count)):
                used[b.name] -= 1  # transparent: the name is not used
                return build(b.decorated)
            child = build(b.decorated)
            if isinstance(b, D.EternalGuard):
                if b.name in leaves:
                    return Guard(nm, child, leaves[b.name])
                var = ident(f"{nm}_open")
                variables.append(Bool(var, True))
                environment.append(EnvChoice(var, (EnvEvent(f"{var}_true", effects={var: True}),
                                                   EnvEvent(f"{var}_false", effects={var: False}))))
                return Guard(nm, child, var)
            if type(b) is D.Inverter:
                return Inverter(nm, child)
            if type(b) is D.FailureIsSuccess:
                return ForceSuccess(nm, child)
            if type(b) is D.SuccessIsFailure:
                return ForceFailure(nm, child)
            if type(b) is D.Retry:
                if b.num_failures < 1:
                    raise ModelError(where, f"Retry num_failures {b.num_failures}: must be at least 1")
                return Retry(nm, child, b.num_failures)
            if type(b) is D.Repeat:
                if b.num_success < 1:
                    raise ModelError(where, f"Repeat num_success {b.num_success} (repeat forever) has no btfsm counterpart")
                return Repeat(nm, child, b.num_success)
            raise ModelError(where, f"py_trees decorator {type(b).__name__} has no btfsm counterpart")
        if isinstance(b, C.Composite):
            raise ModelError(where, f"py_trees composite {type(b).__name__} has no btfsm counterpart")
        if b.name in leaves:
            outs = _outcomes_of(leaves[b.name], where)
        else:
            outs = _builtin_outcomes(b)
            if outs is None:
                warnings.warn(f"{where}: py_trees leaf {type(b).__name__} has no outcomes in leaves=; "
                              "modelled as returning any status", PytreesImportWarning, stacklevel=3)
                outs = _ANY
        return Action(nm, outcomes=outs)

    tree = build(root)
    return Model(name or ident(root.name), variables=tuple(variables), tree=tree,
                 environment=tuple(environment), semantics=semantics)


# ====================================================================== recorded runs

RUN_FORMAT = "btfsm-pytrees-run/1"


class RunRecorder(py_trees.visitors.VisitorBase):
    """A py_trees visitor that records a run for ``btfsm conform --log RUN MODEL``.

    Add it to a ``py_trees.trees.BehaviourTree`` (``tree.visitors.append(RunRecorder(path))``)
    before the first ``tree.tick()``; ``close()`` it at the end. It writes JSON lines: a
    header ``{"format": "btfsm-pytrees-run/1", "nodes": [{"name", "type", "parent"}, ...]}``
    (the tree in pre-order, ``parent`` an earlier index, null for the root), then per tick
    ``{"tick": k, "visited": [[node, status], ...], "running": [node, ...]}``: the nodes
    the tick visited with the status each returned, in the order py_trees visits them
    (each node after its children), and the nodes RUNNING when the tick ended (a node
    stopped during the tick is not). The tree's shape must not change while it records.

    >>> import io
    >>> root = py_trees.composites.Sequence("seq", memory=True, children=[
    ...     py_trees.behaviours.Success(name="a"), py_trees.behaviours.Running(name="b")])
    >>> tree, out = py_trees.trees.BehaviourTree(root), io.StringIO()
    >>> tree.visitors.append(RunRecorder(out))
    >>> tree.tick()
    >>> print(out.getvalue().splitlines()[1])
    {"tick": 0, "visited": [[1, "SUCCESS"], [2, "RUNNING"], [0, "RUNNING"]], "running": [0, 2]}
    """

    def __init__(self, out):
        super().__init__(full=False)
        self._own = isinstance(out, (str, os.PathLike))
        self._out = open(out, "w", encoding="utf-8") if self._own else out
        self._index: "dict | None" = None
        self._nodes: list = []
        self._tick = 0
        self._visited: list = []

    def initialise(self) -> None:
        self._visited = []

    def run(self, behaviour) -> None:
        self._visited.append((behaviour, behaviour.status))  # a later stop() may change it

    def finalise(self) -> None:
        if not self._visited:
            return
        if self._index is None:
            self._header(self._visited[-1][0])  # the root is visited last
        index = self._index
        try:
            visited = [[index[id(b)], status.name] for b, status in self._visited]
        except KeyError:
            raise ValueError("RunRecorder: the tree changed shape while it was recorded") from None
        running = [k for k, b in enumerate(self._nodes) if b.status == Common.Status.RUNNING]
        self._out.write(json.dumps({"tick": self._tick, "visited": visited, "running": running}) + "\n")
        self._tick += 1

    def _header(self, root) -> None:
        nodes, rows = [], []

        def walk(b, parent):
            rows.append({"name": b.name, "type": type(b).__name__, "parent": parent})
            nodes.append(b)
            me = len(nodes) - 1
            for c in b.children:
                walk(c, me)
        walk(root, None)
        self._nodes, self._index = nodes, {id(b): k for k, b in enumerate(nodes)}
        self._out.write(json.dumps({"format": RUN_FORMAT, "nodes": rows}) + "\n")

    def close(self) -> None:
        """Flush the recording (and close the file when the recorder opened it)."""
        self._out.flush()
        if self._own:
            self._out.close()
