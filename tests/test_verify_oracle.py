"""Differential tests: verify's verdicts against the independent brute force
(tests/oracle_bruteforce.py) on random small models, and z3's overlap answers against
exhaustive enumeration over the small domains."""
from __future__ import annotations

import itertools

import pytest
from hypothesis import HealthCheck, given, settings
from memo_strategies import st

from btfsm import (FSM, Action, Bool, Condition, Edge, Enum, EnvChoice, EnvEvent, Int, Marker,
                   MemorySequence, Model, ModelError, Outcome, ReactiveFallback, ReactiveSequence,
                   SkillRequest, State)
from btfsm.expr import BOOL, compile_fn, names_in
from tests.oracle_bruteforce import FSMGraph, ModelGraph
from tests.strategies import random_models
from btfsm.verify.counterexample import replay_counterexample
from btfsm.verify.determinism import analyse, statuses_of_state
from btfsm.verify.explore import explore, explore_fsm
from btfsm.verify.properties.dead import dead_states, non_progress
from btfsm.verify.properties.goals import goal_failures
from btfsm.verify.properties.workable import traps
from btfsm.verify.report import check

SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
VARS = (Bool("b"), Enum("e", ("a", "b", "c")), Int("n", 0, 2))


# ---------------------------------------------------------------------- random small models


def _atom(draw, variables):
    v = draw(st.sampled_from(variables))
    if v.kind == "bool":
        return draw(st.sampled_from([v.name, f"not {v.name}"]))
    if v.kind == "enum":
        x = draw(st.sampled_from(v.values))
        return draw(st.sampled_from([f"{v.name} == '{x}'", f"{v.name} != '{x}'", f"{v.name} in ('{x}', 'a')"]))
    c = draw(st.integers(v.lo, v.hi))
    return f"{v.name} {draw(st.sampled_from(['==', '!=', '<', '>=']))} {c}"


def _guard(draw, variables, none_ok=True):
    k = draw(st.integers(0 if none_ok else 1, 3))
    if k == 0:
        return None
    if k == 1:
        return _atom(draw, variables)
    return f"({_atom(draw, variables)}) {draw(st.sampled_from(['and', 'or']))} ({_atom(draw, variables)})"


def _effects(draw, variables):
    out = {}
    for v in draw(st.lists(st.sampled_from(variables), max_size=2, unique_by=lambda v: v.name)):
        if v.kind == "bool":
            out[v.name] = draw(st.sampled_from(["true", "false", f"not {v.name}"]))
        elif v.kind == "enum":
            out[v.name] = repr(draw(st.sampled_from(v.values)))
        else:  # n + 1 can leave the domain: a DomainError the checker must report
            out[v.name] = draw(st.sampled_from(["0", "2", f"{v.name} + 1", f"max({v.name} - 1, 0)"]))
    return out


def _outcomes(draw, variables):
    kinds = draw(st.lists(st.sampled_from(["success", "failure", "running"]), min_size=1, max_size=3, unique=True))
    return tuple(Outcome(k, _effects(draw, variables) if draw(st.booleans()) else {}) for k in kinds)


def _fsm(draw, variables, name="f", params=False):
    n = draw(st.integers(2, 4))
    ids = [f"s{i}" for i in range(n)]
    goals = ["g0", "g1"][: draw(st.integers(1, 2))]
    states = [State(sid, outcomes=_outcomes(draw, variables)) if draw(st.integers(0, 3)) else State(sid) for sid in ids]
    edges, markers = [], []
    for _ in range(draw(st.integers(1, 6))):
        i, j = draw(st.integers(0, n - 1)), draw(st.integers(0, n - 1))
        direct = i < j and draw(st.integers(0, 3)) == 0
        edges.append(Edge(ids[i], ids[j], draw(st.lists(st.sampled_from(goals), min_size=1, unique=True)),
                          draw(st.sampled_from(["success", "failure", "running"])), _guard(draw, variables), direct,
                          _effects(draw, variables) if draw(st.integers(0, 3)) == 0 else {}))
    for _ in range(draw(st.integers(1, 3))):
        markers.append(Marker(draw(st.sampled_from(ids)), draw(st.lists(st.sampled_from(goals), min_size=1, unique=True)),
                              draw(st.sampled_from(["success", "failure"])), draw(st.sampled_from(["success", "success", "failure"])),
                              _guard(draw, variables), draw(st.integers(0, 3)) == 0))
    ps, retarget, wg = (), "immediate", ""
    if params and draw(st.booleans()):
        ps = (Int("p", 0, 1),)
        retarget = draw(st.sampled_from(["immediate", "withdraw"]))
        wg = goals[0] if retarget == "withdraw" else ""
    terminal = tuple(draw(st.lists(st.sampled_from(ids), max_size=1)))
    return FSM(name, states, ids[0], goals, edges, markers, ps, retarget, wg, terminal)


