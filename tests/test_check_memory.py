"""Issue 24: the full check reads a compact system without building its derived arrays,
and holds one large system at a time; the answers are those of the derived arrays.

(The memory itself is measured by ``benchmarks/check_memory.py``, not here.)
"""
from __future__ import annotations

import numpy as np
import pytest

from btfsm.models.pickplace import pickplace
from btfsm.models.registry import load_builtin
from btfsm.verify.explore import explore, explore_fsm
from btfsm.verify.properties import Context, run_property
from btfsm.verify.report import check
from btfsm.verify.system import components, forward_csr, reverse_reach, strong_components

DERIVED = ("states", "src", "label", "status", "goal")


@pytest.fixture(scope="module")
def systems():
    m = pickplace(3)
    return explore(m, engine="traced"), explore_fsm(m, "skill", engine="traced")


def test_the_compact_readers_agree_with_the_derived_arrays(systems):
    for ts in systems:
        fresh = type(ts).__new__(type(ts))
        fresh.__dict__.update({k: v for k, v in ts.__dict__.items() if k not in DERIVED})
        prog = ts.model.program
        for slot in range(len(prog.slots)):
            assert np.array_equal(fresh.column(slot), ts.column(slot))
        for i in (0, 1, ts.n_states // 2, ts.n_states - 1):
            assert fresh.full_state(i) == ts.full_state(i)
            assert fresh.decode(i) == ts.decode(i)
            assert fresh.path_to(i) == ts.path_to(i)
        for t in (0, 7, ts.n_transitions - 1):
            assert fresh.source(t) == int(ts.src[t]) and fresh.label_of(t) == int(ts.label[t])
        assert np.array_equal(fresh.where(lambda label, status, goal: status == 1), ts.status == 1)
        got = np.concatenate([src for _, _, src in fresh.slices(size=1000)])
        assert np.array_equal(got, ts.src)
        mask = (ts.dst % 3 == 0)
        assert np.array_equal(fresh.any_out(mask), np.isin(np.arange(ts.n_states), ts.src[mask]))
        pos, s, d = fresh.pick(mask)
        assert np.array_equal(pos, np.flatnonzero(mask)) and np.array_equal(s, ts.src[mask])
        offs, targets = forward_csr(fresh, mask)
        assert np.array_equal(np.repeat(np.arange(ts.n_states), np.diff(offs)), ts.src[mask])
        assert np.array_equal(targets, ts.dst[mask])
        count, label = components(fresh, mask)
        ref = strong_components(ts.n_states, ts.src[mask], ts.dst[mask])
        assert count == ref.max() + 1 and len({(a, b) for a, b in zip(label, ref)}) == count
        # backward reachability over the selection, against a fixed point over (src, dst)
        goal = np.zeros(ts.n_states, bool)
        goal[-1] = True
        want = goal.copy()
        while True:
            more = want.copy()
            more[ts.src[mask][want[ts.dst[mask]]]] = True
            if np.array_equal(more, want):
                break
            want = more
        assert np.array_equal(reverse_reach(fresh, goal, mask), want)
        assert not any(k in fresh.__dict__ for k in DERIVED)


def test_the_check_lets_the_models_system_go_before_the_fsms_and_answers_the_same():
    m = pickplace(2)
    names = ["lints", "goal-reachability", "workable-reachability", "no-dead-states", "invariants"]
    r = check(m, names)
    ctx = Context(m)  # used directly: keeps every system, properties in the given order
    direct = [run_property(ctx, n).to_json() for n in [p.name for p in r.results]]
    for a, b in zip(r.results, direct):
        a = a.to_json()
        a.pop("seconds"), b.pop("seconds")
        assert a == b
    assert [s["kind"] for s in r.to_json()["systems"]] == ["model", "fsm"]


def test_the_schedule_frees_the_model_system():
    from btfsm.verify.report import _schedule

    m = load_builtin("ariac-preemptive")
    ctx = Context(m)
    names = ["workable-reachability", "goal-reachability", "no-dead-states", "lints", "invariants"]
    order = list(_schedule(ctx, names))
    # model readers first (a small model: lints read it too), then no-dead-states, then the FSM readers
    assert [n for n, _, _ in order] == ["workable-reachability", "invariants", "lints", "no-dead-states",
                                        "goal-reachability"]
    assert all(during for _, during, _ in order[:3])
    assert order[-2][0] == "no-dead-states" and order[-2][1:] == (False, False)
    ctx.model_needed = False
    ctx.model_ts()
    ctx.done_with_model()
    assert ctx._model_ts is None and ctx.model_size()[1] is True
    with pytest.raises(RuntimeError):
        ctx.model_ts()


def test_components_with_repeated_transitions():
    """Transitions that differ only by label repeat an entry of the CSR, on which scipy's
    strong components never return: ``components`` merges them first."""
    ts = explore(load_builtin("original"))
    pairs = ts.src.astype(np.int64) * ts.n_states + ts.dst
    assert np.unique(pairs).size < pairs.size  # the model has such transitions
    count, label = components(ts)
    ref = strong_components(ts.n_states, ts.src, ts.dst)
    assert count == ref.max() + 1 and len(set(zip(label.tolist(), ref.tolist()))) == count


def test_repeats_found_and_not_invented(systems):
    from btfsm.verify.system import _repeats

    for ts in (*systems, explore(load_builtin("original"))):
        pairs = ts.src.astype(np.int64) * ts.n_states + ts.dst
        assert _repeats(ts) == (np.unique(pairs).size < pairs.size)
