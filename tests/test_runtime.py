"""The runtime (docs/semantics.md section 6): explicit clock, implementations bound by
primitive name and checked against the declared outcomes, observed events checked
against the model, halt callbacks, determinism, and the JSON Lines trace."""
from __future__ import annotations

import io
import json
import random

import pytest
from hypothesis import HealthCheck, given, settings
from memo_strategies import st

from btfsm import (FSM, Action, Bool, Condition, ConformanceError, Edge, Effects, EnvChoice, EnvEvent, Int,
                   Marker, Model, Parallel, ReactiveFallback, ReactiveSequence, SkillRequest, State, Status,
                   failure, running, success)
from btfsm.oracles import RandomOracle
from btfsm.runtime import Clock, Runtime
from btfsm.trace import FORMAT, read_trace, replay

from core_strategies import act, models, pick_events

PROPS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
STOP_EVENTS = [EnvEvent("stop_on", "not stop", {"stop": True}), EnvEvent("stop_off", "stop", {"stop": False})]


class Recorder:
    """An implementation object that answers from a script and logs every call."""

    def __init__(self, answers, log, name):
        self.answers, self.log, self.name = list(answers), log, name

    def tick(self, call):
        self.log.append(("tick", self.name, call.first, call.tick, call.time))
        return self.answers.pop(0)

    def halt(self, call):
        self.log.append(("halt", self.name, call.first, call.tick, call.time))


# --------------------------------------------------------------------------- clock and calls


def test_clock():
    c = Clock(4)
    assert [Clock(4, k).time for k in range(5)] == [0.0, 0.25, 0.5, 0.75, 1.0]
    assert (c.rate, c.tick, c.time) == (4.0, 0, 0.0)


def test_time_is_tick_over_rate():
    seen = []

    def impl(call):
        seen.append((call.tick, call.time, call.first))
        return "success"

    m = Model("clock", tick_rate=4, tree=act("a", "S"))
    rt = Runtime(m, {"a": impl})
    for _ in range(3):
        rt.tick()
    assert seen == [(0, 0.0, True), (1, 0.25, True), (2, 0.5, True)]
    assert rt.clock.tick == 3 and rt.clock.time == 0.75


def test_call_first_marks_each_fresh_run():
    log = []
    m = Model("first", tree=act("a"))
    rt = Runtime(m, {"a": Recorder(["running", "running", "success", "running", "failure", "failure"], log, "a")})
    rt.run(6)
    assert [x[2] for x in log] == [True, False, False, True, False, True]


def test_call_sees_args_and_vars():
    got = []

    def impl(call):
        got.append((call.args, dict(call.vars), call.site.label))
        return "success"

    m = Model("args", variables=[Int("n", 0, 3, 2), Bool("b", True)],
              tree=Action("move", outcomes=[success(n="n + 1")], args={"speed": 3, "to": "bin"}))
    rt = Runtime(m, {"move": impl})
    rt.tick()
    assert [(dict(a), v, label) for a, v, label in got] == [({"speed": 3, "to": "bin"}, {"n": 2, "b": True}, "move")]
    assert rt.vars == {"n": 3, "b": True}


# --------------------------------------------------------------------------- answers


def _three():
    return Model("three", tree=Action("a", outcomes=[running("busy"), success("done"), success("early"), failure("jam")]))


@pytest.mark.parametrize("answer, status", [
    ("busy", Status.RUNNING), ("early", Status.SUCCESS), ("jam", Status.FAILURE),  # names
    (Status.RUNNING, Status.RUNNING), (Status.FAILURE, Status.FAILURE),  # a Status with one outcome
    (0, Status.RUNNING), (2, Status.SUCCESS), (3, Status.FAILURE),  # indices
])
def test_implementation_answers(answer, status):
    rt = Runtime(_three(), {"a": lambda call: answer})
    assert rt.tick().status == status
    rt2 = Runtime(_three(), {"a": type("Impl", (), {"tick": lambda self, call: answer})()})  # object form
    assert rt2.tick().status == status


