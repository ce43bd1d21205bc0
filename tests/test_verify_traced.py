"""The path-compiled engine (verify.traced) gives the scalar engine's system exactly:
same states in the same order, same transitions, labels, statuses, parents, requested
goals, contract violations, domain errors and budget cut, for whole models and FSMs as
open systems, on every built-in model and on random ones."""
from __future__ import annotations

import json
import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from memo_strategies import st

import btfsm.verify.traced as traced
import btfsm.verify.visited as visited
from btfsm.models.registry import BUILTIN, HEAVY, load_builtin
from strategies import random_models

# random models, scalar vs traced engine: 60/40/60 by default, 150/100/150 with BTFSM_LONG=1
# (the two engines also meet on random models in every run in tests/test_durations.py, timed
# models with their FSM levels, tests/test_wide_env.py, wide environments, and
# tests/test_timed_closure.py)
LONG = os.environ.get("BTFSM_LONG") == "1"
from test_spin_crosscheck import seeded_models
from btfsm.verify.explore import explore, explore_fsm

ARRAYS = ("states", "src", "dst", "label", "parent", "status")
FIELDS = ("labels", "complete", "expanded", "violations", "kind", "slots")


def assert_same(a, b):
    for f in ARRAYS:
        x, y = getattr(a, f), getattr(b, f)
        assert x.shape == y.shape and np.array_equal(x, y), f
    for f in FIELDS:
        assert getattr(a, f) == getattr(b, f), f
    assert (a.goal is None) == (b.goal is None) and (a.goal is None or np.array_equal(a.goal, b.goal))
    key = [(e.state, e.script, e.label, e.var, e.value, e.where, e.message) for e in a.errors]
    assert key == [(e.state, e.script, e.label, e.var, e.value, e.where, e.message) for e in b.errors]


def both(model, **kw):
    return explore(model, engine="scalar", **kw), explore(model, engine="traced", **kw)


@pytest.mark.parametrize("name", sorted(set(BUILTIN) - HEAVY))
def test_builtin_models_explore_identically(name):
    assert_same(*both(load_builtin(name)))


@pytest.mark.parametrize("name", sorted(set(BUILTIN) - HEAVY))
def test_builtin_fsms_explore_identically(name):
    m = load_builtin(name)
    for f in m.fsms:
        assert_same(explore_fsm(m, f.name, engine="scalar"), explore_fsm(m, f.name, engine="traced"))


@pytest.mark.parametrize("budget", [1, 2, 50, 777, 5000])
def test_budget_cut_is_the_generic_engines(budget):
    for name in ("pickplace3", "defect-domain", "ariac-preemptive"):
        a, b = both(load_builtin(name), max_states=budget)
        assert_same(a, b)


def test_small_batches_and_hashed_visited_set(monkeypatch):
    monkeypatch.setattr(traced, "CHUNK", 7)
    monkeypatch.setattr(traced, "DENSE_IDS", 0)  # not a table of ids ...
    monkeypatch.setattr(traced, "DENSE_LIMIT", 0)  # ... nor a bitmap: a hash table
    monkeypatch.setattr(visited.Hashed, "FIRST", 4)  # grown many times
    monkeypatch.setattr(traced, "STEP", 5)  # re-hashing and numbering in many slices
    monkeypatch.setattr(traced, "TERMS_LIMIT", 0)  # target codes summed leaf by leaf
    for name in ("pickplace3-dead", "defect-domain", "two-area", "original"):
        m = load_builtin(name)
        assert_same(*both(m))
        f = m.fsms[0].name
        assert_same(explore_fsm(m, f, engine="scalar", max_states=900), explore_fsm(m, f, engine="traced", max_states=900))


def test_bitmap_numbering_in_slices(monkeypatch):
    monkeypatch.setattr(traced, "DENSE_IDS", 0)  # a bitmap, not a table of ids
    monkeypatch.setattr(traced, "STEP", 3)  # ranks and target ids computed a few at a time
    for name in ("pickplace3", "two-area"):
        assert_same(*both(load_builtin(name)))
    assert_same(*both(load_builtin("pickplace3"), max_states=777))  # a state budget cuts it as the scalar engine does


