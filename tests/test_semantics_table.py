"""docs/semantics.md, row by row: one test per row, named as the doc names it.

Leaves are Actions whose outcomes are named after their statuses (``act``); every row is
a table of ticks (``Tick``): which primitives run, in which order, with which outcome,
and what the root status, the running flags and the halts must be afterwards.
``TableOracle`` fails the test when a primitive runs that the row does not script, so
each row also pins down which leaves are ticked. The rows the doc marks as hypothesis
properties run over random models from ``core_strategies``.
"""
from __future__ import annotations

import io
import json
import random
import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from memo_strategies import st

from btfsm import (FSM, Action, Bool, Condition, DomainError, Edge, Effects, EnvChoice, EnvEvent, FailureIsRunning,
                   RunningIsFailure, RunningIsSuccess,
                   ForceFailure, ForceSuccess, Guard, Int, Inverter, Marker, MemoryFallback,
                   MemorySequence, Model, ModelError, Parallel, Primitive, ReactiveFallback,
                   ReactiveSequence, Repeat, Retry, SkillRequest, State, Status, SubTree, failure, running,
                   success)
from btfsm.oracles import RandomOracle, ScriptOracle
from btfsm.runtime import Runtime
from btfsm.trace import read_trace, replay

from test_profile_pytrees import (test_profile_parallel_failure_first, test_profile_parallel_selected,
                                  test_profile_parallel_synchronise)
from core_strategies import (ModOracle, TableOracle, Tick, act, events, models, parents_of,
                             pick_events, run_rows, running_nodes, slot_of, to_reactive, trees,
                             variables)

SECTION_8_PYTREES = (test_profile_parallel_failure_first, test_profile_parallel_selected,
                     test_profile_parallel_synchronise)  # cited by section 8; they run here too
R, S, F = int(Status.RUNNING), int(Status.SUCCESS), int(Status.FAILURE)
PROPS = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
ANSWERS = st.lists(st.integers(0, 11), min_size=8, max_size=64)  # ModOracle cycles through them
DOC = Path(__file__).resolve().parents[1] / "docs" / "semantics.md"

STOP_EVENTS = [EnvEvent("stop_on", "not stop", {"stop": True}), EnvEvent("stop_off", "stop", {"stop": False})]


def _mem(model, steps, slot):
    i = slot_of(model.program, slot)
    return [step.state[i] for step, _ in steps]


def _var(model, step, name):
    return model.program.decode(step.state)[name]


def _pos(seq, item):
    assert item in seq, f"{item} not in {seq}"
    return seq.index(item)


def _ticks(model, numbers, ticks, record=False):
    """(state before, step, oracle) for ``ticks`` ticks answered by ``ModOracle``."""
    p = model.program
    s, pos = p.initial, 0
    for _ in range(ticks):
        oracle = ModOracle(numbers, pos)
        step = p.step(s, oracle, record=record)
        yield s, step, oracle
        s, pos = step.state, oracle.pos


def _no_running_tree():
    """(variables, a tree none of whose nodes can return RUNNING)."""
    return variables().flatmap(lambda vs: st.tuples(st.just(vs), trees(vs, statuses="SF", allow_running=False)))


def test_every_cited_test_exists():
    """The doc's test column and this module agree (tests/test_expr.py is cited as a file);
    section 8's per-profile rows may cite tests of tests/test_profile_*.py and
    tests/test_peer_*.py, which run against the real engines; section 6.1 (time) cites
    tests/test_durations.py, section 6 (the runtime's memo of ticks) tests/test_runtime.py."""
    cited = set(re.findall(r"`(test_\w+)`", DOC.read_text(encoding="utf-8")))
    assert len(cited) > 30
    elsewhere = set()
    for f in [*DOC.parent.parent.glob("tests/test_profile_*.py"), *DOC.parent.parent.glob("tests/test_peer_*.py"),
              DOC.parent.parent / "tests" / "test_durations.py", DOC.parent.parent / "tests" / "test_nav2.py",
              DOC.parent.parent / "tests" / "test_runtime.py"]:
        elsewhere |= set(re.findall(r"^def (test_\w+)\(", f.read_text(encoding="utf-8"), re.M))
    missing = sorted(name for name in cited if not callable(globals().get(name)) and name not in elsewhere)
    assert not missing, f"docs/semantics.md cites tests that do not exist here: {missing}"


# --------------------------------------------------------------------------- 1. state, tick


def test_environment_then_tree():
    """Section 1: events run first in declaration order, each independently; a choice takes
    exactly one enabled option; the tree sees their effects in the same tick; with no
    option enabled the tick cannot happen."""
    m = Model("env", variables=[Int("n", 0, 3), Bool("open", True)],
              environment=[EnvEvent("inc", "n < 3", {"n": "n + 1"}),
                           EnvEvent("dbl", "n >= 1", {"n": "min(n * 2, 3)"}),
                           EnvChoice("door", [EnvEvent("shut", "open", {"open": False}),
                                              EnvEvent("ajar", None, {"open": True})])],
              tree=Condition("root", "n == 2 and not open"))
    p = m.program
    steps = run_rows(m, [Tick("", "S", env="inc dbl shut")])  # 0 -> 1 -> 2, in order
    assert _var(m, steps[0][0], "n") == 2
    assert steps[0][1].asked_env == ["inc", "dbl"]  # inc enabled dbl, which then was asked
    assert events(steps[0][0], "env") == [("env", "inc"), ("env", "dbl"), ("env", "shut")]
    # 'dbl' is not asked while its guard is false
    oracle = TableOracle(p, "", "ajar")
    s = p.step(p.initial, oracle, record=True)
    assert s.status == F and p.decode(s.state)["n"] == 0 and oracle.asked_env == ["inc"]
    # a single enabled option is taken whatever the oracle was told
    one = p.step(steps[0][0].state, TableOracle(p, "", ""), record=True)
    assert ("env", "ajar") in one.events and p.decode(one.state)["open"] is True
    blocked = Model("blocked", variables=[Bool("a")],
                    environment=[EnvChoice("c", [EnvEvent("only", "a", {"a": False})])],
                    tree=Condition("root", "a"))
    step = blocked.program.step(blocked.program.initial, TableOracle(blocked.program))
    assert step.state is None and step.violations == [("blocked", "c")]


def test_never_running_nodes_have_no_flag():
    """Section 1: conditions, instant actions and composites made of them have no running
    flag; a node that can return RUNNING has one."""
    instant = Model("inst", variables=[Bool("b")],
                    tree=ReactiveSequence("root", [Condition("c", "b"), Parallel("par", [act("x", "SF"), act("y", "S")]),
                                                   MemoryFallback("mf", [act("z", "F"), Inverter("inv", act("w", "SF"))]),
                                                   Retry("once", act("u", "SF"), attempts=1)]))
    assert [x.name for x in instant.program.slots if x.kind == "flag"] == []
    runs = Model("runs", tree=ReactiveFallback("root", [act("x", "SF"), Retry("twice", act("u", "SF"), attempts=2)]))
    assert sorted(x.name for x in runs.program.slots if x.kind == "flag") == ["root:running", "twice:running"]


@PROPS
@given(_no_running_tree())
def test_trees_without_running_have_no_flag(pair):
    world, tree = pair
    assert [x.name for x in Model("m", variables=world, tree=tree).program.slots if x.kind == "flag"] == []


