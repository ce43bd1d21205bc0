"""Each property on a small hand-made model: violated (with the expected shortest
counterexample, which replays) and repaired (holds)."""
from __future__ import annotations

import json

import pytest

from btfsm import (FSM, Action, Bool, Condition, Edge, EnvChoice, EnvEvent, Int, Marker, Model,
                   ReactiveFallback, ReactiveSequence, SkillRequest, State, failure, running, success)
from btfsm.verify import check, replay_counterexample
from btfsm.verify.counterexample import Counterexample


def _one(model, name, **kw):
    r = check(model, [name], **kw)
    return r.result(name)


def _replays(res, model):
    ok, text = replay_counterexample(res.counterexample.to_json(), model)
    assert ok, text
    # and through a JSON file round trip
    again = Counterexample.from_json(json.loads(json.dumps(res.counterexample.to_json())))
    assert again.to_json() == res.counterexample.to_json()
    return text


# ---------------------------------------------------------------------- workable-reachability


def _worker(repair: bool):
    """``go`` moves home -> work -> home; a failed work sends the token to ``broken``,
    which only a repair edge leaves."""
    edges = [Edge("home", "work", ["go"]), Edge("work", "home", ["go"]), Edge("work", "broken", ["go"], on="failure")]
    if repair:
        edges.append(Edge("broken", "home", ["go"]))
    f = FSM("arm", [State("home"), State("work", outcomes=[success(), failure()]), State("broken")], "home", ["go"],
            edges, [Marker("work", ["go"])])
    return Model("worker", fsms=[f], tree=SkillRequest("do", fsm="arm", goal="go"))


def test_workable_trap_has_shortest_path_and_trap_region():
    m = _worker(False)
    res = _one(m, "workable-reachability")
    assert res.holds is False
    ce = res.counterexample
    assert [s["fsm"]["arm"][0] for s in ce.steps] == ["work", "broken"]  # shortest: 2 ticks
    assert ce.steps[1]["outcomes"] == [["arm/work", "failure"]]
    assert ["arm", "work->broken"] in ce.steps[1]["fired"]
    assert ce.violation["kind"] == "trap" and ce.violation["trap_region"] == 2  # held, then refused
    assert ce.violation["bottom_sccs"][0][0]["arm.state"] == "broken"
    assert "bottom SCC" in ce.format_text()
    assert "confirmed" in _replays(res, m)


def test_workable_holds_after_repair():
    assert _one(_worker(True), "workable-reachability").holds is True


def test_workable_custom_predicate():
    m = Model("n", [Int("n", 0, 3)], tree=Action("inc", outcomes=[success(n="min(n + 1, 3)")]), workable="n <= 1")
    res = _one(m, "workable-reachability")
    assert res.holds is False and len(res.counterexample.steps) == 2


# ---------------------------------------------------------------------- no-dead-states


def _counter_choice(terminal=None):
    return Model("choice", [Int("n", 0, 2)],
                 environment=[EnvChoice("c", [EnvEvent("inc", "n < 2", {"n": "n + 1"})])], terminal=terminal)


def test_dead_state_found_with_reason():
    m = _counter_choice()
    res = _one(m, "no-dead-states")
    assert res.holds is False
    ce = res.counterexample
    assert len(ce.steps) == 2 and ce.steps[-1]["state"]["n"] == 2
    assert "environment choice 'c' has no enabled option" in ce.violation["text"]
    assert "confirmed" in _replays(res, m)


def test_terminal_states_are_not_dead():
    assert _one(_counter_choice("n == 2"), "no-dead-states").holds is True


def test_fsm_terminal_states_are_not_dead():
    f = FSM("f", [State("a"), State("b")], "a", ["g"], [Edge("a", "b", ["g"])], terminal=["b"])
    tree = ReactiveSequence("root", [Condition("ok", "not stop"), SkillRequest("r", fsm="f", goal="g")])
    env = [EnvChoice("c", [EnvEvent("halt", "f.state == 'a'", {"stop": False})])]
    assert _one(Model("t", [Bool("stop")], fsms=[f], tree=tree, environment=env), "no-dead-states").holds is True


