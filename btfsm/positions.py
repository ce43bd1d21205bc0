"""A position abstraction for timed FSMs: a state split by the state the token came from.

A primitive's duration often depends on where the robot starts, and where it starts is
where the state before left it. ``split_by_entry(model, fsm, table)`` gives each state of
``table`` one copy per group of predecessor states that share a duration interval: the
copy ``s@u`` is entered only from ``u`` (or from the states of its group), so its declared
duration can be the interval of the moves that start where ``u`` leaves the arm. Edges
and markers are copied for every copy of their source; expressions that name a split
state (``arm.state == 's'``) name all its copies. The split model has the same runs as
the original up to the renaming, with finer durations (docs/verification.md 2.1).

``table``: ``{state: {entry: (min, max) seconds}}``; an entry is a predecessor state, or
``""`` for the initial state's start. Every entry of a state in the table must be there.

>>> from btfsm import FSM, Edge, Model, State, Primitive, Action, running, success
>>> f = FSM("arm", states=[State("a", "move"), State("b", "move")], initial="a", goals=("g",),
...         edges=[Edge("a", "b", "g"), Edge("b", "a", "g")])
>>> m = Model("m", primitives=[Primitive("move", (running(), success()))], fsms=[f])
>>> s = split_by_entry(m, "arm", {"a": {"": (0, 1), "b": (0, 2)}})
>>> [st.id for st in s.fsms[0].states], s.fsms[0].initial
(['a@start', 'a@b', 'b'], 'a@start')
>>> sorted((e.source, e.target) for e in s.fsms[0].edges)
[('a@b', 'b'), ('a@start', 'b'), ('b', 'a@b')]
"""
from __future__ import annotations

import dataclasses
from typing import Any, cast

from .errors import ModelError
from .fsm import Edge
from .expr import BoolOp, Compare, Const, Expr, Name, Unary, flat

__all__ = ["split_by_entry", "split_history", "split_by_goal", "split_by_guard", "split_deeper", "base_state", "entries_of",
           "requested_goals", "check_requests", "widen_to_copies", "copies_named", "substitute", "SEP", "GOAL_SEP", "GUARD_SEP"]

SEP = "@"  # a copy by entry: "<state>@<predecessor>"
GOAL_SEP = "#"  # a copy by goal: "<state>#<class>"
GUARD_SEP = "%"  # a copy by a guard on the variables: "<state>%<tag>"


def base_state(name: str) -> str:
    """The state a copy was split from (the name itself for a state that was not split).

    >>> base_state("approach_bins#hub@escape_bins+2"), base_state("grasp_bins"), base_state("put%a@b%c")
    ('approach_bins', 'grasp_bins', 'put')
    """
    return name.split(SEP, 1)[0].split(GOAL_SEP, 1)[0].split(GUARD_SEP, 1)[0]


def widen_to_copies(x: Any, model: Any) -> Any:
    """``x`` (an expression, a ``Response``, any part of a model) with every ``F.state == 'X'``
    (``!=``, ``in``) widened to the copies of X when FSM F of ``model`` has no state X but
    states split from it: a copy ``X#c...`` or ``X@u...`` counts as X, and ``X#c`` names
    the copies of goal copy ``X#c``. Names of states that exist are left alone. The split
    functions widen the model's own expressions, and a ``Model`` widens its requirements
    (``responses``, from a model file too) when built; this is also for expressions
    written against the unsplit model and given afterwards (``btfsm bound --response``, a
    counterexample's requirement).

    >>> from btfsm import FSM, Edge, Model, State, Primitive, running, success
    >>> from btfsm.expr import parse, to_text
    >>> f = FSM("arm", states=[State("a", "move"), State("b", "move")], initial="a", goals=("g",),
    ...         edges=[Edge("a", "b", "g"), Edge("b", "a", "g")])
    >>> m = Model("m", primitives=[Primitive("move", (running(), success()))], fsms=[f])
    >>> s = split_by_entry(m, "arm", {"a": {"": (0, 1), "b": (0, 2)}})
    >>> to_text(widen_to_copies(parse("arm.state == 'a' or arm.state == 'b'"), s))
    "arm.state == 'a@start' or arm.state == 'a@b' or arm.state == 'b'"
    """
    for f in model.fsms:
        ids = {s.id for s in f.states}
        copies: dict = {}
        for s in f.states:
            head = s.id.split(SEP, 1)[0]
            for name in dict.fromkeys((base_state(s.id), head.split(GUARD_SEP, 1)[0], head)):
                if name != s.id and name not in ids:
                    copies.setdefault(name, []).append(s.id)
        if copies:
            x = _rename_any(x, f"{f.name}.state", copies)
    return x