def test_step_is_pure_examples():
    m = Model("pure", variables=[Int("n", 0, 5)],
              tree=ReactiveFallback("root", [act("a", "SF"), act("b", "RSF", S={"n": "n + 1"})]))
    p = m.program
    start = list(p.initial)
    first = p.step(start, ScriptOracle([1, 1]), record=True)
    second = p.step(start, ScriptOracle([1, 1]), record=True)
    assert start == list(p.initial)  # a list input is not written to
    assert (first.state, first.status, first.events) == (second.state, second.status, second.events)
    assert p.decode(first.state)["n"] == 1


@PROPS
@given(models(), ANSWERS, st.integers(0, 6))
def test_step_is_pure(model, numbers, warmup):
    """Same state + same answers = same next state, status, events and violations; the
    input is never modified (hypothesis property over random models and states)."""
    p = model.program
    s, pos = p.initial, 0
    for _ in range(warmup):  # reach some state first
        oracle = ModOracle(numbers, pos)
        s, pos = p.step(s, oracle).state, oracle.pos
    first = ModOracle(numbers, pos)
    a = p.step(s, first, record=True)
    as_list = list(s)
    b = p.step(as_list, ScriptOracle(first.taken), record=True)
    c = p.step(s, ScriptOracle(first.taken), record=True)
    assert as_list == list(s)
    assert isinstance(a.state, tuple) and len(a.state) == len(s)
    for x in (b, c):
        assert (x.state, x.status, x.events, x.violations) == (a.state, a.status, a.events, a.violations)


def test_effects_simultaneous():
    """Every right-hand side reads the state before any write: a swap swaps."""
    m = Model("swap", variables=[Int("x", 0, 3, 1), Int("y", 0, 3, 2), Bool("p", True), Bool("q")],
              environment=[EnvEvent("env_swap", None, {"p": "q", "q": "p"})],
              tree=Action("root", outcomes=[success(x="y", y="x")]))
    p = m.program
    steps = run_rows(m, [Tick("root:S", "S", env="env_swap"), Tick("root:S", "S")])
    first, second = steps[0][0], steps[1][0]
    assert (_var(m, first, "x"), _var(m, first, "y")) == (2, 1)
    assert (_var(m, first, "p"), _var(m, first, "q")) == (False, True)
    assert (_var(m, second, "x"), _var(m, second, "y")) == (1, 2)
    writes = events(first, "write")
    assert ("write", slot_of(p, "x"), 2) in writes and ("write", slot_of(p, "y"), 1) in writes


def test_effects_visible_later_in_tick():
    """Effects are visible to every node ticked after them in the same tick."""
    m = Model("vis", variables=[Int("n", 0, 3)],
              tree=ReactiveSequence("root", [act("a", "S", S={"n": "n + 1"}), Condition("c", "n == 1"),
                                             act("b", "S", S={"n": "n * 2"}), Condition("d", "n == 2")]))
    run_rows(m, [Tick("a:S b:S", "S"), Tick("a:S", "F")])


def test_effect_out_of_domain():
    """A value outside the domain raises DomainError naming the variable and the element."""
    m = Model("dom", variables=[Int("n", 0, 2)],
              tree=Action("root", outcomes=[success("inc", n="n + 1")]))
    p = m.program
    s = p.initial
    for _ in range(2):
        s = p.step(s, ScriptOracle()).state
    assert p.decode(s)["n"] == 2
    with pytest.raises(DomainError) as err:
        p.step(s, ScriptOracle())
    assert err.value.var == "n" and err.value.value == 3
    assert "root" in err.value.where and "inc" in err.value.where
    env = Model("dom_env", variables=[Int("n", 0, 1, 1)], environment=[EnvEvent("drop", None, {"n": "n - 2"})],
                tree=Condition("root", "n == 1"))
    with pytest.raises(DomainError) as err:
        env.program.step(env.program.initial, ScriptOracle([1]))
    assert err.value.var == "n" and "environment.drop" in err.value.where


# --------------------------------------------------------------------------- 2. composites


def test_reactive_sequence():
    m = Model("rs", tree=ReactiveSequence("root", [act("a", "SF"), act("b")]))
    run_rows(m, [
        Tick("a:S b:R", "R", running="root b", halts=""),
        Tick("a:S b:R", "R", running="root b", halts=""),  # a re-ticked; b keeps running
        Tick("a:F", "F", running="", halts="b"),  # FAILURE halts the later running child
        Tick("a:S b:S", "S", running="", halts=""),
        Tick("a:S b:F", "F", running="", halts=""),
    ])
    # RUNNING from an earlier child also halts the later running ones
    m = Model("rs2", tree=ReactiveSequence("root", [Retry("retry", act("a", "SF"), attempts=2), act("b")]))
    run_rows(m, [
        Tick("a:S b:R", "R", running="root b"),
        Tick("a:F", "R", running="root retry", halts="b"),
        Tick("a:S b:S", "S", running="", halts=""),
    ])


def test_reactive_sequence_lint():
    """Two children that can run in a reactive sequence are reported when built."""
    m = Model("lint", tree=ReactiveSequence("root", [act("a"), act("b")]))
    assert [el for el, _ in m.program.lints] == ["tree.root"]
    ok = Model("nolint", tree=ReactiveSequence("root", [act("a", "SF"), act("b")]))
    assert ok.program.lints == []


def test_memory_sequence():
    m = Model("ms", tree=MemorySequence("root", [act("a"), act("b"), act("c")]))
    steps = run_rows(m, [
        Tick("a:S b:R", "R", running="root b"),
        Tick("b:S c:R", "R", running="root c"),  # resumes at b: a is not ticked
        Tick("c:R", "R", running="root c"),
        Tick("c:F", "F", running="", halts=""),
        Tick("a:R", "R", running="root a"),  # FAILURE forgot: back to a
        Tick("a:S b:S c:S", "S", running=""),  # SUCCESS moves on within the tick
        Tick("a:F", "F", running=""),
    ])
    assert _mem(m, steps, "root:child") == [1, 2, 2, 0, 0, 0, 0]


def test_reactive_fallback():
    m = Model("rf", tree=ReactiveFallback("root", [act("a", "SF"), act("b")]))
    run_rows(m, [
        Tick("a:F b:R", "R", running="root b"),
        Tick("a:F b:R", "R", running="root b", halts=""),
        Tick("a:S", "S", running="", halts="b"),  # SUCCESS halts the later running child
        Tick("a:F b:S", "S", running=""),
        Tick("a:F b:F", "F", running=""),
    ])
    m = Model("rf2", tree=ReactiveFallback("root", [Repeat("rep", act("a", "SF"), times=2), act("b")]))
    run_rows(m, [
        Tick("a:F b:R", "R", running="root b"),
        Tick("a:S", "R", running="root rep", halts="b"),  # RUNNING halts them too
        Tick("a:S", "S", running="", halts=""),
    ])


def test_memory_fallback():
    m = Model("mf", tree=MemoryFallback("root", [act("a"), act("b"), act("c")]))
    steps = run_rows(m, [
        Tick("a:F b:R", "R", running="root b"),
        Tick("b:F c:R", "R", running="root c"),  # resumes at b
        Tick("c:S", "S", running=""),
        Tick("a:F b:F c:F", "F", running=""),
        Tick("a:R", "R", running="root a"),
        Tick("a:S", "S", running=""),
    ])
    assert _mem(m, steps, "root:child") == [1, 2, 0, 0, 0, 0]