@pytest.mark.parametrize("answer, words", [
    ("nope", ["'nope'", "not a declared outcome", "busy, done, early, jam"]),
    (Status.SUCCESS, ["SUCCESS", "several"]),
    (4, ["4", "not an outcome"]),
    (-1, ["-1", "not an outcome"]),
    (True, ["True", "not an outcome"]),
    (None, ["None"]),
    (1.0, ["1.0"]),
])
def test_undeclared_answers_are_conformance_errors(answer, words):
    rt = Runtime(_three(), {"a": lambda call: answer})
    with pytest.raises(ConformanceError) as err:
        rt.tick()
    text = str(err.value)
    assert text.startswith("a: ") and all(w in text for w in words), text
    assert rt.clock.tick == 0 and rt.state == rt.program.initial  # the tick did not happen


def test_status_without_outcome_is_a_conformance_error():
    m = Model("two", tree=Action("a", outcomes=[success(), failure()]))
    with pytest.raises(ConformanceError, match="RUNNING; none"):
        Runtime(m, {"a": lambda call: Status.RUNNING}).tick()


def test_fsm_state_sites_are_checked_too():
    arm = FSM("arm", states=[State("work", outcomes=[running("busy"), success("ok")])], goals=["go"],
              markers=[Marker("work", ["go"])])
    m = Model("fsm", fsms=[arm], tree=SkillRequest("req", fsm="arm", goal="go"))
    with pytest.raises(ConformanceError, match="^arm/work: 'work' returned 'gone'"):
        Runtime(m, {"work": lambda call: "gone"}).tick()


def test_missing_implementations():
    m = Model("missing", tree=ReactiveSequence("root", [act("one", "S"), act("two", "SF")]))
    with pytest.raises(ConformanceError, match="two: primitive 'two' has 2 outcomes and no implementation"):
        Runtime(m).tick()  # 'one' has a single outcome: no implementation needed
    rt = Runtime(m, fallback=RandomOracle(3))
    assert {rt.tick().status for _ in range(20)} == {Status.SUCCESS, Status.FAILURE}


# --------------------------------------------------------------------------- observed events


def _env_model():
    return Model("env", variables=[Bool("a"), Bool("b", True)],
                 environment=[EnvEvent("rise", "not a", {"a": True}), EnvEvent("fall", "a", {"a": False}),
                              EnvChoice("pick", [EnvEvent("left", "b", {}), EnvEvent("right", None, {"b": False})])],
                 tree=Condition("root", "a"))


def test_observed_events_must_be_enabled():
    rt = Runtime(_env_model())
    with pytest.raises(ConformanceError, match=r"observed event\(s\) \['fall'\] not enabled"):
        rt.tick(["fall", "left"])  # a is false: 'fall' cannot happen
    with pytest.raises(ConformanceError, match=r"\['ghost'\]"):
        rt.tick(["ghost", "left"])
    assert rt.tick(["rise", "left"]).status == Status.SUCCESS
    assert rt.tick(["fall", "right"]).status == Status.FAILURE  # rise's guard is false again: not asked
    with pytest.raises(ConformanceError, match=r"\['left'\]"):
        rt.tick(["left"])  # b is false now: 'left' is not enabled
    with pytest.raises(TypeError):
        rt.tick("rise")  # one string is not a collection of names


def test_choices_need_exactly_one_observed_option():
    rt = Runtime(_env_model())
    with pytest.raises(ConformanceError, match="choice 'pick' needs exactly one observed option of \\(left, right\\)"):
        rt.tick([])
    with pytest.raises(ConformanceError, match="choice 'pick'"):
        rt.tick(["left", "right"])
    rt.tick(["right"])
    # now only 'right' is enabled: it happens, observed or not
    assert rt.tick([]).status == Status.FAILURE
    assert rt.tick(["right"]).status == Status.FAILURE


def test_blocked_choice_is_an_error():
    m = Model("blocked", variables=[Bool("a", True)],
              environment=[EnvChoice("c", [EnvEvent("only", "a", {"a": False})])], tree=Condition("root", "a"))
    rt = Runtime(m)
    rt.tick()
    with pytest.raises(ConformanceError, match="'c'"):
        rt.tick()
    assert rt.state == (0,) and rt.clock.tick == 1  # the state is kept, not replaced by None


# --------------------------------------------------------------------------- halts