def copies_named(x: Any, model: Any) -> list:
    """The split copies that ``widen_to_copies(x, model)`` names in place of the split
    states ``x`` names (empty when ``x`` names none), in the order found.

    >>> from btfsm import FSM, Edge, Model, State, Primitive, running, success
    >>> from btfsm.expr import parse
    >>> f = FSM("arm", states=[State("a", "move"), State("b", "move")], initial="a", goals=("g",),
    ...         edges=[Edge("a", "b", "g"), Edge("b", "a", "g")])
    >>> m = Model("m", primitives=[Primitive("move", (running(), success()))], fsms=[f])
    >>> s = split_by_entry(m, "arm", {"a": {"": (0, 1), "b": (0, 2)}})
    >>> copies_named(parse("arm.state == 'a'"), s), copies_named(parse("arm.state == 'b'"), s)
    (['a@start', 'a@b'], [])
    """
    before = set(_constants(x))
    return [c for c in dict.fromkeys(_constants(widen_to_copies(x, model))) if c not in before]


def _constants(x) -> list:
    """The constants of an expression, in the order found."""
    if isinstance(x, Const):
        return [x.value]
    if isinstance(x, tuple):
        return [c for v in x for c in _constants(v)]
    if isinstance(x, Expr):
        return [c for f in dataclasses.fields(cast(Any, x)) for c in _constants(getattr(x, f.name))]
    return []


def entries_of(fsm) -> dict:
    """``{state: {predecessor: (direct, goals)}}``: how the token can enter each state;
    ``""`` is the start of the initial state. ``direct``: entered by a direct edge only
    (the predecessor's run was halted), False when some edge fires after it finished."""
    out: dict = {s.id: {} for s in fsm.states}
    out[fsm.initial][""] = (False, ())
    for e in fsm.edges:
        had = out[e.target].get(e.source)
        goals = tuple(dict.fromkeys((had[1] if had else ()) + e.goals))
        out[e.target][e.source] = ((had[0] if had else True) and e.direct, goals)
    return out


def _widest(durations: dict, s: str, preds) -> tuple:
    """The widest interval ``durations[s]`` gives the entries ``preds``."""
    ivs = [tuple(durations[s][u]) for u in preds]
    return (min(iv[0] for iv in ivs), max(iv[1] for iv in ivs))


def _groups(table: dict, entries: dict, durations: "dict | None" = None) -> dict:
    """{state: [(copy name, duration, predecessors)]} for the states of ``table``; with
    ``durations``, a copy declares the widest interval it gives the copy's entries."""
    out = {}
    for s, by_entry in table.items():
        if s not in entries:
            raise ModelError(f"positions.{s}", "no such state")
        missing = [u or "(start)" for u in entries[s] if u not in by_entry]
        if missing:
            raise ModelError(f"positions.{s}", f"no duration for the entry from {', '.join(missing)}")
        groups: dict = {}
        for u in entries[s]:  # None: a copy of its own, keeping the state's duration
            groups.setdefault(("own", u) if by_entry[u] is None else tuple(by_entry[u]), []).append(u)
        if len(groups) == 1:
            (dur, preds), = groups.items()
            dur = None if dur[0] == "own" else dur if durations is None else _widest(durations, s, preds)
            out[s] = [(s, dur, preds)]
            continue
        named = []
        for dur, preds in groups.items():
            tag = preds[0] or "start"
            dur = None if dur[0] == "own" else dur if durations is None else _widest(durations, s, preds)
            named.append((f"{s}{SEP}{tag}" + (f"+{len(preds) - 1}" if len(preds) > 1 else ""), dur, preds))
        out[s] = named
    return out