def test_parallel_thresholds():
    m = Model("par", tree=Parallel("root", [act("a"), act("b")]))  # defaults: all / 1
    run_rows(m, [
        Tick("a:S b:R", "R", running="root b"),
        Tick("a:S b:S", "S", running=""),  # a finished last tick and is ticked again
        Tick("a:R b:F", "F", running="", halts="a"),
        Tick("a:R b:R", "R", running="root a b", halts=""),
        Tick("a:S b:R", "R", running="root b"),
    ])
    m = Model("par1", tree=Parallel("root", [act("a"), act("b")], success_threshold=1, failure_threshold=2))
    run_rows(m, [
        Tick("a:R b:R", "R", running="root a b"),
        Tick("a:R b:S", "S", running="", halts="a"),
        Tick("a:F b:R", "R", running="root b"),  # one failure: one success still reachable
        Tick("a:F b:F", "F", running="", halts=""),
    ])
    m = Model("par23", tree=Parallel("root", [act("a"), act("b"), act("c")], success_threshold=2, failure_threshold=3))
    run_rows(m, [
        Tick("a:F b:R c:R", "R", running="root b c"),
        Tick("a:F b:F c:R", "F", running="", halts="c"),  # 2 failures of 3: 2 successes unreachable
    ])
    m = Model("par12", tree=Parallel("root", [act("a"), act("b"), act("c")], success_threshold=1, failure_threshold=2))
    run_rows(m, [
        Tick("a:F b:R c:R", "R", running="root b c"),
        Tick("a:F b:R c:F", "F", running="", halts="b"),  # failure threshold reached
        Tick("a:S b:R c:R", "S", running="", halts="b c"),
    ])
    for kw in ({"success_threshold": 0}, {"success_threshold": 3}, {"failure_threshold": 0}):
        with pytest.raises(ModelError) as err:
            Model("bad", tree=Parallel("root", [act("a"), act("b")], **kw))
        assert err.value.element == "tree.root"


@PROPS
@given(_no_running_tree(), ANSWERS, st.integers(1, 4))
def test_memory_equals_reactive_without_running(pair, numbers, ticks):
    """When no child ever returns RUNNING, memory and reactive composites agree on every
    tick: same status, same primitives run in the same order, same next world state."""
    world, tree = pair
    mem = Model("mem", variables=world, tree=tree)
    rea = Model("rea", variables=world, tree=to_reactive(tree))
    a, b = mem.program, rea.program
    sa, sb = a.initial, b.initial
    n, pos = len(world), 0
    for _ in range(ticks):
        oa, ob = ModOracle(numbers, pos), ModOracle(numbers, pos)
        xa, xb = a.step(sa, oa, record=True), b.step(sb, ob, record=True)
        assert xa.status == xb.status != R
        assert events(xa, "outcome") == events(xb, "outcome")
        assert xa.state[:n] == xb.state[:n]
        sa, sb, pos = xa.state, xb.state, oa.pos


# --------------------------------------------------------------------------- 3. decorators, leaves


def test_inverter():
    m = Model("inv", tree=Inverter("root", act("a")))
    run_rows(m, [Tick("a:S", "F", running=""), Tick("a:F", "S", running=""),
                 Tick("a:R", "R", running="root a"), Tick("a:S", "F", running="")])


def test_subtree():
    """Rule 'SubTree': the child's status, RUNNING included; halting it halts the child
    (children first). Under btcpp it also resets its child when the child finishes, so a
    stateful leaf below keeps no status for an IfThenElse above
    (test_profile_btcpp_subtree_resets_its_child, against the real engine)."""
    m = Model("sub", tree=SubTree("root", act("a"), tree_id="T"))
    run_rows(m, [Tick("a:S", "S", running=""), Tick("a:F", "F", running=""),
                 Tick("a:R", "R", running="root a"), Tick("a:S", "S", running="")])
    halted = Model("sub_halt", tree=ReactiveSequence("root", [act("b", "SF"), SubTree("s", act("a"))]))
    run_rows(halted, [Tick("b:S a:R", "R", running="root s a", halts=""),
                      Tick("b:F", "F", running="", halts="a s")])


def test_force_success():
    m = Model("fs", tree=ForceSuccess("root", act("a")))
    run_rows(m, [Tick("a:S", "S", running=""), Tick("a:F", "S", running=""),
                 Tick("a:R", "R", running="root a"), Tick("a:F", "S", running="")])


def test_force_failure():
    m = Model("ff", tree=ForceFailure("root", act("a")))
    run_rows(m, [Tick("a:S", "F", running=""), Tick("a:F", "F", running=""),
                 Tick("a:R", "R", running="root a"), Tick("a:S", "F", running="")])


def test_failure_is_running():
    m = Model("fir", tree=FailureIsRunning("root", act("a")))
    run_rows(m, [Tick("a:F", "R", running="root"), Tick("a:S", "S", running=""),
                 Tick("a:R", "R", running="root a"), Tick("a:F", "R", running="root", halts="")])


@pytest.mark.parametrize("cls, letter", [(RunningIsFailure, "F"), (RunningIsSuccess, "S")])
def test_running_is_failure_and_running_is_success(cls, letter):
    m = Model("ri", tree=cls("root", act("a")))
    run_rows(m, [Tick("a:R", letter, running="", halts="a"),  # returned as finished: the child is halted
                 Tick("a:S", "S", running="", halts=""), Tick("a:F", "F", running="", halts=""),
                 Tick("a:R", letter, running="", halts="a")])


def test_retry():
    m = Model("retry", tree=Retry("root", act("a"), attempts=3))
    steps = run_rows(m, [
        Tick("a:F", "R", running="root"),  # 1st failure: RUNNING, the child is idle again
        Tick("a:R", "R", running="root a"),
        Tick("a:F", "R", running="root"),  # 2nd
        Tick("a:F", "F", running=""),  # 3rd: reset, FAILURE
        Tick("a:F", "R", running="root"),
        Tick("a:S", "S", running=""),  # SUCCESS resets
        Tick("a:F", "R", running="root"),
    ])
    assert _mem(m, steps, "root:failures") == [1, 1, 2, 0, 1, 0, 1]
    once = Model("retry1", tree=Retry("root", act("a", "SF"), attempts=1))
    run_rows(once, [Tick("a:F", "F", running=""), Tick("a:S", "S")])
    assert not [x for x in once.program.slots if x.kind == "flag"]  # never RUNNING: no flag
    # halting a Retry resets its count
    m = Model("retry_halt", variables=[Bool("stop")], environment=STOP_EVENTS,
              tree=ReactiveFallback("top", [Condition("stopped", "stop"), Retry("retry", act("a"), attempts=3)]))
    steps = run_rows(m, [
        Tick("a:F", "R", running="top retry"),
        Tick("a:F", "R", running="top retry"),
        Tick("", "S", running="", halts="retry", env="stop_on"),
        Tick("a:F", "R", running="top retry", env="stop_off"),
    ])
    assert _mem(m, steps, "retry:failures") == [1, 2, 0, 1]
    with pytest.raises(ModelError):
        Model("retry0", tree=Retry("root", act("a"), attempts=0))


def test_repeat():
    m = Model("repeat", tree=Repeat("root", act("a"), times=3))
    steps = run_rows(m, [
        Tick("a:S", "R", running="root"),
        Tick("a:R", "R", running="root a"),
        Tick("a:S", "R", running="root"),
        Tick("a:S", "S", running=""),  # 3rd success: reset, SUCCESS
        Tick("a:S", "R", running="root"),
        Tick("a:F", "F", running=""),  # FAILURE resets
        Tick("a:S", "R", running="root"),
    ])
    assert _mem(m, steps, "root:done") == [1, 1, 2, 0, 1, 0, 1]
    with pytest.raises(ModelError):
        Model("repeat0", tree=Repeat("root", act("a"), times=0))


