"""``no-dead-states``: nothing gets stuck.

1. Model level: no reachable state without a successor (an environment choice with no
   enabled option), unless it is terminal: the model's ``terminal`` expression holds, or
   every FSM declares terminal states and every token is on one. States whose every tick
   raises a domain error are left to the ``domain`` property.
2. No reachable **sink**: an FSM state that is not declared terminal and has no edge and
   no marker at all. Every request there replies FAILURE ('not applicable') and the token
   can never leave it, so the robot is frozen although ticks still happen (a FAILURE reply
   counts as progress below, so (3) alone would not see it). Judged in the explored model
   (states where the model's ``terminal`` holds are excused), or in each FSM's open system
   for a model without a tree. The counterexample is the shortest path to it.
3. FSM level, for each FSM: no **non-progress cycle**, a cycle of requests of one goal in
   which no step makes progress. A step makes progress when the token moves, or the reply
   is SUCCESS or FAILURE, or a primitive returned RUNNING (still working; assumed to
   finish). This catches a failing primitive retried forever and a refused withdraw that
   freezes the robot (a request refused with FAILURE is progress: see sinks, 2). The counterexample is a lasso: the shortest path to the nearest
   state on such a cycle, then the shortest cycle through it (both exact at any size:
   scipy strong components and one breadth-first search).
"""
from __future__ import annotations

import numpy as np

from btfsm.status import Status

from ..counterexample import path_counterexample
from ..explore import EnumOracle
from ..system import cyclic_states_of, shortest_cycle
from .base import Result, evaluate, budget_hit

__all__ = ["check", "dead_states", "terminal_mask", "non_progress", "progress_mask", "sink_states", "reachable_sinks"]

RUNNING = int(Status.RUNNING)


def terminal_mask(ts) -> np.ndarray:
    """Which states of a model-level system are terminal."""
    model, prog = ts.model, ts.model.program
    mask = evaluate(ts, model.terminal) if model.terminal is not None else np.zeros(ts.n_states, bool)
    if model.fsms and all(f.terminal for f in model.fsms):
        every = np.ones(ts.n_states, bool)
        for f, ids, tok, _, _ in prog.fsm_info:
            every &= np.isin(ts.column(tok), [ids.index(t) for t in f.terminal])
        mask |= every
    return mask


def dead_states(ts) -> np.ndarray:
    """Expanded, non-terminal states without successor (and not only domain errors)."""
    dead = ts.dead
    if dead.size == 0:
        return dead
    keep = ~terminal_mask(ts)[dead]
    if ts.errors:
        keep &= ~np.isin(dead, [e.state for e in ts.errors])
    return dead[keep]


def sink_states(f) -> tuple:
    """States of FSM ``f`` that are not terminal and have no edge and no marker at all."""
    busy = {e.source for e in f.edges} | {m.state for m in f.markers}
    return tuple(st.id for st in f.states if st.id not in busy and st.id not in f.terminal)


def reachable_sinks(ts, f) -> "tuple | None":
    """(state index, sink id, count) of the nearest reachable state of ``ts`` whose token of
    FSM ``f`` is on a sink (model level: unless ``terminal`` holds there), or None."""
    sinks = sink_states(f)
    prog = ts.model.program
    _, ids, tok, _, _ = prog.fsm_info[prog.fsm_index[f.name]]
    if not sinks or tok not in ts.slots:
        return None
    on = np.isin(ts.column(tok), [ids.index(x) for x in sinks])
    if ts.kind == "model":
        on &= ~terminal_mask(ts)
    hits = np.flatnonzero(on)
    if hits.size == 0:
        return None
    i = int(hits[0])
    return i, ids[int(ts.column(tok)[i])], int(np.unique(ts.column(tok)[hits]).size)


def progress_mask(ts) -> np.ndarray:
    """Per transition of an FSM-level system: does it make progress? (Built a slice of
    transitions at a time from the token's column: no per-transition array but the answer.)"""
    prog = ts.model.program
    tok = prog.fsm_info[ts.open.index][2]
    runs = np.array([any(it[0] == "outcome" and it[3] == "RUNNING" for it in lab) for lab in ts.labels] or [False], bool)
    out = ts.where(lambda label, status, goal: (status != RUNNING) | runs[label])
    col = ts.column(tok)
    for a, b, src in ts.slices():
        out[a:b] |= col[src] != col[ts.dst[a:b]]
    return out


def non_progress(ts) -> "tuple | None":
    """(prefix transitions, cycle transitions) of the nearest non-progress lasso, or None."""
    still = ~progress_mask(ts)
    best = None
    if still.any():
        for g in ts.open.goals:
            sub = still & ts.where(lambda label, status, goal: goal == g)
            if not sub.any():
                continue
            on_cycle = _cycle_states(ts, sub)
            if on_cycle.size == 0:
                continue
            c = int(on_cycle[0])
            if best is None or c < best[0]:
                best = (c, sub)
    if best is None:
        return None
    c, sub = best
    cycle = _shortest_cycle(ts, c, sub)
    return ts.path_to(c), cycle


def _cycle_states(ts, sub) -> np.ndarray:
    """States lying on a cycle of the transitions selected by ``sub``, in BFS order;
    exact at any size (scipy strong components over the selected transitions' CSR)."""
    return cyclic_states_of(ts, sub)


