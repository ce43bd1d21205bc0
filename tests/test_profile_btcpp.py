"""Table tests of the ``btcpp`` profile: scenarios of BehaviorTree.CPP's own test suite
(``tests/gtest_*.cpp``, named in each row) that exercise node semantics, each run in btfsm
under ``semantics: btcpp`` AND in the real engine (``behaviortreepy``), with the root
statuses pinned. Leaves are tables of statuses per tick (``tests/btcpp_peer.py``); a gtest's
timed async action becomes an async leaf that answers RUNNING for as many ticks.
docs/semantics.md section 8.1.
"""
from __future__ import annotations

import pytest

pytest.importorskip("behaviortreepy")

from btcpp_peer import build, compare, run_btfsm  # noqa: E402


def A(name, table):
    return ("async", name, table)


def S(name, table):
    return ("sync", name, table)


def C(name, table):
    return ("cond", name, table)


# (gtest it follows, spec, root status per tick: R S F)
SCENARIOS = [
    ("gtest_sequence SimpleSequenceTest.ConditionTurnToFalse",
     ("MemorySequence", "seq", [C("c", "SFFF"), A("a", "RRRS")]), "RRRS"),
    ("gtest_sequence ComplexSequenceTest.ComplexSequenceConditions1ToFalse",
     ("ReactiveSequence", "seq", [C("c1", "SSFF"), C("c2", "SSSS"), A("a", "RRRR")]), "RRFF"),
    ("gtest_sequence SequenceTripleActionTest.TripleAction",
     ("MemorySequence", "seq", [A("a1", "SSSS"), A("a2", "RRSS"), A("a3", "RRRS")]), "RRRS"),
    ("gtest_sequence SimpleSequenceWithMemoryTest.ConditionTurnToFalse",
     ("SequenceWithMemory", "seq", [C("c", "SFFF"), A("a", "RRRS")]), "RRRS"),
    ("gtest_sequence SequenceWithMemoryTest.Issue_636 (FAILURE keeps the index)",
     ("SequenceWithMemory", "seq", [S("a", "SSSS"), C("b", "SFSS"), S("c", "SSSS")]), "RFRS"),
    ("gtest_fallback SimpleFallbackTest.ConditionChangeWhileRunning",
     ("ReactiveFallback", "fb", [C("c", "FFSS"), A("a", "RRRR")]), "RRSS"),
    ("gtest_fallback ReactiveFallbackTest.Condition2ToTrue",
     ("ReactiveFallback", "fb", [C("c1", "FFFF"), C("c2", "FFSS"), A("a", "RRRR")]), "RRSS"),
    ("gtest_fallback SimpleFallbackWithMemoryTest.ConditionTurnToTrue",
     ("MemoryFallback", "fb", [C("c", "FSSS"), A("a", "RRRF")]), "RRRF"),
    ("gtest_fallback ComplexFallbackWithMemoryTest.Action1Failed",
     ("MemoryFallback", "fb", [("MemoryFallback", "f1", [C("c1", "FFFF"), C("c2", "FFFF")]),
                               ("MemoryFallback", "f2", [A("a1", "RFFF"), A("a2", "RRRS")])]), "RRRS"),
    ("gtest_parallel SimpleParallelTest.ConditionsTrue (success -1)",
     ("Parallel", "par", [C("c1", "SSSS"), C("c2", "SSSS"), A("a1", "RSSS"), A("a2", "RRSS")],
      {"success_threshold": -1, "failure_threshold": 1}), "RRSS"),
    ("gtest_parallel SimpleParallelTest.Threshold_3",
     ("Parallel", "par", [C("c1", "SSSS"), C("c2", "SSSS"), A("a1", "RRSS"), A("a2", "RRRR")],
      {"success_threshold": 3, "failure_threshold": 1}), "RRSS"),
    ("gtest_parallel SimpleParallelTest.Threshold_neg2",
     ("Parallel", "par", [C("c1", "SSSS"), C("c2", "SSSS"), A("a1", "RSSS"), A("a2", "RRRR")],
      {"success_threshold": -2, "failure_threshold": 1}), "RSSS"),
    ("gtest_parallel SimpleParallelTest.Threshold_thresholdFneg1",
     ("Parallel", "par", [C("c1", "FFFF"), C("c2", "SSSS"), A("a1", "RFFF"), A("a2", "RRRR")],
      {"success_threshold": 1, "failure_threshold": -1}), "SSSS"),
    ("gtest_parallel ComplexParallelTest.ConditionRightFalse_thresholdF_2 (the right side fails at once)",
     ("Parallel", "par", [("Parallel", "left", [C("c1", "SSSS"), A("a1", "RRSS")], {"success_threshold": 2}),
                          ("Parallel", "right", [C("c2", "FFFF"), A("a2", "RRRR")], {"success_threshold": 2})],
      {"success_threshold": 2, "failure_threshold": 2}), "FFFF"),
    ("gtest_parallel Parallel.FailingParallel (order decides: failure first)",
     ("Parallel", "par", [S("bad", "FFFF"), S("good", "SSSS")], {"success_threshold": 1, "failure_threshold": 1}), "FFFF"),
    ("gtest_parallel Parallel.ParallelAll",
     ("ParallelAll", "par", [A("a1", "RSSS"), A("a2", "RRFF"), A("a3", "RRRS")], {"max_failures": 1}), "RRRF"),
    ("gtest_parallel Parallel.PauseWithRetry",
     ("Parallel", "par", [("Retry", "retry", A("a1", "RFRS"), {"attempts": 3}), A("a2", "RRRR")],
      {"success_threshold": 1, "failure_threshold": 2}), "RRRS"),
    ("gtest_reactive Reactive.TwoAsyncNodesInReactiveSequence",
     ("ReactiveSequence", "rs", [A("a", "RSSS"), A("b", "RRRS")]), "RRRS"),
    ("gtest_reactive Reactive.ReactiveSequence_FirstChildFails",
     ("ReactiveSequence", "rs", [C("c", "SFSS"), A("a", "RRRR")]), "RFRR"),
    ("gtest_reactive Reactive.ReactiveFallback_SecondChildSucceeds",
     ("ReactiveFallback", "rf", [C("c", "FFFF"), A("a", "RSRS")]), "RSRS"),
    ("gtest_decorator RetryTest.RetryTestA (instant failures: RUNNING between attempts)",
     ("Retry", "retry", S("a", "FFFS"), {"attempts": 3}), "RRFS"),
    ("gtest_decorator RepeatTestAsync.RepeatTestAsync (a running child repeats within the tick)",
     ("Repeat", "rep", A("a", "RSRSRS"), {"times": 3}), "RRRSRR"),
    ("gtest_decorator Decorator.RunOnce (then_skip false)",
     ("MemorySequence", "seq", [("RunOnce", "once", A("a", "RSFF"), {"then_skip": False}), S("b", "SFSF")]), "RFSF"),
    ("gtest_decorator Decorator.KeepRunningUntilFailure",
     ("KeepRunningUntilFailure", "krf", S("a", "SSFS")), "RRFR"),
    ("gtest_decorator Decorator.Inverter_InSequence",
     ("MemorySequence", "seq", [("Inverter", "inv", C("c", "FFSS")), ("ForceFailure", "ff", S("a", "SSSS"))]), "FFFF"),
    ("gtest_if_then_else IfThenElseTest.ConditionRunning",
     ("IfThenElse", "ite", [A("c", "RSSS"), A("then", "RSSS"), A("else", "SSSS")]), "RSSS"),
    ("gtest_if_then_else IfThenElseTest.ConditionFalse_TwoChildren_ReturnsFailure (the failed leaf keeps FAILURE)",
     ("IfThenElse", "ite", [A("c", "FSSS"), A("then", "SSSS")]), "FFFF"),
    ("gtest_while_do_else WhileDoElseTest.ConditionChanges_HaltsDo",
     ("WhileDoElse", "wde", [C("c", "SSFF"), A("do", "RRRR"), A("else", "RRRR")]), "RRRR"),
    ("gtest_while_do_else WhileDoElseTest.ConditionFalse_TwoChildren_ReturnsFailure",
     ("WhileDoElse", "wde", [C("c", "SFSS"), A("do", "RRRR")]), "RFRR"),
    ("gtest_while_do_else (an async condition keeps its status while the branch runs)",
     ("WhileDoElse", "wde", [A("c", "SFFF"), A("do", "RRSS"), A("else", "RRRR")]), "RRSR"),
    ("gtest_parallel (issue 18: success_count 0 succeeds once the first child was ticked)",
     ("Parallel", "par", [A("a", "RRRR"), A("b", "RRRR")], {"success_threshold": 0, "failure_threshold": 1}), "SSSS"),
    ("gtest_parallel (issue 18: failure_count 0 fails after the first child unless it failed)",
     ("Parallel", "par", [S("a", "SFSF"), A("b", "RRSR")], {"success_threshold": 2, "failure_threshold": 0}), "FFFF"),
    ("gtest_parallel (issue 18: failure_count 0 after a first failure: only the success rule decides)",
     ("Parallel", "par", [S("a", "FSFS"), A("b", "RRSR")], {"success_threshold": 1, "failure_threshold": 0}), "RRSS"),
    ("gtest_subtree (issue 18: a SubTree resets its child, so IfThenElse sees the leaf afresh)",
     ("IfThenElse", "ite", [("SubTree", "Check", A("Detect", "FSSS")), S("ok", "SSSS")]), "FSSS"),
    ("gtest_subtree (issue 18: WhileDoElse over a SubTree halts Do when the condition turns false)",
     ("WhileDoElse", "wde", [("SubTree", "Check", A("Detect", "SSFF")), A("Pick", "RRRR"), A("Wait", "RRRR")]), "RRRR"),
]

