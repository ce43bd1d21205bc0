"""``goal-reachability``: every goal that can be requested can still succeed.

Two levels (``Context.goal_level``, ``btfsm check --goal-level``):

* ``open`` (default): each FSM as an open system (``btfsm.verify.explore.explore_fsm``).
  For every reachable state s and every goal g that can be requested in s (g is requested
  by some SkillRequest whose ``pre`` can hold there, or by any request for a model without
  tree), a SUCCESS reply to g must be reachable from s while g stays held: along a
  sequence of g-requests replying RUNNING, then one replying SUCCESS, with everything else
  (environment, free inputs, parameters, outcomes) chosen some way. Decided per goal by
  backward reachability inside the sub-system of g-requests. Only ``pre`` restricts the
  requests: a Condition in front of a SkillRequest in the tree is not seen.
* ``tree``: the requests the tree actually makes, in the explored model. For every
  reachable model state s from which some tick requests g of FSM f (the FSM is driven
  toward g, or a SkillRequest of g replies RUNNING or SUCCESS), a tick in which a
  SkillRequest of g on f replies SUCCESS must be reachable from s (the tree chooses what
  to request on the way). Needs the whole model explored, with at most
  ``TREE_LIMIT`` transitions (each is re-run once); a model without tree is judged at
  ``open`` level.
"""
from __future__ import annotations

import numpy as np

from btfsm.status import Status

from ..counterexample import path_counterexample
from ..explore import successor_scripts
from ..system import cyclic_states, forward_reach, reverse_reach
from ..treegoals import tree_goal_failures
from .base import Result, budget_hit

__all__ = ["check", "goal_failures", "tree_goal_failures", "TREE_LIMIT", "LEVELS"]

TREE_LIMIT = 200_000
LEVELS = ("open", "tree")

RUNNING, SUCCESS, FAILURE = int(Status.RUNNING), int(Status.SUCCESS), int(Status.FAILURE)


def goal_failures(ts) -> dict:
    """goal index -> indices of states where it can be requested but can never succeed."""
    out = {}
    for g in ts.open.goals:  # masks over the edge codes, one byte per transition (TransitionSystem.where)
        requestable = ts.any_out(ts.where(lambda label, status, goal: goal == g))
        target = ts.any_out(ts.where(lambda label, status, goal: (goal == g) & (status == SUCCESS)))
        good = reverse_reach(ts, target, ts.where(lambda label, status, goal: (goal == g) & (status == RUNNING)))
        bad = np.flatnonzero(requestable & ~good)
        if bad.size:
            out[g] = bad
    return out


def check(ctx) -> Result:
    level = getattr(ctx, "goal_level", "open")
    if level not in LEVELS:
        raise ValueError(f"unknown goal level {level!r} (known: {', '.join(LEVELS)})")
    if level == "tree" and ctx.model.tree is not None:
        return _check_tree(ctx)
    res = _check_open(ctx)
    if level == "tree":
        res.notes.insert(0, "the model has no tree: judged at open level")
    return res


def _check_tree(ctx) -> Result:
    ts = ctx.model_ts()
    info: dict = {"level": "tree", "states": ts.n_states}
    if not ts.complete or ts.n_transitions > TREE_LIMIT:
        why = budget_hit(ts) if not ts.complete else f"more than {TREE_LIMIT:,} transitions to re-run"
        return Result("goal-reachability", None, None,
                      [f"level tree: {why}; not decided (--goal-level open judges each FSM alone)"], info)
    fails = tree_goal_failures(ts)
    info["failing"] = {f"{f}/{g}": int(v.size) for (f, g), v in fails.items()}
    notes = [f"level tree: FSM {f}: goal '{g}' can be requested but never succeeds from {v.size} model state(s)"
             for (f, g), v in fails.items()]
    if not fails:
        return Result("goal-reachability", True, None, ["level tree: the requests the tree makes in the explored model"], info)
    (fname, gname), bad = min(fails.items(), key=lambda kv: (int(kv[1][0]), kv[0]))
    i = int(bad[0])
    viol = {"kind": "goal-tree", "fsm": fname, "goal": gname,
            "text": (f"level tree: from here the tree can request '{gname}' of FSM {fname}, but no run from here "
                     f"has a tick in which a request of '{gname}' gets SUCCESS")}
    ce = path_counterexample(ts, ts.path_to(i), "goal-reachability",
                             f"FSM {fname}: goal '{gname}' can be requested by the tree here but can never succeed", viol)
    return Result("goal-reachability", False, ce, notes, info)