def _rename_compare(e, field: str, copies: dict):
    """``e`` (a comparison) with ``field == 's'`` (either side, ``==`` or ``!=``) widened to the copies of s."""
    for a, b in ((e.left, e.right), (e.right, e.left)):
        if isinstance(a, Name) and a.id == field and isinstance(b, Const) and b.value in copies:
            names = copies[b.value]
            if len(names) == 1:
                return Compare(e.op, a, Const(names[0]))
            any_of = BoolOp("or", tuple(Compare("==", a, Const(n)) for n in names))
            return any_of if e.op == "==" else Unary("not", any_of)
    return e


def _rename_any(x, field: str, copies: dict):
    if isinstance(x, Expr):
        if isinstance(x, Compare) and x.op in ("==", "!="):
            return _rename_compare(x, field, copies)
        changes = {f.name: _rename_any(getattr(x, f.name), field, copies) for f in dataclasses.fields(cast(Any, x))}
        if not any(changes[k] is not getattr(x, k) for k in changes):
            return x
        if isinstance(x, BoolOp):  # an 'or' of copies inside an 'or' is one 'or', as the parser reads its text
            return flat(x.op, *changes["args"])
        return dataclasses.replace(cast(Any, x), **changes)
    if isinstance(x, tuple):
        new = tuple(_rename_any(v, field, copies) for v in x)
        return x if all(a is b for a, b in zip(new, x)) else new
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        changes = {}
        for f in dataclasses.fields(x):
            if not f.init:
                continue
            old = getattr(x, f.name)
            new = _rename_any(old, field, copies)
            if new is not old:
                changes[f.name] = new
        return dataclasses.replace(x, **changes) if changes else x
    return x


def _fsm_named(model, fsm: str):
    """FSM ``fsm`` of ``model``, or a ModelError."""
    f = next((x for x in model.fsms if x.name == fsm), None)
    if f is None:
        raise ModelError("positions", f"no FSM named '{fsm}'")
    return f


def _with_fsm(model, new_f, field: str, copies: dict):
    """``model`` with ``new_f`` in place of its FSM of that name, and every other part's
    ``field == 's'`` widened to the copies of s (``copies``: {state: [copy names]})."""
    others = {k: _rename_any(getattr(model, k), field, copies)
              for k in ("tree", "environment", "invariants", "workable", "terminal", "responses")}
    fsms = tuple(new_f if x.name == new_f.name else _rename_any(x, field, copies) for x in model.fsms)
    return dataclasses.replace(model, fsms=fsms, **others)