def _retry(with_failure_edge: bool):
    edges = [Edge("idle", "try", ["go"]), Edge("try", "idle", ["go"])]
    if with_failure_edge:
        edges.append(Edge("try", "idle", ["go"], on="failure"))
    markers = [Marker("try", ["go"])]
    if with_failure_edge:
        markers.append(Marker("try", ["go"], on="failure", outcome="failure"))
    f = FSM("arm", [State("idle"), State("try", outcomes=[success(), failure()])], "idle", ["go"], edges, markers)
    return Model("retry", fsms=[f], tree=SkillRequest("do", fsm="arm", goal="go"))


def test_failing_primitive_retried_forever_is_a_non_progress_lasso():
    m = _retry(False)
    res = _one(m, "no-dead-states")
    assert res.holds is False
    ce = res.counterexample
    assert ce.level == "fsm" and ce.loop == 1
    assert ce.steps[0]["request"]["goal"] == "go" and ce.steps[0]["fsm"]["arm"][0] == "try"
    assert ce.steps[1]["outcomes"] == [["arm/try", "failure"]] and ce.steps[1]["status"] == "RUNNING"
    assert "cycle starts here" in ce.format_text()
    assert "confirmed" in _replays(res, m)


def test_running_primitive_is_progress():
    f = FSM("arm", [State("idle"), State("busy", outcomes=[running(), success()])], "idle", ["go"],
            [Edge("idle", "busy", ["go"]), Edge("busy", "idle", ["go"])], [Marker("busy", ["go"])])
    m = Model("poll", fsms=[f], tree=SkillRequest("do", fsm="arm", goal="go"))
    assert _one(m, "no-dead-states").holds is True
    assert _one(_retry(True), "no-dead-states").holds is True


# ---------------------------------------------------------------------- invariants, contracts, domain


def _counter(expr="min(n + 1, 3)", **kw):
    return Model("cnt", [Int("n", 0, 3)], tree=Action("inc", outcomes=[success(n=expr)]), **kw)


def test_invariant_violation_is_shortest():
    m = _counter(invariants={"small": "n < 3"})
    res = _one(m, "invariants")
    assert res.holds is False and len(res.counterexample.steps) == 3
    assert res.counterexample.steps[-1]["changes"] == {"n": 3}
    assert "confirmed" in _replays(res, m)
    assert _one(_counter(invariants={"range": "n <= 3"}), "invariants").holds is True


def test_no_invariant_is_not_applicable():
    res = _one(_counter(), "invariants")
    assert res.holds is True and res.verdict == "not-applicable" and res.not_applicable == "no invariant declared"


@pytest.mark.parametrize("name,bare,declared", [
    # (property, why on a counter without FSM or declarations, a model where it applies)
    ("workable-reachability", "no skill FSM and no 'workable' expression", lambda: _counter(workable="n == 0")),
    ("goal-reachability", "no skill FSM", lambda: _worker(True)),
    ("determinism", "no skill FSM", lambda: _worker(True)),
    ("contracts", "no skill FSM and no tickOnce wake-up", lambda: _worker(True)),
    ("request-latency", "no skill FSM", lambda: _targeted("immediate")),
    ("invariants", "no invariant declared", lambda: _counter(invariants={"r": "n <= 3"})),
    ("exclusive-actions", "no 'resources:' declared",
     lambda: Model("r", [Int("n", 0, 3)], tree=Action("inc", outcomes=[success()]), resources={"arm": ["inc"]})),
    ("response", "no 'responses:' declared",
     lambda: _counter(responses={"top": {"trigger": "n == 0", "response": "n == 3", "within": 10}})),
    ("no-dead-states", None, lambda: _counter()),
    ("lints", None, lambda: _counter()),
])
def test_not_applicable_table(name, bare, declared):
    """Each property's rule for "not applicable" (docs/verification.md section 2): on a bare
    counter it reports the reason and holds (never fails); where the model declares what it
    needs, it is decided as usual."""
    res = _one(_counter(), name)
    assert res.not_applicable == bare and res.holds is True
    assert res.verdict == ("holds" if bare is None else "not-applicable")
    assert _one(declared(), name).not_applicable is None


