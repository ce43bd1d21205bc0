"""``since(E)`` (docs/semantics.md 7): the ticks since environment event E last happened,
0 on the tick it happens, saturated at its minimum interval in ticks (rule 'Event
spacing''s counter, docs/semantics.md 6.1): table tests, errors, a property test against
a brute-force count over random runs, and the engines' equality on a model that reads it."""
from __future__ import annotations

import dataclasses

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from btfsm import FSM, Edge, EnvEvent, Int, Model, ModelError, Primitive, SkillRequest, State, running, success
from btfsm.expr import Name, compile_fn, parse, since, to_text
from btfsm.oracles import ScriptOracle
from btfsm.verify.explore import explore, explore_fsm

from test_verify_traced import assert_same


def since_model(wait_s: float = 0.3, gate: int = 2, rate: float = 10.0, **changes) -> Model:
    """An arm that moves from a to b only when ``go`` happened at least ``gate`` ticks ago."""
    f = FSM("arm", states=[State("a", "move"), State("b", "move")], initial="a", goals=("g",),
            edges=[Edge("a", "b", "g", guard=f"since(go) >= {gate}"), Edge("a", "a", "g", guard=f"since(go) < {gate}"),
                   Edge("b", "a", "g")])
    m = Model("s", variables=[Int("n", 0, 2)], primitives=[Primitive("move", (running(), success()))], fsms=[f],
              tree=SkillRequest("req", fsm="arm", goal="g"),
              environment=[EnvEvent("go", "n < 2", {"n": "n + 1"}, min_interval=wait_s),
                           EnvEvent("reset", "n == 2", {"n": "0"})], tick_rate=rate)
    return dataclasses.replace(m, **changes) if changes else m


def test_since_parses_to_a_name_and_back():
    assert parse("since(arrive) >= 90") == (since("arrive") >= 90).node
    assert parse("since(arrive)") == Name("since(arrive)")
    assert to_text(parse("since( arrive ) < 3 and n > 0")) == "since(arrive) < 3 and n > 0"


@pytest.mark.parametrize("text", ["since(1)", "since(a, b)", "since()", "since(a.b)", "since(x=a)"])
def test_since_takes_one_event_name(text):
    with pytest.raises(ModelError, match=r"since\(\) takes one environment event's name"):
        parse(text)


@pytest.mark.parametrize("wait_s,rate,wait", [(0.3, 10.0, 3), (0.25, 20.0, 5), (2.0, 1.0, 2)])
def test_since_counts_ticks_and_saturates_at_the_wait(wait_s, rate, wait):
    """Never happened: the wait. The tick it happens: 0. Then one more a tick, up to the wait."""
    m = since_model(wait_s, gate=min(2, wait), rate=rate)
    prog = m.program
    read = compile_fn(parse("since(go)"), prog.scope, "test")
    assert prog.scope["since(go)"].hi == wait and read(prog.initial) == wait
    s = prog.step(prog.initial, ScriptOracle([1])).state  # go happens (the first env question)
    assert read(s) == 0
    seen = []
    for _ in range(wait + 3):
        s = prog.step(s, ScriptOracle([0, 0])).state  # go (when asked) and reset do not happen
        seen.append(read(s))
    assert seen == list(range(1, wait + 1)) + [wait] * 3


@pytest.mark.parametrize("change,where,problem", [
    ({"environment": [EnvEvent("go", "n < 2", {"n": "n + 1"})]}, "fsms.arm.edges.a->b.guard",
     "since(go): no environment event 'go' with a min_interval of 2 ticks or more"),
    ({"environment": [EnvEvent("go", "n < 2", {"n": "n + 1"}, min_interval=0.1)]}, "fsms.arm.edges.a->b.guard",
     "since(go): no environment event 'go' with a min_interval of 2 ticks or more"),
    ({"environment": [EnvEvent("other", "n < 2", {"n": "n + 1"}, min_interval=1.0)]}, "fsms.arm.edges.a->b.guard",
     "no environment event 'go'"),
    ({"environment": [EnvEvent("go", "since(go) > 1", {"n": "n + 1"}, min_interval=1.0)]}, "environment.go",
     "since() cannot be read by an environment entry"),
    ({"environment": [EnvEvent("go", None, {"n": "since(go) % 2"}, min_interval=1.0)]}, "environment.go",
     "since() cannot be read by an environment entry"),
])
def test_since_errors_name_the_element(change, where, problem):
    with pytest.raises(ModelError) as exc:
        since_model(**change).program
    assert exc.value.element == where and problem in exc.value.problem


def test_since_cannot_be_assigned():
    m = since_model()
    f = dataclasses.replace(m.fsms[0], edges=m.fsms[0].edges + (Edge("b", "b", "g", effects={"since(go)": "0"}),))
    with pytest.raises(ModelError, match="'since\\(go\\)' cannot be assigned"):
        dataclasses.replace(m, fsms=(f,)).program