_LETTER = {"RUNNING": "R", "SUCCESS": "S", "FAILURE": "F"}


@pytest.mark.parametrize("scenario", SCENARIOS, ids=[s[0].split(" ")[1] for s in SCENARIOS])
def test_profile_btcpp_gtest_scenarios(scenario):
    _, spec, statuses = scenario
    real, ours, xml = compare(spec, len(statuses))
    assert ours == real, f"{xml}\nbtcpp: {real}\nbtfsm: {ours}"
    assert "".join(_LETTER[s] for s, _ in real) == statuses


# ReactiveFallback[A, B]: A fails on tick 1 and runs afterwards, B always runs (issue 10)
_HAZARD = ("ReactiveFallback", "rf", [A("a", "FRRR"), A("b", "RRRR")])


def test_profile_halt_before_start():
    """btcpp: the reactive fallback starts A before it halts B (BehaviorTree.CPP #1031),
    exactly as the real engine does; btfsm: B is halted before A starts."""
    real, ours, _ = compare(_HAZARD, 3)
    assert ours == real
    assert real[1][1] == [("a", "start"), ("b", "halt")]
    model, leaves = build(_HAZARD, 3, semantics="btfsm")
    default = run_btfsm(model, leaves, 3)
    assert default[1][1] == [("b", "halt"), ("a", "start")]
    assert [s for s, _ in default] == [s for s, _ in real]


