"""``lints``: warnings, never a failure.

The model's own warnings (``model.warnings``: structurally unreachable states, shadowed
or impossible edges) and the program's (``model.program.lints``), plus what exploration
shows: FSM states the token never visits (at the end of a tick, or passing through within
one: the ends of a fired edge), edges and markers that never fire, and goals no
SkillRequest requests; and tree coverage (dead branches): tree nodes that are never ticked
in any reachable state, and leaves that are ticked but never succeed although their
declaration allows it, each with the shortest run that shows why (``--json``:
``info.warnings[].run``). For a model with a tree the explored model is used when it has at
most ``FIRE_LIMIT`` transitions (every transition is re-run once with recording on);
otherwise, and for models without a tree, each FSM as an open system (which
over-approximates what the tree can request), and tree coverage is not computed.
"""
from __future__ import annotations

import numpy as np

from btfsm.bt import Action, Condition, SkillRequest
from btfsm.status import Status

from ..explore import successor_scripts
from .base import Result

RUNNING, SUCCESS, FAILURE = int(Status.RUNNING), int(Status.SUCCESS), int(Status.FAILURE)

__all__ = ["check", "uses_model", "FIRE_LIMIT"]

FIRE_LIMIT = 100_000


def _fired(ts, wanted: set, ticks: "dict | None" = None) -> set:
    """(fsm, element id) of the ``wanted`` edges and markers that fire in some transition
    of ts (stops as soon as all of them have been seen). ``ticks``, when given, is filled
    with tree coverage: ``(node, status) -> (state, script)`` of the first tick (in
    breadth-first order, so after a shortest run) in which the node returned that status;
    the search then goes through every transition."""
    out: set = set()
    order = range(ts.expanded) if ticks is not None else _likely_first(ts, wanted, out)
    for i in order:
        for script, st, _o in successor_scripts(ts, ts.full_state(i)):
            if st is not None:
                for e in st.events or ():
                    if e[0] == "fire":
                        out.add((e[1], e[2]))
                    elif ticks is not None and e[0] == "status" and (e[1], e[2]) not in ticks:
                        ticks[(e[1], e[2])] = (i, script)
        if wanted <= out and ticks is None:
            break
    return out


_PREFIX, _TRIES = 256, 64


def _likely_first(ts, wanted: set, out: set):
    """The expanded states of an FSM's open system in an order that finds the ``wanted``
    elements' firings early: the first ``_PREFIX`` states, then for each element not seen
    firing yet up to ``_TRIES`` states (breadth-first order) whose token is on the
    element's source and where its guard holds (read on the state before the tick), then
    every state not tried yet. Each state comes once, so a search that runs to the end
    sees every state; only when its FSM's states run no subtree (then only its own
    elements fire, and the result does not depend on the order) is the order changed:
    an element whose guard needs a deep state (pick/place's ``reserve_home``, ``bat ==
    0``) is then found in a few states instead of tens of thousands."""
    from .base import evaluate

    n = ts.expanded
    f = ts.model.fsm(ts.fsm) if ts.kind == "fsm" and ts.fsm is not None else None
    if f is None or any(st.subtree is not None for st in f.states) or n <= _PREFIX:
        yield from range(n)
        return
    yield from range(_PREFIX)
    tried = np.zeros(n, bool)
    tried[:_PREFIX] = True
    prog = ts.model.program
    _, ids, tok, _, _ = prog.fsm_info[prog.fsm_index[f.name]]
    col = ts.column(tok)[:n]
    for el in (*f.edges, *f.markers):
        if (f.name, el.id) in out or (f.name, el.id) not in wanted:
            continue
        on = col == ids.index(el.source if hasattr(el, "source") else el.state)
        if el.guard is not None:
            try:
                on &= evaluate(ts, el.guard)[:n]
            except Exception:  # noqa: BLE001 - a guard over names the model scope lacks: token only (an order, not a verdict)
                pass
        picks = np.flatnonzero(on & ~tried)[:_TRIES]
        tried[picks] = True
        yield from picks.tolist()
    for a in range(0, n, 1 << 16):
        yield from (np.flatnonzero(~tried[a:a + (1 << 16)]) + a).tolist()


def _can_succeed(prog, node) -> bool:
    """Whether a leaf's declaration lets it return SUCCESS (composites and decorators: not
    judged, their children are)."""
    if isinstance(node, Action):
        return SUCCESS in prog.prims[node.primitive].statuses()
    return isinstance(node, (Condition, SkillRequest))


