"""``lints``: warnings, never a failure.

The model's own warnings (``model.warnings``: structurally unreachable states, shadowed
or impossible edges) and the program's (``model.program.lints``), plus what exploration
shows: FSM states the token never visits (at the end of a tick, or passing through within
one: the ends of a fired edge), edges and markers that never fire, and goals no
SkillRequest requests. For a model with a tree the explored model is used when it has at
most ``FIRE_LIMIT`` transitions (every transition is re-run once with recording on);
otherwise, and for models without a tree, each FSM as an open system (which
over-approximates what the tree can request).
"""
from __future__ import annotations

import numpy as np

from ..explore import successor_scripts
from .base import Result

__all__ = ["check", "FIRE_LIMIT"]

FIRE_LIMIT = 100_000


def _fired(ts, wanted: set) -> set:
    """(fsm, element id) of the ``wanted`` edges and markers that fire in some transition
    of ts (stops as soon as all of them have been seen)."""
    out = set()
    for i in range(ts.expanded):
        for _script, st, _o in successor_scripts(ts, ts.full_state(i)):
            if st is not None:
                out.update((e[1], e[2]) for e in st.events or () if e[0] == "fire")
        if wanted <= out:
            break
    return out


def check(ctx) -> Result:
    model, prog = ctx.model, ctx.model.program
    warnings = [(el, text) for el, text in model.warnings] + [(el, text) for el, text in prog.lints]
    seen = {el for el, _ in warnings}
    use_model = model.tree is not None and ctx.model_ts().n_transitions <= FIRE_LIMIT and ctx.model_ts().complete
    fired, visited = set(), {}
    wanted = {(f.name, x.id) for f in model.fsms for x in (*f.edges, *f.markers)}
    if use_model:
        ts = ctx.model_ts()
        fired = _fired(ts, wanted)
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
    allw = warnings + found
    notes = [f"{el}: {text}" for el, text in allw]
    return Result("lints", True, None, notes, {"warnings": [{"element": el, "text": text} for el, text in allw]})