def split_by_entry(model, fsm: str, table: dict, durations: "dict | None" = None):
    """``model`` with FSM ``fsm``'s states of ``table`` split by entry (see the module text).
    ``durations`` (the same shape as ``table``): the copies are still ``table``'s, each
    declaring the widest interval ``durations`` gives its entries (two tables on one split:
    the same state names, e.g. durations derived under an assumption beside the plain ones).

    >>> from btfsm import FSM, Edge, Model, State, Primitive, running, success
    >>> f = FSM("arm", states=[State("a", "move"), State("b", "move"), State("c", "move")], initial="a",
    ...         goals=("g",), edges=[Edge("a", "b", "g"), Edge("c", "b", "g"), Edge("b", "a", "g"), Edge("a", "c", "g")])
    >>> m = Model("m", primitives=[Primitive("move", (running(), success()))], fsms=[f])
    >>> s = split_by_entry(m, "arm", {"b": {"a": (0, 2), "c": (0, 2)}}, {"b": {"a": (0, 1), "c": (0, 1.5)}})
    >>> [(st.id, st.duration) for st in s.fsms[0].states]
    [('a', None), ('b', (0.0, 1.5)), ('c', None)]
    """
    f = _fsm_named(model, fsm)
    entries = entries_of(f)
    groups = _groups(table, entries, durations)
    copies = {s.id: [n for n, _, _ in groups[s.id]] if s.id in groups else [s.id] for s in f.states}
    entered = {}  # (state, predecessor) -> copy name
    for s, named in groups.items():
        for name, _, preds in named:
            for u in preds:
                entered[(s, u)] = name
    states = []
    for st in f.states:
        if st.id in groups:
            states += [dataclasses.replace(st, id=name, duration=st.duration if dur is None else dur)
                       for name, dur, _ in groups[st.id]]
        else:
            states.append(st)
    field = f"{fsm}.state"
    edges = [dataclasses.replace(_rename_any(e, field, copies), source=src, target=entered.get((e.target, e.source), e.target),
                                 id="")
             for e in f.edges for src in copies[e.source]]
    markers = [dataclasses.replace(_rename_any(m, field, copies), state=src, id="") for m in f.markers for src in copies[m.state]]
    initial = entered.get((f.initial, ""), f.initial)
    new_f = dataclasses.replace(_rename_any(f, field, copies), states=tuple(states), edges=tuple(edges),
                                markers=tuple(markers), initial=initial)
    return _with_fsm(model, new_f, field, copies)


def split_history(model, fsm: str, states):
    """``model`` with each of ``states`` of FSM ``fsm`` split into one copy per entry
    (``s@u``, none merged, durations kept): a second ``split_by_entry`` of the result
    then gives a state's duration by the entry of its predecessor's copy, two states of
    history (docs/verification.md 2.1).

    >>> from btfsm import FSM, Edge, Model, State, Primitive, running, success
    >>> f = FSM("arm", states=[State("a", "move"), State("b", "move"), State("c", "move")], initial="a",
    ...         goals=("g",), edges=[Edge("a", "b", "g"), Edge("c", "b", "g"), Edge("b", "a", "g"), Edge("a", "c", "g")])
    >>> m = Model("m", primitives=[Primitive("move", (running(), success()))], fsms=[f])
    >>> [st.id for st in split_history(m, "arm", ["b"]).fsms[0].states]
    ['a', 'b@a', 'b@c', 'c']
    """
    f = _fsm_named(model, fsm)
    entries = entries_of(f)
    for s in states:
        if s not in entries:
            raise ModelError(f"positions.{s}", "no such state")
    return split_by_entry(model, fsm, {s: dict.fromkeys(entries[s]) for s in states})