def dead_branches(ts, ticks: dict) -> list:
    """Tree coverage lints from ``ticks`` (``_fired``): ``(element, text, run)`` for each
    topmost node that is never ticked in ``ts`` (its descendants are dead with it) and
    each leaf that is ticked but never succeeds although its declaration allows it. ``run``
    is the shortest run that shows why, as counterexample JSON: up to and including the
    first tick in which the dead node's parent is ticked (it stops before the node), or
    in which the leaf is ticked (it fails or runs)."""
    from ..counterexample import path_counterexample

    model, prog = ts.model, ts.model.program
    ticked = {n for n, _ in ticks}
    out, dead = [], set()

    def run(first, summary, node, parent=None):
        i, script = first
        viol = {"kind": "dead-branch", "node": node, "parent": parent, "text": summary}
        return path_counterexample(ts, ts.path_to(i), "lints", summary, viol, final_script=script).to_json()

    for _path, root in model.roots():
        stack = [(root, None)]
        while stack:
            n, parent = stack.pop()
            if n.name not in ticked:
                dead.add(n.name)
                why = "its parent is never ticked either" if parent is None else (
                    f"'{parent.name}' is ticked but never reaches it")
                if parent is not None:
                    kids = parent.children_of()
                    stuck = [c.name for c in kids[:kids.index(n)] if c.name in ticked and (c.name, SUCCESS) not in ticks]
                    if stuck:
                        why += f"; before it, {', '.join(repr(x) for x in stuck)} never succeed{'s' if len(stuck) == 1 else ''}"
                first = None if parent is None else next(
                    (ticks[(parent.name, st)] for st in (RUNNING, SUCCESS, FAILURE) if (parent.name, st) in ticks), None)
                text = f"never ticked in any reachable state ({why})"
                out.append((f"tree.{n.name}", text,
                            None if first is None else run(first, f"'{n.name}': {text}", n.name, parent.name)))
                continue  # its descendants are dead with it
            if not n.children_of() and (n.name, SUCCESS) not in ticks and _can_succeed(prog, n):
                first = min(ticks[(n.name, st)] for st in (RUNNING, FAILURE) if (n.name, st) in ticks)
                text = "ticked but never succeeds in any reachable state"
                out.append((f"tree.{n.name}", text, run(first, f"'{n.name}': {text}", n.name)))
            stack.extend((c, n) for c in reversed(n.children_of()))
    return out


def uses_model(ctx) -> bool:
    """Whether the lints read the explored model (it has a tree, is complete and has at most
    ``FIRE_LIMIT`` transitions) rather than each FSM's open system."""
    if ctx.model.tree is None:
        return False
    transitions, complete = ctx.model_size()
    return complete and transitions <= FIRE_LIMIT


def check(ctx) -> Result:
    model, prog = ctx.model, ctx.model.program
    warnings = [(el, text) for el, text in model.warnings] + [(el, text) for el, text in prog.lints]
    seen = {el for el, _ in warnings}
    use_model = uses_model(ctx)
    fired, visited, coverage = set(), {}, []
    wanted = {(f.name, x.id) for f in model.fsms for x in (*f.edges, *f.markers)}
    if use_model:
        ts = ctx.model_ts()
        ticks: dict = {}
        fired = _fired(ts, wanted, ticks)
        coverage = dead_branches(ts, ticks)
        for f, ids, tok, _, _ in prog.fsm_info:
            visited[f.name] = (ts, {ids[int(v)] for v in np.unique(ts.column(tok))}, "in the model")
    else:
        for f in model.fsms:
            ts = ctx.fsm_ts(f.name)
            if not ts.complete:
                continue
            fired |= _fired(ts, {w for w in wanted if w[0] == f.name})
            tok = prog.fsm_info[prog.fsm_index[f.name]][2]
            ids = prog.fsm_info[prog.fsm_index[f.name]][1]
            visited[f.name] = (ts, {ids[int(v)] for v in np.unique(ts.column(tok))}, "even as an open system")
    found = []
    for f in model.fsms:
        if f.name not in visited:
            continue
        _, states, where = visited[f.name]
        # a state the token only passes through within a tick (direct edges) is reached too
        states = states | {x for e in f.edges if (f.name, e.id) in fired for x in (e.source, e.target)}
        for st in f.states:
            el = f"fsms.{f.name}.states.{st.id}"
            if st.id not in states and el not in seen:
                found.append((el, f"state '{st.id}' is never reached {where}"))
        for e in f.edges:
            el = f"fsms.{f.name}.edges.{e.id}"
            if (f.name, e.id) not in fired and el not in seen:
                found.append((el, f"edge '{e.id}' never fires {where}"))
        for m in f.markers:
            el = f"fsms.{f.name}.markers.{m.id}"
            if (f.name, m.id) not in fired and el not in seen:
                found.append((el, f"marker '{m.id}' never fires {where}"))
    if model.tree is not None:
        from ..explore import requests_of

        for f in model.fsms:
            asked = {n.goal for n in requests_of(model, f.name)}
            for g in f.goals:
                if g not in asked and not (f.retarget == "withdraw" and g == f.withdraw_goal and asked):
                    found.append((f"fsms.{f.name}.goals", f"goal '{g}' is never requested by a SkillRequest"))
    allw = warnings + found + [(el, text) for el, text, _ in coverage]
    runs = {el: r for el, _, r in coverage if r is not None}
    notes = [f"{el}: {text}" for el, text in allw]
    return Result("lints", True, None, notes, {"warnings": [{"element": el, "text": text, **(
        {"run": runs[el]} if el in runs else {})} for el, text in allw]})
