"""The traced engine's two-phase search of models with timers (issue 12.5; docs/verification.md
2.1 and 5): the reachable code graph first, with the timers' runs guessed ahead, then the
breadth-first numbering. It must give the ordinary search's system exactly (states and
their numbering, transitions, labels, statuses, parents, violations, domain errors), and
give way to the ordinary search wherever a budget cuts the system or paths multiply.
Its parts are checked against plain oracles: the hash table of visited codes against a
dict, the table decoder against per-slot division, the guessed runs against their
definition; and the response sweeps on larger random graphs against a direct recursion.
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from memo_strategies import st

import btfsm.verify.traced as traced
import btfsm.verify.visited as visited
from btfsm import Model, ModelError
from btfsm.files import model_from_data
from btfsm.verify.codec import codec, decode
from btfsm.verify.explore import explore, explore_fsm
from btfsm.verify.properties.response import INF, best_until, worst_until

from strategies import timed_models
from test_verify_traced import assert_same

SLOW_TIMERS = {
    "name": "timers",
    "tick_rate": 10,
    "variables": {"q": {"int": [0, 2]}, "done": {"int": [0, 3]}},
    "primitives": {
        "work": {"outcomes": ["running", {"success": {"q": "q - 1", "done": "done + 1 if done < 3 else done"}},
                              "failure"], "duration": [0.0, 1.5]},
        "check": {"outcomes": ["success", "failure"]},
    },
    "tree": {"ReactiveFallback": "root", "children": [
        {"Condition": "idle", "expr": "q == 0"},
        {"Action": "w", "primitive": "work"}]},
    "environment": [{"event": "arrive", "guard": "q < 2", "effects": {"q": "q + 1"}, "min_interval": 2.0}],
}


def _model():
    return model_from_data(SLOW_TIMERS)


def _ordinary(monkeypatch):
    """Switch the two-phase search off (the ordinary breadth-first search runs)."""
    monkeypatch.setattr(traced, "_timer_slots", lambda *a: ())


def _spy(monkeypatch):
    """Count the systems the two-phase search gave (None: it gave way)."""
    got = []
    real = traced._search_closure
    monkeypatch.setattr(traced, "_search_closure", lambda *a: got.append(real(*a)) or got[-1])
    return got


def test_the_two_phase_search_gives_the_ordinary_system(monkeypatch):
    m = _model()
    got = _spy(monkeypatch)
    a = explore(m, engine="traced")
    assert len(got) == 1 and got[0] is not None and a.n_states > 100
    assert_same(a, explore(m, engine="scalar"))
    with monkeypatch.context() as mp:
        _ordinary(mp)
        assert_same(a, explore(m, engine="traced"))


def test_domain_errors_are_reported_as_the_ordinary_search_reports_them(monkeypatch):
    import copy

    data = copy.deepcopy(SLOW_TIMERS)
    data["primitives"]["work"]["outcomes"][1] = {"success": {"q": "q - 1", "done": "done + 1"}}  # past 3: an error
    m = model_from_data(data)
    got = _spy(monkeypatch)
    a = explore(m, engine="traced")
    assert got and got[0] is not None and a.errors
    assert_same(a, explore(m, engine="scalar"))


@pytest.mark.parametrize("budget", [{"max_states": 7}, {"max_states": 150}, {"max_transitions": 40},
                                    {"max_transitions": 333}, {"max_seconds": 600}])
def test_budgets_cut_where_the_ordinary_search_cuts(monkeypatch, budget):
    m = _model()
    got = _spy(monkeypatch)
    a = explore(m, engine="traced", **budget)
    b = explore(m, engine="scalar", **budget)
    assert_same(a, b)
    assert a.stopped == b.stopped
    if "max_seconds" in budget:
        assert got == []  # a time budget: the ordinary search, whose cut the clock decides
    elif not a.complete:
        assert got == [None]  # the system is cut: the two-phase search gave way


def test_a_budget_that_does_not_cut_keeps_the_two_phase_search(monkeypatch):
    m = _model()
    full = explore(m, engine="scalar")
    got = _spy(monkeypatch)
    a = explore(m, engine="traced", max_states=full.n_states, max_transitions=full.n_transitions)
    assert got and got[0] is not None and a.complete
    assert_same(a, full)


def test_many_paths_give_way_to_the_ordinary_search(monkeypatch):
    """Past PATHS_MIN paths the two-phase search gives way; the ordinary search then stops
    where it always stopped (engine='traced': a "paths" budget)."""
    m = _model()
    monkeypatch.setattr(traced, "PATHS_MIN", 3)
    got = _spy(monkeypatch)
    a = explore(m, engine="traced")
    assert got == [None] and a.stopped == "paths"
    with monkeypatch.context() as mp:
        _ordinary(mp)
        assert_same(a, explore(m, engine="traced"))


def test_a_tracer_failure_in_the_first_phase_gives_way(monkeypatch):
    """The tracer may fail on a guessed state no run reaches: the ordinary search runs."""
    m = _model()
    calls, real = [], traced._Engine.expand

    def expand(self, codes, cap=traced.ROWS_LIMIT):
        calls.append(len(codes))
        if len(calls) == 2:
            raise traced.Untraceable("on a guessed state")
        return real(self, codes, cap)

    monkeypatch.setattr(traced._Engine, "expand", expand)
    got = _spy(monkeypatch)
    a = explore(m, engine="traced")
    assert got == [None] and len(calls) > 2
    assert_same(a, explore(m, engine="scalar"))


def test_progress_during_both_phases():
    m = _model()
    calls = []
    a = explore(m, engine="traced", progress=lambda *x: calls.append(x))
    assert len(calls) >= 2 and calls[-1][:2] == (a.n_states, a.n_transitions)


def test_guessed_unreachable_states_are_never_numbered(monkeypatch):
    """Guessing far ahead expands states no run reaches; the system stays the same."""
    m = _model()
    monkeypatch.setattr(traced, "RUN_GUESS", 1000)
    assert_same(explore(m, engine="traced"), explore(m, engine="scalar"))


@settings(max_examples=120, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(timed_models(), st.sampled_from([None, 60, 3000]), st.sampled_from([1, 3, 16]))
def test_random_timed_models_explore_as_the_scalar_engine(model, budget, guess):
    try:
        model.program
    except ModelError:
        return
    keep, traced.RUN_GUESS = traced.RUN_GUESS, guess
    try:
        traced_ts = explore(model, engine="traced", max_states=budget or 3000)
    finally:
        traced.RUN_GUESS = keep
    assert_same(traced_ts, explore(model, engine="scalar", max_states=budget or 3000))
    for f in model.fsms:
        assert_same(explore_fsm(model, f.name, engine="traced", max_states=800),
                    explore_fsm(model, f.name, engine="scalar", max_states=800))


def test_random_timed_models_use_the_two_phase_search(monkeypatch):
    """The property above is not vacuous: on the same kind of models, most systems come
    from the two-phase search (the others are cut by the budget or have no timer)."""
    got = _spy(monkeypatch)

    @settings(max_examples=40, deadline=None, derandomize=True, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
    @given(timed_models())
    def run(model):
        try:
            model.program
        except ModelError:
            return
        explore(model, engine="traced", max_states=3000)

    run()
    assert sum(ts is not None for ts in got) >= 10, len(got)


# ---------------------------------------------------------------------- the parts


@settings(max_examples=200, deadline=None, derandomize=True, database=None)
@given(st.lists(st.lists(st.integers(0, 4095), max_size=60), max_size=8), st.booleans())
def test_the_first_phase_numbers_codes_in_the_order_first_met(batches, hashed):
    """What ``_closure`` does with each batch's targets: the unseen ones, distinct, in the
    order first met, are numbered next; ``number`` gives every code its entry at the end."""
    c0 = 7
    seen = (visited.Hashed if hashed else visited.Bitmap)(1 << 12, c0)
    ref = {c0: 0}
    for batch in batches:
        codes = np.array(batch, np.int64)
        new = codes[traced._first_positions(codes, np.flatnonzero(~seen.seen(codes)), 1 << 12)]
        assert new.tolist() == [c for c in dict.fromkeys(batch) if c not in ref]
        seen.add(new)
        for c in new.tolist():
            ref[c] = len(ref)
    every = np.array(sorted(ref), np.int64)
    assert seen.number(every.copy()).tolist() == [ref[c] for c in every.tolist()]
    assert seen.codes[:seen.n].tolist() == list(ref)


@settings(max_examples=150, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.filter_too_much])
@given(st.lists(st.tuples(st.sampled_from([1, 2, 3, 7, 300, 70000]), st.integers(-3, 3)), min_size=1, max_size=9),
       st.data())
def test_decode_by_table_equals_division(slots, data):
    prog = SimpleNamespace(slots=[SimpleNamespace(size=s, lo=lo) for s, lo in slots])
    kept = tuple(range(len(slots)))
    mults, offset, total = codec(prog, kept)
    assume(total < 1 << 62)  # the engines' code space (traced.Untraceable past it)
    codes = np.array(data.draw(st.lists(st.integers(0, total - 1), min_size=1, max_size=40)), np.int64)
    got = decode(prog, kept, codes + offset, offset, mults)
    for col, (size, lo) in enumerate(slots):
        assert got[:, col].tolist() == ((codes // mults[col]) % size + lo).tolist()


def test_guessed_runs_follow_timer_steps_within_their_domains():
    m = _model()
    prog = m.program
    kept = tuple(range(len(prog.slots)))
    eng = traced._Engine(m, prog.step, kept, prog.initial, None)
    timers = traced._timer_slots(prog, kept, eng.mults)
    assert timers
    ts = explore(m, engine="scalar")
    mults = np.array(eng.mults, np.int64)
    codes = ts.states.astype(np.int64) @ mults - eng.offset
    src, dst = codes[ts.src], codes[ts.dst]
    guess = traced._timer_runs(eng, timers, src, dst)
    assert len(guess)
    rows = decode(prog, kept, guess + eng.offset, eng.offset, eng.mults)
    for k, info in enumerate(prog.slots):
        assert (rows[:, k] >= info.lo).all() and (rows[:, k] < info.lo + max(info.size, 1)).all()
    # every guess is dst + j * (dst - src) of a step that moves timers only, by one tick
    delta = ts.states[ts.dst].astype(np.int64) - ts.states[ts.src]
    tick = np.ones(len(src), bool)
    for k in range(len(prog.slots)):
        tick &= np.isin(delta[:, k], (0, 1)) if k in timers else delta[:, k] == 0
    tick &= (delta[:, list(timers)] == 1).any(axis=1)
    steps = set(zip(dst[tick].tolist(), (dst - src)[tick].tolist()))
    for g in guess.tolist():
        assert any((g - d) % s == 0 and 1 <= (g - d) // s <= traced.RUN_GUESS for d, s in steps if s), g


def test_no_timer_no_two_phase_search(monkeypatch):
    from btfsm.models.registry import load_builtin

    got = _spy(monkeypatch)
    explore(load_builtin("pickplace3"), engine="traced")
    explore(Model("m", variables=[]), engine="traced")
    assert got == []


# ---------------------------------------------------------------------- the response sweeps


def rec_worst(n, src, dst, stop):
    """Longest stop-free path to a stop node by recursion with colours (INF on a reachable
    stop-free cycle or dead end)."""
    succ = [[] for _ in range(n)]
    for a, b in zip(src.tolist(), dst.tolist()):
        succ[a].append(b)
    memo, on = {}, set()

    def go(u):
        if stop[u]:
            return 0
        if u in memo:
            return memo[u]
        if u in on or not succ[u]:
            return INF
        on.add(u)
        w = 0
        for v in succ[u]:
            x = go(v)
            if x == INF:
                w = INF
                break
            w = max(w, x + 1)
        on.discard(u)
        memo[u] = w
        return w
    return [go(u) for u in range(n)]


def rec_best(n, src, dst, stop):
    dist = [INF] * n
    frontier = [u for u in range(n) if stop[u]]
    for u in frontier:
        dist[u] = 0
    k = 0
    while frontier:
        k += 1
        nxt = []
        for a, b in zip(src.tolist(), dst.tolist()):
            if b in frontier and dist[a] == INF:
                dist[a] = k
                nxt.append(a)
        frontier = set(nxt)
    return dist


@settings(max_examples=150, deadline=None, derandomize=True, database=None)
@given(st.integers(2, 40), st.data())
def test_sweeps_on_larger_graphs_equal_a_recursion(n, data):
    m = data.draw(st.integers(0, 4 * n))
    edges = data.draw(st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1)), min_size=m, max_size=m))
    dag = data.draw(st.booleans())
    if dag:  # mostly acyclic: long finite worst cases
        edges = [(a, b) if a < b else (b, a) for a, b in edges if a != b]
    stop = np.array(data.draw(st.lists(st.booleans(), min_size=n, max_size=n)), bool)
    src = np.array([e[0] for e in edges], np.int64)
    dst = np.array([e[1] for e in edges], np.int64)
    import sys

    sys.setrecursionlimit(max(1000, 10 * n))
    assert worst_until(n, src, dst, stop).tolist() == rec_worst(n, src, dst, stop)
    assert best_until(n, src, dst, stop).tolist() == rec_best(n, src, dst, stop)