def split_by_goal(model, fsm: str, classes: dict):
    """``model`` with FSM ``fsm``'s states of ``classes`` split by the goal their run
    serves: ``classes`` is ``{state: {class name: (goals...)}}`` (every goal the state
    serves in exactly one class). The copy ``s#c`` runs only for the goals of class c:
    the edges entering s for a goal of c enter ``s#c``; a request for a goal of another
    class c' moves the token from ``s#c`` to ``s#c'`` by a direct edge (after s's own
    direct edges for that goal), which halts the run and starts it afresh, as a
    withdrawn request's next run of s does (docs/semantics.md 5). Replies are unchanged:
    every copy has s's markers.

    >>> from btfsm import FSM, Edge, Model, State, Primitive, running, success
    >>> f = FSM("arm", states=[State("a", "move"), State("b")], initial="a", goals=("g", "h"),
    ...         edges=[Edge("a", "b", ("g", "h")), Edge("b", "a", ("g", "h"))])
    >>> m = Model("m", primitives=[Primitive("move", (running(), success()))], fsms=[f])
    >>> s = split_by_goal(m, "arm", {"a": {"G": ("g",), "H": ("h",)}})
    >>> [st.id for st in s.fsms[0].states]
    ['a#G', 'a#H', 'b']
    >>> sorted((e.source, e.target, e.goals, e.direct) for e in s.fsms[0].edges)[:3]
    [('a#G', 'a#H', ('h',), True), ('a#G', 'b', ('g',), False), ('a#H', 'a#G', ('g',), True)]
    """
    f = _fsm_named(model, fsm)
    ids = {st.id for st in f.states}

    def goals_of(e):
        return tuple(f.goals) if "*" in e.goals else tuple(e.goals)

    cls = {}  # state -> {goal: copy name}
    for s, groups in classes.items():
        if s not in ids:
            raise ModelError(f"positions.{s}", "no such state")
        cls[s] = {g: f"{s}{GOAL_SEP}{c}" for c, goals in groups.items() for g in goals}
    copies = {st.id: list(dict.fromkeys(cls[st.id].values())) if st.id in cls else [st.id] for st in f.states}
    states = []
    for st in f.states:
        states += [dataclasses.replace(st, id=n) for n in copies[st.id]] if st.id in cls else [st]
    field = f"{fsm}.state"
    edges = []
    for st in f.states:
        own = [e for e in f.edges if e.source == st.id]
        for src in copies[st.id]:
            out = []
            mine = {g for g, n in cls.get(st.id, {}).items() if n == src}
            for e in own:
                goals = goals_of(e)
                if st.id in cls:  # a copy keeps its class's goals; the others switch copies first
                    goals = tuple(g for g in goals if g in mine or g not in cls[st.id])
                    if not goals:
                        continue
                    e = dataclasses.replace(e, goals=goals)
                if e.target in cls:  # one edge per copy of the target its goals enter
                    by: dict = {}
                    for g in goals:
                        by.setdefault(cls[e.target].get(g, copies[e.target][0]), []).append(g)
                    out += [dataclasses.replace(_rename_any(e, field, copies), source=src, target=t, goals=tuple(gs), id="")
                            for t, gs in by.items()]
                else:
                    out.append(dataclasses.replace(_rename_any(e, field, copies), source=src, id=""))
            if st.id in cls:  # a request of another class moves to its copy, after s's own direct edges
                first = [x for x in out if x.direct]
                switch: dict = {}
                for g, n in cls[st.id].items():
                    if n != src:
                        switch.setdefault(n, []).append(g)
                out = first + [Edge(src, n, tuple(gs), direct=True) for n, gs in switch.items()] + \
                    [x for x in out if not x.direct]
            edges += out
    markers = [dataclasses.replace(_rename_any(m, field, copies), state=src, id="") for m in f.markers
               for src in copies[m.state]]
    new_f = dataclasses.replace(f, states=tuple(states), edges=tuple(edges), markers=tuple(markers),
                                initial=copies[f.initial][0])
    return _with_fsm(model, new_f, field, copies)


def substitute(x, values: dict):
    """Expression ``x`` with every variable named in ``values`` replaced by its expression
    there: what ``x`` reads after simultaneous effects ``values`` (``{name: Expr}``).

    >>> from btfsm.expr import parse, to_text
    >>> to_text(substitute(parse("n > 0 and not b"), {"n": parse("n - 1"), "b": parse("false")}))
    'n - 1 > 0 and not false'
    """
    if isinstance(x, Name):
        return values.get(x.id, x)
    if isinstance(x, Expr):
        changes = {f.name: substitute(getattr(x, f.name), values) for f in dataclasses.fields(cast(Any, x))}
        return dataclasses.replace(cast(Any, x), **changes)
    if isinstance(x, tuple):
        return tuple(substitute(v, values) for v in x)
    return x


