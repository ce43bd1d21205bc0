"""Time in the model (docs/semantics.md section 6.1): durations of primitive runs and the
spacing of environment events, written once in ``Program.step``.

Table tests pin the tick rule (which ticks of a run may end it) for each declaration;
brute force over answer scripts checks it on the step function itself; hypothesis checks
that the traced engine and the scalar reference give the same systems on random timed
models, that models without time compile to the same slots as before, and the file
format round trip.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import jsonschema
import pytest
from hypothesis import HealthCheck, given, settings

from btfsm import Action, Condition, EnvEvent, Int, Model, ModelError, Primitive, ReactiveSequence, running, success
from btfsm.cli import main
from btfsm.errors import ConformanceError
from btfsm.files import dumps_model, loads_model, model_to_data
from btfsm.models.registry import BUILTIN, SAME_FORM, load_builtin
from btfsm.oracles import ScriptOracle
from btfsm.runtime import Runtime
from btfsm.timing import duration_ticks, interval_ticks
from btfsm.verify.explore import explore, explore_fsm

from strategies import timed_models
from test_verify_traced import assert_same

SCHEMA = json.loads((Path(__file__).resolve().parents[1] / "btfsm" / "schema" / "model.schema.json").read_text(encoding="utf-8"))


def one_action(duration, rate=10.0, statuses=("running", "success")):
    outs = tuple(running() if s == "running" else success() for s in statuses)
    return Model("m", primitives=[Primitive("work", outs, duration=duration)], tree=Action("w", primitive="work"),
                 tick_rate=rate)


def ends_on(model, k) -> bool:
    """Can the run end (answer SUCCESS, outcome 1) on its k-th tick? (k-1 RUNNING answers first.)"""
    prog = model.program
    s = prog.initial
    for _ in range(k - 1):
        step = prog.step(s, ScriptOracle([0]))
        if step.state is None:
            return False
        s = step.state
    return prog.step(s, ScriptOracle([1])).state is not None


# (min, max) seconds, rate -> (lo, hi): the ticks of running on which the run may end
TICK_TABLE = [
    ((0.25, 1.0), 10.0, (4, 11)),
    ((0.3, 0.3), 10.0, (4, 4)),  # a whole number of ticks stays that number
    ((0.0, 0.0), 10.0, (1, 1)),
    ((0.05, 0.1), 10.0, (2, 2)),
    ((0.0, None), 10.0, (1, None)),
    ((0.5, None), 4.0, (3, None)),
    ((1.0, 2.0), 1.0, (2, 3)),
]


@pytest.mark.parametrize("duration,rate,want", TICK_TABLE)
def test_duration_ticks_table(duration, rate, want):
    assert duration_ticks(duration, rate) == want


@pytest.mark.parametrize("duration,rate,want", TICK_TABLE)
def test_the_step_function_ends_a_run_exactly_on_the_allowed_ticks(duration, rate, want):
    lo, hi = want
    m = one_action(duration, rate)
    for k in range(1, (hi or lo + 3) + 3):
        assert ends_on(m, k) == (lo <= k and (hi is None or k <= hi)), k


def test_a_run_must_end_by_its_maximum():
    m = one_action((0.0, 0.2))  # hi = 3
    prog = m.program
    s = prog.initial
    for _ in range(2):
        s = prog.step(s, ScriptOracle([0])).state
    step = prog.step(s, ScriptOracle([0]))  # a third RUNNING answer: past the maximum
    assert step.state is None and step.violations[0][0] == "timing"
    assert "must end by then (0.2 s)" in step.violations[0][2]


def test_a_halted_run_starts_afresh():
    # the condition holds until the environment flips it; the halted run's count restarts
    m = Model("h", variables=[Int("stop", 0, 1)],
              primitives=[Primitive("work", (running(), success()), duration=(0.3, None))],
              tree=ReactiveSequence("root", [Condition("go", "stop == 0"), Action("w", primitive="work")]),
              environment=[EnvEvent("flip", None, {"stop": "1 - stop"})])
    prog = m.program
    timer = next(i for i, sl in enumerate(prog.slots) if sl.kind == "timer")
    s = prog.initial
    for script in ([0, 0], [0, 0]):  # no flip, RUNNING; twice
        s = prog.step(s, ScriptOracle(script)).state
    assert s[timer] == 2
    s = prog.step(s, ScriptOracle([1])).state  # flip: stop = 1, the run is halted
    assert s[timer] == 0
    s = prog.step(s, ScriptOracle([1, 0])).state  # flip back: the run starts again
    assert s[timer] == 1
    assert prog.step(s, ScriptOracle([0, 1])).state is None  # SUCCESS on its 2nd tick: too soon (lo = 4)


def test_fsm_state_duration_overrides_the_primitive():
    m = load_builtin("two-area")
    f = m.fsms[0]
    st = next(s for s in f.states if s.primitive)
    prim = m.all_primitives()[st.primitive]
    if not any(o.status.name == "RUNNING" for o in prim.outcomes):
        pytest.skip("needs a state whose primitive can run")
    timed = dataclasses.replace(m, fsms=(dataclasses.replace(f, states=tuple(
        dataclasses.replace(s, duration=(0.5, 1.0)) if s.id == st.id else s for s in f.states)),) + tuple(m.fsms[1:]))
    site = next(x for x in timed.program.sites if x.state == st.id)
    assert site.ticks == (6, 11) and timed.program.slots[site.timer].size == 11


@pytest.mark.parametrize("gap,rate,wait", [(30.0, 10.0, 300), (0.25, 10.0, 3), (0.0, 10.0, 0), (1.0, 1.0, 1)])
def test_event_spacing(gap, rate, wait):
    assert interval_ticks(gap, rate) == wait
    m = Model("e", variables=[Int("n", 0, 50)], environment=[EnvEvent("tick", "n < 50", {"n": "n + 1"}, min_interval=gap)],
              tick_rate=rate)
    prog = m.program
    s = prog.step(prog.initial, ScriptOracle([1])).state  # it may happen on the first tick
    assert s[0] == 1
    for t in range(1, max(wait, 1) + 2):  # then it is asked again only from tick `wait` on
        o = ScriptOracle([1])
        s = prog.step(s, o).state
        if o.arities:  # enabled: it happened
            assert t >= wait
            break
    else:
        raise AssertionError("never enabled again")


def test_timer_slots_exist_exactly_where_time_is_declared():
    for name in sorted(set(BUILTIN) - SAME_FORM):  # SAME_FORM: another model's states, other numbers
        m = load_builtin(name)
        timed = any(e.min_interval for e in m.environment if hasattr(e, "min_interval")) or \
            any(s.duration for f in m.fsms for s in f.states) or any(p.duration for p in m.primitives)
        assert any(sl.kind == "timer" for sl in m.program.slots) == bool(timed), name
        assert timed == name.endswith("-timed"), name


def test_bad_durations_are_model_errors():
    with pytest.raises(ModelError, match="max .* is below min"):
        Primitive("p", (running(), success()), duration=(1.0, 0.5))
    with pytest.raises(ModelError, match="no RUNNING outcome"):
        one_action((0.5, 1.0), statuses=("success",)).program
    with pytest.raises(ModelError, match="only RUNNING outcomes"):
        one_action((0.0, 1.0), statuses=("running",)).program
    with pytest.raises(ModelError, match="min_interval"):
        EnvEvent("e", None, (), min_interval=-1)


def test_the_runtime_refuses_an_answer_outside_the_duration():
    m = one_action((0.5, 1.0))
    rt = Runtime(m, {"work": lambda call: "success"})  # ends at once: too soon
    with pytest.raises(ConformanceError, match="may end from tick 6 .0.5 s. on .the declared duration."):
        rt.tick()


def test_file_round_trip_and_schema():
    text = """