def test_domain_is_not_applicable_without_int_or_fsm():
    m = Model("b", [Bool("b")], tree=Action("flip", outcomes=[success(b="not b")]))
    assert _one(m, "domain").not_applicable == "no int variable and no skill FSM"
    assert _one(_counter(), "domain").verdict == "holds"


def test_contract_violation():
    f = FSM("f", [State("s0")], "s0", ["g"], [], [Marker("s0", ["g"])])
    m = Model("post", [Bool("b")], fsms=[f], tree=SkillRequest("r", fsm="f", goal="g", post="b"))
    res = _one(m, "contracts")
    assert res.holds is False
    assert res.counterexample.steps[-1]["violations"] == [["post", "r"]]
    assert "confirmed" in _replays(res, m)
    ok = Model("post", [Bool("b", True)], fsms=[f], tree=SkillRequest("r", fsm="f", goal="g", post="b"))
    assert _one(ok, "contracts").holds is True


def test_domain_error_path_ends_with_the_failing_tick():
    m = _counter("n + 1")
    res = _one(m, "domain")
    assert res.holds is False
    ce = res.counterexample
    assert len(ce.steps) == 4 and "outside its domain" in ce.steps[-1]["error"]
    assert ce.violation["var"] == "n" and ce.violation["value"] == 4
    assert "confirmed" in _replays(res, m)
    assert _one(_counter(), "domain").holds is True


def test_domain_error_at_fsm_level_without_tree():
    f = FSM("f", [State("a", outcomes=[success(n="n + 1")])], "a", ["g"], [], [Marker("a", ["g"])])
    m = Model("fsmonly", [Int("n", 0, 1)], fsms=[f])
    res = _one(m, "domain")
    assert res.holds is False and res.counterexample.level == "fsm"
    assert "confirmed" in _replays(res, m)


# ---------------------------------------------------------------------- goal-reachability


def _pickplace(fixed: bool):
    edges = [Edge("home", "reach", ["pick"]), Edge("reach", "grip", ["pick"]), Edge("grip", "home", ["pick"]),
             Edge("reach", "home", ["place"], direct=True), Edge("home", "drop", ["place"]), Edge("drop", "home", ["place"]),
             Edge("grip", "home", ["place"], direct=True)]
    if fixed:
        edges.append(Edge("drop", "home", ["pick"], direct=True))
    arm = FSM("arm", [State("home"), State("reach", outcomes=[running(), success()]),
                      State("grip", outcomes=[success(holding=True)]), State("drop", outcomes=[success(holding=False)])],
              "home", ["pick", "place"], edges, [Marker("grip", ["pick"]), Marker("drop", ["place"])])
    tree = ReactiveFallback("root", [
        ReactiveSequence("do_place", [Condition("has", "holding"), SkillRequest("place", fsm="arm", goal="place")]),
        ReactiveSequence("do_pick", [Condition("p", "part"), SkillRequest("pick", fsm="arm", goal="pick", post="holding")])])
    return Model("pp", [Bool("holding"), Bool("part")], fsms=[arm], tree=tree,
                 environment=[EnvEvent("arrive", "not part", {"part": True})])


def test_goal_not_applicable_is_reported():
    m = _pickplace(False)
    res = _one(m, "goal-reachability")
    assert res.holds is False
    ce = res.counterexample
    assert ce.violation["goal"] == "pick" and ce.steps[-1]["fsm"]["arm"][0] == "drop"
    assert "not applicable" in ce.violation["text"]
    assert "confirmed" in _replays(res, m)


