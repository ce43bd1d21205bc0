"""The automated skill-transition procedure (verify/skills.py, ``btfsm skills``)."""
import json
import subprocess
import sys

import pytest

from btfsm import (FSM, Bool, Condition, Edge, EnvEvent, Marker, Model, Parallel, Primitive,
                   ReactiveFallback, ReactiveSequence, SkillRequest, State, running, success)
from btfsm.models.original import original, original_preemptive
from btfsm.verify.skills import check_support, counts, derive, format_text, skills_of, to_dot, to_json

MOVE = Primitive("move", (running(), success()))


def _names(d, kind=None):
    return {(d.name(a), d.name(b)) for (a, b, k) in d.pairs if a is not None and (kind is None or k == kind)}


def _urgent_model(fsm, name="m"):
    """work is preempted by serve when the environment raises ``call``."""
    tree = ReactiveFallback("root", [
        ReactiveSequence("urgent", [Condition("called", "call"), SkillRequest("serve_call", fsm="arm", goal="serve")]),
        SkillRequest("do_work", fsm="arm", goal="work"),
    ])
    return Model(name, variables=[Bool("call")], primitives=[MOVE], fsms=[fsm], tree=tree,
                 environment=[EnvEvent("call", "not call", {"call": True}), EnvEvent("hang_up", "call", {"call": False})])


def _arm(serve_from_w1: bool) -> FSM:
    edges = [Edge("home", "w1", ["work"]), Edge("w1", "home", ["work"]), Edge("home", "s1", ["serve"]),
             Edge("s1", "home", ["serve", "work"])]
    if serve_from_w1:
        edges.append(Edge("w1", "home", ["serve"], direct=True))
    return FSM("arm", states=[State("home", "move"), State("w1", "move"), State("s1", "move")], initial="home",
               goals=["work", "serve"], edges=edges, markers=[Marker("w1", ["work"]), Marker("s1", ["serve"])])


def test_skills_are_fsm_goal_pairs_in_tree_order():
    m = original()
    sk = skills_of(m)
    assert [s.goal for s in sk] == ["bins/place", "agv/place", "conveyor/pick", "bins/pick"]
    assert sk[1].nodes == ("place_on_location_x", "place_on_location")  # two nodes, one skill


def test_supported_preemption():
    d = derive(_urgent_model(_arm(True)))
    assert [s.goal for s in d.skills] == ["serve", "work"]
    assert ("work", "serve") in _names(d, "preemption")
    assert ("serve", "work") in _names(d, "completion")
    sup = check_support(d)
    assert sup and all(s.supported for s in sup)


def test_unsupported_preemption_has_a_counterexample():
    d = derive(_urgent_model(_arm(False)))
    assert ("work", "serve") in _names(d, "preemption")
    sup = {(d.name(s.a), d.name(s.b), s.kind): s for s in check_support(d)}
    bad = sup[("work", "serve", "preemption")]
    assert not bad.supported
    assert d.pairs[(1, 0, "preemption")].refused > 0  # the tree asked, the FSM refused at once
    cx = bad.counterexample
    # right after the refused switch: serve not applicable at w1; work was withdrawn, and the
    # fallback handed the FSM back to do_work in the same tick (rule 'Hand-over'), so work is held
    assert cx["from_state"] == "w1" and cx["held_goal"] == "work" and cx["request"] == "serve"
    assert cx["steps"][0]["reply"] == "FAILURE" and cx["steps"][0].get("not_applicable")
    assert sup[("serve", "work", "completion")].supported
    text = format_text(d, list(sup.values()))
    assert "UNSUPPORTED preemption work -> serve" in text and "not applicable" in text


def test_original_memory_executive_never_preempts():
    d = derive(original())
    c = counts(d)
    assert (c["completion"], c["preemption"], c["failure"]) == (7, 0, 0)
    assert all(s.supported for s in check_support(d))


def test_original_preemptive_gives_the_papers_nine_and_the_freeze():
    d = derive(original_preemptive())
    c = counts(d)
    assert (c["completion_or_preemption"], c["completion"], c["preemption"]) == (9, 7, 2)
    assert _names(d, "preemption") == {("bins/pick", "conveyor/pick"), ("agv/place", "bins/place")}
    bad = [s for s in check_support(d) if not s.supported]
    assert [(d.name(s.a), d.name(s.b), s.kind) for s in bad] == [("agv/place", "bins/place", "preemption")]
    cx = bad[0].counterexample
    assert cx["from_state"].startswith(("release on agv", "detach approach on agv", "escape agv"))
    assert cx["steps"][-1].get("repeats") and cx["steps"][0]["state"] == cx["from_state"]
    assert any("[withdraw, direct] => failure" in f for f in cx["steps"][0]["fired"])


def test_refused_requests_do_not_start_skills():
    f = _arm(True)
    tree = ReactiveFallback("root", [
        SkillRequest("serve_call", fsm="arm", goal="serve", pre="call"),  # fails at once without the call
        SkillRequest("do_work", fsm="arm", goal="work"),
    ])
    m = Model("pre", variables=[Bool("call")], primitives=[MOVE], fsms=[f], tree=tree,
              environment=[EnvEvent("call", "not call", {"call": True}), EnvEvent("hang_up", "call", {"call": False})])
    d = derive(m)
    assert ("work", "serve") in _names(d, "preemption")
    assert ("serve", "work") in _names(d)
    assert ("work", "work") in _names(d, "completion")