# ---------------------------------------------------------------- one test per section-8 row


def _both(spec, ticks):
    """(real BT.CPP log, btfsm log under btcpp, btfsm log under the default profile)."""
    real, ours, _ = compare(spec, ticks)
    model, leaves = build(spec, ticks, semantics="btfsm")
    return real, ours, run_btfsm(model, leaves, ticks)


def test_profile_btcpp_parallel():
    """parallel_memory: BT.CPP's Parallel stops at the first threshold reached in child order
    and does not tick finished children again; btfsm ticks all and prefers success."""
    real, ours, default = _both(("Parallel", "par", [S("bad", "FF"), S("good", "SS")],
                                 {"success_threshold": 1, "failure_threshold": 1}), 2)
    assert ours == real and real[0] == ("FAILURE", [("bad", "tick")])
    assert default[0] == ("SUCCESS", [("bad", "tick"), ("good", "tick")])
    spec = ("Parallel", "par", [A("a", "SSSS"), A("b", "RRSS")], {"success_threshold": -1})
    real, ours, default = _both(spec, 2)
    assert ours == real and real[1] == ("RUNNING", [("b", "run")])  # a finished: not ticked again
    assert default[1] == ("RUNNING", [("a", "start"), ("b", "run")])


def test_profile_btcpp_loop_wake_up():
    """loop_wake_up: a child that finishes at once makes Retry/Repeat/SequenceWithMemory
    return RUNNING; a child that had been running is ticked again in the same tick."""
    real, ours, default = _both(("Retry", "retry", A("a", "RFRF"), {"attempts": 3}), 3)
    assert ours == real
    assert real[1] == ("RUNNING", [("a", "run"), ("a", "start")])  # failed after running: again at once
    assert default[1] == ("RUNNING", [("a", "run")])
    real, ours, default = _both(("SequenceWithMemory", "swm", [S("a", "SS"), S("b", "SS")]), 2)
    assert ours == real and [s for s, _ in real] == ["RUNNING", "SUCCESS"]
    assert [s for s, _ in default] == ["SUCCESS", "SUCCESS"]


