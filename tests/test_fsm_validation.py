"""Goal-driven FSMs check themselves when a model is built: structural errors raise a
ModelError naming the element by id; doubts that leave the model usable (unreachable
states, edges and markers that can never fire) are warnings, also reported by id."""
from __future__ import annotations

import dataclasses

import pytest
from hypothesis import HealthCheck, given, settings
from memo_strategies import st

from btfsm import (FSM, Bool, Edge, Int, Marker, Model, ModelError, Primitive, SkillRequest, State, Status,
                   failure, running, success)
from btfsm.oracles import FirstOracle

from core_strategies import act, models

PROPS = settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])

WORK = State("work", outcomes=[running("busy"), success("ok"), failure("jam")])


def arm(**kw):
    """home (pass) -> work for goal go, success at work; override any field."""
    base = dict(states=[State("home"), WORK], initial="home", goals=["go"],
                edges=[Edge("home", "work", ["go"]), Edge("work", "home", ["go"], on="failure")],
                markers=[Marker("work", ["go"])])
    base.update(kw)
    return FSM("arm", **base)


def build(fsm, **kw):
    return Model("m", fsms=[fsm], **kw)


def error_of(fsm, **kw):
    with pytest.raises(ModelError) as err:
        build(fsm, **kw)
    return err.value.element, err.value.problem


def test_a_valid_fsm_has_no_warning():
    m = build(arm())
    assert m.warnings == ()
    assert [e.id for e in m.fsms[0].edges] == ["home->work", "work->home"]
    assert [x.id for x in m.fsms[0].markers] == ["work:success"]


# --------------------------------------------------------------------------- errors


@pytest.mark.parametrize("kw, element, problem", [
    (dict(edges=[Edge("home", "nowhere", ["go"])]), "fsms.arm.edges.home->nowhere.target", "unknown state 'nowhere'"),
    (dict(edges=[Edge("nowhere", "home", ["go"])]), "fsms.arm.edges.nowhere->home.source", "unknown state 'nowhere'"),
    (dict(markers=[Marker("gone", ["go"])]), "fsms.arm.markers.gone:success.state", "unknown state 'gone'"),
    (dict(initial="gone"), "fsms.arm.initial", "unknown state 'gone'"),
    (dict(terminal=["gone"]), "fsms.arm.terminal", "unknown state 'gone'"),
    (dict(states=[State("home"), WORK, State("home")]), "fsms.arm.states", "duplicate state 'home'"),
    (dict(states=[]), "fsms.arm", "has no states"),
    (dict(states=[State("")]), "fsms.arm.states[0]", "non-empty string"),
    (dict(states=[State("home"), State("work", primitive="pass", subtree=act("t"))]), "fsms.arm.states.work",
     "both a primitive and a subtree"),
    (dict(states=[State("home"), State("work", primitive="undeclared")]), "fsms.arm.states.work.primitive",
     "unknown primitive 'undeclared'"),
    (dict(edges=[Edge("home", "work", ["go"], id="e"), Edge("work", "home", ["go"], id="e")]), "fsms.arm.edges",
     "duplicate edge id 'e'"),
    (dict(markers=[Marker("work", ["go"], id="m"), Marker("home", ["go"], id="m")]), "fsms.arm.markers",
     "duplicate marker id 'm'"),
    (dict(edges=[Edge("home", "work", ["fly"])]), "fsms.arm.edges.home->work.goals", "unknown goal 'fly'"),
    (dict(edges=[Edge("home", "work", [])]), "fsms.arm.edges.home->work.goals", "serves no goal"),
    (dict(markers=[Marker("work", ["fly"])]), "fsms.arm.markers.work:success.goals", "unknown goal 'fly'"),
    (dict(goals=[]), "fsms.arm.goals", "at least one goal"),
    (dict(goals=["go", "go"]), "fsms.arm.goals", "duplicate goal 'go'"),
    (dict(goals=["go", "*"]), "fsms.arm.goals", "'*'"),
    (dict(markers=[Marker("work", ["go"], outcome="running")]), "fsms.arm.markers.work:success.outcome",
     "success or failure, not running"),
    (dict(markers=[Marker("work", ["go"], direct=True, outcome=Status.RUNNING)]), "fsms.arm.markers.work:direct.outcome",
     "not running"),
    (dict(retarget="sometimes"), "fsms.arm.retarget", "immediate, withdraw"),
    (dict(retarget="withdraw"), "fsms.arm.withdraw_goal", "'' is not a goal of arm"),
    (dict(retarget="withdraw", withdraw_goal="home"), "fsms.arm.withdraw_goal", "'home' is not a goal of arm"),
    (dict(params=["t"]), "fsms.arm.params[0]", "variable declaration"),
    (dict(params=[Int("t", 0, 2), Int("t", 0, 3)]), "fsms.arm.params", "duplicate parameter 't'"),
    (dict(params=[Int("t", 3, 1)]), "fsms.arm.params.t", "lo <= hi"),
])
def test_structural_errors(kw, element, problem):
    got_element, got_problem = error_of(arm(**kw))
    assert got_element == element and problem in got_problem, (got_element, got_problem)