def test_guard():
    m = Model("guard", variables=[Bool("ok", True)],
              environment=[EnvEvent("off", "ok", {"ok": False}), EnvEvent("on", "not ok", {"ok": True})],
              tree=Guard("root", act("a"), condition="ok"))
    steps = run_rows(m, [
        Tick("a:R", "R", running="root a"),
        Tick("", "F", running="", halts="a", env="off"),  # false: halt the running child
        Tick("", "F", running="", halts=""),  # the child is idle: nothing to halt
        Tick("a:S", "S", running="", env="on"),
        Tick("a:F", "F", running=""),
    ])
    assert steps[1][1].halted == ["a"]
    assert steps[2][1].halted == []


def test_effects_decorator():
    counters = [Int(n, 0, 5) for n in ("started", "succeeded", "failed", "halted")]
    eff = Effects("eff", act("a"), on_start={"started": "started + 1"}, on_success={"succeeded": "succeeded + 1"},
                  on_failure={"failed": "failed + 1"}, on_halt={"halted": "halted + 1"})
    m = Model("eff", variables=[Bool("stop")] + counters, environment=STOP_EVENTS,
              tree=ReactiveFallback("root", [Condition("stopped", "stop"), eff]))
    steps = run_rows(m, [
        Tick("a:R", "R", running="root eff a"),
        Tick("a:R", "R", running="root eff a"),  # not starting: no on_start
        Tick("", "S", running="", halts="a eff", env="stop_on"),
        Tick("a:S", "S", running="", env="stop_off"),
        Tick("a:F", "F", running=""),
        Tick("a:R", "R", running="root eff a"),
    ])
    counts = [tuple(_var(m, step, c.name) for c in counters) for step, _ in steps]
    assert counts == [(1, 0, 0, 0), (1, 0, 0, 0), (1, 0, 0, 1), (2, 1, 0, 1), (3, 1, 1, 1), (4, 1, 1, 1)]
    p = m.program
    ev = events(steps[3][0], "write", "outcome")
    started, succeeded = slot_of(p, "started"), slot_of(p, "succeeded")
    assert _pos(ev, ("write", started, 2)) < _pos(ev, ("outcome", "a", "success")) < _pos(ev, ("write", succeeded, 1))
    # over an instant child (no running flag) every tick is a start
    inst = Model("eff2", variables=counters,
                 tree=Effects("root", act("a", "SF"), on_start={"started": "started + 1"}, on_failure={"failed": "failed + 1"}))
    steps = run_rows(inst, [Tick("a:S", "S"), Tick("a:F", "F")])
    assert [(_var(inst, s, "started"), _var(inst, s, "failed")) for s, _ in steps] == [(1, 0), (2, 1)]


def test_condition():
    m = Model("cond", variables=[Int("n", 0, 3)], environment=[EnvEvent("inc", "n < 3", {"n": "n + 1"})],
              tree=Condition("root", "n >= 2"))
    run_rows(m, [Tick("", "F", running=""), Tick("", "F", env="inc"), Tick("", "S", env="inc"), Tick("", "S")])
    assert [x.kind for x in m.program.slots] == ["var"]  # a condition adds nothing to the state


def test_action_outcomes():
    m = Model("act", variables=[Int("n", 0, 9)],
              tree=ReactiveSequence("root", [
                  act("check", "SF"),
                  Action("move", outcomes=[running("busy", n="n + 1"), success("done", n="0"), failure("jam")])]))
    p = m.program
    steps = run_rows(m, [
        Tick("check:S move:busy", "R", running="root move"),
        Tick("check:S move:busy", "R", running="root move", halts=""),
        Tick("check:S move:done", "S", running=""),
        Tick("check:S move:jam", "F", running=""),
    ])
    assert [_var(m, s, "n") for s, _ in steps] == [1, 2, 0, 0]
    assert events(steps[0][0], "outcome", "write") == [("outcome", "check", "success"), ("outcome", "move", "busy"),
                                                       ("write", slot_of(p, "n"), 1)]
    names = [x.name for x in p.slots]
    assert "move:running" in names and "check:running" not in names  # instant: no flag
    # a declared primitive shared by two actions: two sites, each with the same outcomes
    shared = Model("shared", primitives=[Primitive("beep", (success(), failure()))],
                   tree=MemorySequence("root", [Action("one", "beep"), Action("two", "beep")]))
    assert sorted((s.label, s.primitive) for s in shared.program.sites) == [("one", "beep"), ("two", "beep")]
    run_rows(shared, [Tick("one:S two:F", "F"), Tick("one:F", "F")])


def _arm(**kw):
    """home (pass) -> work (moving / arrived) for goal 'go'; success at work."""
    base = dict(states=[State("home"), State("work", outcomes=[running("moving"), success("arrived", at=True)])],
                initial="home", goals=["go"], edges=[Edge("home", "work", ["go"])], markers=[Marker("work", ["go"])])
    base.update(kw)
    return FSM("arm", **base)


def test_skill_request():
    m = Model("skill", variables=[Bool("ready"), Bool("at")], fsms=[_arm()],
              environment=[EnvEvent("ready_on", "not ready", {"ready": True})],
              tree=SkillRequest("req", fsm="arm", goal="go", pre="ready"))
    p = m.program
    steps = run_rows(m, [
        Tick("", "F", running=""),  # pre false: FAILURE, the FSM is not ticked
        Tick("arm/home:S", "R", running="req", env="ready_on"),
        Tick("arm/work:moving", "R", running="req"),
        Tick("arm/work:arrived", "S", running=""),
    ])
    assert [p.fsm_state(s.state, "arm") for s, _ in steps] == [("home", None), ("work", "go"), ("work", "go"), ("work", None)]
    assert events(steps[1][0], "fire") == [("fire", "arm", "home->work")]
    assert events(steps[3][0], "fire") == [("fire", "arm", "work:success")]
    assert all(not s.violations for s, _ in steps)
    # pre turning false under a running request: FAILURE, no FSM step, the goal is withdrawn
    m = Model("skill2", variables=[Bool("ready", True), Bool("at")], fsms=[_arm()],
              environment=[EnvEvent("ready_off", "ready", {"ready": False})],
              tree=SkillRequest("req", fsm="arm", goal="go", pre="ready"))
    steps = run_rows(m, [
        Tick("arm/home:S", "R", running="req"),
        Tick("arm/work:moving", "R", running="req"),
        Tick("", "F", running="", halts="", env="ready_off"),
        Tick("", "F", running=""),
    ])
    step, oracle = steps[2]
    assert oracle.halted == ["arm/work"] and events(step, "withdraw") == [("withdraw", "arm", "req")]
    assert m.program.fsm_state(step.state, "arm") == ("work", None)
    assert steps[3][1].halted == [] and not events(steps[3][0], "withdraw")


def test_skill_contracts():
    arm = FSM("arm", states=[State("work", outcomes=[success("ok", at=True), success("bad"), failure("jam")])],
              goals=["go"], markers=[Marker("work", ["go"]), Marker("work", ["go"], on="failure", outcome="failure")])
    m = Model("contract", variables=[Bool("at"), Bool("ready", True)], fsms=[arm],
              environment=[EnvEvent("reset", "at", {"at": False}), EnvEvent("unready", "ready", {"ready": False})],
              tree=SkillRequest("req", fsm="arm", goal="go", pre="ready", post="at"))
    steps = run_rows(m, [
        Tick("arm/work:bad", "S"),  # SUCCESS while post is false: a violation
        Tick("arm/work:jam", "F"),  # not SUCCESS: no contract to check
        Tick("arm/work:ok", "S"),
        Tick("arm/work:bad", "S", env="reset"),  # 'at' still false after the reset
        Tick("", "F", env="unready"),  # pre false: the FSM is not ticked, no violation
    ])
    assert [s.violations for s, _ in steps] == [[("post", "req")], [], [], [("post", "req")], []]
    assert events(steps[0][0], "violation") == [("violation", "req", "post")]
    assert not events(steps[2][0], "violation")


