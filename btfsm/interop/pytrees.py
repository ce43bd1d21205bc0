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
``Retry(num_failures=k)``                       ``Retry(attempts=max(1, ceil(k)))``
``Repeat(num_success=k)``, k a whole number >= 1 ``Repeat(times=k)``
``Repeat(num_success=k)``, any other k (-1, 0)   ``KeepRunningUntilFailure`` (for ever)
``SuccessIsRunning``                            ``KeepRunningUntilFailure``
``FailureIsRunning``, ``RunningIs{Failure,Success}`` the btfsm decorators of those names
``EternalGuard``                                ``Guard``
``CheckBlackboardVariableValue`` (a constant)    ``Condition`` over the key's variable
``SetBlackboardVariable(overwrite=True)``         ``Action`` whose SUCCESS writes the constant
``PassThrough``, ``Count`` (read only)           the child itself (they change no status)
=============================================== =========================================

py_trees compares its counts as its code says: ``Retry`` fails when the failures it
counted reach ``num_failures`` (``<``), so 0 or -3 fail at the first failure like 1;
``Repeat`` succeeds when its count *equals* ``num_success``, which -1, 0 or 2.5 never do.
Everything else (docs/interop.md lists each refusal and why: ``Timeout``, wall-clock
time; ``OneShot``; ...) is refused with
a ``ModelError`` naming the node. ``from_pytrees`` raises nothing else, whatever the tree.

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
import keyword
import math
import operator
import os
import re
import unicodedata
import warnings
from collections.abc import Mapping
from typing import Any, Callable, cast

try:
    import py_trees
except ImportError as exc:  # pragma: no cover - exercised only without py_trees
    raise ImportError("btfsm.interop.pytrees needs py_trees 2.x: pip install 'py_trees>=2.2' "
                      "(or the btfsm 'test' / 'bench' extras)") from exc

from ..bt import (NODE_TYPES, Action, Condition, Decorator, Effects, Guard, KeepRunningUntilFailure, MemoryFallback,
                  MemorySequence, Node, Parallel, ReactiveFallback, ReactiveSequence, Repeat, Retry, SkillRequest,
                  file_fields)
from ..errors import ModelError
from ..expr import Const, as_expr
from ..model import EnvChoice, EnvEvent, Model
from ..primitives import Outcome, Primitive
from ..status import Status
from ..world import RESERVED_NAMES, Bool, Enum, Int, check_label

__all__ = ["from_pytrees", "node_names", "to_pytrees", "AnswerBehaviour", "PytreesImportWarning", "RunRecorder",
           "RUN_FORMAT"]

Common = py_trees.common
_TO_PT = {Status.RUNNING: Common.Status.RUNNING, Status.SUCCESS: Common.Status.SUCCESS,
          Status.FAILURE: Common.Status.FAILURE}
_FROM_PT = {v: k for k, v in _TO_PT.items()}
#: btfsm decorator -> the py_trees decorator of the same rule that takes only a name and a
#: child (the node classes' ``pytrees`` names); KeepRunningUntilFailure is written as
#: ``Repeat(num_success=-1)`` and read from ``SuccessIsRunning`` too
_PLAIN_DECORATORS: dict[type, str] = {cls: cls.pytrees for cls in NODE_TYPES.values()
                     if issubclass(cls, Decorator) and cls.pytrees and not file_fields(cls)}


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
            policy: Any
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
            return py_trees.decorators.EternalGuard(name=name, child=build(cast(Node, n.child)),
                                                    condition=lambda: _guard_open(answer(name), name))
        if isinstance(n, Retry):
            return py_trees.decorators.Retry(name=n.name, child=build(cast(Node, n.child)), num_failures=n.attempts)
        if isinstance(n, Repeat):
            return py_trees.decorators.Repeat(name=n.name, child=build(cast(Node, n.child)), num_success=n.times)
        if type(n) is KeepRunningUntilFailure:
            return py_trees.decorators.Repeat(name=n.name, child=build(cast(Node, n.child)), num_success=-1)
        if type(n) in _PLAIN_DECORATORS:
            return getattr(py_trees.decorators, _PLAIN_DECORATORS[type(n)])(name=n.name, child=build(cast(Node, getattr(n, "child"))))
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


