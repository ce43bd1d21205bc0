"""``exclusive-actions``: leaves that share a resource never run at once.

A model declares resources (``Model.resources``, the file's ``resources:`` key): groups
of Action and SkillRequest nodes that drive one physical thing (an arm, a gripper). The
step function reports (docs/semantics.md, rule 'Exclusive resources') a leaf of a group
that starts (is ticked while idle; a leaf that cannot return RUNNING starts on every
tick) while another leaf of the group is running, and two leaves of a group both running
at the end of a tick. This property holds when no reachable tick reports either. It is
BehaviorTree.CPP's issue #1031 hazard: under ``semantics: btcpp`` a reactive fallback
starts the new async child before it halts the old one; btfsm's halt-before-start
(docs/semantics.md section 4) halts first.

The counterexample is a shortest one (states are numbered breadth first, so the tick
from the state of least index reaching a violation ends a shortest path), and replays
with ``btfsm replay``.

>>> from btfsm.verify.properties import Context
>>> from btfsm.models.registry import load_builtin
>>> check(Context(load_builtin("ariac-preemptive"))).holds
True
"""
from __future__ import annotations

from ..counterexample import path_counterexample
from .base import Result, budget_hit

__all__ = ["check", "NAME"]

NAME = "exclusive-actions"


def check(ctx) -> Result:
    model = ctx.model
    if not model.resources:
        return Result(NAME, True, None, [], not_applicable="no 'resources:' declared")
    groups = ", ".join(f"{name} ({', '.join(members)})" for name, members in model.resources)
    ts = ctx.model_ts()
    found = [(t, v) for t, vs in ts.violations for v in vs if v[0] == "exclusive"]
    if not found:
        notes = [f"resources: {groups}"]
        if not ts.complete:
            notes.append(f"{budget_hit(ts)}: not decided")
        return Result(NAME, True if ts.complete else None, None, notes)
    t, v = min(found, key=lambda p: (ts.source(p[0]), p[0]))
    _, res, leaf, other, when = v
    n_ticks = len({t for t, _ in found})
    notes = [f"resources: {groups}",
             f"{n_ticks} transition(s) run two leaves of one resource at once "
             f"({', '.join(sorted({p[1][1] for p in found}))})"]
    why = _why(model, leaf, other)
    if when == "start":
        text = f"in the last tick '{leaf}' started while '{other}' was still running; both use resource '{res}'. {why}"
        summary = f"'{leaf}' can start while '{other}' runs (both use '{res}')"
    else:
        text = f"at the end of the last tick '{leaf}' and '{other}' are both running; both use resource '{res}'. {why}"
        summary = f"'{leaf}' and '{other}' can both be running (both use '{res}')"
    viol = {"kind": "exclusive", "resource": res, "node": leaf, "other": other, "when": when, "text": text}
    ce = path_counterexample(ts, ts.path_to(ts.source(t)) + [t], NAME, summary, viol)
    return Result(NAME, False, ce, notes)


def _why(model, a: str, b: str) -> str:
    """Why two leaves can overlap, from their lowest common ancestor."""
    from btfsm.bt import Parallel, walk

    parent: dict = {}
    for _, root in model.roots():
        for n in walk(root):
            for c in n.children_of():
                parent[c.name] = n
    x: "str | None"
    y: "str | None"
    chain, x = [], a
    while x is not None:
        chain.append(x)
        x = parent[x].name if x in parent else None
    y = b
    while y is not None and y not in chain:
        y = parent[y].name if y in parent else None
    if y is None:
        return ("They are in different trees (an FSM state's subtree and the tree that requests it, or two "
                "subtrees): nothing halts one before the other starts.")
    node = next(n for _, r in model.roots() for n in walk(r) if n.name == y)
    if isinstance(node, Parallel):
        return f"Their lowest common ancestor '{y}' is a Parallel: its children run side by side and never halt each other."
    if model.semantics != "btfsm":
        return (f"Under {model.semantics} semantics '{y}' starts a new child before it halts the running one "
                "(BehaviorTree.CPP issue #1031); btfsm's halt before start (the default profile) halts the "
                "running branch first.")
    return ("An action that cannot return RUNNING halts nothing before it is ticked (docs/semantics.md section 4): "
            "it runs on every tick beside the running one.")