# --------------------------------------------------------------------------- 4. halting


def test_halt_idempotent():
    m = Model("idem", variables=[Bool("stop")], environment=STOP_EVENTS,
              tree=ReactiveFallback("root", [Condition("stopped", "stop"), act("a")]))
    steps = run_rows(m, [
        Tick("a:R", "R", running="root a"),
        Tick("", "S", running="", halts="a", env="stop_on"),
        Tick("", "S", running="", halts=""),  # preempted again: a is idle, nothing happens
        Tick("", "S", running="", halts=""),
    ])
    assert [o.halted for _, o in steps] == [[], ["a"], [], []]
    assert steps[2][0].state == steps[3][0].state


@PROPS
@given(models(), ANSWERS, st.integers(1, 6))
def test_halt_only_running_nodes(model, numbers, ticks):
    """Halting is idempotent, tick by tick: a halt event only ever names a node whose flag
    is set at that moment, each halted Action tells the oracle exactly once, and replaying
    the status and halt events over the flags before the tick gives the flags after it."""
    p = model.program
    flag = {x.name[: -len(":running")]: i for i, x in enumerate(p.slots) if x.kind == "flag"}
    actions = {n.name for n in model.nodes() if isinstance(n, Action)}
    for s, step, oracle in _ticks(model, numbers, ticks, record=True):
        live = {n: bool(s[i]) for n, i in flag.items()}
        halted_actions = []
        for e in step.events:
            if e[0] == "status" and e[1] in flag:
                live[e[1]] = e[2] == R
            elif e[0] == "status":
                assert e[2] != R, f"{e[1]} has no running flag but returned RUNNING"
            elif e[0] == "halt":
                assert live[e[1]], f"halted {e[1]} while it was idle"
                live[e[1]] = False
                if e[1] in actions:
                    halted_actions.append(e[1])
        assert live == {n: bool(step.state[i]) for n, i in flag.items()}
        assert sorted(h for h in oracle.halted if h in actions) == sorted(halted_actions)


def test_halt_before_start():
    # a reactive fallback switching to a higher-priority branch halts the old one first
    m = Model("hbs", tree=ReactiveFallback("root", [act("hi"), act("lo")]))
    steps = run_rows(m, [
        Tick("hi:F lo:R", "R", running="root lo"),
        Tick("hi:R", "R", running="root hi", halts="lo"),
        Tick("hi:F lo:R", "R", running="root lo", halts=""),  # hi was running: lo starts, nothing to halt
    ])
    ev = steps[1][0].events
    assert _pos(ev, ("halt", "lo")) < _pos(ev, ("outcome", "hi", "running"))
    assert steps[1][1].log == [("halt", "lo"), ("outcome", "hi")]
    # the new leaf fails at once: the halted branch starts afresh in the same tick
    steps = run_rows(m, [
        Tick("hi:F lo:R", "R", running="root lo"),
        Tick("hi:F lo:R", "R", running="root lo", halts="lo"),
    ])
    assert steps[1][1].log == [("halt", "lo"), ("outcome", "hi"), ("outcome", "lo")]
    # the halted branch is the child of the common ancestor: halted children first
    m = Model("hbs2", tree=ReactiveFallback("root", [act("hi"), ReactiveSequence("seq", [act("c", "SF"), act("lo")])]))
    steps = run_rows(m, [
        Tick("hi:F c:S lo:R", "R", running="root seq lo"),
        Tick("hi:R", "R", running="root hi", halts="lo seq"),
    ])
    ev = steps[1][0].events
    assert _pos(ev, ("halt", "seq")) < _pos(ev, ("outcome", "hi", "running"))
    # a skill's goal is withdrawn before the new action starts
    m = Model("hbs3", variables=[Bool("at"), Bool("w")], fsms=[_arm()],
              environment=[EnvEvent("want", "not w", {"w": True})],
              tree=ReactiveFallback("root", [ReactiveSequence("urgent", [Condition("wanted", "w"), act("hi")]),
                                             SkillRequest("req", fsm="arm", goal="go")]))
    steps = run_rows(m, [
        Tick("arm/home:S", "R", running="root req"),
        Tick("arm/work:moving", "R", running="root req", halts=""),
        Tick("hi:R", "R", running="root urgent hi", halts="req", env="want"),
    ])
    step, oracle = steps[2]
    assert oracle.log == [("halt", "arm/work"), ("outcome", "hi")]
    assert _pos(step.events, ("withdraw", "arm", "req")) < _pos(step.events, ("outcome", "hi", "running"))
    assert _pos(step.events, ("halt", "req")) < _pos(step.events, ("outcome", "hi", "running"))
    assert m.program.fsm_state(step.state, "arm") == ("work", None)
    # leaves under a Parallel never halt each other
    m = Model("par", tree=Parallel("root", [MemorySequence("ms", [act("a")]), act("b")]))
    run_rows(m, [
        Tick("a:R b:S", "R", running="root ms a"),
        Tick("a:R b:R", "R", running="root ms a b", halts=""),
        Tick("a:R b:F", "F", running="", halts="a ms"),
    ])
    # ... but a leaf outside the Parallel halts the whole running Parallel
    m = Model("par2", tree=ReactiveFallback("root", [act("hi"), Parallel("par", [act("a"), act("b")])]))
    run_rows(m, [
        Tick("hi:F a:R b:R", "R", running="root par a b"),
        Tick("hi:R", "R", running="root hi", halts="a b par"),
    ])
    # instant leaves never halt anything: bookkeeping re-ticks every tick
    m = Model("inst", variables=[Int("n", 0, 9)],
              tree=ReactiveSequence("root", [act("book", "S", S={"n": "min(n + 1, 9)"}), act("lo")]))
    run_rows(m, [
        Tick("book:S lo:R", "R", running="root lo"),
        Tick("book:S lo:R", "R", running="root lo", halts=""),
        Tick("book:S lo:S", "S", running="", halts=""),
    ])


@PROPS
@given(models(), ANSWERS, st.integers(4, 16))
def test_no_orphan_running(model, numbers, ticks):
    """After every tick, a node's running flag is set only if its parent's is (roots of
    the tree and of FSM subtrees excepted)."""
    p = model.program
    parent = parents_of(model)
    for _, step, _ in _ticks(model, numbers, ticks):
        live = running_nodes(p, step.state)
        orphans = sorted(n for n in live if parent[n] is not None and parent[n] not in live)
        assert not orphans, f"running without a running parent: {orphans}"


@PROPS
@given(models(), ANSWERS, st.integers(4, 16))
def test_idle_memory_is_reset(model, numbers, ticks):
    """An idle memory composite starts at child 0 and an idle Retry / Repeat has counted
    nothing: after every tick, a node whose flag is clear has its memory at 0. (The
    memories a halt keeps by definition, SequenceWithMemory's index, RunOnce's result and
    a kept condition status under btcpp, are not drawn here: sections 1 and 8.1.)"""
    p = model.program
    pairs = []
    for i, info in enumerate(p.slots):
        if info.kind == "memory":
            node = info.name.rsplit(":", 1)[0]
            flag = [k for k, x in enumerate(p.slots) if x.name == f"{node}:running"]
            pairs.append((node, flag[0] if flag else None, i))
    for _, step, _ in _ticks(model, numbers, ticks):
        for node, flag, mem in pairs:
            if flag is None or not step.state[flag]:
                assert step.state[mem] == 0, f"{node} is idle but remembers {step.state[mem]}"