def test_halt_callbacks_on_preemption():
    log = []
    m = Model("halt", variables=[Bool("stop")], environment=STOP_EVENTS,
              tree=ReactiveFallback("root", [Condition("stopped", "stop"), act("a")]))
    rec = Recorder(["running", "running", "running", "success"], log, "a")
    rt = Runtime(m, {"a": rec})
    rt.tick()
    rt.tick()
    rt.tick(["stop_on"])  # preempted while busy: halted
    rt.tick()
    rt.tick(["stop_off"])  # starts afresh
    rt.tick()
    rt.tick(["stop_on"])  # finished last tick: nothing to halt
    assert log == [("tick", "a", True, 0, 0.0), ("tick", "a", False, 1, 0.1), ("halt", "a", False, 2, 0.2),
                   ("tick", "a", True, 4, 0.4), ("tick", "a", False, 5, 0.5)]


def test_halt_before_start_in_the_runtime():
    """The old branch is halted before the new action's first call; if that fails at once
    the old branch restarts in the same tick (a fresh run)."""
    log = []
    m = Model("hbs", tree=ReactiveFallback("root", [act("hi"), act("lo")]))
    rt = Runtime(m, {"hi": Recorder(["failure", "failure", "running"], log, "hi"),
                     "lo": Recorder(["running", "running"], log, "lo")})
    rt.run(3)
    assert [x[:3] for x in log] == [
        ("tick", "hi", True), ("tick", "lo", True),
        ("halt", "lo", False), ("tick", "hi", True), ("tick", "lo", True),
        ("halt", "lo", False), ("tick", "hi", True)]


def test_withdraw_halts_the_fsm_state():
    log = []
    arm = FSM("arm", states=[State("home"), State("work", outcomes=[running("busy"), success("ok")])], goals=["go"],
              edges=[Edge("home", "work", ["go"])], markers=[Marker("work", ["go"])])
    m = Model("wd", variables=[Bool("stop")], fsms=[arm], environment=STOP_EVENTS,
              tree=ReactiveFallback("root", [Condition("stopped", "stop"), SkillRequest("req", fsm="arm", goal="go")]))
    rt = Runtime(m, {"work": Recorder(["busy", "busy", "ok"], log, "work")})
    rt.run(2)
    assert rt.fsm_state("arm") == ("work", "go")
    rt.tick(["stop_on"])
    assert rt.fsm_state("arm") == ("work", None)
    rt.tick(["stop_off"])
    rt.tick()
    assert [x[:3] for x in log] == [("tick", "work", True), ("halt", "work", False), ("tick", "work", True),
                                    ("tick", "work", False)]
    assert rt.fsm_state("arm") == ("work", None) and rt.last.status == Status.SUCCESS


# --------------------------------------------------------------------------- determinism and traces


def _events_fn(seed, forced=True):
    rng = random.Random(seed)
    return lambda rt: pick_events(rt.program, rt.state, rng, forced)


def _trace(model, seed, ticks, **kw):
    out = io.StringIO()
    rt = Runtime(model, fallback=RandomOracle(seed), trace=out, **kw)
    rt.run(ticks, _events_fn(seed))
    rt.close()
    return out.getvalue()


@PROPS
@given(models(), st.integers(0, 2**16), st.integers(1, 15))
def test_same_seed_same_trace(model, seed, ticks):
    """Two runs with the same seed write identical traces; the deferred trace (rendered
    by re-running the step function) is the same file as the live one."""
    first = _trace(model, seed, ticks)
    assert _trace(model, seed, ticks) == first
    assert _trace(model, seed, ticks, trace_mode="live") == first
    assert replay(first.splitlines(), model) is None


def test_different_seeds_differ():
    m = Model("coin", variables=[Int("n", 0, 50)], tree=Action("flip", outcomes=[success(n="min(n + 1, 50)"), failure()]))
    traces = {_trace(m, seed, 20) for seed in range(5)}
    assert len(traces) == 5


def test_deferred_trace_with_an_unobserved_forced_option():
    """A choice whose only enabled option was not reported still renders (the runtime
    accepts it; the deferred trace must too)."""
    m = Model("forced", variables=[Bool("a")],
              environment=[EnvChoice("c", [EnvEvent("x", "a", {}), EnvEvent("y", None, {})])],
              tree=Condition("root", "not a"))
    out = io.StringIO()
    rt = Runtime(m, trace=out)
    rt.tick()
    rt.close()
    header, records = read_trace(out.getvalue().splitlines())
    assert records[0]["env"] == ["y"]


