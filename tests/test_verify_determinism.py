"""Guard determinism with z3: overlaps, witnesses, pre-filter, gaps."""
from __future__ import annotations

import pytest

from btfsm import FSM, Bool, Edge, Enum, Int, Marker, Model, State, failure, running, success
from btfsm.verify import check, replay_counterexample
from btfsm.verify.determinism import _disjoint, _literals, analyse, confirm_overlap, describe_overlap


def _model(edges, markers=(), states=None, variables=None, params=()):
    states = states or [State("a", outcomes=[success(), failure()]), State("b")]
    variables = variables or [Enum("mode", ("idle", "busy", "off")), Bool("full"), Int("q", 0, 3)]
    return Model("det", variables, fsms=[FSM("f", states, "a", ["g", "h"], edges, markers, params)])


def test_overlap_with_decoded_witness():
    m = _model([Edge("a", "b", ["g"], guard="mode == 'busy' and q > 1"), Edge("a", "a", ["g"], guard="q >= 3 or full")])
    overlaps, _ = analyse(m)
    assert len(overlaps) == 1
    o = overlaps[0]
    assert (o["state"], o["point"], o["kind"], o["a"], o["b"], o["goals"]) == ("a", "on success", "edge", "a->b", "a->a", ["g"])
    assert o["values"]["mode"] == "busy" and isinstance(o["values"]["full"], bool)
    assert o["values"]["q"] > 1 and (o["values"]["q"] >= 3 or o["values"]["full"])
    assert "can both fire" in describe_overlap(o)
    assert confirm_overlap(m, o)[0]


def test_disjoint_guards_hold():
    m = _model([Edge("a", "b", ["g"], guard="mode == 'busy'"), Edge("a", "a", ["g"], guard="mode == 'idle'"),
                Edge("a", "b", ["g"], on="failure", guard="q < 2"), Edge("a", "a", ["g"], on="failure", guard="q >= 2")])
    assert analyse(m)[0] == []


def test_points_are_separate_and_goals_merge():
    # same guards but different firing points (direct vs on success): not a pair
    m = _model([Edge("a", "b", ["g", "h"], guard="full"), Edge("a", "b", ["g", "h"], direct=True, guard="full"),
                Edge("a", "b", ["g", "h"], on="failure"), Edge("a", "a", ["g", "h"], on="failure", guard="q == 1")])
    overlaps, _ = analyse(m)
    assert [(o["point"], o["goals"]) for o in overlaps] == [("on failure", ["g", "h"])]


def test_markers_overlap_too():
    m = _model([], [Marker("a", ["g"], guard="full"), Marker("a", ["g"], outcome="failure", guard="q == 0")])
    overlaps, _ = analyse(m)
    assert [(o["kind"], o["a"]) for o in overlaps] == [("marker", "a:success")]


def test_statuses_the_state_cannot_return_are_skipped():
    states = [State("a", outcomes=[success()]), State("b")]
    m = _model([Edge("a", "b", ["g"], on="failure"), Edge("a", "a", ["g"], on="failure")], states=states)
    assert analyse(m)[0] == []


def test_state_token_is_fixed_in_the_query():
    m = _model([Edge("a", "b", ["g"], guard="f.state == 'a'"), Edge("a", "a", ["g"], guard="f.state == 'b'")])
    assert analyse(m)[0] == []


def test_params_by_bare_name():
    m = _model([Edge("a", "b", ["g"], guard="target == 1"), Edge("a", "a", ["g"], guard="target >= 1")],
               params=(Int("target", 0, 2),))
    overlaps, _ = analyse(m)
    assert overlaps and overlaps[0]["values"] == {"target": 1}


def test_literal_prefilter():
    m = _model([Edge("a", "b", ["g"])])
    scope = m.program.fsm_scope(m.fsms[0])
    from btfsm import parse

    la, lb = _literals(parse("mode == 'busy' and full"), scope), _literals(parse("mode in ('idle', 'off')"), scope)
    assert la == {"mode": frozenset({1}), "full": frozenset({1})} and lb == {"mode": frozenset({0, 2})}
    assert _disjoint(la, lb)
    assert not _disjoint(la, _literals(parse("not full or q == 1"), scope))  # an or of two names: no literal
    assert _disjoint(_literals(parse("not full"), scope), la)


def test_gaps_are_information():
    states = [State("a", outcomes=[success(), failure(), running()]), State("b")]
    m = _model([Edge("a", "b", ["g"], guard="q > 1")], states=states)
    overlaps, gaps = analyse(m)
    assert overlaps == []
    kinds = {(x["status"], x["kind"]) for x in gaps if x["state"] == "a"}
    assert ("success", "uncovered") in kinds and ("failure", "no-edge") in kinds
    assert ("running", "no-edge") not in kinds  # polling is by design
    unc = next(x for x in gaps if x["kind"] == "uncovered")
    assert unc["values"]["q"] <= 1
    r = check(m, ["determinism"])
    assert r.result("determinism").holds is True and any("gap" in n for n in r.result("determinism").notes)


def test_property_counterexample_is_static_and_replays():
    m = _model([Edge("a", "b", ["g"], guard="full"), Edge("a", "a", ["g"], guard="q == 2")])
    res = check(m, ["determinism"]).result("determinism")
    assert res.holds is False
    ce = res.counterexample
    assert ce.level == "static" and ce.steps == []
    assert "'a->b'" in ce.format_text() and "'a->a'" in ce.format_text()
    ok, text = replay_counterexample(ce.to_json(), m)
    assert ok and "confirmed" in text
    bad = ce.to_json()
    bad["violation"]["values"] = {"full": False, "q": 2}
    assert not replay_counterexample(bad, m)[0]


@pytest.mark.parametrize("n", [40])
def test_solver_is_reused(n):
    """Many pairs, one solver per FSM: the cache holds one term per guard."""
    edges = [Edge("a", "b", ["g"], guard=f"q == {i % 4} and mode != 'off'") for i in range(n)]
    m = _model(edges)
    overlaps, _ = analyse(m, gaps=False)
    # edges with the same q value overlap: 4 groups of 10 -> 4 * C(10, 2) pairs
    assert len(overlaps) == 4 * 45


def test_witnesses_are_the_same_on_every_call():
    """Each analysis builds its terms in its own z3 context, so asking again in the same
    process gives the same witness values (z3's shared main context did not)."""
    from btfsm.models.registry import load_builtin

    m = load_builtin("pickplace3-bug")
    first = analyse(m)
    for _ in range(3):
        assert analyse(load_builtin("pickplace3-bug")) == first
        assert analyse(m) == first