def split_by_guard(model, fsm: str, guards: dict):
    """``model`` with FSM ``fsm``'s states of ``guards`` split by the model's variables:
    ``guards`` is ``{state: {tag: guard}}``, the guards of a state disjoint and together
    always true. The copy ``s%tag`` is entered when its guard holds in the state the
    entering edge leads to (the guard read after the edge's effects: each edge into s
    becomes one edge per copy, in its place, guarded by ``edge guard and copy guard``
    with the edge's effects substituted; a guard ``false`` adds no edge), so a copy's duration may depend on what the
    variables say when its run starts (the token does not leave s while it runs, and only
    the FSM's edges change the variables a copy's guard reads in the models this is for:
    that is the caller's to ensure). Edges and markers leaving s are copied for every copy.
    The initial state cannot be split. Same runs as the original up to the renaming
    (``tests/test_positions.py`` checks it against explicit exploration).

    >>> from btfsm import FSM, Edge, Int, Model, State, Primitive, running, success
    >>> from btfsm.expr import to_text
    >>> f = FSM("arm", states=[State("a", "move"), State("b", "move")], initial="a", goals=("g",),
    ...         edges=[Edge("a", "b", "g", effects={"n": "n + 1 if n < 2 else 0"}), Edge("b", "a", "g")])
    >>> m = Model("m", variables=[Int("n", 0, 2)], primitives=[Primitive("move", (running(), success()))], fsms=[f])
    >>> s = split_by_guard(m, "arm", {"b": {"lo": "n == 0", "hi": "n > 0"}})
    >>> [st.id for st in s.fsms[0].states]
    ['a', 'b%lo', 'b%hi']
    >>> [(e.source, e.target, to_text(e.guard)) for e in s.fsms[0].edges if e.source == "a"]
    [('a', 'b%lo', '(n + 1 if n < 2 else 0) == 0'), ('a', 'b%hi', '(n + 1 if n < 2 else 0) > 0')]
    """
    from .expr import as_expr

    f = _fsm_named(model, fsm)
    ids = {st.id for st in f.states}
    for s in guards:
        if s not in ids:
            raise ModelError(f"positions.{s}", "no such state")
        if s == f.initial:
            raise ModelError(f"positions.{s}", "the initial state cannot be split by guard")
    copies = {st.id: [f"{st.id}{GUARD_SEP}{t}" for t in guards[st.id]] if st.id in guards else [st.id]
              for st in f.states}
    field = f"{fsm}.state"
    tagged = {s: [(f"{s}{GUARD_SEP}{t}", _rename_any(as_expr(g), field, copies)) for t, g in by.items()]
              for s, by in guards.items()}
    states = []
    for st in f.states:
        states += [dataclasses.replace(st, id=n) for n in copies[st.id]] if st.id in guards else [st]
    edges = []
    for e in f.edges:
        e = _rename_any(e, field, copies)
        for src in copies[e.source]:
            if e.target not in tagged:
                edges.append(dataclasses.replace(e, source=src, id=""))
                continue
            values = dict(e.effects)
            for name, g in tagged[e.target]:
                if isinstance(g, Const) and g.value is False:
                    continue  # never entered this way
                g = substitute(g, values)
                edges.append(dataclasses.replace(e, source=src, target=name, id="",
                                                 guard=g if e.guard is None else flat("and", e.guard, g)))
    markers = [dataclasses.replace(_rename_any(m, field, copies), state=src, id="") for m in f.markers
               for src in copies[m.state]]
    new_f = dataclasses.replace(f, states=tuple(states), edges=tuple(edges), markers=tuple(markers))
    return _with_fsm(model, new_f, field, copies)