def _cell():
    arm = FSM("arm", states=[State("home"), State("work", outcomes=[running("busy"), success("ok")])], goals=["go"],
              edges=[Edge("home", "work", ["go"])], markers=[Marker("work", ["go"])])
    return Model("cell", tick_rate=4, variables=[Bool("stop"), Int("count", 0, 9)], fsms=[arm], environment=STOP_EVENTS,
                 tree=ReactiveFallback("root", [Condition("stopped", "stop"),
                                                Effects("eff", SkillRequest("req", fsm="arm", goal="go"),
                                                        on_success={"count": "count + 1"})]))


def test_trace_file_contents(tmp_path):
    path = tmp_path / "run.jsonl"
    m = _cell()
    rt = Runtime(m, {"work": lambda call: "busy" if call.first else "ok"}, trace=str(path))
    for events in ([], [], ["stop_on"], ["stop_off"], []):
        rt.tick(events)
    rt.close()
    lines = path.read_text(encoding="utf-8").splitlines()
    header = json.loads(lines[0])
    assert header == {"format": FORMAT, "model": "cell", "tick_rate": 4,
                      "initial": {"stop": False, "count": 0, "arm.state": "home", "arm.goal": "none",
                                  "root:running": 0, "eff:running": 0, "req:running": 0}}
    recs = [json.loads(x) for x in lines[1:]]
    assert [r["tick"] for r in recs] == [0, 1, 2, 3, 4]
    assert [r["time"] for r in recs] == [0.0, 0.25, 0.5, 0.75, 1.0]
    assert [r["status"] for r in recs] == ["RUNNING", "RUNNING", "SUCCESS", "RUNNING", "SUCCESS"]
    assert recs[0]["outcomes"] == [["arm/home", "success"]]
    assert recs[0]["fired"] == [["arm", "home->work"]]
    assert recs[0]["changes"] == {"stopped": "FAILURE", "req": "RUNNING", "eff": "RUNNING", "root": "RUNNING"}
    assert recs[0]["fsm"] == {"arm": ["work", "go"]}
    assert recs[1]["outcomes"] == [["arm/work", "busy"]] and recs[1]["changes"] == {}
    assert recs[2]["env"] == ["stop_on"] and recs[2]["writes"] == {"stop": True}
    assert recs[2]["changes"] == {"stopped": "SUCCESS", "req": "halted", "eff": "halted", "root": "SUCCESS"}
    assert recs[2]["fired"] == [["arm", "<withdraw>"]] and recs[2]["fsm"] == {"arm": ["work", None]}
    assert recs[2]["outcomes"] == []
    assert recs[3]["outcomes"] == [["arm/work", "busy"]]  # a fresh run after the halt
    assert recs[4]["outcomes"] == [["arm/work", "ok"]] and recs[4]["fired"] == [["arm", "work:success"]]
    assert recs[4]["writes"] == {"count": 1} and recs[4]["violations"] == []
    assert all(set(r) == {"tick", "time", "status", "env", "outcomes", "changes", "fired", "fsm", "writes", "violations"}
               for r in recs)
    assert read_trace(str(path)) == (header, recs)
    assert replay(str(path), m) is None


def test_trace_records_violations_and_busy():
    arm = FSM("arm", states=[State("work", outcomes=[success("ok")])], goals=["go", "other"],
              markers=[Marker("work", ["go", "other"])])
    slow = FSM("slow", states=[State("w", outcomes=[running("moving")])], goals=["x", "y"],
               markers=[Marker("w", ["x", "y"], on="failure")])
    m = Model("viol", variables=[Bool("done")], fsms=[arm, slow],
              tree=Parallel("root", [SkillRequest("a", fsm="arm", goal="go", post="done"),
                                     SkillRequest("b1", fsm="slow", goal="x"), SkillRequest("b2", fsm="slow", goal="y")]))
    out = io.StringIO()
    rt = Runtime(m, {"moving": "moving"}, trace=out)
    rt.tick()
    rt.close()
    rec = read_trace(out.getvalue().splitlines())[1][0]
    # b2 asks 'slow' while b1 holds it (RUNNING) in the same tick: a conflict ('busy')
    assert rec["violations"] == [["violation", "a", "post"], ["busy", "slow", "b2"]]
    assert rt.last.violations == [("post", "a"), ("busy", "b2", "slow")]