def test_goal_reachability_holds_when_every_goal_can_take_over():
    assert _one(_pickplace(True), "goal-reachability").holds is True


def test_goal_stuck_forever():
    f = FSM("f", [State("a"), State("b", outcomes=[running()])], "a", ["g"], [Edge("a", "b", ["g"])],
            [Marker("b", ["g"], on="failure", outcome="failure")])  # b never fails: RUNNING forever
    m = Model("stuck", fsms=[f])
    res = _one(m, "goal-reachability")
    assert res.holds is False and "stuck" in res.counterexample.violation["text"]


def test_pre_limits_the_requestable_goals():
    """'place' is only requested while holding (its SkillRequest's pre)."""
    arm = FSM("arm", [State("home"), State("grip", outcomes=[success(holding=True)]),
                      State("drop", outcomes=[success(holding=False)])], "home", ["pick", "place"],
              [Edge("home", "grip", ["pick"]), Edge("grip", "home", ["pick"]), Edge("home", "drop", ["place"]),
               Edge("drop", "home", ["place"]), Edge("grip", "home", ["place"], direct=True),
               Edge("drop", "home", ["pick"], direct=True)],
              [Marker("grip", ["pick"]), Marker("drop", ["place"]), Marker("home", ["place"], direct=True, outcome="failure",
                                                                           guard="not holding")])
    tree = ReactiveFallback("root", [SkillRequest("place", fsm="arm", goal="place", pre="holding"),
                                     SkillRequest("pick", fsm="arm", goal="pick")])
    assert _one(Model("pre", [Bool("holding")], fsms=[arm], tree=tree), "goal-reachability").holds is True
    no_pre = ReactiveFallback("root", [SkillRequest("place", fsm="arm", goal="place"), SkillRequest("pick", fsm="arm", goal="pick")])
    assert _one(Model("nopre", [Bool("holding")], fsms=[arm], tree=no_pre), "goal-reachability").holds is False


# ---------------------------------------------------------------------- request-latency


def _targeted(retarget: str):
    f = FSM("arm", [State("home"), State("move", outcomes=[running(), success()])], "home", ["go", "back"],
            [Edge("home", "move", ["go"]), Edge("move", "home", ["back"], direct=True)],
            [Marker("move", ["go"]), Marker("home", ["back"], direct=True)],
            params=[Int("target", 0, 1)], retarget=retarget, withdraw_goal="back" if retarget == "withdraw" else "")
    tree = ReactiveFallback("root", [SkillRequest("go1", fsm="arm", goal="go", params={"target": "1"}, pre="want"),
                                     SkillRequest("go0", fsm="arm", goal="go", params={"target": "0"})])
    return Model("target", [Bool("want")], fsms=[f], tree=tree,
                 environment=[EnvEvent("flip", None, {"want": "not want"})])


def test_withdraw_protocol_violates_request_latency():
    m = _targeted("withdraw")
    res = _one(m, "request-latency")
    assert res.holds is False
    ce = res.counterexample
    assert ce.violation["request"]["params"] == {"target": 1} and ce.violation["held"] == {"target": 0}
    assert "withdraw_goal 'back'" in ce.violation["text"]
    assert "confirmed" in _replays(res, m)


def test_immediate_retarget_holds():
    assert _one(_targeted("immediate"), "request-latency").holds is True


def test_no_params_is_not_applicable():
    res = _one(_worker(True), "request-latency")
    assert res.holds is True and res.not_applicable == "no FSM has parameters"


# ---------------------------------------------------------------------- budget, report, tampering


def test_budget_hit_gives_undecided_not_a_verdict():
    m = _counter(invariants={"range": "n <= 3"}, workable="n <= 3")
    r = check(m, ["workable-reachability", "invariants"], max_states=2)
    assert not r.complete and r.exit_code == 3
    assert [x.holds for x in r.results] == [None, None]
    # a violation seen in the explored part is still definite
    r = check(_counter(invariants={"zero": "n == 0"}), ["invariants"], max_states=2)
    assert r.result("invariants").holds is False and r.exit_code == 1