def node_names(root) -> list:
    """``[(behaviour, btfsm node name), ...]`` in pre-order, for every behaviour of the
    tree under ``root`` that ``from_pytrees`` turns into a node (``PassThrough`` and
    ``Count`` are read as their child and get none).

    A name is kept as the user wrote it (unicode and spaces included) wherever btfsm
    accepts it as a node name: one line of printable text, at most 256 characters, no
    ``${...}``. A name it cannot carry becomes a safe one (each non-printable character
    as ``_``, ``${`` as ``$_{``, cut to 240 characters; an empty name is ``unnamed``).
    The first behaviour with a name keeps it; a later behaviour with the same name gets
    ``_2``, ``_3``, ... (the first suffix no behaviour of the tree uses), so every valid
    py_trees tree imports, whatever its names (py_trees does not ask for unique names).

    >>> import py_trees
    >>> B = py_trees.behaviours
    >>> root = py_trees.composites.Sequence("Tür offen", memory=False,
    ...                                     children=[B.Success("a"), B.Success("a_2"), B.Success("a")])
    >>> [n for _, n in node_names(root)]
    ['Tür offen', 'a', 'a_2', 'a_3']
    """
    root = _root_of(root)
    order: list = []
    _walk_behaviours(root, order)
    return list(zip(order, btfsm_names([b.name for b in order])))


def btfsm_names(names) -> list:
    """The btfsm node names of behaviours named ``names`` (in pre-order, PassThrough and
    Count left out), by ``node_names``' rule; ``btfsm conform --log`` uses it to name the
    nodes of a py_trees recording.

    >>> btfsm_names(["a", "a_2", "a", "", "x\\ny"])
    ['a', 'a_2', 'a_3', 'unnamed', 'x_y']
    """
    labels = [_label(n) for n in names]
    taken = set(labels)
    given: set = set()
    out = []
    for lab in labels:
        nm, k = lab, 1
        while nm in given or (k > 1 and nm in taken):
            k += 1
            nm = f"{lab[:240]}_{k}"
        given.add(nm)
        out.append(nm)
    return out


def _root_of(root):
    """``root`` itself, or the root of a ``py_trees.trees.BehaviourTree``."""
    if isinstance(root, py_trees.trees.BehaviourTree):
        root = root.root
    if not isinstance(root, py_trees.behaviour.Behaviour):
        raise ModelError("tree", f"expected a py_trees behaviour or BehaviourTree, got {type(root).__name__}")
    return root


def _walk_behaviours(root, order):
    """Pre-order list of the behaviours that become nodes; ModelError on a behaviour met
    twice (py_trees cannot tick such a tree: a behaviour has one parent)."""
    seen: set = set()
    stack = [root]
    while stack:
        b = stack.pop()
        if not isinstance(b, py_trees.behaviour.Behaviour):
            raise ModelError("tree", f"a child is not a py_trees behaviour: {type(b).__name__}")
        if id(b) in seen:
            raise ModelError("tree", f"behaviour {_label(getattr(b, 'name', ''))!r} appears twice in the tree")
        seen.add(id(b))
        if not isinstance(getattr(b, "name", None), str):
            raise ModelError("tree", f"a behaviour's name must be a string (py_trees' rule), got {type(getattr(b, 'name', None)).__name__}")
        if isinstance(b, py_trees.decorators.Decorator):
            if not isinstance(b, (py_trees.decorators.PassThrough, py_trees.decorators.Count)):
                order.append(b)
            stack.append(b.decorated)
        else:
            order.append(b)
            kids = list(getattr(b, "children", None) or ())
            stack.extend(reversed(kids))


def _label(name) -> str:
    """``name`` if btfsm accepts it as a node name (check_label), else a safe label made from it."""
    text = name if isinstance(name, str) else str(name)
    try:
        return check_label(text, "", "node name")
    except ModelError:
        pass
    safe = "".join(c if c.isprintable() else "_" for c in text).replace("${", "$_{")[:240]
    return safe or "unnamed"