name: timed
variables: {q: {int: [0, 1]}}
primitives:
  work: {outcomes: [running, {success: {q: 0}}], duration: [0.2, 0.4]}
tree: {Action: w, primitive: work, duration: {min: 0.1, max: 0.5}}
environment:
  - {event: arrive, guard: q < 1, effects: {q: q + 1}, min_interval: 1.0}
responses:
  serve: {trigger: "event:arrive", response: q == 0, within: 0.5}
"""
    m = loads_model(text)
    assert m.primitives[0].duration == (0.2, 0.4) and m.tree.duration == (0.1, 0.5)
    assert m.environment[0].min_interval == 1.0 and m.responses[0].within == 0.5
    data = model_to_data(m)
    jsonschema.validate(data, SCHEMA)
    assert loads_model(dumps_model(m)) == m


@pytest.mark.parametrize("snippet,where", [
    ("primitives: {work: {outcomes: [running, success], duration: [1, 0.5]}}\ntree: {Action: w, primitive: work}",
     "primitives.work.duration: max (0.5 s) is below min (1 s)"),
    ("tree: {Action: w, outcomes: [running, success], duration: [a, 1]}", "tree.duration: min must be"),
    ("environment: [{event: e, min_interval: -2}]", "environment[0].min_interval: expected a finite number"),
    ("responses: {r: {trigger: 'event:e', response: 'x ==', within: 1}}", "responses.r.response"),
    ("responses: {r: {trigger: 'event:e'}}", "responses.r"),
    ("variables: {q: bool}\nresponses: {r: {trigger: 'event:e', response: zz}}", "responses.r.trigger: no environment event"),
    ("variables: {q: bool}\nresponses: {r: {trigger: q, response: zz}}", "responses.r.response: unknown name 'zz'"),
])
def test_bad_time_declarations_exit_2(tmp_path, capsys, snippet, where):
    p = tmp_path / "bad.yaml"
    p.write_text("name: bad\n" + snippet + "\n", encoding="utf-8")
    assert main(["validate", str(p)]) == 2
    err = capsys.readouterr().err
    assert where in err and "Traceback" not in err


@settings(max_examples=120, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(timed_models())
def test_random_timed_models_explore_identically(model):
    try:
        model.program
    except ModelError:
        return  # e.g. a state's inline outcomes that cannot honour the drawn duration
    assert_same(explore(model, engine="scalar", max_states=2000), explore(model, engine="traced", max_states=2000))
    for f in model.fsms:
        assert_same(explore_fsm(model, f.name, engine="scalar", max_states=800),
                    explore_fsm(model, f.name, engine="traced", max_states=800))