# --------------------------------------------------------------------------- 5. FSM tick


def _fsm_model(fsm, variables=(), **kw):
    return Model("fsm", variables=list(variables), fsms=[fsm], **kw)


def _request(model, state, goal, script="", fsm=None, params=()):
    p = model.program
    fsm = fsm or model.fsms[0].name
    oracle = TableOracle(p, script)
    step = p.fsm_step(state, fsm, goal, params, oracle, record=True)
    oracle.finished()
    return step, oracle


def test_fsm_direct_chain():
    f = FSM("f", states=[State("a", outcomes=[running(), success()]), State("b", outcomes=[running(), success()]),
                         State("c", outcomes=[running(), success()]), State("x")],
            goals=["g", "h"],
            edges=[Edge("a", "x", ["g"], direct=True, guard="n == 5"),  # disabled: skipped
                   Edge("a", "b", ["g"], direct=True, effects={"n": "n + 1"}),
                   Edge("a", "c", ["g"], direct=True),  # enabled, but b comes first
                   Edge("b", "c", ["g"], direct=True, guard="n == 1", effects={"m": "n"}),  # sees a->b's effect
                   Edge("a", "b", ["h"])],
            markers=[Marker("c", ["g"])])
    m = _fsm_model(f, [Int("n", 0, 5), Int("m", 0, 5)])
    p = m.program
    step, oracle = _request(m, p.initial, "g", "f/c:S")  # nothing runs before c
    assert step.status == S
    assert events(step, "fire") == [("fire", "f", "a->b"), ("fire", "f", "b->c"), ("fire", "f", "c:success")]
    assert oracle.log == [("halt", "f/a"), ("halt", "f/b"), ("outcome", "f/c")]  # left a and b
    assert p.fsm_state(step.state, "f") == ("c", None)
    assert (p.decode(step.state)["n"], p.decode(step.state)["m"]) == (1, 1)
    # the direct edges of g do nothing for h: a runs
    step, _ = _request(m, p.initial, "h", "f/a:S")
    assert p.fsm_state(step.state, "f") == ("b", "h") and step.status == R
    with pytest.raises(ModelError):  # a direct cycle cannot be built (the chain is bounded)
        _fsm_model(FSM("f", states=[State("a"), State("b")], goals=["g"],
                       edges=[Edge("a", "b", ["g"], direct=True), Edge("b", "a", ["g"], direct=True)]))


def test_fsm_direct_marker():
    f = FSM("f", states=[State("a", outcomes=[running(), success()]), State("b", outcomes=[running(), success()])],
            goals=["g", "h", "k"],
            edges=[Edge("a", "b", ["h"], direct=True), Edge("a", "b", ["g"])],
            markers=[Marker("a", ["g"], direct=True, outcome="success", guard="done"),
                     Marker("b", ["h"], direct=True, outcome="failure"),
                     Marker("a", ["k"], direct=True, outcome="success")])
    m = _fsm_model(f, [Bool("done")], environment=[EnvEvent("finish", None, {"done": True})])
    p = m.program
    step, _ = _request(m, p.initial, "g", "f/a:R")  # guard false: the state runs
    assert step.status == R and p.fsm_state(step.state, "f") == ("a", "g")
    done = p.step(p.initial, TableOracle(p, "", "finish")).state
    step, _ = _request(m, done, "g", "")  # guard true: reply at once, nothing runs
    assert step.status == S and events(step, "fire") == [("fire", "f", "a:direct")]
    assert p.fsm_state(step.state, "f") == ("a", None)
    step, oracle = _request(m, p.initial, "h", "")  # after a direct chain
    assert step.status == F and p.fsm_state(step.state, "f") == ("b", None)
    assert events(step, "fire") == [("fire", "f", "a->b"), ("fire", "f", "b:direct")]
    step, _ = _request(m, step.state, "g", "")  # b has only an h marker: g is not applicable
    assert step.status == F and events(step) == [("not-applicable", "f", "b")]
    step, _ = _request(m, p.initial, "k", "")
    assert step.status == S


def test_fsm_not_applicable():
    f = FSM("f", states=[State("a", outcomes=[running(), success()]), State("b", outcomes=[running(), success()])],
            goals=["g", "h", "k"],
            edges=[Edge("a", "b", ["g"]), Edge("a", "b", ["k"], guard="false"), Edge("b", "a", ["g"], direct=True)])
    m = _fsm_model(f)
    p = m.program
    step, _ = _request(m, p.initial, "h", "")  # no edge or marker for h at a
    assert step.status == F and p.fsm_state(step.state, "f") == ("a", None)
    assert events(step) == [("not-applicable", "f", "a")]
    step, _ = _request(m, p.initial, "k", "f/a:S")  # guards are ignored: k applies at a
    assert step.status == R and p.fsm_state(step.state, "f") == ("a", "k")
    at_b, _ = _request(m, p.initial, "g", "f/a:S")
    step, _ = _request(m, at_b.state, "k", "")  # nothing for k at b
    assert step.status == F and events(step) == [("not-applicable", "f", "b")]
    # a held goal is cleared by the FAILURE reply
    held, _ = _request(m, p.initial, "g", "f/a:R")
    step, _ = _request(m, held.state, "h", "")
    assert p.fsm_state(step.state, "f") == ("a", None)


def test_fsm_runs_state_once():
    f = FSM("f", states=[State("a", outcomes=[running("busy", n="n + 1"), success("ok", n="n + 1")])], goals=["g"],
            markers=[Marker("a", ["g"], on="failure", outcome="failure")])
    m = _fsm_model(f, [Int("n", 0, 9)])
    p = m.program
    s = p.initial
    for k, out in enumerate(["busy", "ok", "ok", "busy"], 1):
        step, oracle = _request(m, s, "g", f"f/a:{out}")  # exactly one run per request
        assert oracle.log == [("outcome", "f/a")]
        assert p.decode(step.state)["n"] == k
        # a status without edge or marker leaves the token where it is: it runs again
        assert step.status == R and p.fsm_state(step.state, "f") == ("a", "g")
        s = step.state
    # a state that runs a subtree ticks it once; leaving (here: a withdrawal) halts it
    f = FSM("f", states=[State("s", subtree=MemorySequence("seq", [act("a"), act("b")])), State("t")], goals=["g"],
            edges=[Edge("s", "t", ["g"])], markers=[Marker("t", ["g"], direct=True)])
    m = Model("sub", variables=[Bool("stop")], fsms=[f], environment=STOP_EVENTS,
              tree=ReactiveFallback("root", [Condition("stopped", "stop"), SkillRequest("req", fsm="f", goal="g")]))
    steps = run_rows(m, [
        Tick("a:S b:R", "R", running="root req seq b"),
        Tick("", "S", running="", halts="b seq req", env="stop_on"),
        Tick("a:S b:S", "R", running="root req", env="stop_off"),  # the subtree starts afresh
        Tick("", "S", running=""),
    ])
    assert [m.program.fsm_state(x.state, "f") for x, _ in steps] == [("s", "g"), ("s", None), ("t", "g"), ("t", None)]