def test_decision_keys_past_their_limit_walk_the_trie(monkeypatch):
    monkeypatch.setattr(traced, "KEY_LIMIT", 4)  # (keys of more than two decisions: the row-set walk)
    assert_same(*both(load_builtin("pickplace3"), max_states=2000))
    monkeypatch.setattr(traced, "KEY_LIMIT", 1 << 62)
    monkeypatch.setattr(traced, "NEW_KEYS", 0)  # batches with many new keys walk it too, the others by key
    assert_same(*both(load_builtin("pickplace3"), max_states=2000))


def test_a_switch_on_a_computed_value_widens_its_key():
    """A decision on an int that is no slot's value (a list index computed from a variable)
    has no known range: the traced engine's decision keys widen it as its values come
    (forgetting the groups kept), and the system stays the scalar engine's."""
    from btfsm import Int, Model
    from btfsm.verify import scalar
    from btfsm.verify.search import Budget, SearchTask

    m = Model("hop", variables=[Int("x", 0, 9)])
    hops = (3, 5, 7, 9, 1, 2, 4, 6, 8, 0, 1, 2)

    class Step:
        status, violations = 0, None

        def __init__(self, state):
            self.state = state

    def run(s, o):
        c = o.choose(("input", 0), (1, 2))
        return Step((hops[s[0] + c + 1],))  # the index: a switch on x + c + 1

    task = SearchTask(m, "model", None, (0,), run, (0,))
    a, b = (e.search(task, Budget()) for e in (scalar, traced))
    assert b.n_states == 9 and b.n_transitions == 18
    assert_same(a, b)


def test_compact_storage_derives_the_same_arrays():
    ts = explore(load_builtin("pickplace3"), engine="traced")
    assert ts.codes is not None and ts.edge is not None  # stored compactly ...
    assert ts.dst.dtype == np.int32 and ts.edge.dtype == np.int8 and ts.parent.dtype == np.int32
    assert "src" not in ts.__dict__ and "states" not in ts.__dict__
    assert ts.offsets.dtype == np.int32 and ts.nbytes <= 12 * ts.n_states + 5 * ts.n_transitions + 64
    ref = explore(load_builtin("pickplace3"), engine="scalar")
    assert_same(ts, ref)  # ... and derives the scalar engine's arrays on first use
    assert np.array_equal(ts.offsets, np.searchsorted(ref.src, np.arange(ref.n_states + 1)))


def test_start_state_and_progress():
    m = load_builtin("pickplace3")
    start = m.program.encode({"area": 1, "grip": True})
    calls = []
    a = explore(m, start=start, engine="scalar")
    b = explore(m, start=start, engine="traced", progress=lambda *x: calls.append(x))
    assert_same(a, b)
    assert calls and calls[-1][:2] == (b.n_states, b.n_transitions)


def test_domain_errors_are_reported_like_the_generic_engine():
    a, b = both(load_builtin("defect-domain"))
    assert b.errors and len(a.errors) == len(b.errors)


def test_untraceable_falls_back_to_the_scalar_engine(monkeypatch):
    def refuse(self, *args):
        raise TypeError("not here")
    monkeypatch.setattr(traced._Tracer, "apply", refuse)
    m = load_builtin("pickplace3")
    with pytest.raises(traced.Untraceable):
        explore(m, engine="traced")
    assert_same(explore(m), explore(m, engine="scalar"))


def test_unknown_engine_is_refused():
    with pytest.raises(ValueError):
        explore(load_builtin("two-area"), engine="fast")


def test_a_decision_is_recorded_once_per_value():
    g = traced._Graph(2, [1])
    t = traced._Tracer(g)
    x, tok = traced.Sym(t, g.cols[0], 3), traced.Sym(t, g.cols[1], 2)
    y = x + 1
    assert isinstance(y, traced.Sym) and y.v == 4
    assert bool(y > 3) and bool(y > 3)  # the second is known
    assert [1, 2, 3][tok] == 3 and tok == 2  # a control slot is switched once, then constant
    assert t.path == [("b", g.ids[(">", y.n, g.const(3))], True), ("s", g.cols[1], 2)]