def _shortest_cycle(ts, c, sub) -> list:
    """Transitions of a shortest cycle from ``c`` back to ``c`` inside ``sub``: one BFS from
    ``c`` over the selected transitions and the nearest edge back (``shortest_cycle``);
    exact and linear at any size. ``c`` lies on a cycle (``_cycle_states``)."""
    t, src, dst = ts.pick(sub)
    found = shortest_cycle(ts.n_states, src, dst, c)
    if found is None:
        raise AssertionError(f"state {c} is on no cycle of the selected transitions")
    return t[np.asarray(found, np.int64)].tolist()


def check(ctx) -> Result:
    model = ctx.model
    notes: list = []
    info: dict = {}
    ts = ctx.model_ts()
    dead = dead_states(ts)
    info["dead_states"] = int(dead.size)
    undecided = not ts.complete
    if undecided:
        notes.append(f"model: {budget_hit(ts)} ({ts.n_states} states); only the {ts.expanded} expanded states were checked")
    ce = None
    if dead.size:
        i = int(dead[0])
        why = _why_dead(ts, i)
        viol = {"kind": "dead", "count": int(dead.size), "text": f"no tick can happen here: {why}"
                f"\n{dead.size} dead state(s) in all (declare 'terminal' if stopping here is intended)"}
        ce = path_counterexample(ts, ts.path_to(i), "no-dead-states",
                                 f"{dead.size} reachable state(s) have no successor and are not terminal", viol)
        notes.append(f"model: {dead.size} dead state(s)")
    hit = budget_hit(ts)  # the non-progress notes below name the model's budget, as they always did
    sinks = {}  # FSM -> (path length, build the counterexample)
    for f in model.fsms:
        sts = ts if model.tree is not None else ctx.fsm_ts(f.name)
        found = reachable_sinks(sts, f)
        if found is not None:
            sinks[f.name] = (len(sts.path_to(found[0])), _sink_counterexample(sts, f.name, found) if ce is None else None)
            notes.append(f"FSM {f.name}: sink state '{found[1]}' is reachable (no edge, no marker, not terminal)")
    info["sinks"] = sorted(sinks)
    if ce is None and sinks:
        ce = sinks[min(sinks, key=lambda k: sinks[k][0])][1]
    ts = sts = sinks = None  # type: ignore[assignment]  # nothing here holds the model's system any more
    ctx.done_with_model()  # the rest reads FSM systems only
    lassos = {}
    for f in model.fsms:
        fts = ctx.fsm_ts(f.name)
        if not fts.complete:
            undecided = True
            notes.append(f"FSM {f.name}: {hit}; non-progress cycles not decided")
            continue
        found = non_progress(fts)
        if found is not None:
            lassos[f.name] = (fts, *found)
            notes.append(f"FSM {f.name}: non-progress cycle requesting "
                         f"'{f.goals[fts.goal_of(found[1][0])]}' (prefix {len(found[0])}, cycle {len(found[1])})")
    info["non_progress"] = sorted(lassos)
    if ce is None and lassos:
        name = min(lassos, key=lambda k: len(lassos[k][1]) + len(lassos[k][2]))
        fts, prefix, cycle = lassos[name]
        f = model.fsm(name)
        gname = f.goals[fts.goal_of(cycle[0])]
        viol = {"kind": "non-progress", "goal": gname}
        ce = path_counterexample(fts, prefix + cycle, "no-dead-states",
                                 f"FSM {name}: a non-progress cycle requesting '{gname}'", viol, loop=len(prefix))
        ce.violation["text"] = _non_progress_text(f, gname, ce.steps[len(prefix):])
    if ce is not None:
        return Result("no-dead-states", False, ce, notes, info)
    return Result("no-dead-states", None if undecided else True, None, notes, info)


def _sink_counterexample(sts, name, found):
    i, sid = found[0], found[1]
    viol = {"kind": "sink", "fsm": name, "state": sid,
            "text": (f"FSM {name} is now in state '{sid}', which has no edge and no marker: every request "
                     f"gets FAILURE ('not applicable') and the token can never leave it, so {name} is frozen "
                     f"for good (declare '{sid}' in the FSM's terminal states if stopping there is intended, "
                     "or add an edge out of it)")}
    return path_counterexample(sts, sts.path_to(i), "no-dead-states",
                               f"FSM {name}: sink state '{sid}' is reachable (every request fails there forever)", viol)


def _non_progress_text(f, gname, cycle_steps) -> str:
    """Why the cycle makes no progress, saying how the token moves within it."""
    ids = {e.id: e for e in f.edges}
    passed = [ids[e] for st in cycle_steps for fsm, e in st.get("fired", []) if fsm == f.name and e in ids]
    if passed:
        route = " -> ".join([passed[0].source] + [e.target for e in passed])
        token = (f"the token moves ({route}) but each request ends with it back where the request started")
    else:
        token = "the token does not move"
    return (f"requesting '{gname}' again and again comes back to the same state with no progress: {token}, "
            "the reply stays RUNNING and no primitive reports RUNNING "
            "(e.g. a failing primitive retried forever, or a refused request)")


def _why_dead(ts, i) -> str:
    st = ts.model.program.step(ts.full_state(i), EnumOracle(()))
    blocked = [v[1] for v in (st.violations or []) if v[0] == "blocked"]
    if st.state is None and blocked:
        return f"environment choice '{blocked[0]}' has no enabled option"
    return "every tick from here is blocked"