def test_unknown_property_is_refused():
    with pytest.raises(ValueError, match="known: workable-reachability"):
        check(_counter(), ["nope"])


def test_report_json_has_the_contract_fields():
    r = check(_counter("n + 1"))
    d = json.loads(json.dumps(r.to_json()))
    assert {"model", "states", "transitions", "seconds", "properties"} <= set(d)
    assert d["model"] == "cnt" and d["states"] >= 4
    names = [p["name"] for p in d["properties"]]
    assert names[0] == "workable-reachability" and "domain" in names
    dom = next(p for p in d["properties"] if p["name"] == "domain")
    assert dom["holds"] is False and dom["counterexample"]["model"] == "cnt"
    assert all(isinstance(s["script"], list) for s in dom["counterexample"]["steps"])


@pytest.mark.parametrize("field,value", [("outcome", "nothing"), ("state", 0), ("status", "FAILURE")])
def test_tampered_counterexample_does_not_replay(field, value):
    m = _counter(invariants={"small": "n < 3"})
    ce = _one(m, "invariants").counterexample.to_json()
    step = ce["steps"][1]
    if field == "outcome":
        step["outcomes"] = [["inc", value]]
    elif field == "state":
        step["state"]["n"] = value
    else:
        step["status"] = value
    ok, text = replay_counterexample(ce, m)
    assert not ok and text


def test_replay_refuses_another_model():
    ce = _one(_counter(invariants={"small": "n < 3"}), "invariants").counterexample
    ok, text = replay_counterexample(ce.to_json(), _worker(True))
    assert not ok and "not 'worker'" in text


def test_lints_report_never_firing_elements_and_unrequested_goals():
    m = _pickplace(False)
    res = _one(m, "lints")
    assert res.holds is True
    text = "\n".join(res.notes)
    assert "edge 'reach->home' never fires in the model" in text
    f = FSM("f", [State("a"), State("b")], "a", ["g", "h"], [Edge("a", "b", ["g"]), Edge("b", "a", ["h"])])
    lone = Model("lone", fsms=[f], tree=SkillRequest("r", fsm="f", goal="g"))
    text = "\n".join(_one(lone, "lints").notes)
    assert "goal 'h' is never requested" in text and "edge 'b->a' never fires" in text


def test_predicates_with_constant_negation():
    """``not true`` must be false in vectorised predicates (numpy's ``~True`` is -2)."""
    m = _counter(invariants={"odd": "n >= 0 and not true"}, workable="not (1 > 2) or n == 3")
    assert _one(m, "invariants").holds is False
    assert _one(m, "workable-reachability").holds is True


# ---------------------------------------------------------------------- issue 9: the traps

from btfsm import MemoryFallback, MemorySequence, Parallel  # noqa: E402
from btfsm.runtime import Runtime  # noqa: E402
from btfsm.verify.explore import explore  # noqa: E402


def _door_cup_fsm():
    return FSM("arm", [State("home"), State("door", outcomes=[running("busy"), success("ok")]),
                       State("cup", outcomes=[running("busy"), success("ok")])], "home", ["open_door", "pick_cup", "home"],
               [Edge("home", "door", ["open_door"]), Edge("door", "cup", ["pick_cup"], direct=True),
                Edge("home", "cup", ["pick_cup"], direct=True), Edge("cup", "home", ["home", "open_door"], direct=True),
                Edge("door", "home", ["home"], direct=True)],
               [Marker("door", ["open_door"]), Marker("cup", ["pick_cup"]), Marker("home", ["home"], direct=True)])