def test_fsm_marker_reply():
    f = FSM("f", states=[State("a", outcomes=[success("hit", n="1"), success("miss"), failure("jam"), running("busy")]),
                         State("b")],
            goals=["g"], edges=[Edge("a", "b", ["g"], guard="n == 1")],
            markers=[Marker("a", ["g"], on="success", outcome="success", guard="n == 1", id="ok"),
                     Marker("a", ["g"], on="success", outcome="failure", id="nope"),
                     Marker("a", ["g"], on="failure", outcome="failure", id="jammed")])
    m = _fsm_model(f, [Int("n", 0, 1)])
    p = m.program
    cases = {"hit": (S, ["ok", "a->b"]),  # the guard sees the run's effect (n = 1)
             "miss": (F, ["nope"]), "jam": (F, ["jammed"]), "busy": (R, [])}
    for out, (reply, fired) in cases.items():
        step, _ = _request(m, p.initial, "g", f"f/a:{out}")
        assert step.status == reply, out
        assert [e[2] for e in events(step, "fire")] == fired, out
        assert p.fsm_state(step.state, "f")[1] == ("g" if reply == R else None)


def test_fsm_edge_on_status():
    f = FSM("f", states=[State("a", outcomes=[success("done", n="1"), failure("jam"), running("busy")]),
                         State("b"), State("c"), State("d")],
            goals=["g"],
            edges=[Edge("a", "b", ["g"], guard="n == 0", id="wrong"),
                   Edge("a", "c", ["g"], effects={"k": "k + 1"}, id="right"),
                   Edge("a", "b", ["g"], id="later"),
                   Edge("a", "d", ["g"], on="failure", id="fail")],
            markers=[Marker("a", ["g"], id="reply")])
    m = _fsm_model(f, [Int("n", 0, 1), Int("k", 0, 3)])
    p = m.program
    step, oracle = _request(m, p.initial, "g", "f/a:done")
    assert [e[2] for e in events(step, "fire")] == ["reply", "right"]  # marker (5) before edge (6)
    assert p.fsm_state(step.state, "f") == ("c", None) and p.decode(step.state)["k"] == 1
    assert oracle.log == [("outcome", "f/a"), ("halt", "f/a")]  # leaving a is notified
    step, _ = _request(m, p.initial, "g", "f/a:jam")
    assert p.fsm_state(step.state, "f") == ("d", "g") and step.status == R
    step, oracle = _request(m, p.initial, "g", "f/a:busy")  # no edge on RUNNING: stays
    assert p.fsm_state(step.state, "f") == ("a", "g") and oracle.halted == []
    # an edge on RUNNING leaves a busy state (the runtime halts its primitive)
    f2 = FSM("f", states=[State("a", outcomes=[running("busy")]), State("b")], goals=["g"],
             edges=[Edge("a", "b", ["g"], on="running", guard="go")])
    m2 = _fsm_model(f2, [Bool("go", True)])
    step, oracle = _request(m2, m2.program.initial, "g", "f/a:busy")
    assert oracle.log == [("outcome", "f/a"), ("halt", "f/a")] and m2.program.fsm_state(step.state, "f")[0] == "b"


# --------------------------------------------------------------------------- 5. requests, goals, parameters


def _work_fsm(**kw):
    base = dict(states=[State("home"), State("work", outcomes=[running("busy"), success("ok")])], goals=["g", "h"],
                edges=[Edge("home", "work", ["g", "h"])], markers=[Marker("work", ["g", "h"])])
    base.update(kw)
    return FSM("f", **base)


def test_fsm_once_per_tick():
    m = Model("once", fsms=[_work_fsm()],
              tree=Parallel("root", [SkillRequest("r1", fsm="f", goal="g"), SkillRequest("r2", fsm="f", goal="g"),
                                     SkillRequest("r3", fsm="f", goal="h")], success_threshold=2, failure_threshold=2))
    p = m.program
    steps = run_rows(m, [
        Tick("f/home:S", "R", running="root r1 r2"),  # r2: same reply without a step; r3: busy
        Tick("f/work:busy", "R", running="root r1 r2"),
    ])
    for step, _ in steps:
        assert events(step, "busy") == [("busy", "f", "r3")]
        assert step.violations == [("busy", "r3", "f")]  # a conflict (rule 'Conflict')
        assert [e for e in events(step, "status") if e[1] == "r3"] == [("status", "r3", F)]
    assert [p.fsm_state(s.state, "f") for s, _ in steps] == [("work", "g"), ("work", "g")]
    # r1 lets go (SUCCESS) and r3 starts: a hand-over, the FSM steps again for 'h' (rule 'Hand-over');
    # the Parallel succeeds (r1, r2) and halts r3, which withdraws 'h'
    step, oracle = run_rows(m, [Tick("f/work:ok f/work:busy", "S", running="", halts="r3")], steps[-1][0].state)[0]
    assert events(step, "handover", "withdraw") == [("handover", "f", "r3"), ("withdraw", "f", "r3")]
    assert not step.violations and p.fsm_state(step.state, "f") == ("work", None)


def _handover_fsm(**kw):
    base = dict(states=[State("home"), State("door", outcomes=[running("busy"), success("ok")]),
                        State("cup", outcomes=[running("busy"), success("ok")])],
                goals=["open_door", "pick_cup"],
                edges=[Edge("home", "door", ["open_door"]), Edge("door", "cup", ["pick_cup"], direct=True),
                       Edge("home", "cup", ["pick_cup"], direct=True)],
                markers=[Marker("door", ["open_door"]), Marker("cup", ["pick_cup"])])
    base.update(kw)
    return FSM("arm", **base)


def _handover_model():
    return Model("handover", variables=[Bool("fell_back")], fsms=[_handover_fsm()],
                 tree=MemoryFallback("root", [
                     MemorySequence("seq", [SkillRequest("open", fsm="arm", goal="open_door"),
                                            SkillRequest("pick", fsm="arm", goal="pick_cup")]),
                     Action("fallback", outcomes=[success(fell_back="true")])]))


def test_fsm_handover():
    m = _handover_model()
    p = m.program
    steps = run_rows(m, [
        Tick("arm/home:S", "R", running="root seq open"),
        Tick("arm/door:busy", "R", running="root seq open"),
        # 'open' succeeds; 'pick' starts in the same tick: the FSM steps again, for it
        Tick("arm/door:ok arm/cup:busy", "R", running="root seq pick", halts=""),
        Tick("arm/cup:ok", "S", running=""),
    ])
    step = steps[2][0]
    assert events(step, "handover", "busy") == [("handover", "arm", "pick")]
    assert [e for e in events(step, "status") if e[1] in ("open", "pick")] == [("status", "open", S), ("status", "pick", R)]
    assert p.fsm_state(step.state, "arm") == ("cup", "pick_cup")
    assert all(not s.violations for s, _ in steps)
    assert not any(p.decode(s.state)["fell_back"] for s, _ in steps)  # the fallback never fires


def test_fsm_conflict():
    # r1 replies SUCCESS at once every tick (direct markers); r2 started by a hand-over in
    # tick 0 and is running in tick 1 when r1 takes the FSM again: a conflict
    f = _work_fsm(markers=[Marker("home", ["g"], direct=True), Marker("work", ["g"], direct=True), Marker("work", ["h"])])
    m = Model("conflict", fsms=[f], tree=Parallel("root", [SkillRequest("r1", fsm="f", goal="g"),
                                                           SkillRequest("r2", fsm="f", goal="h")]))
    steps = run_rows(m, [
        Tick("f/home:S", "R", running="root r2"),
        Tick("", "F", running=""),
    ])
    assert events(steps[0][0], "handover") == [("handover", "f", "r2")] and not steps[0][0].violations
    assert events(steps[1][0], "busy") == [("busy", "f", "r2")] and steps[1][0].violations == [("busy", "r2", "f")]