def _env(draw, variables, choices=True):
    out = []
    for k in range(draw(st.integers(0, 2))):
        if choices and draw(st.integers(0, 3)) == 0:
            out.append(EnvChoice(f"c{k}", [EnvEvent(f"c{k}o{i}", _guard(draw, variables), _effects(draw, variables))
                                           for i in range(draw(st.integers(1, 2)))]))
        else:
            out.append(EnvEvent(f"ev{k}", _guard(draw, variables), _effects(draw, variables)))
    return out


@st.composite
def tree_models(draw):
    """Small models with a tree of conditions, actions and skill requests over one FSM."""
    variables = draw(st.lists(st.sampled_from(VARS), min_size=1, max_size=3, unique_by=lambda v: v.name))
    f = _fsm(draw, variables, params=True)
    counter = itertools.count()

    def leaf():
        k = draw(st.integers(0, 3))  # 2, 3: a skill request
        name = f"l{next(counter)}"
        if k == 0:
            return Condition(name, _atom(draw, variables))
        if k == 1:
            return Action(name, outcomes=_outcomes(draw, variables))
        params = {p.name: str(draw(st.integers(p.lo, p.hi))) for p in f.params}
        pre = _guard(draw, variables) if draw(st.booleans()) else None
        post = _atom(draw, variables) if draw(st.booleans()) else None
        return SkillRequest(name, fsm=f.name, goal=draw(st.sampled_from(f.goals)), params=params, pre=pre, post=post)

    kinds = [ReactiveSequence, ReactiveFallback, MemorySequence]
    kids = []
    for _ in range(draw(st.integers(1, 3))):
        if draw(st.integers(0, 2)) == 0:
            kids.append(draw(st.sampled_from(kinds))(f"c{next(counter)}", [leaf() for _ in range(draw(st.integers(1, 2)))]))
        else:
            kids.append(leaf())
    tree = draw(st.sampled_from(kinds))("root", kids)
    invariants = {f"inv{i}": _guard(draw, variables, False) for i in range(draw(st.integers(0, 2)))}
    workable = _guard(draw, variables) if draw(st.booleans()) else None
    terminal = _guard(draw, variables) if draw(st.integers(0, 3)) == 0 else None
    try:
        return Model("rand", variables, (), (f,), tree, _env(draw, variables), invariants, workable, terminal)
    except ModelError:
        return Model("rand", variables, (), (), None, _env(draw, variables))


@st.composite
def fsm_models(draw):
    """Small models of one FSM without a tree (the FSM level), with environment events."""
    variables = draw(st.lists(st.sampled_from(VARS), min_size=1, max_size=3, unique_by=lambda v: v.name))
    f = _fsm(draw, variables, params=True)
    return Model("fsm", variables, (), (f,), None, _env(draw, variables, choices=False))


# ---------------------------------------------------------------------- model level


def _state_set(ts):
    return {ts.full_state(i) for i in range(ts.n_states)}


def _compare_model(m, bound=4000):
    try:
        bf = ModelGraph(m, bound)
    except OverflowError:
        return None
    ts = explore(m)
    assert ts.complete
    full = [ts.full_state(i) for i in range(ts.n_states)]
    assert set(full) == bf.states
    assert ts.n_states == len(bf.states)
    assert {(full[int(a)], full[int(b)]) for a, b in zip(ts.src, ts.dst)} == bf.edges
    assert {full[int(i)] for i in dead_states(ts)} == bf.dead()
    assert {full[int(i)] for i in traps(ts)} == bf.traps()
    assert {full[e.state] for e in ts.errors} == bf.errors
    assert {full[int(ts.src[t])] for t, vs in ts.violations if any(v[0] == "post" for v in vs)} == bf.posts
    return ts, bf


@SETTINGS
@given(tree_models())
def test_model_level_matches_bruteforce(m):
    got = _compare_model(m)
    if got is None:
        return
    ts, bf = got
    r = check(m, ["workable-reachability", "no-dead-states", "invariants", "domain", "contracts"])
    assert r.result("workable-reachability").holds is (not bf.traps())
    assert r.result("domain").holds is (not bf.errors)
    assert r.result("contracts").holds is (not bf.posts)
    bad = bf.invariant_violations()
    assert r.result("invariants").holds is (not any(bad.values()))
    if bf.dead():
        assert r.result("no-dead-states").holds is False


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(random_models(max_vars=2, max_fsms=1, tree_depth=2))
def test_shared_random_models_match_bruteforce(m):
    """The project's broad model strategy (every node type, subtrees, params, choices)."""
    _compare_model(m, bound=1500)