def test_since_is_refused_where_event_spacing_is_not_modelled():
    """The vectorised engine and the SMV/Promela exports (``step_spec``) keep no spacing counter."""
    from btfsm.verify import vector
    from btfsm.verify.stepspec import step_spec

    for run in (lambda m: vector.explore(m), lambda m: step_spec(m, "arm")):
        with pytest.raises(ModelError, match=r"since\(go\) is read: .* do not model rules 'Durations' and 'Event spacing'"):
            run(since_model())


def test_time_is_refused_where_it_is_not_modelled():
    """Any declared time (a duration, an event's spacing) is refused there too, not only
    since(): those routes would explore the model as if it had none (7 states where the
    step function has 25, measured on a timed model)."""
    from btfsm.verify import vector
    from btfsm.verify.stepspec import step_spec

    m = since_model()
    spaced = dataclasses.replace(m, fsms=(dataclasses.replace(m.fsms[0], edges=(Edge("a", "b", "g"), Edge("b", "a", "g"))),))
    timed = dataclasses.replace(spaced, environment=tuple(dataclasses.replace(e, min_interval=None) for e in m.environment),
                                primitives=[Primitive("move", (running(), success()), duration=(0.1, 0.3))])
    for m, counter in ((timed, "arm:ran"), (spaced, "go:since")):
        for run in (lambda m: vector.explore(m), lambda m: step_spec(m, "arm")):
            with pytest.raises(ModelError, match=f"the model declares time \\(the counter '{counter}'"):
                run(m)


@settings(max_examples=60, deadline=None, derandomize=True, database=None, suppress_health_check=[HealthCheck.too_slow])
@given(wait_s=st.sampled_from([0.2, 0.3, 0.5]), answers=st.lists(st.integers(0, 1), min_size=1, max_size=120))
def test_since_is_the_ticks_since_the_event_in_random_runs(wait_s, answers):
    """The brute-force oracle: count the ticks since the last ("env", "go") of each tick's
    trace; since(go) equals it, saturated at the wait, in every state of the run."""
    m = since_model(wait_s)
    prog = m.program
    wait = prog.scope["since(go)"].hi
    read = compile_fn(parse("since(go)"), prog.scope, "test")
    s, last, tick = prog.initial, None, 0
    feed = iter(answers * 4)
    while tick < 60:
        step = prog.step(s, ScriptOracle([next(feed, 0) for _ in range(8)]), record=True)
        tick += 1
        if step.state is None:
            break
        s = step.state
        if ("env", "go") in step.events:
            last = tick
        assert read(s) == (wait if last is None else min(tick - last, wait))


def test_engines_agree_on_a_model_that_reads_since():
    m = since_model()
    ts = explore(m, engine="scalar")
    assert_same(ts, explore(m, engine="traced"))
    assert_same(explore_fsm(m, "arm", engine="scalar"), explore_fsm(m, "arm", engine="traced"))
    # the guard holds on every a -> b step (the token enters b with since(go) >= 2), and
    # without it some step enters b sooner
    free = dataclasses.replace(m, fsms=(dataclasses.replace(m.fsms[0], edges=(Edge("a", "b", "g"), Edge("b", "a", "g"))),))

    def ages_entering_b(t):
        d = [t.decode(i) for i in range(t.n_states)]
        return {d[int(j)]["go:since"] for i in range(t.n_states)
                for j in t.successors(i) if d[i]["arm.state"] == "a" and d[int(j)]["arm.state"] == "b"}

    assert min(ages_entering_b(ts)) == 2 and min(ages_entering_b(explore(free, engine="scalar"))) < 2


def test_since_in_a_model_file():
    """The file syntax is the expression's: written and read back, the same program."""
    from btfsm.files import dumps_model, loads_model

    m = since_model()
    text = dumps_model(m)
    assert "since(go) >= 2" in text
    back = loads_model(text)
    assert back.program.scope["since(go)"] == m.program.scope["since(go)"]
    assert_same(explore(back, engine="scalar"), explore(m, engine="scalar"))


def test_the_tree_program_has_the_full_programs_layout():
    """``Program.without_environment`` (what the engines step after the environment) lays
    out the slots as the full program, when only a requirement reads since(E) too."""
    from btfsm.timing import Response

    m = since_model()
    plain = dataclasses.replace(m.fsms[0], edges=(Edge("a", "b", "g"), Edge("b", "a", "g")))
    m2 = dataclasses.replace(m, fsms=(plain,), responses=(Response("r", "event:go", "since(go) >= 2"),))
    for model in (m, m2):
        full, tree = model.program, model.program.without_environment()
        assert [s.name for s in tree.slots] == [s.name for s in full.slots] and not tree.env
    assert_same(explore(m2, engine="scalar"), explore(m2, engine="traced"))