def _ident(label: str, taken: set) -> str:
    """An ASCII identifier made from ``label`` (accents dropped, other characters as ``_``),
    not in ``taken`` (``_2``, ``_3``... appended), which it joins."""
    text = unicodedata.normalize("NFKD", label)
    text = "".join(c for c in text if not unicodedata.combining(c))
    base = re.sub(r"[^A-Za-z0-9_]", "_", text)[:64]
    if not re.match(r"[A-Za-z_]", base):
        base = f"g_{base}"
    x, k = base, 1
    while x in taken or x in RESERVED_NAMES or keyword.iskeyword(x):
        k += 1
        x = f"{base}_{k}"
    taken.add(x)
    return x


def _guard_expression(spec, where):
    """A guard's condition from ``guards=`` / ``leaves=``: ModelError when it is none."""
    try:
        return as_expr(spec)
    except ModelError as exc:
        raise exc.at(where) from None
    except (TypeError, ValueError) as exc:
        raise ModelError(where, f"a guard's condition must be an expression over the model's variables: {exc}") from None


def _is_status_word(x) -> bool:
    try:
        Status.parse(x)
        return True
    except (ValueError, TypeError, AttributeError):
        return False


def _count(x, what, where):
    """A py_trees count (``num_failures``, ``num_success``): a number, else ModelError."""
    if isinstance(x, bool):  # py_trees compares it as the number it is (True == 1)
        return int(x)
    if not isinstance(x, (int, float)):
        raise ModelError(where, f"{what} {x!r} is not a number")
    return x


_OPERATORS: dict[Any, str] = {operator.eq: "==", operator.ne: "!=", operator.lt: "<", operator.le: "<=", operator.gt: ">",
              operator.ge: ">="}


def _constant(generator, where, what):
    """The constant a py_trees blackboard behaviour was given (it keeps it in a lambda);
    ModelError when it was given a callable (Python code, which btfsm does not run)."""
    cells = getattr(generator, "__closure__", None) or ()
    if getattr(generator, "__qualname__", "").endswith("__init__.<locals>.<lambda>") and len(cells) == 1:
        value = cells[0].cell_contents
        if not callable(value):
            return value
    raise ModelError(where, f"{what} is computed by Python code; btfsm models constant values only")


def _blackboard_vars(order, names, initial, idents):
    """{key: (value var, set-flag var, [Var, Var])} for the keys the tree's
    CheckBlackboardVariableValue / SetBlackboardVariable behaviours use: one variable of
    the values written and compared (bool, int or enum of strings) and a bool that says
    whether the key exists (py_trees' check fails on a key that does not)."""
    B = py_trees.behaviours
    values: dict = {}
    for b in order:
        where = f"tree.{names[id(b)]}"
        if type(b) is B.CheckBlackboardVariableValue:
            key, v = b.check.variable, _constant(b.check.value_generator, where, "the compared value")
            if b.check.operator not in _OPERATORS:
                raise ModelError(where, f"comparison {getattr(b.check.operator, '__name__', b.check.operator)!r}: "
                                        "btfsm models ==, !=, <, <=, >, >= (the operator module's eq ... ge)")
        elif type(b) is B.SetBlackboardVariable:
            key, v = b.variable_name, _constant(b.variable_value_generator, where, "the value written")
            if not b.overwrite:
                raise ModelError(where, "SetBlackboardVariable(overwrite=False) succeeds or fails on whether the "
                                        "key exists; btfsm models overwrite=True (write a check before it)")
        else:
            continue
        values.setdefault(key, []).append((v, where))
    for key, v in (initial or {}).items():
        values.setdefault(key, []).append((v, f"blackboard.{key}"))
    for key, vals in values.items():
        if not isinstance(key, str) or "." in key or not key:
            raise ModelError(vals[0][1], f"blackboard variable {key!r}: btfsm models plain keys (no nested attributes)")
    out = {}
    for key, vals in values.items():
        kinds = {bool if isinstance(v, bool) else int if isinstance(v, int) else str if isinstance(v, str) else None
                 for v, _ in vals}
        if len(kinds) != 1 or None in kinds:
            raise ModelError(vals[0][1], f"blackboard variable '{key}' takes values of several kinds or of a kind "
                                         "btfsm does not model (one of bool, int, str)")
        name = _ident(key, idents)
        flag = _ident(f"{name}_exists", idents)
        known = key in (initial or {})
        init = initial[key] if known else None
        kind = kinds.pop()
        if kind is bool:
            var = Bool(name, bool(init))
        elif kind is int:
            nums = [v for v, _ in vals]
            var = Int(name, min(nums), max(nums), init if known else min(nums))
        else:
            texts = tuple(dict.fromkeys(v for v, _ in vals))
            var = Enum(name, texts, init if known else texts[0])
        out[key] = (name, flag, [var, Bool(flag, known)])
    return out


