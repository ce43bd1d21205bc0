"""The vectorised engine (verify.vector) against the generic one (verify.explore): same
reachable states, same transitions (source, target, readable label, status), same dead
states, contract violations and domain errors, on the pick/place benchmark and on random
models (the strategies of tests/test_spin_crosscheck.py), at the whole-model and the FSM
level, with dense and sparse visited sets and with small chunks."""
from __future__ import annotations

from collections import Counter

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from memo_strategies import st

from btfsm import FSM, Action, Bool, Edge, Int, Model, ReactiveFallback, SkillRequest, State, success
from btfsm.errors import ModelError
from btfsm.models.pickplace import SPIN_STATES, pickplace
from test_spin_crosscheck import feature_model, random_models, seeded_models
from btfsm.verify import vector
from btfsm.verify.explore import explore, explore_fsm


def _rows(ts):
    return [tuple(int(x) for x in r) for r in ts.states]


def summary(ts):
    """Everything two explorations must agree on, independent of state numbering."""
    rows = _rows(ts)
    trans = Counter((rows[a], rows[b], ts.labels[lab], int(st))
                    for a, b, lab, st in zip(ts.src.tolist(), ts.dst.tolist(), ts.label.tolist(), ts.status.tolist()))
    dead = {rows[i] for i in ts.dead.tolist()}
    viol = Counter((rows[int(ts.src[t])], rows[int(ts.dst[t])], ts.labels[int(ts.label[t])], v) for t, v in ts.violations)
    errors = Counter((rows[e.state], e.script, e.label, e.var, e.value) for e in ts.errors)
    return set(rows), trans, dead, viol, errors


def same(a, b):
    sa, sb = summary(a), summary(b)
    for what, x, y in zip(("states", "transitions", "dead", "violations", "errors"), sa, sb):
        assert x == y, f"{what} differ: generic-only {_diff(x, y)}, vector-only {_diff(y, x)}"
    assert a.n_states == b.n_states and a.n_transitions == b.n_transitions
    assert a.complete and b.complete


def _diff(x, y):
    if isinstance(x, Counter):
        return list((x - y).items())[:3]
    return list(x - y)[:3]


def check_parents(ts):
    """Parents are transitions into the state from an earlier level (BFS)."""
    depth = ts.depth()
    for i in range(1, ts.n_states):
        t = int(ts.parent[i])
        assert int(ts.dst[t]) == i and depth[int(ts.src[t])] == depth[i] - 1


# ---------------------------------------------------------------------- pick/place


@pytest.mark.parametrize("kw", [{}, {"dead": True}, {"bug": True}])
def test_pickplace_size3_same_as_generic(kw):
    m = pickplace(3, **kw)
    tv = vector.explore(m)
    same(explore(m), tv)
    same(explore_fsm(m, "skill"), vector.explore(m, fsm="skill"))
    check_parents(tv)


def test_pickplace_counts_match_spin():
    r = vector.reach(pickplace(6))
    assert (r.n_states, len(r.dead), r.complete) == (SPIN_STATES[6], 0, True)
    d = vector.reach(pickplace(3, dead=True))
    assert (d.n_states, len(d.dead)) == (8_624, 1_024)
    # SPIN's BFS finds the first invalid end state at depth 6
    assert min(len(d.path_to(int(i))) - 1 for i in d.dead) == 6


