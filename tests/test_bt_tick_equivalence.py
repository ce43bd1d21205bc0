"""benchmarks/bt_tick.py does the same work in btfsm and py_trees (so its timings compare).

The 30-node anchor tree is built in both libraries; every tick must visit the same nodes
in the same order with the same statuses, halt the same running actions and give the
same root status. Skipped when py_trees (the ``bench`` extra) is not installed.
"""
from __future__ import annotations

import importlib.util
import io
import pathlib

import pytest
from hypothesis import given, settings, strategies as st

pytest.importorskip("py_trees")

from btfsm import (ConformanceError, Effects, ForceSuccess, Guard, Inverter, MemorySequence,  # noqa: E402
                   Parallel, ReactiveFallback, ReactiveSequence, Retry, Status)
from btfsm.runtime import Runtime  # noqa: E402
from btfsm.trace import replay  # noqa: E402

_PATH = pathlib.Path(__file__).resolve().parents[1] / "benchmarks" / "bt_tick.py"
_spec = importlib.util.spec_from_file_location("bt_tick", _PATH)
bt_tick = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bt_tick)

TICKS = 2000


def _btfsm_shape(node):
    kinds = {ReactiveSequence: "Sequence/reactive", MemorySequence: "Sequence/memory",
             ReactiveFallback: "Selector/reactive", Parallel: "Parallel", Inverter: "Inverter",
             Retry: "Retry", ForceSuccess: "FailureIsSuccess", Guard: "EternalGuard",
             Effects: "StatusToBlackboard"}
    kind = kinds.get(type(node), "leaf")
    return (node.name, kind, tuple(_btfsm_shape(c) for c in node.children_of()))


def _pytrees_shape(b):
    import py_trees

    kind = type(b).__name__
    if isinstance(b, py_trees.composites.Composite) and not isinstance(b, py_trees.composites.Parallel):
        kind += "/memory" if b.memory else "/reactive"
    elif not b.children:
        kind = "leaf"
    return (b.name, kind, tuple(_pytrees_shape(c) for c in b.children))


def test_same_tree_node_for_node():
    model = bt_tick.build_model(100)
    shape = _btfsm_shape(model.tree)
    assert shape == _pytrees_shape(bt_tick.build_pytrees()[0])
    nodes = list(bt_tick.walk(model.tree))
    leaves = [n for n in nodes if not n.children_of()]
    assert (len(nodes), len(nodes) - len(leaves), len(leaves)) == (30, 14, 16)
    assert model.warnings == () and model.program.lints == []


def test_counters_equal_py_trees():
    ref = bt_tick.pytrees_counters(TICKS)
    assert bt_tick.btfsm_counters(TICKS) == ref
    assert bt_tick.step_counters(TICKS) == ref
    # the scenario exercises preemption and completion, not only steady running
    assert ref["halts"] > 0 and ref["root_success_ticks"] > 0


def test_every_tick_visits_the_same_nodes():
    assert bt_tick.btfsm_visit_log(TICKS) == bt_tick.pytrees_visit_log(TICKS)


def test_comparison_detects_a_different_tree():
    # a one-tick change of one action on one side only must show up
    assert bt_tick.btfsm_visit_log(300) != bt_tick.pytrees_visit_log(300, {"MoveTo": 7})
    assert bt_tick.btfsm_counters(300) != bt_tick.pytrees_counters(300, {"Dock": 5})


@settings(max_examples=12, deadline=None)
@given(st.fixed_dictionaries({name: st.integers(1, 9) for name in bt_tick.DURATIONS}))
def test_equivalent_for_any_durations(durations):
    ticks = 300
    assert bt_tick.btfsm_visit_log(ticks, durations) == bt_tick.pytrees_visit_log(ticks, durations)
    ref = bt_tick.pytrees_counters(ticks, durations)
    assert bt_tick.btfsm_counters(ticks, durations) == ref == bt_tick.step_counters(ticks, durations)


def test_measure_reports_ratio_and_overhead():
    rep = bt_tick.measure(200, 1, modes=("py_trees", "runtime", "runtime+trace", "step", "step+record"))
    assert rep["identical"] and rep["nodes"] == 30 and rep["leaves"] == 16
    assert rep["runtime_vs_py_trees"] > 0 and "runtime+trace_overhead_pct" in rep


# ---- the Runtime fast paths this benchmark added (reused oracle, outcome-name cache)


def test_runtime_trace_replays():
    out = io.StringIO()
    rt = Runtime(bt_tick.build_model(500), bt_tick.implementations(), trace=out)
    statuses = {rt.tick().status for _ in range(500)}
    assert statuses <= set(Status) and Status.SUCCESS in statuses
    assert replay(out.getvalue().splitlines(), rt.model) is None


def test_runtime_answers_and_events_still_checked():
    from btfsm import EnvEvent, Int, Model, Action, running, success

    m = Model("m", variables=[Int("n", 0, 9)], environment=[EnvEvent("e", None, {"n": "n + 1"})],
              tree=Action("a", outcomes=[running("busy"), success(n="n + 1")]))
    answers = iter([Status.RUNNING, 1, "busy", "success", "nope"])
    rt = Runtime(m, {"a": lambda call: next(answers)})
    assert [rt.tick(ev).status for ev in (["e"], [], (), ["e"])] == [Status.RUNNING, Status.SUCCESS] * 2
    assert rt.vars["n"] == 4
    with pytest.raises(ConformanceError, match="not a declared outcome"):
        rt.tick()
    with pytest.raises(ConformanceError, match="not enabled"):
        Runtime(m, {"a": lambda call: "busy"}).tick(["zzz"])