def _door_then_cup():
    """MemorySequence[open_door, pick_cup, home] on one FSM with a fallback behind it."""
    return Model("handover", variables=[Bool("fell_back")], fsms=[_door_cup_fsm()],
                 tree=MemoryFallback("root", [
                     MemorySequence("seq", [SkillRequest("open", fsm="arm", goal="open_door"),
                                            SkillRequest("pick", fsm="arm", goal="pick_cup"),
                                            SkillRequest("back", fsm="arm", goal="home")]),
                     Action("fallback", outcomes=[success(fell_back="true")])]),
                 invariants=[("no_fallback", "not fell_back")])


def test_handover_checker_and_runtime_agree():
    m = _door_then_cup()
    r = check(m, ["invariants", "contracts"])
    assert r.exit_code == 0  # the fallback never fires, no conflict
    ts = explore(m)
    assert not ts.violations and set(ts.status.tolist()) <= {0, 1}  # never FAILURE
    # the runtime (same step function) starts pick_cup in the tick open_door succeeds
    script = {"arm/door": ["busy", "ok"], "arm/cup": ["busy", "ok"]}
    seen = {k: 0 for k in script}

    def answer(call):
        label = call.site.label
        out = script[label][min(seen[label], 1)]
        seen[label] += 1
        return out
    impls = {"door": answer, "cup": answer}
    rt = Runtime(m, impls)
    statuses = [rt.tick().status.name[0] for _ in range(4)]
    # home->door; door busy; door ok and pick_cup starts (cup busy); cup ok and 'back' succeeds at once
    assert statuses == ["R", "R", "R", "S"]
    assert not m.program.decode(rt.state)["fell_back"]


def test_concurrent_requests_are_a_contract_violation():
    m = Model("conflict", fsms=[_door_cup_fsm()],
              tree=Parallel("root", [SkillRequest("open", fsm="arm", goal="open_door"),
                                     SkillRequest("pick", fsm="arm", goal="pick_cup")]))
    res = _one(m, "contracts")
    assert res.holds is False
    ce = res.counterexample
    assert ce.violation["kind"] == "conflict" and ce.violation["node"] == "pick" and ce.violation["fsm"] == "arm"
    assert ["busy", "pick", "arm"] in ce.steps[-1]["violations"]
    assert "one FSM serves one request at a time" in ce.format_text()
    assert "confirmed" in _replays(res, m)


def _sink(terminal=()):
    f = FSM("arm", [State("home"), State("p1", outcomes=[running("moving"), success("there")]), State("stuck")], "home",
            ["go"], [Edge("home", "p1", ["go"]), Edge("p1", "stuck", ["go"])], [Marker("p1", ["go"])], terminal=terminal)
    return f


@pytest.mark.parametrize("tree", [True, False])
def test_reachable_sink_is_a_dead_state(tree):
    m = Model("sink", fsms=[_sink()], tree=SkillRequest("req", fsm="arm", goal="go") if tree else None)
    res = _one(m, "no-dead-states")
    assert res.holds is False
    ce = res.counterexample
    assert ce.violation["kind"] == "sink" and ce.violation["state"] == "stuck"
    assert ce.steps[-1]["fsm"]["arm"][0] == "stuck" if tree else ce.steps[-1]["state"]["arm.state"] == "stuck"
    assert "every request gets FAILURE ('not applicable')" in ce.format_text()
    assert "confirmed" in _replays(res, m)
    # declared terminal: intended, not reported
    ok = Model("sink", fsms=[_sink(("stuck",))], tree=SkillRequest("req", fsm="arm", goal="go") if tree else None)
    assert _one(ok, "no-dead-states").holds is True


def test_workable_without_tree_is_vacuous():
    m = Model("notree", fsms=[_sink(("stuck",))])
    res = _one(m, "workable-reachability")
    assert res.holds is True and res.info["vacuous"]
    assert any("vacuous" in n for n in res.notes)
    text = check(m, ["workable-reachability"]).format_text()
    assert "holds (vacuously: the model has no tree)" in text and "vacuous:" in text
    assert not _one(_worker(True), "workable-reachability").info.get("vacuous")