def _check_open(ctx) -> Result:
    model = ctx.model
    info: dict
    notes, info, undecided = [], {}, False
    worst = None  # (depth, fsm, goal, state)
    for f in model.fsms:
        ts = ctx.fsm_ts(f.name)
        fails = goal_failures(ts)
        info[f.name] = {"states": ts.n_states, "goals": [f.goals[g] for g in ts.open.goals],
                        "failing": {f.goals[g]: int(v.size) for g, v in fails.items()}}
        if not ts.complete:
            undecided = True
            notes.append(f"FSM {f.name}: {budget_hit(ts)} ({ts.n_states} states); not decided")
            continue
        for g, bad in fails.items():
            i = int(bad[0])
            d = len(ts.path_to(i))
            notes.append(f"FSM {f.name}: goal '{f.goals[g]}' can never succeed from {bad.size} state(s)")
            if worst is None or d < worst[0]:
                worst = (d, ts, g, i)
    if worst is None:
        return Result("goal-reachability", None if undecided else True, None, notes, info)
    info["level"] = "open"
    _, ts, g, i = worst
    f = model.fsm(ts.fsm)
    text = _explain(ts, g, i) + (
        "\n  (level open: the FSM is judged alone, requested in every state where the `pre` of a request of "
        f"'{f.goals[g]}' can hold; a Condition in front of the request in the tree is not seen: move it into "
        "`pre:`, or check with --goal-level tree)" if model.tree is not None else "")
    viol = {"kind": "goal", "goal": f.goals[g], "text": text}
    ce = path_counterexample(ts, ts.path_to(i), "goal-reachability",
                             f"FSM {f.name}: goal '{f.goals[g]}' can be requested here but can never succeed",
                             viol)
    return Result("goal-reachability", False, ce, notes, info)


def _explain(ts, g, i) -> str:
    """What happens instead when goal g is requested from state i."""
    f = ts.model.fsm(ts.fsm)
    gname = f.goals[g]
    is_g = ts.goal == g
    outs = [t for t in ts.out_transitions(i).tolist() if is_g[t]]
    replies = {int(ts.status[t]) for t in outs}
    lines = [f"requesting '{gname}' from here never gets SUCCESS:"]
    if replies == {FAILURE}:
        causes = set()
        markers = {m.id for m in f.markers if m.outcome == Status.FAILURE}
        for _script, st, o in successor_scripts(ts, ts.full_state(i)):
            if st is None or ("choice", ("goal",), g) not in o.picks:
                continue
            for ev in st.events or ():
                if ev[0] == "not-applicable":
                    causes.add(f"not applicable: state '{ev[2]}' has no edge and no marker for '{gname}'")
                elif ev[0] == "fire" and ev[2] in markers:
                    causes.add(f"marker '{ev[2]}' replies FAILURE")
        lines.append("  it replies FAILURE at once" + (f" ({'; '.join(sorted(causes))})" if causes else ""))
        return "\n".join(lines)
    held = is_g & (ts.status == RUNNING)
    region = np.flatnonzero(forward_reach(ts, i, held))
    tok = ts.slots.index(ts.model.program.fsm_info[ts.open.index][2])
    ids = ts.model.program.fsm_info[ts.open.index][1]
    where = sorted({ids[int(x)] for x in ts.states[region, tok]})
    fails = any(int(ts.status[t]) == FAILURE for s in region.tolist() for t in ts.out_transitions(s).tolist() if is_g[t])
    looping = _on_cycles(ts, region, held)
    loop_where = sorted({ids[int(x)] for x in ts.states[looping, tok]}) if looping.size else where
    if fails:
        end = "can only reply FAILURE or keep RUNNING"
    elif len(loop_where) > 1:
        end = f"keeps RUNNING forever, the token cycling through {', '.join(loop_where)}"
    else:
        route = _route_within(ts, g, (looping if looping.size else region)[:_RERUN])
        end = (f"keeps RUNNING forever, the token cycling within each request ({route})" if route
               else f"keeps RUNNING forever with the token on {loop_where[0]} (stuck)")
    lines.append(f"  while it is held (RUNNING) its requests end with the token only on {', '.join(where)} "
                 f"({region.size} state(s)); from there it {end}")
    return "\n".join(lines)



_RERUN = 50  # region states re-run to see the token's moves within a request


def _route_within(ts, g, states) -> "str | None":
    """``home -> p1 -> p2 -> home``: the edges a g-request fires from one of ``states``
    (re-run with recording), or None when the token never moves within a request."""
    f = ts.model.fsm(ts.fsm)
    edges = {e.id: e for e in f.edges}
    for i in states.tolist():
        for _script, st, o in successor_scripts(ts, ts.full_state(i)):
            if st is None or ("choice", ("goal",), g) not in o.picks:
                continue
            fired = [edges[ev[2]] for ev in st.events or () if ev[0] == "fire" and ev[1] == f.name and ev[2] in edges]
            if fired:
                return " -> ".join([fired[0].source] + [e.target for e in fired])
    return None


def _on_cycles(ts, region, held) -> np.ndarray:
    """States of ``region`` on a cycle of ``held`` transitions (where RUNNING repeats);
    exact at any size (scipy strong components, ``btfsm.verify.system.cyclic_states``)."""
    inside = np.zeros(ts.n_states, bool)
    inside[region] = True
    t = np.flatnonzero(held & inside[ts.src] & inside[ts.dst])
    return cyclic_states(ts.n_states, ts.src[t], ts.dst[t])
