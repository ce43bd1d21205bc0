"""``workable-reachability``: AG EF workable.

From every reachable state some workable state can still be reached. ``workable`` is the
model's ``workable`` expression, by default "every FSM token on its initial state"
(``Program.workable``). Decided by backward reachability from the workable states over a
CSR of reversed transitions (numpy, linear in the transitions). A *trap* is a reachable
state from which no workable state is reachable; the counterexample is the shortest path
to the nearest trap, with the trap region reachable from it and its bottom SCC(s).
"""
from __future__ import annotations

import numpy as np

from ..counterexample import path_counterexample
from ..system import bottom_components, bottom_sccs, components, forward_reach, reverse_reach
from .base import Result, evaluate, budget_hit

__all__ = ["check", "workable_mask", "traps"]

_SHOW = 8


def workable_mask(ts) -> np.ndarray:
    """Boolean array: which states of a model-level system are workable."""
    model, prog = ts.model, ts.model.program
    if model.workable is not None:
        return evaluate(ts, model.workable)
    mask = np.ones(ts.n_states, bool)
    for f, ids, tok, _, _ in prog.fsm_info:
        mask &= ts.column(tok) == ids.index(f.initial)
    return mask


def traps(ts) -> np.ndarray:
    """Indices of trap states (no workable state reachable), in BFS order.

    Every state reaches a bottom SCC (one that no transition leaves; a state without
    successors is one), and from a bottom SCC only its own states are reachable: so there
    is no trap exactly when every bottom SCC holds a workable state. That is decided first,
    on the system's own CSR (scipy strong components: an int32 label per state, no copy of
    the transitions); only when some bottom SCC has no workable state are the traps
    counted by backward reachability."""
    good = workable_mask(ts)
    count, label = components(ts)
    has_good = np.zeros(count, bool)
    has_good[label[good]] = True
    if has_good.all() or not (bottom_components(ts, count, label) & ~has_good).any():
        return np.zeros(0, np.int64)
    del label
    return np.flatnonzero(~reverse_reach(ts, good))


def check(ctx) -> Result:
    ts = ctx.model_ts()
    bad = traps(ts)
    what = "workable states: " + ("every FSM token on its initial state (default)" if ctx.model.workable is None
                                  else f"those where `{ctx.model.workable}` holds")
    info = {"states": ts.n_states, "traps": int(bad.size)}
    if ctx.model.tree is None:
        what += ("; vacuous: the model has no tree, so no tick requests anything and no FSM token "
                 "moves (only the environment runs); the FSMs are judged as open systems by "
                 "goal-reachability and no-dead-states")
        info["vacuous"] = True
    if bad.size == 0:
        if not ts.complete:
            return Result("workable-reachability", None, None,
                          [what, f"{budget_hit(ts)}: every explored state reaches a workable one, "
                                 "but unexplored states are not decided"], info)
        return Result("workable-reachability", True, None, [what], info)
    if not ts.complete:
        # a trap in a partial system may reach a workable state through unexplored states
        return Result("workable-reachability", None, None,
                      [what, f"{budget_hit(ts)}: {bad.size} explored state(s) reach no workable state within "
                             "the explored part; undecided"], info)
    i = int(bad[0])
    region = np.flatnonzero(forward_reach(ts, i))
    bottoms = _bottom_sccs(ts, region)
    prog = ctx.model.program
    lines = [f"after these ticks no workable state can be reached any more ({what})",
             f"trap region reachable from here: {region.size} state(s); {bad.size} trap state(s) in all"]
    for k, scc in enumerate(bottoms[:3]):
        lines.append(f"bottom SCC {k + 1} ({len(scc)} state(s)), e.g.:")
        for j in scc[:_SHOW]:
            lines.append("  " + _brief(prog, ts.full_state(j)))
    viol = {"kind": "trap", "state": _decoded(prog, ts.full_state(i)), "trap_region": int(region.size),
            "traps": int(bad.size), "bottom_sccs": [[_decoded(prog, ts.full_state(j)) for j in scc[:_SHOW]] for scc in bottoms[:3]],
            "text": "\n".join(lines)}
    ce = path_counterexample(ts, ts.path_to(i), "workable-reachability",
                             f"{bad.size} reachable state(s) can never get back to a workable state", viol)
    return Result("workable-reachability", False, ce, [what], info)


def _bottom_sccs(ts, region) -> list:
    """Bottom SCCs of the sub-graph on ``region`` (lists of state indices), nearest first;
    exact at any size (scipy strong components)."""
    return bottom_sccs(ts.n_states, ts.src, ts.dst, region)


def _decoded(prog, state) -> dict:
    return {prog.slots[k].name: _plain(prog.decode_slot(k, v)) for k, v in enumerate(state) if prog.slots[k].kind not in ("flag", "memory")}


def _plain(x):
    return x.item() if hasattr(x, "item") else x


def _brief(prog, state) -> str:
    d = _decoded(prog, state)
    return ", ".join(f"{k}={str(v).lower() if isinstance(v, bool) else v}" for k, v in d.items())
