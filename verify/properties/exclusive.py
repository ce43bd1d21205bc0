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
        return Result(NAME, True, None, ["no resources declared (the model's 'resources:' key): nothing to check"])
    groups = ", ".join(f"{name} ({', '.join(members)})" for name, members in model.resources)
    ts = ctx.model_ts()
    found = [(t, v) for t, vs in ts.violations for v in vs if v[0] == "exclusive"]
    if not found:
        notes = [f"resources: {groups}"]
        if not ts.complete:
            notes.append(f"{budget_hit(ts)}: not decided")
        return Result(NAME, True if ts.complete else None, None, notes)
    t, v = min(found, key=lambda p: (int(ts.src[p[0]]), p[0]))
    _, res, leaf, other, when = v
    n_ticks = len({t for t, _ in found})
    notes = [f"resources: {groups}",
             f"{n_ticks} transition(s) run two leaves of one resource at once "
             f"({', '.join(sorted({p[1][1] for p in found}))})"]
    if when == "start":
        text = (f"in the last tick '{leaf}' started while '{other}' was still running; both use resource "
                f"'{res}'. A reactive node that starts a new child before it halts the running one "
                "(BehaviorTree.CPP issue #1031; semantics btcpp/pytrees) does this; btfsm's halt-before-start "
                "halts the running branch first. Leaves that cannot return RUNNING start on every tick.")
        summary = f"'{leaf}' can start while '{other}' runs (both use '{res}')"
    else:
        text = (f"at the end of the last tick '{leaf}' and '{other}' are both running; both use resource "
                f"'{res}' (a Parallel over them, or leaves in different subtrees)")
        summary = f"'{leaf}' and '{other}' can both be running (both use '{res}')"
    viol = {"kind": "exclusive", "resource": res, "node": leaf, "other": other, "when": when, "text": text}
    ce = path_counterexample(ts, ts.path_to(int(ts.src[t])) + [t], NAME, summary, viol)
    return Result(NAME, False, ce, notes)
