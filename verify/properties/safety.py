"""Safety properties found on the explored states and transitions.

* ``invariants``: each user invariant holds in every reachable state (model level).
* ``contracts``: no reachable tick has a SkillRequest reply SUCCESS while its ``post`` is
  false, none has two requests use one FSM at once (a request refused as ``busy``,
  docs/semantics.md rule 'Conflict'), and every tick returns: under ``semantics: btcpp``
  with ``tick: once`` BehaviorTree.CPP's ``tickOnce()`` can re-tick the root for ever
  (``tick-loop``, rule 'tickOnce') (``Step.violations``; model level).
* ``domain``: no effect writes outside its variable's domain. Model level; for a model
  without a tree (whose FSMs never step at model level) also each FSM as an open system.

A violation found in a partial exploration (state budget hit) is still a real one: its
path exists. Only "holds" needs the whole state space.
"""
from __future__ import annotations

import numpy as np

from ..counterexample import path_counterexample
from .base import Result, evaluate, budget_hit

__all__ = ["check_invariants", "check_contracts", "check_domain"]


def _undecided(ts) -> "bool | None":
    return True if ts.complete else None


def check_invariants(ctx) -> Result:
    model = ctx.model
    if not model.invariants:
        return Result("invariants", True, None, [], not_applicable="no invariant declared")
    ts = ctx.model_ts()
    first, notes, counts = None, [], {}
    for name, expr in model.invariants:
        bad = np.flatnonzero(~evaluate(ts, expr))
        counts[name] = int(bad.size)
        if bad.size:
            notes.append(f"invariant '{name}' is false in {bad.size} reachable state(s)")
            if first is None or bad[0] < first[0]:
                first = (int(bad[0]), name, expr)
    if first is None:
        return Result("invariants", _undecided(ts), None,
                      notes + ([] if ts.complete else [f"{budget_hit(ts)}: not decided"]), {"violations": counts})
    i, name, expr = first
    viol = {"kind": "invariant", "name": name, "text": f"invariant '{name}' ({expr}) is false here"}
    ce = path_counterexample(ts, ts.path_to(i), "invariants", f"invariant '{name}' can be broken", viol)
    return Result("invariants", False, ce, notes, {"violations": counts})


def check_contracts(ctx) -> Result:
    ts = ctx.model_ts()
    found = [(t, v) for t, vs in ts.violations for v in vs if v[0] in ("post", "busy", "tick-loop")]
    if not found:
        return Result("contracts", _undecided(ts), None, [] if ts.complete else [f"{budget_hit(ts)}: not decided"])
    posts = [p for p in found if p[1][0] == "post"]
    busy = [p for p in found if p[1][0] == "busy"]
    loops = [p for p in found if p[1][0] == "tick-loop"]
    t, v = min(found, key=lambda p: (ts.source(p[0]), p[0]))
    notes = []
    if loops:
        notes.append(f"{len(loops)} transition(s) whose tickOnce() never returns (wake-up re-ticks in a loop)")
    if posts:
        notes.append(f"{len(posts)} transition(s) reply SUCCESS with post false at {', '.join(sorted({v[1] for _, v in posts}))}")
    if busy:
        notes.append(f"{len(busy)} transition(s) with two requests using one FSM at once (refused: "
                     f"{', '.join(sorted({v[1] for _, v in busy}))})")
    if v[0] == "tick-loop":
        viol = {"kind": "tick-loop", "node": v[1],
                "text": ("in the last tick BehaviorTree.CPP's tickOnce() never returns: a Retry, Repeat or "
                         "SequenceWithMemory emits a wake-up signal and the root returns RUNNING on every re-tick, "
                         "from a state it had before (docs/semantics.md 8.1, rule 'tickOnce'); tick it with "
                         "tickExactlyOnce() (tick: exactly-once), or change the tree")}
        summary = f"tickOnce() of '{v[1]}' can loop for ever (the tick never returns)"
    elif v[0] == "post":
        viol = {"kind": "contract", "node": v[1],
                "text": f"'{v[1]}' replied SUCCESS in the last tick while its post-condition is false"}
        summary = f"SkillRequest '{v[1]}' can reply SUCCESS with its post-condition false"
    else:
        viol = {"kind": "conflict", "node": v[1], "fsm": v[2],
                "text": (f"in the last tick '{v[1]}' was refused (FAILURE, 'busy'): another request used FSM "
                         f"'{v[2]}' in the same tick while '{v[1]}' was running or the other one was; "
                         "one FSM serves one request at a time (docs/semantics.md, rule 'Conflict'): "
                         "put the requests in sequence, or give each its own FSM")}
        summary = f"SkillRequest '{v[1]}' and another request use FSM '{v[2]}' at the same time"
    ce = path_counterexample(ts, ts.path_to(ts.source(t)) + [t], "contracts", summary, viol)
    return Result("contracts", False, ce, notes)


def check_domain(ctx) -> Result:
    model = ctx.model
    systems = [ctx.model_ts()]
    if model.tree is None:
        systems += [ctx.fsm_ts(f.name) for f in model.fsms]
    notes, worst, undecided = [], None, False
    for ts in systems:
        undecided |= not ts.complete
        if ts.errors:
            e = min(ts.errors, key=lambda e: e.state)
            where = "model" if ts.kind == "model" else f"FSM {ts.fsm}"
            notes.append(f"{where}: {len(ts.errors)} tick(s) write outside a domain")
            d = len(ts.path_to(e.state))
            if worst is None or d < worst[0]:
                worst = (d, ts, e)
    if worst is None:
        return Result("domain", None if undecided else True, None, [f"{budget_hit(ts)}: not decided"] if undecided else [])
    _, ts, e = worst
    viol = {"kind": "domain", "var": e.var, "value": e.value, "where": e.where, "text": f"the last tick fails: {e.message}"}
    ce = path_counterexample(ts, ts.path_to(e.state), "domain", f"{e.where} writes {e.var} = {e.value}, outside its domain",
                             viol, final_script=e.script)
    return Result("domain", False, ce, notes)