def test_fsm_held_goal():
    m = _fsm_model(_work_fsm(markers=[Marker("work", ["g", "h"]), Marker("work", ["h"], on="running", outcome="failure")]))
    p = m.program
    held = []
    s = p.initial
    for goal, script in [("g", "f/home:S"), ("g", "f/work:busy"), ("g", "f/work:ok"), ("h", "f/work:ok"),
                         ("g", "f/work:busy"), ("h", "f/work:busy")]:
        step, _ = _request(m, s, goal, script)
        s = step.state
        held.append((Status(step.status).name[0], p.fsm_state(s, "f")[1]))
    # RUNNING holds the requested goal; SUCCESS and FAILURE clear it
    assert held == [("R", "g"), ("R", "g"), ("S", None), ("S", None), ("R", "g"), ("F", None)]


def test_withdraw_on_halt():
    m = Model("wd", variables=[Bool("stop")], fsms=[_work_fsm()], environment=STOP_EVENTS,
              tree=ReactiveFallback("root", [Condition("stopped", "stop"), SkillRequest("req", fsm="f", goal="g")]))
    p = m.program
    steps = run_rows(m, [
        Tick("f/home:S", "R", running="root req"),
        Tick("f/work:busy", "R", running="root req"),
        Tick("", "S", running="", halts="req", env="stop_on"),
        Tick("", "S", running="", halts=""),
    ])
    step, oracle = steps[2]
    assert oracle.halted == ["f/work"]  # the token's state is left-notified
    assert events(step, "withdraw", "halt") == [("withdraw", "f", "req"), ("halt", "req")]
    assert p.fsm_state(step.state, "f") == ("work", None)  # goal cleared, token stays
    assert steps[3][1].halted == [] and not events(steps[3][0], "withdraw")
    # not when another request already stepped the FSM this tick
    m = Model("wd2", variables=[Bool("stop")], fsms=[_work_fsm()], environment=STOP_EVENTS,
              tree=Parallel("root", [SkillRequest("ra", fsm="f", goal="g"),
                                     ReactiveSequence("seq", [Condition("go", "not stop"), SkillRequest("rb", fsm="f", goal="g")])],
                            success_threshold=1, failure_threshold=2))
    steps = run_rows(m, [
        Tick("f/home:S", "R", running="root ra seq rb"),
        Tick("f/work:busy", "R", running="root ra", halts="rb", env="stop_on"),
    ])
    step, oracle = steps[1]
    assert oracle.halted == [] and not events(step, "withdraw")
    assert m.program.fsm_state(step.state, "f") == ("work", "g")


def test_params_immediate():
    f = FSM("f", states=[State("home", outcomes=[running("busy"), success("ok")])], goals=["g"],
            params=[Int("t", 0, 3)], markers=[Marker("home", ["g"], guard="t == 3")])
    m = Model("pi", variables=[Int("target", 0, 3, 2)], fsms=[f],
              environment=[EnvEvent("retarget", "target != 3", {"target": "3"})],
              tree=SkillRequest("req", fsm="f", goal="g", params={"t": "target"}))
    p = m.program
    steps = run_rows(m, [
        Tick("f/home:busy", "R"),  # t: 0 -> 2, then the step, in the same tick
        Tick("f/home:ok", "R"),  # the marker needs t == 3
        Tick("f/home:ok", "S", env="retarget"),  # t = 3 is set before the step: the marker sees it
    ])
    assert [p.decode(s.state)["f.t"] for s, _ in steps] == [2, 2, 3]


def test_params_withdraw():
    f = FSM("f", states=[State("idle"), State("work", outcomes=[running("busy"), success("ok")]),
                         State("retract", outcomes=[running("moving"), success("in")])],
            goals=["go", "home"], params=[Int("t", 0, 3)], retarget="withdraw", withdraw_goal="home",
            edges=[Edge("idle", "work", ["go"]), Edge("work", "retract", ["home"], direct=True),
                   Edge("retract", "idle", ["home"])],
            markers=[Marker("work", ["go"]), Marker("idle", ["home"], direct=True)])
    m = Model("pw", variables=[Int("target", 0, 3, 1)], fsms=[f],
              environment=[EnvEvent("retarget", "target != 2", {"target": "2"})],
              tree=SkillRequest("req", fsm="f", goal="go", params={"t": "target"}))
    p = m.program
    steps = run_rows(m, [
        Tick("", "R"),  # 0 != 1: withdraw; idle's direct marker succeeds at once: adopt t = 1
        Tick("f/idle:S", "R"),  # the requested skill starts on a later tick
        Tick("f/work:busy", "R"),
        Tick("f/retract:moving", "R", env="retarget"),  # toward 'home': RUNNING, t stays 1
        Tick("f/retract:in", "R"),
        Tick("", "R"),  # home reached (direct marker): adopt t = 2, still RUNNING
        Tick("f/idle:S", "R"),
        Tick("f/work:ok", "S"),
    ])
    assert [p.decode(s.state)["f.t"] for s, _ in steps] == [1, 1, 1, 1, 1, 2, 2, 2]
    assert [p.fsm_state(s.state, "f") for s, _ in steps] == [
        ("idle", "go"), ("work", "go"), ("work", "go"), ("retract", "go"), ("idle", "go"),
        ("idle", "go"), ("work", "go"), ("work", None)]
    assert steps[3][1].halted == ["f/work"]  # the direct edge left work


# --------------------------------------------------------------------------- 6. runtime, traces


def _events_fn(seed, forced=True):
    rng = random.Random(seed)
    return lambda rt: pick_events(rt.program, rt.state, rng, forced)


@PROPS
@given(models(), st.integers(0, 2**16), st.integers(1, 12), st.booleans())
def test_runtime_never_raises(model, seed, ticks, forced):
    """A valid model driven by random answers ticks without error and stays in its domains
    (``forced``: whether a choice's only enabled option is reported by the sensors)."""
    rt = Runtime(model, fallback=RandomOracle(seed), record=True)
    events_of = _events_fn(seed, forced)
    p = model.program
    for _ in range(ticks):
        step = rt.tick(events_of(rt))
        assert step.status in (Status.RUNNING, Status.SUCCESS, Status.FAILURE)
        for info, val in zip(p.slots, rt.state):
            lo = info.lo if info.kind in ("var", "param") else 0
            assert lo <= val < lo + info.size, f"{info.name} = {val}"
    assert rt.clock.tick == ticks


@PROPS
@given(models(), st.integers(0, 2**16), st.integers(1, 12), st.booleans(), st.sampled_from(["deferred", "live"]))
def test_replay_reproduces_trace(model, seed, ticks, forced, mode):
    """A recorded runtime trace (either trace mode) replays exactly; a tampered one is
    caught at its tick."""
    out = io.StringIO()
    rt = Runtime(model, fallback=RandomOracle(seed), trace=out, trace_mode=mode)
    rt.run(ticks, _events_fn(seed, forced))
    rt.close()
    lines = out.getvalue().splitlines()
    assert len(lines) == ticks + 1
    assert replay(lines, model) is None
    header, records = read_trace(lines)
    last = records[-1]
    last["status"] = {"RUNNING": "SUCCESS", "SUCCESS": "FAILURE", "FAILURE": "RUNNING"}[last["status"]]
    tampered = lines[:-1] + [json.dumps(last)]
    assert replay(tampered, model) == (ticks - 1, "regenerated record differs in status")