def test_reach_agrees_with_explore():
    m = pickplace(3, dead=True)
    r, ts = vector.reach(m), vector.explore(m)
    assert r.n_states == ts.n_states and r.n_transitions == ts.n_transitions
    rows = _rows(ts)  # once (it was rebuilt for each of the 1,024 dead states)
    assert {tuple(x) for x in r.states().tolist()} == set(rows)
    assert {tuple(x) for x in r.states(r.dead).tolist()} == {rows[i] for i in ts.dead.tolist()}
    for i in (1, r.n_states // 2, r.n_states - 1):  # a parent chain ends at the initial state
        path = r.path_to(i)
        assert path[0] == 0 and path[-1] == i and all(r.parent[b] == a for a, b in zip(path, path[1:]))


@pytest.mark.parametrize("dense", [True, False])
def test_small_chunks_and_sparse_visited_set(dense, monkeypatch):
    if not dense:
        monkeypatch.setattr(vector, "DENSE_LIMIT", 16)
    m = pickplace(3, dead=True)
    same(explore(m), vector.explore(m, chunk=37))


def test_budget_marks_incomplete():
    r = vector.reach(pickplace(3), max_states=1000)
    assert not r.complete and r.n_states == 1000
    ts = vector.explore(pickplace(3), max_states=1000)
    assert not ts.complete and ts.n_states == 1000 and ts.expanded < 1000


# ---------------------------------------------------------------------- random models


_SETTINGS = dict(deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


@settings(max_examples=60, **_SETTINGS)
@given(seeded_models(tree=True, wild=True))
def test_random_whole_models_same_as_generic(model):
    same(explore(model), vector.explore(model))


@settings(max_examples=60, **_SETTINGS)
@given(seeded_models(wild=True))
def test_random_fsm_level_same_as_generic(model):
    same(explore_fsm(model, "f"), vector.explore(model, fsm="f"))


@settings(max_examples=40, **_SETTINGS)
@given(random_models(wild=True))
def test_random_models_hypothesis_draws(model):
    """The shrinkable strategy too (small models, edge cases first)."""
    if model.tree is not None:
        same(explore(model), vector.explore(model))
    same(explore_fsm(model, "f"), vector.explore(model, fsm="f"))


def same_as_labelled(model, fsm=None, **kw):
    """``reach`` (the unlabelled path: one request per token group over every input and
    environment answer) finds what ``explore`` (one request per answer) finds, numbered
    alike: the same codes in the same order, levels, dead states, domain-error states and
    counts; every parent is a BFS parent (a transition into the state from the level
    before). The parents themselves may differ: the labelled path splits the answers
    further (a choice asked or not), so it can meet a state from another parent first."""
    r, ts = vector.reach(model, fsm=fsm, **kw), vector.explore(model, fsm=fsm, **kw)
    assert r.n_states == ts.n_states and r.n_transitions == ts.n_transitions and r.complete == ts.complete
    assert r.states().tolist() == ts.states.tolist()
    depth = ts.depth()
    assert np.array_equal(np.diff(r.levels), np.bincount(depth, minlength=len(r.levels) - 1))
    edges = set(zip(ts.src.tolist(), ts.dst.tolist()))
    assert r.parent[0] == -1
    assert all((p, i) in edges and depth[p] == depth[i] - 1 for i, p in enumerate(r.parent.tolist()) if i)
    assert sorted(r.dead.tolist()) == sorted(ts.dead.tolist())
    assert r.error_states.tolist() == sorted({e.state for e in ts.errors})
    return r


@settings(max_examples=20, **_SETTINGS)
@given(seeded_models(tree=True, wild=True))
def test_reach_numbers_random_models_like_explore(model):
    same_as_labelled(model)
    same_as_labelled(model, chunk=7)


@settings(max_examples=20, **_SETTINGS)
@given(seeded_models(wild=True))
def test_reach_numbers_random_fsms_like_explore(model):
    same_as_labelled(model, fsm="f")


def test_reach_numbers_the_hand_written_features_like_explore(monkeypatch):
    m = feature_model()
    same_as_labelled(m)
    same_as_labelled(m, fsm="arm", chunk=7)
    r = same_as_labelled(pickplace(3, dead=True))
    monkeypatch.setattr(vector, "MERGED_ROWS", 5)  # a token group's answers in several requests
    s = same_as_labelled(pickplace(3, dead=True))
    assert s.parent.tolist() == r.parent.tolist()  # the same order of transitions, so the same parents


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(0, 3000), st.sampled_from([4, 300, 2**20, 2**31 - 1]),
       st.sampled_from([np.int32, np.uint32]))
def test_the_first_occurrences_of_a_level_are_np_unique(seed, n, span, dtype):
    """A level's new codes are deduplicated by a hash table, then sorted (parents: each
    code's first occurrence): exactly ``np.unique(..., return_index=True)``, collisions
    and repeats included."""
    codes = np.random.default_rng(seed).integers(0, span, n).astype(dtype)
    want, got = np.unique(codes, return_index=True), vector._first_unique(codes)
    assert got[0].dtype == codes.dtype
    assert got[0].tolist() == want[0].tolist() and got[1].tolist() == want[1].tolist()


# ---------------------------------------------------------------------- scope


def test_out_of_scope_trees_are_refused():
    arm = FSM("arm", states=[State("a")], goals=["go"], edges=[Edge("a", "a", ["go"])])
    m = Model("t", variables=[Bool("x")], fsms=[arm],
              tree=ReactiveFallback("root", [Action("act", outcomes=[success()]), SkillRequest("r", fsm="arm", goal="go")]))
    with pytest.raises(ModelError, match="single SkillRequest"):
        vector.reach(m)
    same(explore_fsm(m, "arm"), vector.explore(m, fsm="arm"))  # the FSM alone is in scope


def test_subtree_states_are_refused():
    arm = FSM("arm", states=[State("a", subtree=Action("inner", outcomes=[success()]))], goals=["go"])
    m = Model("t", fsms=[arm], tree=SkillRequest("r", fsm="arm", goal="go"))
    with pytest.raises(ModelError, match="subtree"):
        vector.reach(m)


def test_domain_errors_are_reported_like_the_generic_engine():
    arm = FSM("arm", states=[State("a", outcomes=[success(n="n + 1")])], goals=["go"], edges=[Edge("a", "a", ["go"])])
    m = Model("overflow", variables=[Int("n", 0, 2)], fsms=[arm], tree=SkillRequest("r", fsm="arm", goal="go"))
    tv, tg = vector.explore(m), explore(m)
    same(tg, tv)
    assert len(tv.errors) == 1 and tv.errors[0].var == "n" and tv.errors[0].value == 3
    assert list(tv.dead) == [2] or len(tv.dead) == 1


def test_states_are_decoded_like_the_generic_engine():
    m = pickplace(3)
    tv = vector.explore(m)
    assert tv.slots == explore(m).slots and tv.states.dtype == np.int8
    assert tv.decode(0) == explore(m).decode(0)


def test_hand_written_features_same_as_generic():
    m = feature_model()
    tg, tv = explore(m), vector.explore(m)
    same(tg, tv)
    assert tv.violations and any(st == 2 for st in tv.status)  # a post breach and a FAILURE reply
    same(explore_fsm(m, "arm"), vector.explore(m, fsm="arm"))
    same(explore_fsm(m, "arm", goals=["rest"]), vector.explore(m, fsm="arm", goals=["rest"]))