# ---------------------------------------------------------------------- FSM level


@SETTINGS
@given(fsm_models())
def test_fsm_level_matches_bruteforce(m):
    f = m.fsms[0]
    try:
        bf = FSMGraph(m, f.name, 4000)
    except OverflowError:
        return
    ts = explore_fsm(m, f.name)
    assert ts.complete
    mine = {tuple(int(x) for x in row) for row in ts.states}
    proj = {tuple(s[k] for k in ts.slots) for s in bf.states}
    assert mine == proj
    fails = goal_failures(ts)
    got = {(tuple(int(x) for x in ts.states[i]), g) for g, idx in fails.items() for i in idx.tolist()}
    want = {(tuple(s[k] for k in ts.slots), g) for s, g in bf.goal_failures()}
    assert got == want
    assert (non_progress(ts) is not None) == bf.non_progress()
    r = check(m, ["goal-reachability", "no-dead-states"])
    assert r.result("goal-reachability").holds is (not want)
    assert r.result("no-dead-states").holds is (not (bf.non_progress() or bf.sink()))


# ---------------------------------------------------------------------- counterexamples replay


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(tree_models(), fsm_models()))
def test_every_counterexample_replays(m):
    r = check(m, max_states=3000)
    for res in r.results:
        ce = res.counterexample
        if ce is None:
            continue
        ok, text = replay_counterexample(ce.to_json(), m)
        assert ok, (res.name, text, ce.format_text())
        if ce.level != "static":
            assert ce.steps or res.name in ("workable-reachability", "goal-reachability", "no-dead-states",
                                            "invariants", "request-latency")


# ---------------------------------------------------------------------- determinism vs enumeration


def _overlaps_by_enumeration(m) -> set:
    prog = m.program
    out = set()
    for f in m.fsms:
        scope = prog.fsm_scope(f)
        fi = prog.fsm_index[f.name]
        tok = prog.fsm_info[fi][2]
        for si, stt in enumerate(f.states):
            for g in f.goals:
                edges, markers = f.edges_from(stt.id, g), f.markers_at(stt.id, g)
                if not edges and not markers:
                    continue
                groups = [[e for e in edges if e.direct], [x for x in markers if x.direct]]
                for s in statuses_of_state(prog, stt):
                    groups += [[e for e in edges if not e.direct and e.on == s],
                               [x for x in markers if not x.direct and x.on == s]]
                for items in groups:
                    for i in range(len(items)):
                        for j in range(i + 1, len(items)):
                            a, b = items[i], items[j]
                            if _can_both(prog, scope, tok, si, a.guard, b.guard):
                                out.add((f.name, stt.id, a.id, b.id))
    return out


def _can_both(prog, scope, tok, si, ga, gb) -> bool:
    names = sorted((names_in(ga) | names_in(gb)))
    slots = sorted({scope[n].index for n in names})
    fa = compile_fn(ga, scope, "a", BOOL) if ga is not None else (lambda s: True)
    fb = compile_fn(gb, scope, "b", BOOL) if gb is not None else (lambda s: True)
    doms = [range(prog.slots[k].lo, prog.slots[k].lo + prog.slots[k].size) if k != tok else [si] for k in slots]
    for vals in itertools.product(*doms):
        s = list(prog.initial)
        s[tok] = si
        for k, v in zip(slots, vals):
            s[k] = v
        if fa(s) and fb(s):
            return True
    return False


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(tree_models(), fsm_models(), random_models(max_vars=3, max_fsms=2, tree_depth=1)))
def test_determinism_matches_enumeration(m):
    overlaps, _ = analyse(m)
    got = {(o["fsm"], o["state"], o["a"], o["b"]) for o in overlaps}
    assert got == _overlaps_by_enumeration(m)
    from btfsm.verify.determinism import confirm_overlap

    for o in overlaps:
        assert confirm_overlap(m, o)[0]


@pytest.mark.parametrize("seed", range(3))
def test_oracle_agrees_on_fixed_examples(seed):
    """A deterministic sanity check of the brute force itself on a hand-made model."""
    from btfsm import success

    m = Model("cnt", [Int("n", 0, 2)], (), (), Action("inc", outcomes=[success(n=f"min(n + {seed + 1}, 2)")]),
              (EnvEvent("reset", "n == 2", {"n": 0}),))
    bf = ModelGraph(m)
    assert len(bf.states) == len(_state_set(explore(m)))
