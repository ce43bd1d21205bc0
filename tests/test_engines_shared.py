"""One test suite for every exploration engine (``btfsm.verify.search.Explorer``: a model,
or one of its FSMs as an open system, to its ``TransitionSystem`` under budgets),
parametrized over the implementations (the pattern of dd's ``tests/common.py``): the
scalar and traced engines of ``btfsm.verify.explore`` (the ``Search`` Protocol; reached
with ``engine="scalar"``/``"traced"``), its ``auto`` choice between them, and the
vectorised engine ``btfsm.verify.vector.explore`` (on the systems it describes).

What every engine must do: find exactly the states and transitions a brute-force
breadth-first search over ``all_choices`` finds, label them as ``Program.step`` does,
start numbering at the initial state, and stop at a state budget with ``complete``
False and ``stopped == "states"``. The engines of ``btfsm.verify.explore`` also agree on
the numbering.
"""
from __future__ import annotations

from collections import deque
from functools import partial

import pytest

from btfsm.models.pickplace import pickplace
from btfsm.oracles import all_choices
from btfsm.verify import vector
from btfsm.verify.explore import explore, explore_fsm, open_fsm
from btfsm.verify.labels import readable
from btfsm.verify.search import EnumOracle, Explorer

from core_strategies import every_question_model


def _by_name(name: str, model, *, fsm=None, goals=None, **budgets):
    if fsm is None:
        return explore(model, engine=name, **budgets)
    return explore_fsm(model, fsm, goals=goals, engine=name, **budgets)


#: name -> engine (each an ``Explorer``)
ENGINES: dict[str, Explorer] = {
    "scalar": partial(_by_name, "scalar"),
    "traced": partial(_by_name, "traced"),
    "auto": partial(_by_name, "auto"),
    "vector": vector.explore,
}


#: (case name, model, fsm or None, engines that describe it: the vectorised engine describes
#: single-SkillRequest trees and FSMs, not the "tree" model)
CASES = [("tree", every_question_model(), None, ("scalar", "traced", "auto")),
         ("pickplace1", pickplace(1), None, tuple(ENGINES)),
         ("pickplace1-fsm", pickplace(1), "skill", tuple(ENGINES))]
PAIRS = [(engine, case) for case, _, _, engines in CASES for engine in engines]


def _brute_force(model, fsm):
    """States and (source, label, target) triples, full states, by BFS over every answer."""
    prog = model.program
    if fsm is None:
        run, start = (lambda s, o: prog.step(s, o, True)), prog.initial
        op = None
    else:
        op = open_fsm(model, fsm)
        run = lambda s, o: op.run(s, o, True)  # noqa: E731
        start = prog.initial
    seen, todo, edges = {start}, deque([start]), set()
    while todo:
        s = todo.popleft()
        for _, step, o in all_choices(run, s, EnumOracle):
            if step.state is None:
                continue
            t = step.state if op is None else tuple(step.state)
            edges.add((s, readable(prog, tuple(o.picks), op)[0], t))
            if t not in seen:
                seen.add(t)
                todo.append(t)
    return seen, edges


BRUTE = {case: _brute_force(model, fsm) for case, model, fsm, _ in CASES}
_CASE = {case: (model, fsm) for case, model, fsm, _ in CASES}


def _system(ts):
    states = [ts.full_state(i) for i in range(ts.n_states)]
    edges = {(states[int(ts.src[t])], ts.labels[int(ts.label[t])], states[int(ts.dst[t])])
             for t in range(ts.n_transitions)}
    return states, edges


@pytest.mark.parametrize("engine,case", PAIRS)
def test_the_states_and_transitions_of_the_brute_force(engine, case):
    model, fsm = _CASE[case]
    ts = ENGINES[engine](model, fsm=fsm)
    assert ts.complete and ts.stopped is None
    states, edges = _system(ts)
    want_states, want_edges = BRUTE[case]
    assert len(states) == len(set(states)), f"{engine}: a state numbered twice"
    assert states[0] == model.program.initial
    assert set(states) == want_states
    assert edges == want_edges
    assert ts.n_transitions == len(want_edges)


@pytest.mark.parametrize("engine,case", PAIRS)
def test_a_state_budget_stops_the_search(engine, case):
    model, fsm = _CASE[case]
    ts = ENGINES[engine](model, fsm=fsm, max_states=5)
    assert not ts.complete and ts.stopped == "states"
    assert 1 <= ts.n_states <= 5
    states, edges = _system(ts)
    want_states, want_edges = BRUTE[case]
    assert set(states) <= want_states and edges <= want_edges


@pytest.mark.parametrize("case", [c for c, _, _, _ in CASES])
def test_the_engines_of_explore_number_alike(case):
    model, fsm = _CASE[case]
    systems = [ENGINES[e](model, fsm=fsm) for e in ("scalar", "traced", "auto")]
    a = systems[0]
    for b in systems[1:]:
        assert [a.full_state(i) for i in range(a.n_states)] == [b.full_state(i) for i in range(b.n_states)]
        assert (a.src.tolist(), a.dst.tolist()) == (b.src.tolist(), b.dst.tolist())
        assert [a.labels[k] for k in a.label] == [b.labels[k] for k in b.label]