@pytest.mark.parametrize("edges, goal, cycle", [
    ([Edge("home", "work", ["go"], direct=True), Edge("work", "home", ["go"], direct=True)], "go", "home -> work -> home"),
    ([Edge("work", "work", ["go"], direct=True)], "go", "work -> work"),
    ([Edge("a", "b", ["go", "back"], direct=True), Edge("b", "c", ["back"], direct=True),
      Edge("c", "a", ["back"], direct=True)], "back", "a -> b -> c -> a"),
])
def test_direct_edge_cycles(edges, goal, cycle):
    f = arm(states=[State("home"), WORK, State("a"), State("b"), State("c")], goals=["go", "back"], edges=edges)
    element, problem = error_of(f)
    assert element == "fsms.arm.edges"
    assert f"direct edges form a cycle for goal '{goal}': {cycle}" in problem


def test_cycles_that_are_allowed():
    """Direct edges of different goals, or a cycle closed by a non-direct edge, are fine:
    each goal's direct chain still ends."""
    f = arm(goals=["go", "back"], edges=[Edge("home", "work", ["go"], direct=True), Edge("work", "home", ["back"], direct=True),
                                        Edge("work", "home", ["go"])],
            markers=[Marker("work", ["go"]), Marker("home", ["back"], direct=True)])
    m = build(f)
    assert m.program.fsm_step(m.program.initial, "arm", "go", (), FirstOracle()).status == Status.RUNNING


def test_model_level_fsm_errors():
    with pytest.raises(ModelError) as err:
        Model("m", variables=[Bool("arm")], fsms=[arm()])
    assert (err.value.element, err.value.problem) == ("fsms.arm", "name 'arm' is used twice")
    with pytest.raises(ModelError) as err:
        Model("m", fsms=[arm(), arm()])
    assert err.value.element == "fsms.arm"
    with pytest.raises(ModelError) as err:
        Model("m", fsms=[FSM("my arm", states=[State("s")], goals=["g"])])
    assert err.value.element == "fsms.my arm" and "not an identifier" in err.value.problem
    with pytest.raises(ModelError) as err:
        Model("m", variables=[Int("t", 0, 1)], fsms=[arm(params=[Int("t", 0, 2)])])
    assert err.value.element == "fsms.arm.params.t" and "hides a variable" in err.value.problem


@pytest.mark.parametrize("request_, element, problem", [
    (SkillRequest("r", fsm="hand", goal="go"), "tree.r.fsm", "unknown FSM 'hand'"),
    (SkillRequest("r", fsm="arm", goal="fly"), "tree.r.goal", "'fly' is not a goal of arm"),
    (SkillRequest("r", fsm="arm", goal="go", params={"t": 1}), "tree.r.params", "takes parameters []"),
])
def test_bad_requests(request_, element, problem):
    with pytest.raises(ModelError) as err:
        Model("m", fsms=[arm()], tree=request_)
    assert err.value.element == element and problem in err.value.problem


def test_inline_primitives_of_two_fsms_do_not_mix():
    """Two states with the same id declaring different outcomes inline: either the model
    is refused, or each state keeps its own outcomes."""
    a = FSM("a", states=[State("work", outcomes=[success(x=True)])], goals=["g"], markers=[Marker("work", ["g"])])
    b = FSM("b", states=[State("work", outcomes=[failure()])], goals=["g"],
            markers=[Marker("work", ["g"], on="failure", outcome="failure")])
    try:
        m = Model("mix", variables=[Bool("x")], fsms=[a, b], tree=SkillRequest("r", fsm="a", goal="g"))
    except ModelError as err:
        assert err.element.startswith("fsms.")
        return
    step = m.program.step(m.program.initial, FirstOracle())
    assert step.status == Status.SUCCESS and m.program.decode(step.state)["x"] is True


@pytest.mark.parametrize("mutual", [False, True])
def test_a_subtree_requesting_its_own_fsm_is_refused_or_terminates(mutual):
    """A state's subtree that requests the FSM it belongs to (directly or through another
    FSM) must not make a tick recurse without end."""
    if mutual:
        f = FSM("f", states=[State("s", subtree=SkillRequest("to_g", fsm="g", goal="go"))], goals=["go"],
                markers=[Marker("s", ["go"])])
        g = FSM("g", states=[State("s2", subtree=SkillRequest("to_f", fsm="f", goal="go"))], goals=["go"],
                markers=[Marker("s2", ["go"])])
        fsms = [f, g]
    else:
        fsms = [FSM("f", states=[State("s", subtree=SkillRequest("inner", fsm="f", goal="go"))], goals=["go"],
                    markers=[Marker("s", ["go"])])]
    try:
        m = Model("loop", fsms=fsms, tree=SkillRequest("outer", fsm="f", goal="go"))
    except ModelError as err:
        assert err.element.startswith("fsms.")
        return
    m.program.step(m.program.initial, FirstOracle())  # must end (no RecursionError)


