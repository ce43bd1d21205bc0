"""Wide environments (issue 18, point 5): when the environment's answers multiply
(``traced.ENV_WIDE``), the traced engine walks one trie per environment entry and one
for the tree (``traced._Staged``). The system is the scalar engine's, field by field: on
the six-counter example, on every built-in model and on random models with several
independent (and dependent) environment entries, under state and transition budgets."""
from __future__ import annotations

import dataclasses
import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from memo_strategies import st

import btfsm.verify.traced as traced
from btfsm import EnvChoice, EnvEvent, Int, Model
from btfsm.files import load_model
from btfsm.models.registry import BUILTIN, HEAVY, load_builtin
from btfsm.verify.explore import explore
from strategies import random_models
from test_verify_traced import assert_same

LONG = os.environ.get("BTFSM_LONG") == "1"  # long randomized runs (common.md): 400 models, else 30
SIX = Path(__file__).resolve().parent.parent / "docs" / "examples" / "six_counters.yaml"


def both(model, **kw):
    return explore(model, engine="scalar", **kw), explore(model, engine="traced", **kw)


@pytest.fixture
def staged(monkeypatch):
    """Every model with an environment takes the staged search."""
    monkeypatch.setattr(traced, "ENV_WIDE", 1)


def test_six_counters_take_the_staged_search(monkeypatch):
    m = load_model(str(SIX))
    assert traced.env_width(m.program) == 3 ** 6 >= traced.ENV_WIDE
    calls = []
    monkeypatch.setattr(traced._Staged, "expand", lambda self, *a, _f=traced._Staged.expand: calls.append(1) or _f(self, *a))
    for kw in ({"max_states": 3000}, {"max_transitions": 20000}, {"max_states": 1}):
        a, b = both(m, **kw)
        assert_same(a, b)
        assert not b.complete
    assert calls
    del calls[:]
    ts = explore(m, max_states=3000)  # auto: the traced engine at once (no scalar probe)
    assert (ts.n_states, ts.n_transitions, ts.stopped) == (3000, 35260, "states") and calls


@pytest.mark.parametrize("name", sorted(n for n in set(BUILTIN) - HEAVY))
def test_builtin_models_explore_identically_staged(staged, name):
    m = load_builtin(name)
    if not m.environment:
        pytest.skip("no environment")
    assert_same(*both(m))


def test_budget_cut_and_small_batches_staged(staged, monkeypatch):
    monkeypatch.setattr(traced, "CHUNK", 5)
    monkeypatch.setattr(traced, "ROWS_LIMIT", 40)  # batches split often
    for name, kw in (("pickplace3", {"max_states": 333}), ("defect-domain", {}), ("two-area", {"max_transitions": 1001}),
                     ("two-area", {"max_transitions": 1})):
        assert_same(*both(load_builtin(name), **kw))


@pytest.mark.parametrize("limit", [3, 50])
def test_one_state_walked_in_slices(staged, monkeypatch, limit):
    """A state whose rows pass ROWS_LIMIT is walked on in slices, and stops early once a
    budget is hit among its successors: the same system, cut at the same transition."""
    monkeypatch.setattr(traced, "ROWS_LIMIT", limit)
    six = load_model(str(SIX))
    for m, kws in ((six, ({"max_states": 300}, {"max_transitions": 2000}, {"max_states": 2})),
                   (load_builtin("defect-domain"), ({"max_states": 10},)),
                   (load_builtin("pickplace3"), ({"max_transitions": 500},))):
        for kw in kws:
            assert_same(*both(m, **kw))


def test_dense_and_hashed_kind_tables_agree(staged, monkeypatch):
    m = load_builtin("pickplace3")
    ref = explore(m, engine="scalar")
    monkeypatch.setattr(traced._Staged, "TABLE", 0)  # every (environment key, tree leaf) pair hashed
    assert_same(ref, explore(m, engine="traced"))


def _counter_choice(i: int, guards: tuple, lo: int, hi: int):
    """Choice ``zc{i}`` on ``w{i}``: up, down, stay; each option's guard drawn (an unguarded
    up or down can leave the domain: a domain error)."""
    up = EnvEvent(f"zup{i}", f"w{i} < {hi}" if guards[0] else None, {f"w{i}": f"w{i} + 1"})
    down = EnvEvent(f"zdown{i}", f"w{i} > {lo}" if guards[1] else None, {f"w{i}": f"w{i} - 1"})
    stay = EnvEvent(f"zstay{i}", f"w{i} != {lo}" if guards[2] else None)
    return EnvChoice(f"zc{i}", (up, down, stay))


@st.composite
def wide_models(draw):
    """A random model with 2 to 4 extra counters, each moved by its own choice (independent
    choices), and an event that reads one counter and writes another (dependent entries),
    placed anywhere among the model's own environment entries."""
    base = draw(random_models(max_vars=3, max_fsms=2, tree_depth=2))
    k = draw(st.integers(2, 4))
    hi = draw(st.integers(1, 3))
    extra = [_counter_choice(i, tuple(draw(st.booleans()) for _ in range(3)), 0, hi) for i in range(k)]
    if draw(st.booleans()):
        extra.append(EnvEvent("zcarry", f"w0 == {hi}", {"w1": "0"}))
    env = list(base.environment)
    for e in extra:
        env.insert(draw(st.integers(0, len(env))), e)
    return dataclasses.replace(base, variables=tuple(base.variables) + tuple(Int(f"w{i}", 0, hi) for i in range(k)),
                               environment=tuple(env))


@settings(max_examples=400 if LONG else 30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(wide_models(), st.sampled_from(["max_states", "max_transitions", None]), st.integers(1, 2000))
def test_random_wide_models_explore_identically(model, budget, limit):
    assert traced.env_width(model.program) >= 3 ** 2
    kw = {budget: limit} if budget else {"max_states": 2000}
    old = traced.ENV_WIDE
    traced.ENV_WIDE = 1
    try:
        assert_same(*both(model, **kw))
    finally:
        traced.ENV_WIDE = old


@pytest.mark.parametrize("n", [6, 12])
def test_free_booleans_are_staged_and_cut_exactly(n):
    """``n`` free boolean events: 2**n answers per state, paths 2 per event."""
    m = Model("free", variables=[Int("x", 0, 1)] + [Int(f"b{i}", 0, 1) for i in range(n)],
              environment=[EnvEvent(f"flip{i}", None, {f"b{i}": f"1 - b{i}"}) for i in range(n)])
    assert traced.env_width(m.program) >= traced.ENV_WIDE
    a, b = both(m, max_transitions=3 * 2 ** n + 5)
    assert_same(a, b)
    assert b.stopped == "transitions" and b.n_transitions == 3 * 2 ** n + 5