def split_deeper(model, fsm: str, table: dict, deep: dict, cond: "tuple | None" = None):
    """A third state of history where it pays: ``model`` (split by ``split_history``, before
    ``split_by_entry(model, fsm, table)``) with each state of ``deep`` split again by the
    copy it is entered from, and ``table`` rewritten for the result: ``(model, table)``.

    ``deep``: ``{state: {entry: [group, {successor: max seconds}]}}``; the entries of one
    group share a copy of the state (named as ``split_by_entry`` names it), which declares
    the widest interval ``table[state]`` gives them; a successor's row for that copy is
    ``(0, the greatest seconds of its group's entries)``. So a successor entered from a run
    halted on its way knows where that run began (docs/verification.md 2.1). States and
    entries of ``deep`` the model does not have are left out. ``cond``: ``(table, deep)``
    of another derivation of the same split (its seconds on these groups): then
    ``(model, table, its table)``, the model's copies declaring its seconds (two tables on
    one split, as ``split_by_entry``'s ``durations``).

    >>> from btfsm import FSM, Edge, Model, State, Primitive, running, success
    >>> f = FSM("arm", states=[State("a", "move"), State("b", "move"), State("c", "move")], initial="a",
    ...         goals=("g",), edges=[Edge("a", "b", "g"), Edge("c", "b", "g"), Edge("b", "c", "g"), Edge("c", "a", "g")])
    >>> m = Model("m", primitives=[Primitive("move", (running(), success()))], fsms=[f])
    >>> s, t = split_deeper(m, "arm", {"b": {"a": (0, 1), "c": (0, 2)}, "c": {"b": (0, 3)}},
    ...                     {"b": {"a": [0, {"c": 1.0}], "c": [1, {"c": 2.5}]}})
    >>> [st.id for st in s.fsms[0].states], t
    (['a', 'b@a', 'b@c', 'c'], {'c': {'b@a': (0.0, 1.0), 'b@c': (0.0, 2.5)}})
    >>> [(st.id, st.duration) for st in split_by_entry(s, "arm", t).fsms[0].states]
    [('a', None), ('b@a', (0.0, 1.0)), ('b@c', (0.0, 2.0)), ('c@b@a', (0.0, 1.0)), ('c@b@c', (0.0, 2.5))]
    """
    f = _fsm_named(model, fsm)
    entries = entries_of(f)
    deep = {u: rows for u, rows in deep.items() if u in entries}
    groups = {u: {w: (0, g) for w, (g, _) in rows.items() if w in entries[u]} for u, rows in deep.items()}
    split = split_by_entry(model, fsm, groups, {u: (cond[0] if cond else table)[u] for u in groups})
    copies = {u: [(name, preds) for name, _, preds in named] for u, named in _groups(groups, entries).items()}
    out = []
    for tab, dp in ((table, deep),) + ((cond,) if cond is not None else ()):
        new = {s: dict(rows) for s, rows in tab.items() if s not in groups}
        for u, named in copies.items():
            for name, preds in named:
                most: dict = {}
                for w in preds:
                    for y, hi in dp[u][w][1].items():
                        most[y] = max(most.get(y, 0.0), hi)
                for y, hi in most.items():
                    if y in new:
                        new[y].pop(u, None)
                        new[y][name] = (0.0, hi)
        out.append(new)
    return (split, *out)


def requested_goals(model, fsm: str) -> set:
    """The goals of FSM ``fsm`` that some skill request of ``model`` asks for (no other goal
    ever runs one of its states: docs/semantics.md 5)."""
    return {n.goal for n in model.requests_of(fsm)}


def check_requests(model, fsm: str, requested) -> None:
    """ValueError when ``model`` asks FSM ``fsm`` for a goal a derivation (its ``requested``
    goals; empty: not recorded) assumed no request asks for."""
    more = sorted(requested_goals(model, fsm) - set(requested)) if requested else []
    if more:
        raise ValueError(f"{model.name} requests {', '.join(more)} of FSM '{fsm}', which the derivation's "
                         "model never asks for (its copies' runs for them are not bounded): derive it for this model")