def test_replay_reports_the_first_difference():
    m = _cell()
    out = io.StringIO()
    rt = Runtime(m, {"work": lambda call: "busy" if call.first else "ok"}, trace=out)
    for events in ([], [], [], ["stop_on"]):
        rt.tick(events)
    rt.close()
    lines = out.getvalue().splitlines()
    assert replay(lines, m) is None
    rec = json.loads(lines[2])
    rec["outcomes"] = [["arm/work", "ok"]]  # tick 1 claims the run finished
    assert replay(lines[:2] + [json.dumps(rec)] + lines[3:], m) == (1, "regenerated record differs in changes, fired, fsm, status, writes")
    rec["outcomes"] = [["arm/work", "nope"]]
    assert replay(lines[:2] + [json.dumps(rec)] + lines[3:], m) == (1, "arm/work: outcome 'nope' is not declared")
    rec["outcomes"] = []
    assert replay(lines[:2] + [json.dumps(rec)] + lines[3:], m) == (1, "arm/work ran but the trace records no more outcomes")
    other = Model("other", tree=Condition("c", "true"))
    assert replay(lines, other) == (0, "trace is of model 'cell', not 'other'")
    with pytest.raises(ValueError):
        read_trace(lines[1:])  # no header


def test_runtime_from_a_given_state():
    m = Model("start", variables=[Int("n", 0, 5)], tree=Action("inc", outcomes=[success(n="n + 1")]))
    rt = Runtime(m, state=(3,))
    rt.tick()
    assert rt.vars == {"n": 4} and rt.state == (4,)


# --------------------------------------------------------------------------- the memo of ticks


def _memo_run(model, seed, ticks, memo: bool):
    """Per tick (state, status, events, violations) or the error that ended the run, and
    every implementation call in order, with the runtime's memo on or off."""
    rng, events_rng, calls, out = random.Random(seed), random.Random(seed + 1), [], []

    class Impl:  # answers at random, mostly the first outcome (so that states repeat with new answers)
        def tick(self, call):
            calls.append(("tick", call.site.label, call.first, call.tick, call.goal))
            return 0 if rng.random() < 0.6 else rng.randrange(len(call.site.outcomes))

        def halt(self, call):
            calls.append(("halt", call.site.label, call.tick))

    rt = Runtime(model, {p: Impl() for p in model.all_primitives()}, record=True)
    if not memo:
        rt.MEMO_STATES = 0
    for _ in range(ticks):
        try:
            step = rt.tick(pick_events(rt.program, rt.state, events_rng))
        except ConformanceError as exc:
            out.append(str(exc))
            break
        out.append((step.state, step.status, step.events, step.violations))
    return out, calls, len(rt._memo)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(models(), st.integers(0, 2**16), st.integers(1, 30))
def test_memoized_ticks_are_the_step_function_s(model, seed, ticks):
    """The runtime memoizes ticks per state (``Runtime._step``): with the memo and without
    it, the implementations see the same calls in the same order and every tick has the
    same result (state, status, events, violations)."""
    with_memo, without = _memo_run(model, seed, ticks, True), _memo_run(model, seed, ticks, False)
    assert with_memo[:2] == without[:2] and without[2] == 0


def test_a_tick_from_a_state_seen_before_calls_the_implementations_and_reuses_the_result(monkeypatch):
    """The cell model ticks from the same state while the arm works: with the memo the
    step function runs only for new answers, the implementation on every tick as without it."""
    from btfsm.semantics import Program

    step = Program.step

    def run(memo):
        answers, log, runs = ["busy"] * 5 + ["ok"] + ["busy"] * 3 + ["ok"] + ["busy"] * 2, [], []
        monkeypatch.setattr(Program, "step", lambda self, *a: runs.append(1) or step(self, *a))
        rt = Runtime(_cell(), {"work": Recorder(answers, log, "work")})
        if not memo:
            rt.MEMO_STATES = 0
        statuses = [rt.tick().status for _ in range(12)]
        return statuses, log, rt.vars["count"], len(runs)

    with_memo, without = run(True), run(False)
    assert with_memo[:3] == without[:3] and with_memo[2] == 2 and len(with_memo[1]) == 11
    assert without[3] == 12 and with_memo[3] <= 7  # a "busy" tick from a state seen busy before: no step function