def _away_and_back(guard=True, order=("out", "back")):
    f = FSM("arm", [State("home"), State("away")], "home", ["out", "back"],
            [Edge("home", "away", ["out"]), Edge("away", "home", ["back"])],
            [Marker("away", ["out"], direct=True), Marker("away", ["back"])])
    req = {g: SkillRequest(g, fsm="arm", goal=g) for g in ("out", "back")}
    if guard:
        req["back"] = ReactiveSequence("guarded", [Condition("is_away", "arm.state == 'away'"), req["back"]])
    return Model("away", fsms=[f], tree=MemorySequence("trip", [req[g] for g in order]))


def test_goal_level_tree_sees_conditions_in_front_of_requests():
    m = _away_and_back()
    res = _one(m, "goal-reachability")  # open: 'back' requested at home, not applicable there
    assert res.holds is False and "level open" in res.counterexample.violation["text"]
    assert "--goal-level tree" in res.counterexample.violation["text"] and "`pre:`" in res.counterexample.violation["text"]
    res = _one(m, "goal-reachability", goal_level="tree")
    assert res.holds is True and res.info["level"] == "tree"
    bad = _away_and_back(guard=False, order=("back", "out"))  # the tree really asks 'back' at home
    res = _one(bad, "goal-reachability", goal_level="tree")
    assert res.holds is False and res.counterexample.violation["kind"] == "goal-tree"
    assert res.counterexample.violation["text"].startswith("level tree")
    assert "confirmed" in _replays(res, bad)
    with pytest.raises(ValueError, match="goal level"):
        _one(m, "goal-reachability", goal_level="nope")


def _through():
    """A request passes home -> p1 -> p2 (direct edges), runs p2 and goes back home."""
    f = FSM("arm", [State("home"), State("p1"), State("p2", outcomes=[success("ok"), failure("jam")])], "home", ["go"],
            [Edge("home", "p1", ["go"], direct=True), Edge("p1", "p2", ["go"], direct=True),
             Edge("p2", "home", ["go"], on="failure"), Edge("p2", "home", ["go"])],
            [Marker("p2", ["go"], guard="false")])
    return Model("through", fsms=[f], tree=SkillRequest("req", fsm="arm", goal="go"))


def test_texts_say_how_the_token_moves_within_a_request():
    m = _through()
    ce = _one(m, "no-dead-states").counterexample
    assert ce.violation["kind"] == "non-progress"
    assert "the token moves (home -> p1 -> p2 -> home)" in ce.violation["text"]
    assert "does not move" not in ce.violation["text"]
    text = _one(m, "goal-reachability").counterexample.violation["text"]
    assert "cycling within each request (home -> p1 -> p2 -> home)" in text and "(stuck)" not in text
    # the token passes p1 within every tick: p1 is reached, not a lint
    lints = _one(m, "lints").notes
    assert not any("'p1' is never reached" in n or "'p2' is never reached" in n for n in lints), lints


def test_steps_print_events_in_order():
    """A higher-priority request starting withdraws the old goal before its own edge fires."""
    f = FSM("arm", [State("home", outcomes=[running("moving"), success()]), State("away", outcomes=[running("moving")])],
            "home", ["go", "stay"], [Edge("home", "away", ["go"])], [Marker("home", ["stay"], on="failure")])
    m = Model("order", variables=[Bool("call")], fsms=[f],
              environment=[EnvEvent("ring", "not call and arm.goal == 'stay'", {"call": True})],
              tree=ReactiveFallback("root", [ReactiveSequence("urgent", [Condition("called", "call"),
                                                                         SkillRequest("go", fsm="arm", goal="go")]),
                                             SkillRequest("stay", fsm="arm", goal="stay")]),
              invariants=[("quiet", "not (call and arm.state == 'away')")])
    ce = _one(m, "invariants").counterexample
    line = ce.format_text().splitlines()
    step = next(x for x in line if "ring" in x)
    assert step.index("withdraw arm (stay)") < step.index("fired arm:home->away"), step
    assert ce.steps[-1]["sequence"][0][0] in ("outcome", "withdraw", "halt")