def test_concurrent_skills_of_two_fsms():
    def arm(name):
        return FSM(name, states=[State("home", "move"), State("w", "move")], initial="home", goals=["go"],
                   edges=[Edge("home", "w"), Edge("w", "home")], markers=[Marker("w")])
    tree = Parallel("both", [SkillRequest("left_go", fsm="left", goal="go"), SkillRequest("right_go", fsm="right", goal="go")])
    m = Model("two", primitives=[MOVE], fsms=[arm("left"), arm("right")], tree=tree)
    d = derive(m)
    assert ("left:go", "right:go") in _names(d, "concurrent")
    assert not d.single_fsm


def test_held_reading_is_stricter():
    """The brief's reading (from every state where a is held) also flags states in which
    the tree never asks for b; the default reading checks where the switch happens."""
    from btfsm import Bool as B

    f = FSM("arm", states=[State("home", "move"), State("w1", "move"), State("s1", "move")], initial="home",
            goals=["work", "serve"],
            edges=[Edge("home", "w1", ["work"]), Edge("w1", "home", ["work"]), Edge("w1", "home", ["serve"], direct=True),
                   Edge("home", "s1", ["serve"]), Edge("s1", "home")],
            markers=[Marker("w1", ["work"]), Marker("s1", ["serve"]),
                     Marker("home", ["serve"], direct=True, outcome="failure", guard="not call")])  # refuses without a call
    m = _urgent_model(f)
    assert m.var("call") == B("call")
    d = derive(m)
    assert all(s.supported for s in check_support(d))
    strict = {(d.name(s.a), d.name(s.b), s.kind): s.supported for s in check_support(d, where="held")}
    assert strict[("work", "serve", "preemption")] is False
    with pytest.raises(ValueError):
        check_support(d, where="nowhere")


def test_budget_makes_it_incomplete():
    d = derive(original(), max_states=50)
    assert not d.complete and d.states == 50


def test_outputs():
    d = derive(original_preemptive())
    sup = check_support(d)
    data = to_json(d, sup)
    json.dumps(data)
    assert data["counts"]["possible"] == 16 and data["complete"]
    unsupported = [t for t in data["transitions"] if t.get("supported") is False]
    assert len(unsupported) == 1 and unsupported[0]["counterexample"]["request"] == "bins/place"
    dot = to_dot(d, sup)
    assert dot.startswith('digraph "original-preemptive skills"') and dot.count("->") == 9
    assert dot.count("unsupported") == 1 and dot.count("style=dashed") == 2


def test_witness_replays_to_the_transition():
    """The witness of a pair is a path of choice scripts ending with the tick that starts b."""
    from btfsm.oracles import ScriptOracle

    m = original_preemptive()
    d = derive(m)
    (a, b, k), pair = next((key, p) for key, p in d.pairs.items() if key[2] == "preemption")
    prog = m.program
    state = prog.initial
    for script in pair.witness[:-1]:
        state = prog.step(state, ScriptOracle(script)).state
    assert any(state[prog.nodes[n].flag] for n in d.skills[a].nodes)  # a is running before the tick
    step = prog.step(state, ScriptOracle(pair.witness[-1]), record=True)
    halted = {ev[1] for ev in step.events if ev[0] == "halt"}
    assert halted & set(d.skills[a].nodes)
    assert {ev[1] for ev in step.events if ev[0] == "status"} & set(d.skills[b].nodes)


# ------------------------------------------------------------------ CLI
def _cli(*args):
    # not "python -m btfsm.cli": there btfsm.cli.UsageError is another class than __main__'s
    code = "import sys; from btfsm.cli import main; sys.exit(main(sys.argv[1:]))"
    p = subprocess.run([sys.executable, "-c", code, "skills", *args], capture_output=True, text=True, timeout=300)
    assert "Traceback" not in p.stderr, p.stderr
    return p


def test_cli_exit_codes_and_formats():
    p = _cli("ariac-preemptive")
    assert p.returncode == 0, p.stderr
    assert "transitions: " in p.stdout and "FSM support: 17 of 17" in p.stdout
    p = _cli("original-preemptive", "--format", "json")
    assert p.returncode == 1
    assert json.loads(p.stdout)["counts"]["completion_or_preemption"] == 9
    p = _cli("spectrum-hold", "--format", "dot")
    assert p.returncode == 0 and p.stdout.startswith("digraph")
    p = _cli("original", "--max-states", "20")
    assert p.returncode == 3 and "incomplete" in p.stderr
    for bad in (("no-such-model",), ("original", "--max-states", "0"), ("original", "--format", "svg")):
        p = _cli(*bad)
        assert p.returncode == 2, (bad, p.stderr)
        assert p.stderr.strip().count("\n") == 0 or "usage" in p.stderr


def test_cli_model_without_tree(tmp_path):
    pytest.importorskip("btfsm.files")
    path = tmp_path / "bare.yaml"
    path.write_text("name: bare\nvariables: {x: bool}\n")
    p = _cli(str(path))
    assert p.returncode == 2 and "no tree" in p.stderr