@settings(max_examples=150 if LONG else 60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(random_models())
def test_random_models_explore_identically(model):
    assert_same(*both(model, max_states=3000))


@settings(max_examples=100 if LONG else 40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(random_models(), st.integers(1, 3000))
def test_random_fsms_explore_identically(model, budget):
    for f in model.fsms:
        assert_same(explore_fsm(model, f.name, engine="scalar", max_states=budget),
                    explore_fsm(model, f.name, engine="traced", max_states=budget))


@settings(max_examples=150 if LONG else 60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seeded_models(tree=True, wild=True), st.integers(1, 400))
def test_random_whole_models_explore_identically(model, budget):
    assert_same(*both(model, max_states=budget))


def _without_times(obj):
    if isinstance(obj, dict):
        return {k: _without_times(v) for k, v in obj.items() if k != "seconds"}
    if isinstance(obj, list):
        return [_without_times(v) for v in obj]
    return obj


@pytest.mark.parametrize("name", ["original-preemptive", "defect-domain", "pickplace3-bug"])
def test_check_reports_are_the_same_with_either_engine(name):
    """Verdicts and counterexamples (shortest paths follow the same BFS numbering)."""
    from btfsm.verify.report import check

    m = load_builtin(name)
    a, b = (_without_times(check(m, engine=e).to_json()) for e in ("scalar", "traced"))
    assert a == b  # determinism's z3 witnesses included: each analysis has its own z3 context
    assert any(p["holds"] is False for p in b["properties"])


def test_cli_engine_option(capsys):
    from btfsm.cli import main

    codes = [main(["check", "defect-trap", "--json", "--engine", e]) for e in ("scalar", "traced")]
    first, second = (json.loads(x) for x in capsys.readouterr().out.strip().splitlines())
    assert codes == [1, 1] and _without_times(first) == _without_times(second)
    assert main(["check", "defect-trap", "--engine", "fast"]) == 2  # usage error: one line, exit 2


def test_auto_explores_small_systems_with_the_scalar_engine(monkeypatch):
    """engine='auto': at most AUTO_SCALAR_STATES states -> the scalar engine alone; larger
    systems are explored again by the traced engine; the same system either way."""
    from btfsm.verify import explore as explore_mod

    small = load_builtin("ariac-preemptive")
    ref = explore(small, engine="traced")
    called = []
    real = traced.search
    monkeypatch.setattr(traced, "search", lambda *a, **k: called.append(1) or real(*a, **k))
    assert_same(explore(small), ref)
    assert called == []
    big = load_builtin("pickplace3")  # 10,288 states
    assert big and explore_mod.AUTO_SCALAR_STATES < 10_288
    assert_same(explore(big), explore(big, engine="scalar"))
    assert called == [1]
    # a state budget within the probe is the user's cut, as the engines agree on it
    assert_same(explore(big, max_states=100), explore(big, engine="traced", max_states=100))


def test_auto_keeps_the_scalar_engine_for_narrow_levels(monkeypatch):
    """A system larger than the probe whose breadth-first levels average fewer than
    AUTO_NARROW_LEVEL states (ARIAC with 40 tray parts and a queue of 8: 11,319 states in
    levels of about 18) is explored by the scalar engine; the same system either way."""
    from btfsm.models.ariac import preemptive
    from btfsm.verify import explore as explore_mod

    m = preemptive(n_tray=40, queue_max=8)
    ref = explore(m, engine="traced")
    assert ref.n_states > explore_mod.AUTO_SCALAR_STATES
    assert ref.n_states < explore_mod.AUTO_NARROW_LEVEL * (int(ref.depth().max()) + 1)
    called = []
    monkeypatch.setattr(traced, "search", lambda *a, **k: called.append(1))
    assert_same(explore(m), ref)
    assert called == []