def test_profile_btcpp_stale_condition():
    """stale_condition: an async condition of WhileDoElse keeps its SUCCESS while the branch
    runs (BT.CPP does not tick it); btfsm ticks it again."""
    spec = ("WhileDoElse", "wde", [A("c", "SFFF"), A("do", "RRRR"), A("else", "RRRR")])
    real, ours, default = _both(spec, 2)
    assert ours == real and real[1] == ("RUNNING", [("do", "run")])
    assert default[1] == ("RUNNING", [("do", "halt"), ("c", "start"), ("else", "start")])  # halt before start


def test_profile_btcpp_subtree_resets_its_child():
    """Rule 'SubTree' (issue 18): BT.CPP's SubTreeNode resets its child when it finishes, so a
    stateful leaf at a SubTree's root keeps no status: WhileDoElse sees the condition turn
    false and halts Pick. The same leaf without the SubTree keeps its SUCCESS (stale
    condition), and Pick keeps running: both as in the real engine."""
    sub = ("WhileDoElse", "wde", [("SubTree", "Check", A("Detect", "SSFF")), A("Pick", "RRRR"), A("Wait", "RRRR")])
    real, ours, _ = _both(sub, 3)
    assert ours == real and real[2] == ("RUNNING", [("Detect", "start"), ("Pick", "halt"), ("Wait", "start")])
    inline = ("WhileDoElse", "wde", [A("Detect", "SSFF"), A("Pick", "RRRR"), A("Wait", "RRRR")])
    real, ours, _ = _both(inline, 3)
    assert ours == real and real[2] == ("RUNNING", [("Pick", "run")])


def test_profile_btcpp_tick_once():
    """Rule 'tickOnce' (Model.tick, --tick): BT.CPP's tick_once() ticks the root again while
    it returns RUNNING and a wake-up signal is pending; tick_exactly_once() does not. Both
    against the real engine."""
    spec = ("Retry", "retry", S("a", "FFFS"), {"attempts": 3})
    real, ours, _ = compare(spec, 4, tick="once")
    assert ours == real and real[0] == ("FAILURE", [("a", "tick")] * 3)  # three attempts in one tick_once()
    real, ours, _ = compare(spec, 4, tick="exactly-once")
    assert ours == real and [s for s, _ in real] == ["RUNNING", "RUNNING", "FAILURE", "SUCCESS"]


_LOOPS = ("ReactiveSequence", "rs", [("Repeat", "r1", S("a", "SSSS"), {"times": 2}),
                                     ("Repeat", "r2", S("b", "SSSS"), {"times": 2})])


