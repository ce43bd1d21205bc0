"""Goal-driven finite-state machines (the paper's skill FSMs).

One token per FSM, shared by all goals. A state runs a primitive or a BT subtree. Edges
(source, target, goals served, guard, the status that fires them, ``direct`` flag,
effects) move the token; markers (state, goals, guard, ``direct`` flag, status, outcome)
are how the FSM replies SUCCESS or FAILURE to the requesting BT node. The per-tick rule
is in docs/semantics.md and implemented once in ``btfsm.semantics``.

>>> f = FSM("arm", states=[State("home"), State("work", primitive="work")], initial="home",
...         goals=["go"], edges=[Edge("home", "work", ["go"]), Edge("work", "home", ["go"])],
...         markers=[Marker("work", ["go"], outcome="success")])
>>> [e.id for e in f.edges]
['home->work', 'work->home']
>>> f.validate({"work": frozenset({Status.SUCCESS})})
[]
"""
from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass
from typing import Any, Mapping, Sequence, cast

from .bt import Node
from .errors import ModelError
from .expr import ExprLike, as_expr, is_true, to_text
from .primitives import EffectsLike, Outcome, effects_of
from .status import Status
from .world import Var, check_label, check_name
from .timing import duration_of

__all__ = ["State", "Edge", "Marker", "FSM", "ALL_GOALS", "RETARGET_MODES"]

ALL_GOALS = "*"
RETARGET_MODES = ("immediate", "withdraw")


@dataclass(frozen=True)
class State:
    """A state runs ``primitive`` (with constant ``args``), or a BT ``subtree``, or, with
    neither, the built-in instant primitive ``pass`` (SUCCESS). ``outcomes`` declares the
    primitive inline."""

    id: str
    primitive: str = ""
    args: "Mapping[str, Any] | Sequence[Any]" = ()  # a tuple of (name, value) once built
    subtree: "Node | None" = None
    outcomes: "Sequence[Any] | None" = None
    duration: "tuple | None" = None  # (min, max) seconds in this state; default: the primitive's

    def __post_init__(self):
        object.__setattr__(self, "duration", duration_of(self.duration, f"states.{self.id}.duration"))
        if self.outcomes is not None:
            object.__setattr__(self, "outcomes", tuple(o if isinstance(o, Outcome) else Outcome(**o) for o in self.outcomes))
        args = self.args
        object.__setattr__(self, "args", tuple(sorted(args.items())) if hasattr(args, "items") else tuple(tuple(p) for p in args))


def _goals(goals) -> tuple:
    if isinstance(goals, str):
        goals = (goals,)
    return tuple(goals)


@dataclass(frozen=True)
class Edge:
    """Moves the token from ``source`` to ``target`` for the ``goals`` it serves, when the
    source's run returns ``on`` (or, if ``direct``, before anything runs) and ``guard`` holds."""

    source: str
    target: str
    goals: "Sequence[str] | str" = (ALL_GOALS,)  # a tuple once built
    on: "Status | str | None" = Status.SUCCESS  # a Status (None if direct) once built
    guard: "ExprLike | None" = None  # an Expr once built
    direct: bool = False
    effects: EffectsLike = ()
    id: str = ""

    def __post_init__(self):
        object.__setattr__(self, "goals", _goals(self.goals))
        object.__setattr__(self, "on", None if self.direct else Status.parse(self.on if self.on is not None else "success"))
        object.__setattr__(self, "guard", None if self.guard is None else as_expr(self.guard))
        object.__setattr__(self, "effects", effects_of(self.effects))


@dataclass(frozen=True)
class Marker:
    """Makes the FSM reply ``outcome`` for ``goals`` when ``state``'s run returns ``on`` (or,
    if ``direct``, as soon as the token rests on ``state``) and ``guard`` holds."""

    state: str
    goals: "Sequence[str] | str" = (ALL_GOALS,)  # a tuple once built
    on: "Status | str | None" = Status.SUCCESS  # a Status (None if direct) once built
    outcome: "Status | str" = Status.SUCCESS  # a Status once built
    guard: "ExprLike | None" = None  # an Expr once built
    direct: bool = False
    id: str = ""

    def __post_init__(self):
        object.__setattr__(self, "goals", _goals(self.goals))
        object.__setattr__(self, "on", None if self.direct else Status.parse(self.on if self.on is not None else "success"))
        object.__setattr__(self, "outcome", Status.parse(self.outcome))
        object.__setattr__(self, "guard", None if self.guard is None else as_expr(self.guard))


