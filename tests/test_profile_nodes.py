"""The node types added for BehaviorTree.CPP (docs/semantics.md sections 2 and 3), under
the default ``btfsm`` profile; under ``btcpp`` the same trees run against the real engine
in tests/test_profile_btcpp.py and tests/test_peer_btcpp.py. Leaves answer from a table of
statuses per tick (``tests/btcpp_peer.py``)."""
from __future__ import annotations

import pytest

from btcpp_peer import build, run_btfsm
from btfsm.errors import ModelError


def _run(spec, ticks, semantics="btfsm"):
    model, leaves = build(spec, ticks, semantics=semantics)
    return run_btfsm(model, leaves, ticks)


def _statuses(log):
    return "".join(s[0] for s, _ in log)


def test_sequence_with_memory():
    """FAILURE keeps the index: the failed child is ticked again, earlier ones are not;
    a halt keeps it too."""
    spec = ("SequenceWithMemory", "swm", [("sync", "a", "SSSS"), ("cond", "b", "FFSS"), ("async", "c", "RRRS")])
    log = _run(spec, 4)
    assert _statuses(log) == "FFRS"
    assert log[1][1] == [("b", "cond")] and log[2][1] == [("b", "cond"), ("c", "start")]
    outer = ("ReactiveFallback", "rf", [("cond", "k", "FSFF"), spec])
    log = _run(outer, 4)
    assert log[1][1] == [("k", "cond")]  # k succeeds: swm is not running (it failed), nothing to halt
    assert log[2][1] == [("k", "cond"), ("b", "cond"), ("c", "start")]  # index kept: resumes at b


def test_parallel_all():
    """Ticks the unfinished children until all finished; FAILURE at max_failures failures."""
    spec = ("ParallelAll", "pa", [("async", "a", "RFSS"), ("async", "b", "RRSS")], {"max_failures": 1})
    log = _run(spec, 3)
    assert _statuses(log) == "RRF" and log[2][1] == [("b", "run")]
    spec = ("ParallelAll", "pa", [("async", "a", "RFSS"), ("async", "b", "RRSS")], {"max_failures": 2})
    assert _statuses(_run(spec, 3)) == "RRS"


def test_if_then_else():
    """The condition picks the branch; the branch is kept while it runs; two children and a
    failed condition: FAILURE."""
    spec = ("IfThenElse", "ite", [("cond", "c", "SFFF"), ("async", "t", "RRSS"), ("async", "e", "SSSS")])
    log = _run(spec, 3)
    assert _statuses(log) == "RRS" and log[1][1] == [("t", "run")]
    assert _statuses(_run(("IfThenElse", "ite", [("cond", "c", "FS"), ("sync", "t", "SS")]), 2)) == "FS"
    with pytest.raises(ModelError, match="2 or 3 children"):
        build(("IfThenElse", "ite", [("cond", "c", "FS")]), 2)


def test_while_do_else():
    """The condition is ticked every tick; SUCCESS ticks the second child (halting the
    third), FAILURE the third (halting the second)."""
    spec = ("WhileDoElse", "wde", [("cond", "c", "SSFF"), ("async", "do", "RRRR"), ("async", "else", "RRRR")])
    log = _run(spec, 3)
    assert _statuses(log) == "RRR"
    assert log[2][1] == [("c", "cond"), ("do", "halt"), ("else", "start")]
    assert _statuses(_run(("WhileDoElse", "wde", [("cond", "c", "SF"), ("sync", "do", "SS")]), 2)) == "SF"


def test_keep_running_until_failure():
    """Child SUCCESS -> RUNNING, FAILURE -> FAILURE."""
    assert _statuses(_run(("KeepRunningUntilFailure", "k", ("sync", "a", "SSF")), 3)) == "RRF"


def test_run_once():
    """After the child finished once, its status is returned without ticking it (then_skip
    false); then_skip true (SKIPPED) is refused."""
    log = _run(("RunOnce", "once", ("async", "a", "RFSS"), {"then_skip": False}), 4)
    assert _statuses(log) == "RFFF" and log[2][1] == [] and log[3][1] == []
    with pytest.raises(ModelError, match="then_skip"):
        build(("RunOnce", "once", ("sync", "a", "SS"), {"then_skip": True}), 2)


def test_parallel_all_children_do_not_compete():
    """Under btfsm, halt before start never halts a sibling under a ParallelAll (section 4)."""
    spec = ("ParallelAll", "pa", [("KeepRunningUntilFailure", "k", ("async", "a", "SSSS")), ("async", "b", "RRRR")],
            {"max_failures": 1})
    log = _run(spec, 2)
    assert log[1][1] == [("a", "start"), ("b", "run")]


def test_kept_memories_are_fsm_state():
    """Memories a halt keeps (RunOnce, SequenceWithMemory) are part of an FSM's open-system
    state when they sit in a state's subtree: the scalar and traced engines agree (a
    regression: only flags and resettable memories were stored)."""
    from test_verify_traced import assert_same

    from btfsm import FSM, Action, Bool, Marker, Model, Outcome, RunOnce, State
    from btfsm.status import Status
    from btfsm.verify.explore import explore_fsm

    once = RunOnce("once", Action("act", outcomes=(Outcome(Status.SUCCESS),)), then_skip=False)
    fsm = FSM("f", (State("home", outcomes=(Outcome(Status.SUCCESS),)), State("work", subtree=once)), "work", ("go",), (),
              (Marker("work", ("go",), Status.FAILURE, Status.SUCCESS), Marker("home", ("go",), Status.SUCCESS, Status.SUCCESS)))
    model = Model("m", variables=(Bool("v"),), fsms=(fsm,))
    for budget in (1, 2, 3, 50):
        assert_same(explore_fsm(model, "f", engine="scalar", max_states=budget),
                    explore_fsm(model, "f", engine="traced", max_states=budget))