def test_profile_btcpp_tick_once_loop(tmp_path, capsys):
    """A tick_once() that never returns: r1's first success wakes the tree up, r1 then
    succeeds and r2 wakes it up, r1 starts again and halts r2 (a reactive sequence), and so
    on for ever. The real engine loops (run apart, stopped after many callbacks); btfsm
    finds the repeated state, and `btfsm check` reports it under `contracts` with a
    counterexample that replays; with --tick exactly-once the property holds."""
    real, ours, _ = compare(_LOOPS, 3, tick="once")
    assert real == ours == [("LOOP", [])]
    model, _ = build(_LOOPS, 3, tick="once")
    from btfsm.cli import main
    from btfsm.files import dump_model

    path = tmp_path / "loop.yaml"
    dump_model(model, path)
    assert main(["check", str(path), "--property", "contracts", "--counterexample-dir", str(tmp_path / "ce")]) == 1
    out = capsys.readouterr().out
    assert "contracts: tickOnce() of 'rs' can loop for ever (the tick never returns)" in out
    (ce,) = (tmp_path / "ce").iterdir()
    assert main(["replay", str(ce), str(path)]) == 0
    assert "confirmed: tick 1: tickOnce() re-ticks 'rs' in a loop" in capsys.readouterr().out
    assert main(["check", str(path), "--property", "contracts", "--tick", "exactly-once"]) == 0


def test_tick_option_in_files_and_flags():
    """`tick:` in a model (or side) file and --tick: once (the default) or exactly-once;
    anything else is a one-line error naming the field."""
    from btfsm.errors import ModelError
    from btfsm.files import load_model, loads_model, model_to_data

    text = "name: m\nsemantics: btcpp\nprimitives: {a: [success]}\ntree: {Action: a}\n"
    assert loads_model(text).tick == "once" and "tick" not in model_to_data(loads_model(text))
    exact = loads_model(text + "tick: exactly-once\n")
    assert exact.tick == "exactly-once" and model_to_data(exact)["tick"] == "exactly-once"
    with pytest.raises(ModelError, match=r"tick: expected one of once, exactly-once, got 'sometimes'"):
        loads_model(text + "tick: sometimes\n")
    assert load_model("bt-cpp-1031", tick="exactly-once").tick == "exactly-once"


def test_run_once_then_skip_refused():
    """SKIPPED is out of scope: RunOnce(then_skip=True) is refused under every profile."""
    from btfsm.errors import ModelError

    for semantics in ("btfsm", "btcpp"):
        with pytest.raises(ModelError, match="then_skip"):
            build(("RunOnce", "once", S("a", "SS"), {"then_skip": True}), 2, semantics=semantics)


def test_profile_btcpp_skill_restart_in_tick():
    """restart_in_tick: a SkillRequest under Repeat that finishes after running is started
    again in the same tick (BT.CPP calls onStart again); btfsm shares its first reply."""
    spec = ("Repeat", "rep", ("skill", "sk", "RSSS"), {"times": 3})
    real, ours, default = _both(spec, 2)
    assert ours == real and real[1] == ("RUNNING", [("sk", "run"), ("sk", "start")])
    assert default[1] == ("RUNNING", [("sk", "run")])


def test_profile_btcpp_issue10_memory_sequence_resumes():
    """Issue 10's first example: ReactiveFallback[A, MemorySequence[B, C]] where A can run but
    fails at once while C runs: BT.CPP keeps C running and resumes it; btfsm halts the
    sequence before A starts, so B runs again."""
    spec = ("ReactiveFallback", "rf", [A("a", "FFFF"), ("MemorySequence", "seq", [A("b", "SSSS"), A("c", "RRRR")])])
    real, ours, default = _both(spec, 2)
    assert ours == real and real[1] == ("RUNNING", [("a", "start"), ("c", "run")])
    assert default[1] == ("RUNNING", [("c", "halt"), ("a", "start"), ("b", "start"), ("c", "start")])
