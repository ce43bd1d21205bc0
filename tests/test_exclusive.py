"""Exclusive resources (docs/semantics.md section 4) and the ``exclusive-actions`` property.

Table tests pin the rule down tick by tick (which violation, where in the tick's event
order); the CLI tests run ``btfsm check ... --counterexample-dir`` and ``btfsm replay`` end
to end on the BehaviorTree.CPP #1031 example; hypothesis compares the property with an
independent brute-force search (tests/oracle_bruteforce.py's enumeration of answers) on
random models under every profile, and checks what halt-before-start guarantees under
``btfsm``.
"""
from __future__ import annotations

import dataclasses
import glob
import json
from collections import deque
from pathlib import Path

import jsonschema
import pytest
from hypothesis import HealthCheck, given, settings
from memo_strategies import st

from btfsm import (FSM, Action, Bool, Condition, EnvEvent, Guard, Model, ModelError, Parallel,
                   ReactiveFallback, ReactiveSequence, SkillRequest, State, Edge, Marker, running, success)
from btfsm.bt import walk
from btfsm.cli import main
from btfsm.files import dumps_model, loads_model, model_to_data
from btfsm.models.registry import load_builtin
from btfsm.oracles import Oracle
from btfsm.profiles import SEMANTICS
from btfsm.verify import check, replay_counterexample

from core_strategies import models
from oracle_bruteforce import all_answers

SCHEMA = json.loads((Path(__file__).resolve().parents[1] / "btfsm" / "schema" / "model.schema.json").read_text(encoding="utf-8"))


class _Answers(Oracle):
    """Oracle: environment events from tick ``t_env`` on, first outcome of every primitive
    (all of them 'running' here), halts noted in ``log``."""

    def __init__(self, t_env):
        self.t, self.t_env, self.log = 0, t_env, []

    def env(self, i):
        return self.t >= self.t_env

    def choose(self, i, enabled):
        return 0

    def outcome(self, site):
        self.log.append(("run", site.label))
        return 0

    def halt(self, site):
        self.log.append(("halt", site.label))


def _fallback_1031(semantics="btfsm", **kw):
    """ReactiveFallback[Guard(part)[pick], place]: both async, both on the arm."""
    return Model("m1031", variables=[Bool("part", False)],
                 tree=ReactiveFallback("root", [Guard("g", Action("pick", outcomes=[running(), success(part=False)]), "part"),
                                                Action("place", outcomes=[running()])]),
                 environment=[EnvEvent("arrive", "not part", {"part": True})],
                 resources=kw.pop("resources", {"arm": ["pick", "place"]}), semantics=semantics, **kw)


def _ticks(model, n, t_env=1):
    p, s, o, out = model.program, model.program.initial, _Answers(t_env), []
    for t in range(n):
        o.t, o.log = t, []
        step = p.step(s, o, record=True)
        out.append((step, o.log))
        s = step.state
    return out


# ---------------------------------------------------------------------- the rule, table tests
def test_btfsm_halts_before_the_new_action_starts():
    ticks = _ticks(_fallback_1031("btfsm"), 3)
    assert [step.violations for step, _ in ticks] == [[], [], []]
    assert ticks[1][1] == [("halt", "place"), ("run", "pick")]


@pytest.mark.parametrize("semantics", ["btcpp", "pytrees"])
def test_btcpp_starts_before_it_halts_the_old_action(semantics):
    """BehaviorTree.CPP #1031: tick 2 starts pick while place runs, then halts place."""
    ticks = _ticks(_fallback_1031(semantics), 3)
    step, log = ticks[1]
    assert log == [("run", "pick"), ("halt", "place")]
    assert step.violations == [("exclusive", "arm", "pick", "place", "start")]
    ev = [e for e in step.events if e[0] in ("violation", "outcome", "halt")]
    assert ev[0] == ("violation", "pick", "exclusive arm: starts while place runs")  # before pick's onStart
    assert ticks[0][0].violations == [] and ticks[2][0].violations == []  # only one runs at the end of a tick


def test_no_resources_no_violation_and_same_states():
    with_res, without = _fallback_1031("btcpp"), _fallback_1031("btcpp", resources=())
    a, b = _ticks(with_res, 4), _ticks(without, 4)
    assert [s.state for s, _ in a] == [s.state for s, _ in b]
    assert all(not s.violations for s, _ in b)


def test_parallel_two_async_on_one_resource_violate_under_every_profile():
    for sem in SEMANTICS:
        m = Model("par", tree=Parallel("root", [Action("a", outcomes=[running()]), Action("b", outcomes=[running()])]),
                  resources={"arm": ["a", "b"]}, semantics=sem)
        (t1, _), (t2, _) = _ticks(m, 2)
        assert t1.violations == [("exclusive", "arm", "b", "a", "start"), ("exclusive", "arm", "a", "b", "end")], sem
        assert t2.violations == [("exclusive", "arm", "a", "b", "end")], sem  # both keep running


