"""Tree-level goal reachability (``goal-reachability --goal-level tree``): which goals the
tree can request in which model states, and whether a SUCCESS for them stays reachable.

Shared by ``btfsm.verify.properties.goals`` (the property) and
``btfsm.verify.counterexample`` (confirming a replayed counterexample), so that neither
imports the other.
"""
from __future__ import annotations

import numpy as np

from btfsm.bt import SkillRequest, walk
from btfsm.oracles import all_choices
from btfsm.status import Status

from .explore import EnumOracle
from .system import reverse_reach

__all__ = ["tree_goal_failures"]

SUCCESS, FAILURE = int(Status.SUCCESS), int(Status.FAILURE)


class _Driven(EnumOracle):
    """An ``EnumOracle`` that also notes every (fsm index, goal index) an FSM is driven toward."""

    __slots__ = ("driven",)

    def __init__(self, script=()):
        super().__init__(script)
        self.driven = set()

    def request(self, fsm_index, goal_index):
        self.driven.add((fsm_index, goal_index))


def tree_goal_failures(ts) -> dict:
    """(fsm name, goal) -> indices of model states from which the tree can request the goal
    but no tick where it succeeds is reachable (``tree`` level; ``ts`` a model system)."""
    from btfsm.errors import DomainError

    model, prog = ts.model, ts.model.program
    nodes = {}  # SkillRequest name -> (fsm index, goal index)
    for _path, root in model.roots():
        for n in walk(root):
            if isinstance(n, SkillRequest):
                fi = prog.fsm_index[n.fsm]
                nodes[n.name] = (fi, model.fsms[fi].goals.index(n.goal))
    pairs = sorted(set(nodes.values()))
    asked = {p: np.zeros(ts.n_states, bool) for p in pairs}
    won = {p: np.zeros(ts.n_states, bool) for p in pairs}
    run = prog.step
    for i in range(ts.expanded):
        for _taken, st, o in all_choices(lambda s, o: run(s, o, True), tuple(ts.full_state(i)), _Driven, (DomainError,)):
            if isinstance(st, DomainError) or st is None or st.state is None:
                continue
            seen = set(o.driven)
            for ev in st.events or ():
                if ev[0] == "status" and ev[1] in nodes and ev[2] != FAILURE:
                    seen.add(nodes[ev[1]])
                    if ev[2] == SUCCESS:
                        won[nodes[ev[1]]][i] = True
            for p in seen:
                if p in asked:
                    asked[p][i] = True
    out = {}
    for p in pairs:
        bad = np.flatnonzero(asked[p] & ~reverse_reach(ts, won[p]))
        if bad.size:
            fi, g = p
            out[(model.fsms[fi].name, model.fsms[fi].goals[g])] = bad
    return out