def _literal(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    return repr(v) if isinstance(v, str) else str(v)


def from_pytrees(root, leaves: "dict | None" = None, name: "str | None" = None,
                 semantics: str = "pytrees", guards: "dict | None" = None,
                 blackboard: "dict | None" = None) -> Model:
    """A btfsm ``Model`` of the py_trees tree under ``root`` (a behaviour, or a
    ``py_trees.trees.BehaviourTree``: its root).

    ``leaves`` maps a leaf behaviour's name to its outcomes: a ``Primitive``, a status
    (``"success"``), or a list of statuses / ``Outcome`` objects (with effects on model
    variables, if the model is extended). py_trees' own finite leaves map without an entry
    (``Success``, ``Failure``, ``Running``, ``Dummy``; ``SuccessEveryN``, ``Periodic``,
    ``TickCounter`` and ``StatusQueue`` to the set of statuses they can return). Any other
    leaf may return any status (a ``PytreesImportWarning`` names it). An ``EternalGuard``'s
    condition (Python code) becomes a bool variable ``<guard>_open`` (an ASCII identifier
    made from the guard's name, unique) that the environment sets freely before each tick
    (an ``EnvChoice``), unless ``guards`` maps the guard's name to an expression over those
    variables (a ``leaves`` entry that is an expression string, not a status, still does,
    when no leaf has that name). py_trees' ``CheckBlackboardVariableValue`` (a constant
    compared with ``==``, ``!=``, ``<``, ``<=``, ``>``, ``>=``) is a ``Condition`` and
    ``SetBlackboardVariable(overwrite=True)`` of a constant an ``Action`` that writes it,
    over one model variable per key (named after it; bool, int over the values used, or
    an enum of strings) and a bool ``<key>_exists``: a key starts unset (a check fails)
    unless ``blackboard`` gives its initial value. Node names are the py_trees names, kept as written where
    btfsm can carry them (``node_names``); duplicates get ``_2``, ``_3``... Nodes with no
    counterpart raise ``ModelError`` naming the node; nothing else is raised for any
    input."""
    for arg, given in (("leaves", leaves), ("guards", guards), ("blackboard", blackboard)):
        if given is not None and not isinstance(given, Mapping):
            raise ModelError(arg, f"expected a mapping of behaviour names, got {type(given).__name__}")
    leaves = dict(leaves or {})
    guards = dict(guards or {})
    try:
        names = {id(b): nm for b, nm in node_names(root)}
        root = _root_of(root)
        leaf_names = {b.name for b in root.iterate() if not getattr(b, "children", None)
                      and not isinstance(b, py_trees.decorators.Decorator)}
        return _import(root, names, leaves, guards, leaf_names, name, semantics, dict(blackboard or {}))
    except RecursionError:
        raise ModelError("tree", "the tree is nested too deeply to import") from None


def _import(root, names, leaves, guards, leaf_names, name, semantics, blackboard):
    variables, environment = [], []
    idents: set = set()
    mapped = [b for b in root.iterate() if b.name not in leaves and id(b) in names]
    bb = _blackboard_vars(mapped, names, blackboard, idents)
    for _, _, pair in bb.values():
        variables.extend(pair)
    B = py_trees.behaviours

    def build(b) -> Node:
        C, D = py_trees.composites, py_trees.decorators
        if isinstance(b, (D.PassThrough, D.Count)):
            return build(b.decorated)  # transparent: no node, no name
        nm = names[id(b)]
        where = f"tree.{nm}"
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
                return Parallel(nm, kids, synchronise=bool(pol.synchronise))
            if isinstance(pol, P.SuccessOnOne):
                return Parallel(nm, kids, success_threshold=1)
            if isinstance(pol, P.SuccessOnSelected):
                chosen = list(pol.children or ())
                sel = tuple(k.name for k, c in zip(kids, b.children) if any(c is x for x in chosen))
                if len(sel) != len(chosen) or not sel:
                    raise ModelError(where, "SuccessOnSelected must select children of this parallel")
                return Parallel(nm, kids, selected=sel, synchronise=bool(pol.synchronise))
            raise ModelError(where, f"unknown parallel policy {type(pol).__name__}")
        if isinstance(b, D.Decorator):
            child = build(b.decorated)
            if isinstance(b, D.EternalGuard):
                spec = guards.get(b.name)
                if spec is None and b.name not in leaf_names and isinstance(leaves.get(b.name), str) \
                        and not _is_status_word(leaves[b.name]):
                    spec = leaves[b.name]
                if spec is not None:
                    return Guard(nm, child, _guard_expression(spec, f"{where}.condition"))
                var = _ident(f"{nm}_open", idents)
                variables.append(Bool(var, True))
                environment.append(EnvChoice(var, (EnvEvent(f"{var}_true", effects={var: True}),
                                                   EnvEvent(f"{var}_false", effects={var: False}))))
                return Guard(nm, child, var)
            plain = {getattr(D, pt): cls for cls, pt in _PLAIN_DECORATORS.items()}
            if type(b) in plain:  # Inverter, FailureIsSuccess, SuccessIsRunning...: the btfsm decorator of its rule
                return plain[type(b)](nm, child)
            if type(b) is D.Retry:
                # py_trees counts failures and fails when the count reaches num_failures (a
                # "<" test): any count <= 1 fails at the first failure, as Retry(1) does
                k = _count(b.num_failures, "Retry num_failures", where)
                if math.isnan(k):  # no count is below NaN
                    k = 1
                if k == math.inf:
                    raise ModelError(where, "Retry num_failures inf (retry for ever) has no btfsm counterpart")
                return Retry(nm, child, max(1, math.ceil(k)))
            if type(b) is D.Repeat:
                # py_trees succeeds when its success count *equals* num_success: a count it
                # never reaches (-1, 0, any value that is not a whole number >= 1) repeats for
                # ever, which is KeepRunningUntilFailure
                k = _count(b.num_success, "Repeat num_success", where)
                if math.isfinite(k) and k >= 1 and k == int(k):
                    return Repeat(nm, child, int(k))
                return KeepRunningUntilFailure(nm, child)
            raise ModelError(where, f"py_trees decorator {type(b).__name__} has no btfsm counterpart")
        if isinstance(b, C.Composite):
            raise ModelError(where, f"py_trees composite {type(b).__name__} has no btfsm counterpart")
        if type(b) is B.CheckBlackboardVariableValue and b.name not in leaves:
            var, flag, _ = bb[b.check.variable]
            value = _constant(b.check.value_generator, where, "the compared value")
            return Condition(nm, f"{flag} and {var} {_OPERATORS[b.check.operator]} {_literal(value)}")
        if type(b) is B.SetBlackboardVariable and b.name not in leaves:
            var, flag, _ = bb[b.variable_name]
            value = _constant(b.variable_value_generator, where, "the value written")
            return Action(nm, outcomes=(Outcome(Status.SUCCESS, effects={var: Const(value), flag: Const(True)}),))
        if b.name in leaves:
            outs = _outcomes_of(leaves[b.name], where)
        else:
            outs = _builtin_outcomes(b)
            if outs is None:
                warnings.warn(f"{where}: py_trees leaf {type(b).__name__} has no outcomes in leaves=; "
                              "modelled as returning any status", PytreesImportWarning, stacklevel=4)
                outs = _ANY
        return Action(nm, outcomes=outs)

    tree = build(root)
    model_name = name if name is not None else _ident(_label(root.name), set())
    return Model(model_name, variables=tuple(variables), tree=tree,
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
        index = cast(dict, self._index)  # set by _header
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