@dataclass(frozen=True)
class FSM:
    """A goal-driven FSM.

    ``params``: variables a request sets (the paper's skill parameters, e.g. the target).
    ``retarget``: what a request with other parameter values does: ``immediate`` adopts
    them at once; ``withdraw`` (the authors' original protocol) first drives the token
    with ``withdraw_goal`` and adopts them, replying RUNNING, once that goal succeeds.
    ``terminal``: states where having no successor is intended.
    """

    name: str
    states: Sequence[State] = ()  # each sequence a tuple once built
    initial: str = ""
    goals: "Sequence[str] | str" = ()
    edges: Sequence[Edge] = ()
    markers: Sequence[Marker] = ()
    params: Sequence[Any] = ()
    retarget: str = "immediate"
    withdraw_goal: str = ""
    terminal: "Sequence[str] | str" = ()

    def __post_init__(self):
        goals = _goals(self.goals)
        object.__setattr__(self, "goals", goals)
        object.__setattr__(self, "states", tuple(self.states))
        object.__setattr__(self, "params", tuple(self.params))
        object.__setattr__(self, "terminal", _goals(self.terminal))
        if not self.initial and self.states:
            object.__setattr__(self, "initial", self.states[0].id)
        object.__setattr__(self, "edges", _with_ids(self.edges, goals, lambda e: f"{e.source}->{e.target}"))
        object.__setattr__(self, "markers", _with_ids(self.markers, goals, lambda m: f"{m.state}:{'direct' if m.direct else m.on.name.lower()}"))

    # ------------------------------------------------------------------ queries
    def state(self, sid: str) -> State:
        for st in self.states:
            if st.id == sid:
                return st
        raise KeyError(sid)

    def edges_from(self, sid: str, goal: str) -> list:
        return [e for e in self._by_state("_edges_by_source", self.edges, "source").get(sid, ()) if goal in e.goals]

    def markers_at(self, sid: str, goal: str) -> list:
        return [m for m in self._by_state("_markers_by_state", self.markers, "state").get(sid, ()) if goal in m.goals]

    def _by_state(self, attr: str, items, key: str) -> dict:
        """{state: its items in declaration order}, built once (the FSM is immutable)."""
        idx = self.__dict__.get(attr)
        if idx is None:
            idx = {}
            for x in items:
                idx.setdefault(getattr(x, key), []).append(x)
            object.__setattr__(self, attr, idx)
        return idx

    # ------------------------------------------------------------------ validation
    def validate(self, statuses_of: "dict | None" = None, element: str = "") -> list:
        """Raise ModelError on malformed structure; return warnings ``(element, text)`` for
        unreachable states and elements that can never fire (found without solving guards).

        ``statuses_of`` maps a primitive name to the statuses it can return."""
        where = element or f"fsms.{self.name}"
        check_name(self.name, where, "FSM name")
        ids = [s.id for s in self.states]
        if not ids:
            raise ModelError(where, "has no states")
        for i, sid in enumerate(ids):
            check_label(sid, f"{where}.states[{i}]", "state id")
        _no_dups(ids, f"{where}.states", "state")
        for i, st in enumerate(self.states):
            if not isinstance(st.id, str) or not st.id:
                raise ModelError(f"{where}.states[{i}]", "state id must be a non-empty string")
            if st.primitive and st.subtree is not None:
                raise ModelError(f"{where}.states.{st.id}", "runs both a primitive and a subtree")
        if self.initial not in ids:
            raise ModelError(f"{where}.initial", f"unknown state '{self.initial}'")
        if not self.goals:
            raise ModelError(f"{where}.goals", "an FSM needs at least one goal")
        for g in self.goals:
            if not isinstance(g, str) or not g or g == ALL_GOALS:
                raise ModelError(f"{where}.goals", f"goal {g!r} must be a non-empty string other than '*'")
            check_label(g, f"{where}.goals", "goal")
        _no_dups(self.goals, f"{where}.goals", "goal")
        for i, p in enumerate(self.params):
            if not isinstance(p, Var):
                raise ModelError(f"{where}.params[{i}]", "a parameter is a variable declaration")
            p.validated(f"{where}.params.{p.name}")
        _no_dups([p.name for p in self.params], f"{where}.params", "parameter")
        if self.retarget not in RETARGET_MODES:
            raise ModelError(f"{where}.retarget", f"must be one of {', '.join(RETARGET_MODES)}")
        if self.retarget == "withdraw" and self.withdraw_goal not in self.goals:
            raise ModelError(f"{where}.withdraw_goal", f"'{self.withdraw_goal}' is not a goal of {self.name}")
        for t in self.terminal:
            if t not in ids:
                raise ModelError(f"{where}.terminal", f"unknown state '{t}'")
        el: Any
        for kind, items in (("edge", self.edges), ("marker", self.markers)):
            for i, el in enumerate(items):
                check_label(el.id, f"{where}.{kind}s[{i}]", f"{kind} id", limit=None)
        _no_dups([e.id for e in self.edges], f"{where}.edges", "edge id")
        _no_dups([m.id for m in self.markers], f"{where}.markers", "marker id")
        known = set(ids)
        for e in self.edges:
            ew = f"{where}.edges.{e.id}"
            for end, sid in (("source", e.source), ("target", e.target)):
                if sid not in known:
                    raise ModelError(f"{ew}.{end}", f"unknown state '{sid}'")
            self._check_goals(e.goals, ew)
        for m in self.markers:
            mw = f"{where}.markers.{m.id}"
            if m.state not in known:
                raise ModelError(f"{mw}.state", f"unknown state '{m.state}'")
            self._check_goals(m.goals, mw)
            if m.outcome == Status.RUNNING:
                raise ModelError(f"{mw}.outcome", "a marker replies success or failure, not running")
        self._check_direct_cycles(where)
        return self._warnings(where, statuses_of or {})

    def _check_goals(self, goals, where):
        if not goals:
            raise ModelError(f"{where}.goals", "serves no goal")
        for g in goals:
            if g not in self.goals:
                raise ModelError(f"{where}.goals", f"unknown goal '{g}'")

    def _check_direct_cycles(self, where):
        for g in self.goals:
            succ = defaultdict(list)
            for e in self.edges:
                if e.direct and g in e.goals:
                    succ[e.source].append(e.target)
            colour: dict = {}
            for start in list(succ):
                path = _find_cycle(start, succ, colour)
                if path:
                    raise ModelError(f"{where}.edges", f"direct edges form a cycle for goal '{g}': {' -> '.join(path)} (a direct chain must end)")

    def _warnings(self, where, statuses_of) -> list:
        out = []
        reach, todo = {self.initial}, [self.initial]
        nxt = defaultdict(set)
        for e in self.edges:
            nxt[e.source].add(e.target)
        while todo:
            for t in nxt[todo.pop()]:
                if t not in reach:
                    reach.add(t)
                    todo.append(t)
        for st in self.states:
            if st.id not in reach:
                out.append((f"{where}.states.{st.id}", f"state '{st.id}' is unreachable from '{self.initial}'"))
        for g in self.goals:
            for st in self.states:
                out += self._shadowing(where, st, g, statuses_of)
        return out

    def _shadowing(self, where, st, g, statuses_of) -> list:
        out = []
        directs = [e for e in self.edges_from(st.id, g) if e.direct]
        blocker = next((e for e in directs if is_true(e.guard)), None)
        statuses = self._statuses(st, statuses_of)
        for e in self.edges_from(st.id, g):
            if blocker is not None and e is not blocker and (not e.direct or directs.index(e) > directs.index(blocker)):
                out.append((f"{where}.edges.{e.id}", f"never fires for goal '{g}': shadowed by direct edge '{blocker.id}'"))
            elif not e.direct and statuses is not None and e.on not in statuses:
                out.append((f"{where}.edges.{e.id}", f"never fires: state '{st.id}' never returns {e.on.name}"))
        for m in self.markers_at(st.id, g):
            if blocker is not None:
                out.append((f"{where}.markers.{m.id}", f"never fires for goal '{g}': shadowed by direct edge '{blocker.id}'"))
            elif not m.direct and statuses is not None and m.on not in statuses:
                out.append((f"{where}.markers.{m.id}", f"never fires: state '{st.id}' never returns {m.on.name}"))
        return out

    @staticmethod
    def _statuses(st: State, statuses_of) -> "frozenset | None":
        if st.subtree is not None:
            return None
        if st.outcomes is not None:
            return frozenset(o.status for o in st.outcomes)
        if not st.primitive:
            return frozenset({Status.SUCCESS})
        return statuses_of.get(st.primitive)