def test_instant_action_starts_on_every_tick():
    """An action that cannot return RUNNING halts nothing: ticked while an async action of its
    resource runs, it is a violation under btfsm too."""
    m = Model("inst", variables=[Bool("go", False)],
              tree=ReactiveFallback("root", [ReactiveSequence("s", [Condition("c", "go"), Action("tap", outcomes=[success()])]),
                                             Action("move", outcomes=[running()])]),
              environment=[EnvEvent("on", "not go", {"go": True})], resources={"arm": ["tap", "move"]})
    ticks = _ticks(m, 2)
    assert ticks[0][0].violations == []
    assert ticks[1][0].violations == [("exclusive", "arm", "tap", "move", "start")]


def test_skill_request_whose_pre_is_false_does_not_start():
    """Under btcpp (no halt before start) a request whose pre is false does not start, so
    nothing is reported; once pre holds it starts while the other request runs."""
    fsm = FSM("arm", states=[State("idle", outcomes=[running()])], initial="idle", goals=["pick", "place"],
              edges=[Edge("idle", "idle", ["pick", "place"], "running")])
    fsm2 = dataclasses.replace(fsm, name="arm2")
    m = Model("pre", variables=[Bool("ok", False)], fsms=[fsm, fsm2],
              tree=ReactiveFallback("root", [SkillRequest("first", "arm", "pick", pre="ok"),
                                             SkillRequest("second", "arm2", "place")]),
              environment=[EnvEvent("ok_on", "not ok", {"ok": True})], resources={"arm": ["first", "second"]},
              semantics="btcpp")
    ticks = _ticks(m, 3, t_env=2)
    assert [s.violations for s, _ in ticks] == [[], [], [("exclusive", "arm", "first", "second", "start")]]


def test_leaves_in_an_fsm_subtree_count():
    """A resource may list leaves of FSM state subtrees; the end-of-tick check sees them."""
    fsm = FSM("arm", states=[State("work", subtree=Action("grip", outcomes=[running()]))], initial="work", goals=["go"],
              markers=[Marker("work", ["go"], "success", "success")])
    m = Model("sub", fsms=[fsm], tree=Parallel("root", [SkillRequest("req", "arm", "go"), Action("move", outcomes=[running()])]),
              resources={"gripper": ["grip", "move"]})
    (t1, _), = _ticks(m, 1)
    assert ("exclusive", "gripper", "grip", "move", "end") in t1.violations


# ---------------------------------------------------------------------- declaration
@pytest.mark.parametrize("resources, element, problem", [
    ({"arm": ["pick", "nope"]}, "resources.arm[1]", "unknown node 'nope'"),
    ({"arm": ["pick", "root"]}, "resources.arm[1]", "'root' is a ReactiveFallback"),
    ({"arm": ["pick", "pick"]}, "resources.arm[1]", "listed twice"),
    ({"arm": []}, "resources.arm", "lists no node"),
    ({"arm": ["pick", 3]}, "resources.arm[1]", "expected a node name"),
    ({"": ["pick"]}, "resources", "resource name"),
    ((("arm", ("pick",)), ("arm", ("place",))), "resources.arm", "declared twice"),
    (5, "resources", "expected a mapping"),
])
def test_bad_declarations_are_model_errors(resources, element, problem):
    with pytest.raises(ModelError) as exc:
        _fallback_1031(resources=resources)
    assert exc.value.element == element and problem in exc.value.problem


def test_a_resource_of_one_leaf_is_a_warning():
    m = _fallback_1031(resources={"arm": "pick"})
    assert m.resources == (("arm", ("pick",)),)
    assert ("resources.arm", "only 'pick' uses it: nothing can run beside it") in m.warnings


def test_file_round_trip_and_schema():
    m = _fallback_1031("btcpp")
    data = model_to_data(m)
    assert data["resources"] == {"arm": ["pick", "place"]}
    jsonschema.validate(data, SCHEMA)
    assert loads_model(dumps_model(m)) == m
    assert "resources" not in model_to_data(_fallback_1031(resources=()))


def test_file_errors_name_the_file_path_and_line():
    text = dumps_model(_fallback_1031()).replace("arm: [pick, place]", "arm: [pick, nowhere]")
    with pytest.raises(ModelError) as exc:
        loads_model(text, file_name="m.yaml")
    assert exc.value.element.startswith("resources.arm") and "unknown node 'nowhere'" in exc.value.problem
    assert "line" in exc.value.problem
    with pytest.raises(ModelError) as exc:
        loads_model(dumps_model(_fallback_1031()).replace("arm: [pick, place]", "arm: {a: 1}"), file_name="m.yaml")
    assert exc.value.element == "resources.arm"