def test_lints_are_grouped_and_quiet_hides_them():
    m = _door_then_cup()
    r = check(m)
    text = r.format_text()
    lint = r.result("lints")
    assert f"{len(lint.notes)} warning(s): " in text and "(--verbose lists them)" in text
    assert not any(n in text for n in lint.notes)
    assert all(n in r.format_text(verbose=True) for n in lint.notes)
    quiet = r.format_text(quiet=True)
    assert "warning(s):" not in quiet and "gap" not in quiet and "information" not in quiet


def test_counterexample_file_names_differ_per_violation():
    a = _one(_worker(False), "workable-reachability").counterexample
    b = _one(Model("worker", fsms=[_sink()], tree=SkillRequest("do", fsm="arm", goal="go")), "workable-reachability").counterexample
    assert a.file_name() != b.file_name() and a.file_name().startswith("worker.workable-reachability.")
    assert a.file_name() == _one(_worker(False), "workable-reachability").counterexample.file_name()  # stable


# ---------------------------------------------------------------------- tree coverage (dead branches)


def _nav(guard_written: bool):
    """A guard before FollowPath; nothing writes ``path_ok`` unless ``guard_written``."""
    env = [EnvEvent("plan", None, {"path_ok": "True"})] if guard_written else []
    return Model("nav", [Bool("path_ok"), Bool("done")], environment=env, tree=ReactiveFallback("root", [
        ReactiveSequence("follow", [Condition("path_valid", "path_ok"),
                                    Action("FollowPath", outcomes=[running(), success(done="True")])]),
        Action("Wait", outcomes=[running(), success()])]))


def _coverage(model):
    lint = check(model, ["lints"]).result("lints")
    return {w["element"]: w for w in lint.info["warnings"] if w["text"].startswith(("never ticked", "ticked but"))}


def test_dead_branch_never_ticked_with_the_run_that_shows_why():
    found = _coverage(_nav(False))
    assert set(found) == {"tree.path_valid", "tree.FollowPath"}
    assert found["tree.path_valid"]["text"] == "ticked but never succeeds in any reachable state"
    assert found["tree.FollowPath"]["text"] == ("never ticked in any reachable state ('follow' is ticked but never "
                                                "reaches it; before it, 'path_valid' never succeeds)")
    for w in found.values():  # the shortest run: one tick, in which the guard is ticked and fails
        run = w["run"]
        assert len(run["steps"]) == 1 and run["steps"][0]["choices"] == [["outcome", "Wait", "running", "RUNNING"]]
        ok, text = replay_counterexample(run, _nav(False))
        assert ok, text


def test_covered_tree_has_no_dead_branch():
    assert _coverage(_nav(True)) == {}


def test_dead_subtree_reports_its_topmost_node_only():
    m = Model("d", [Bool("never")], tree=ReactiveFallback("root", [
        Action("always", outcomes=[success()]),
        ReactiveSequence("spare", [Action("a", outcomes=[success()]), Action("b", outcomes=[success()])])]))
    found = _coverage(m)
    assert set(found) == {"tree.spare"} and "'root' is ticked but never reaches it" in found["tree.spare"]["text"]


def test_a_leaf_that_cannot_succeed_by_declaration_is_not_reported():
    m = Model("f", [Bool("b")], tree=ReactiveFallback("root", [
        Action("fails", outcomes=[failure()]), Action("ok", outcomes=[success()])]))
    assert _coverage(m) == {}


def test_no_coverage_beyond_the_rerun_limit(monkeypatch):
    import btfsm.verify.properties.lints as lints

    monkeypatch.setattr(lints, "FIRE_LIMIT", 1)
    assert _coverage(_nav(False)) == {}