def _with_ids(elements, goals, default_id) -> tuple:
    used: dict
    out, used = [], {}
    for el in elements:
        if ALL_GOALS in el.goals:
            el = _replace(el, goals=tuple(goals))
        if not el.id:
            base = default_id(el)
            n = used.get(base, 0)
            used[base] = n + 1
            el = _replace(el, id=base if n == 0 else f"{base}#{n}")
        out.append(el)
    return tuple(out)


def _replace(el, **changes):
    import dataclasses

    return dataclasses.replace(el, **changes)


def _no_dups(items, where, what):
    seen = set()
    for x in items:
        if x in seen:
            raise ModelError(where, f"duplicate {what} '{x}'")
        seen.add(x)


def _find_cycle(start, succ, colour):
    """Iterative DFS; returns a cycle as a list of states, or None."""
    if colour.get(start):
        return None
    stack, path = [(start, iter(succ[start]))], [start]
    colour[start] = 1
    while stack:
        node, it = stack[-1]
        for t in it:
            if colour.get(t) == 1:
                return path[path.index(t):] + [t]
            if not colour.get(t):
                colour[t] = 1
                stack.append((t, iter(succ[t])))
                path.append(t)
                break
        else:
            colour[node] = 2
            stack.pop()
            path.pop()
    return None


def describe(el) -> str:
    """One line for an edge or marker, for messages and pictures."""
    guard = f" [{to_text(el.guard)}]" if el.guard is not None else ""
    if isinstance(el, Edge):
        trig = "direct" if el.direct else cast(Status, el.on).name.lower()
        return f"{el.id}: {el.source} -> {el.target} on {trig}{guard}"
    trig = "direct" if el.direct else el.on.name.lower()
    return f"{el.id}: {el.state} on {trig}{guard} => {el.outcome.name.lower()}"