# ---------------------------------------------------------------------- the property
def _prop(model):
    return check(model, ["exclusive-actions"]).results[0]


def test_no_resources_is_not_applicable():
    r = _prop(_fallback_1031("btcpp", resources=()))
    assert r.holds is True and r.verdict == "not-applicable" and r.not_applicable == "no 'resources:' declared"


def test_shortest_counterexample_replays():
    r = _prop(_fallback_1031("btcpp"))
    assert r.holds is False
    ce = r.counterexample
    assert len(ce.steps) == 2 and ce.violation["kind"] == "exclusive" and ce.violation["when"] == "start"
    ok, text = replay_counterexample(ce.to_json(), _fallback_1031("btcpp"))
    assert ok, text
    ok, text = replay_counterexample(ce.to_json(), _fallback_1031("btfsm"))  # halt before start removes it
    assert not ok
    assert _prop(_fallback_1031("btfsm")).holds is True


@pytest.mark.parametrize("name", ["ariac-preemptive", "ariac-baseline"])
def test_paper_models_hold_under_btfsm(name):
    m = load_builtin(name)
    assert m.resources == (("arm", ("pick_part", "place_on_location", "pick_part_from_queue",
                                    "place_on_intermediate_location")),)
    assert _prop(m).holds is True


def test_ariac_preemptive_violates_it_under_btcpp():
    m = dataclasses.replace(load_builtin("ariac-preemptive"), semantics="btcpp")
    r = _prop(m)
    assert r.holds is False and len(r.counterexample.steps) == 2
    assert (r.counterexample.violation["node"], r.counterexample.violation["other"]) == ("pick_part_from_queue", "pick_part")
    assert _prop(dataclasses.replace(load_builtin("ariac-baseline"), semantics="btcpp")).holds is True


def test_cli_end_to_end(tmp_path, capsys):
    """The issue's 'done when': exit 1 with a counterexample under btcpp that ``btfsm replay``
    reproduces (exit 0), exit 0 under btfsm."""
    ce_dir = tmp_path / "ce"
    assert main(["check", "bt-cpp-1031", "--property", "exclusive-actions", "--counterexample-dir", str(ce_dir)]) == 1
    out = capsys.readouterr().out
    assert "exclusive-actions  VIOLATED" in out and "under btcpp semantics" in out
    (path,) = glob.glob(str(ce_dir / "*.json"))
    assert main(["replay", path, "bt-cpp-1031"]) == 0
    assert "confirmed: tick 2: 'pick_from_conveyor' started while 'place_on_agv' was running" in capsys.readouterr().out
    assert main(["replay", path, "bt-cpp-1031", "--semantics", "btfsm"]) == 1
    capsys.readouterr()
    assert main(["check", "bt-cpp-1031", "--semantics", "btfsm", "--property", "exclusive-actions"]) == 0
    assert "exclusive-actions  holds" in capsys.readouterr().out


def test_cli_run_stops_at_the_violation(capsys):
    assert main(["run", "bt-cpp-1031", "--ticks", "50", "--seed", "1"]) == 1
    assert "exclusive resource 'arm': 'pick_from_conveyor' started while 'place_on_agv' was running" in capsys.readouterr().err
    assert main(["run", "bt-cpp-1031", "--ticks", "50", "--seed", "1", "--semantics", "btfsm"]) == 0


# ---------------------------------------------------------------------- random models
def _async_leaves(model):
    """Leaves of the main tree that can return RUNNING and have no Parallel ancestor."""
    prog, out = model.program, []

    def visit(n, under_parallel):
        if isinstance(n, (Action, SkillRequest)) and not under_parallel and prog.nodes[n.name].flag is not None:
            out.append(n.name)
        for c in n.children_of():
            visit(c, under_parallel or isinstance(n, Parallel))
    visit(model.tree, False)
    return out


def _first_violation_depth(model, limit=3000):
    """Brute force: BFS over every answer script of every tick; the number of ticks of the
    shortest run whose last tick reports an ``exclusive`` violation (None: none; raises
    OverflowError past ``limit`` states)."""
    prog = model.program
    depth, todo = {prog.initial: 0}, deque([prog.initial])
    while todo:
        s = todo.popleft()
        for res, _ in all_answers(lambda o, s=s: prog.step(s, o)):
            if isinstance(res, tuple) or res.state is None:
                continue
            if any(v[0] == "exclusive" for v in res.violations):
                return depth[s] + 1  # BFS: the first found is at least as shallow as any later one
            if res.state not in depth:
                depth[res.state] = depth[s] + 1
                todo.append(res.state)
                if len(depth) > limit:
                    raise OverflowError
    return None