# --------------------------------------------------------------------------- warnings


def warnings_of(fsm, **kw):
    return dict(build(fsm, **kw).warnings)


def test_unreachable_states():
    w = warnings_of(arm(states=[State("home"), WORK, State("spare"), State("lost")],
                        edges=[Edge("home", "work", ["go"]), Edge("lost", "home", ["go"])]))
    assert w == {"fsms.arm.states.spare": "state 'spare' is unreachable from 'home'",
                 "fsms.arm.states.lost": "state 'lost' is unreachable from 'home'"}


def test_shadowed_by_an_unguarded_direct_edge():
    f = arm(goals=["go", "back"],
            edges=[Edge("home", "work", ["go"], direct=True, id="jump"),
                   Edge("home", "work", ["go", "back"], id="walk"),  # shadowed for go only
                   Edge("home", "work", ["go"], direct=True, id="late"),  # after the blocker
                   Edge("work", "home", ["back"], direct=True, guard="ready", id="guarded"),
                   Edge("work", "home", ["back"], id="after_guarded")],  # a guarded direct edge shadows nothing
            markers=[Marker("home", ["go"], id="never"), Marker("work", ["go"]), Marker("home", ["back"], direct=True)])
    w = warnings_of(f, variables=[Bool("ready")])
    assert w == {"fsms.arm.edges.walk": "never fires for goal 'go': shadowed by direct edge 'jump'",
                 "fsms.arm.edges.late": "never fires for goal 'go': shadowed by direct edge 'jump'",
                 "fsms.arm.markers.never": "never fires for goal 'go': shadowed by direct edge 'jump'"}


def test_elements_on_statuses_the_primitive_never_returns():
    f = arm(states=[State("home"), WORK, State("grip", primitive="grip"), State("sub", subtree=act("t"))],
            edges=[Edge("home", "work", ["go"]), Edge("home", "grip", ["go"], on="failure", id="home_fails"),
                   Edge("work", "grip", ["go"], on="failure"), Edge("work", "sub", ["go"], on="running"),
                   Edge("grip", "home", ["go"], on="running", id="grip_runs"), Edge("grip", "sub", ["go"]),
                   Edge("sub", "home", ["go"], on="failure")],  # a subtree may return anything
            markers=[Marker("work", ["go"]), Marker("home", ["go"], on="running", outcome="failure", id="home_runs"),
                     Marker("grip", ["go"], on="failure", outcome="failure")])
    w = warnings_of(f, primitives=[Primitive("grip", (success(), failure()))])
    assert w == {"fsms.arm.edges.home_fails": "never fires: state 'home' never returns FAILURE",
                 "fsms.arm.edges.grip_runs": "never fires: state 'grip' never returns RUNNING",
                 "fsms.arm.markers.home_runs": "never fires: state 'home' never returns RUNNING"}


def test_fsm_validate_directly():
    f = arm(states=[State("home"), State("work", primitive="work")])
    assert f.validate({"work": frozenset({Status.SUCCESS})}) == [
        ("fsms.arm.edges.work->home", "never fires: state 'work' never returns FAILURE")]
    assert f.validate() == []  # statuses unknown: no status warning
    assert f.validate({"work": frozenset(Status)}, element="skills.arm") == []


# --------------------------------------------------------------------------- properties


@PROPS
@given(models(environment=False))
def test_random_models_validate(model):
    """Random valid models build, and every warning names an edge, marker or state that exists."""
    known = set()
    for f in model.fsms:
        known |= {f"fsms.{f.name}.edges.{e.id}" for e in f.edges}
        known |= {f"fsms.{f.name}.markers.{m.id}" for m in f.markers}
        known |= {f"fsms.{f.name}.states.{s.id}" for s in f.states}
    assert {el for el, _ in model.warnings} <= known


@PROPS
@given(models(environment=False), st.data())
def test_injected_direct_cycles_are_refused(model, data):
    fsms = [f for f in model.fsms]
    if not fsms:
        return
    f = data.draw(st.sampled_from(fsms))
    ids = [s.id for s in f.states]
    a, b = data.draw(st.sampled_from(ids)), data.draw(st.sampled_from(ids))
    g = data.draw(st.sampled_from(f.goals))
    loop = [Edge(a, b, [g], direct=True, id="loop1")] + ([Edge(b, a, [g], direct=True, id="loop2")] if a != b else [])
    bad = dataclasses.replace(f, edges=tuple(f.edges) + tuple(loop))
    with pytest.raises(ModelError) as err:
        Model("m", variables=model.variables, fsms=[bad if x is f else x for x in fsms], tree=model.tree)
    assert err.value.element == f"fsms.{f.name}.edges" and f"for goal '{g}'" in err.value.problem