RANDOM = settings(max_examples=150, deadline=None, derandomize=True, database=None,
                  suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large])


@RANDOM
@given(models(depth=2), st.sampled_from(SEMANTICS), st.data())
def test_property_agrees_with_brute_force(model, semantics, data):
    """The checker's verdict and shortest counterexample length equal a brute-force BFS's,
    for random resources over the model's Action/SkillRequest leaves, under every profile."""
    leaves = [n.name for _, root in model.roots() for n in walk(root) if isinstance(n, (Action, SkillRequest))]
    if len(leaves) < 2:
        return
    group = data.draw(st.lists(st.sampled_from(leaves), min_size=2, max_size=4, unique=True))
    m = dataclasses.replace(model, semantics=semantics, resources={"r": group})
    try:
        want = _first_violation_depth(m)
    except OverflowError:
        return
    r = _prop(m)
    assert r.holds is (want is None)
    if want is not None:
        assert len(r.counterexample.steps) == want
        ok, text = replay_counterexample(r.counterexample.to_json(), m)
        assert ok, text


@settings(RANDOM, max_examples=200)
@given(models(depth=3))
def test_halt_before_start_keeps_async_leaves_exclusive(model):
    """Under btfsm, the leaves of the main tree that can return RUNNING and have no Parallel
    ancestor, all on one resource, never run at once (halt before start)."""
    group = _async_leaves(model)
    if len(group) < 2:
        return
    m = dataclasses.replace(model, semantics="btfsm", resources={"all": group})
    r = _prop(m)
    assert r.holds is not False, r.counterexample.format_text() if r.counterexample else r.notes


# ---------------------------------------------------------------------- the real engine
def test_real_btcpp_starts_before_it_halts_on_the_example():
    """models/examples/bt_cpp_1031.yaml in real BehaviorTree.CPP 4 (behaviortreepy): the tick
    that sees the part calls pick_from_conveyor's onStart before place_on_agv's onHalted,
    exactly as the btcpp profile's counterexample says; btfsm's order is the reverse."""
    bt = pytest.importorskip("behaviortreepy")
    from btfsm.runtime import Runtime

    xml = """<root BTCPP_format="4" main_tree_to_execute="Main"><BehaviorTree ID="Main">
      <ReactiveFallback name="root">
        <ReactiveSequence name="conveyor_first">
          <PartOnBelt name="part_on_belt"/><PickFromConveyor name="pick_from_conveyor"/>
        </ReactiveSequence>
        <PlaceOnAgv name="place_on_agv"/>
      </ReactiveFallback></BehaviorTree></root>"""
    tick, log = [0], []
    f = bt.BehaviorTreeFactory()
    f.register_simple_condition("PartOnBelt", lambda node: bt.NodeStatus.SUCCESS if tick[0] >= 2 else bt.NodeStatus.FAILURE)
    for tag, name in (("PickFromConveyor", "pick_from_conveyor"), ("PlaceOnAgv", "place_on_agv")):
        f.register_simple_stateful_action(
            tag, lambda node, n=name: (log.append((tick[0], n, "start")), bt.NodeStatus.RUNNING)[1],
            lambda node, n=name: (log.append((tick[0], n, "running")), bt.NodeStatus.RUNNING)[1],
            lambda node, n=name: log.append((tick[0], n, "halt")))
    tree = f.create_tree_from_text(xml)
    for k in (1, 2, 3):
        tick[0] = k
        tree.tick_exactly_once()

    def ours(semantics):
        out = []

        class Leaf:
            def __init__(self, name):
                self.name = name

            def tick(self, call):
                out.append((call.tick + 1, self.name, "start" if call.first else "running"))
                return "running"

            def halt(self, call):
                out.append((call.tick + 1, self.name, "halt"))
        m = load_builtin("bt-cpp-1031")
        rt = Runtime(dataclasses.replace(m, semantics=semantics), {n: Leaf(n) for n in ("pick_from_conveyor", "place_on_agv")})
        viol = [rt.tick(["part_arrives"] if k == 2 else []).violations for k in (1, 2, 3)]
        return out, viol
    cpp_log, viol = ours("btcpp")
    assert cpp_log == log
    assert log[1:3] == [(2, "pick_from_conveyor", "start"), (2, "place_on_agv", "halt")]
    assert viol == [[], [("exclusive", "arm", "pick_from_conveyor", "place_on_agv", "start")], []]
    btfsm_log, viol = ours("btfsm")
    assert btfsm_log[1:3] == [(2, "place_on_agv", "halt"), (2, "pick_from_conveyor", "start")]
    assert viol == [[], [], []]
