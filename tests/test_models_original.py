"""The port of the authors' MovementManager and executive (models/original.py).

Counts and the transit table come from original-design.md sections 3.1-3.7; the tick
traces are the stub runs of section 3.8 (every primitive succeeding at once)."""
import importlib
import pytest

from btfsm.oracles import SucceedOracle
from btfsm.status import Status
from btfsm.models.original import (ROTATIONS, TARGETS, TRACKS, movement_manager, original,
                             original_preemptive, transit_table)

MM = "movement_manager"



@pytest.fixture(scope="module")
def fsm():
    return movement_manager()


@pytest.fixture(scope="module")
def model():
    return original()


def test_counts(fsm):
    assert len(fsm.states) == 42
    assert fsm.goals == TRACKS and len(fsm.goals) == 8
    assert len(fsm.edges) == 105
    assert sum(e.direct for e in fsm.edges) == 42
    assert sum((not e.direct) and e.on == Status.SUCCESS for e in fsm.edges) == 63
    assert len(fsm.markers) == 29
    assert all(len(e.goals) == 1 for e in fsm.edges)  # one edge per (source, track, key), as add_transition
    assert fsm.initial == "approach bins"
    assert fsm.retarget == "withdraw" and fsm.withdraw_goal == "withdraw"
    assert [p.name for p in fsm.params] == ["target"]


def test_no_collisions_one_edge_per_source_track_key(fsm):
    keys = [(e.source, e.goals[0], "direct" if e.direct else e.on) for e in fsm.edges]
    assert len(set(keys)) == len(keys)


# original-design.md section 3.3, full instantiation (S: on SUCCESS, D: direct)
APPR = {"B": "approach bins", "A": "approach agv", "C": "approach conveyor"}
TABLE_33 = {
    "bins to agv": "D:B D:B S:A S:A D:B D:B",
    "bins to conveyor": "D:B D:B D:B D:B S:C S:C",
    "agv to bins": "S:B S:B D:A D:A D:A D:A",
    "agv to conveyor": "D:A D:A D:A D:A S:C S:C",
    "conveyor to bins": "S:B S:B D:C D:C D:C D:C",
    "conveyor to agv": "D:C D:C S:A S:A D:C D:C",
}
HUB_33 = {
    "approach bins": ["enable gripper on bins", "put on bins", "bins to agv", "bins to agv", "bins to conveyor", "bins to conveyor"],
    "approach agv": ["agv to bins", "agv to bins", "enable gripper on agv", "put on agv", "agv to conveyor", "agv to conveyor"],
    "approach conveyor": ["conveyor to bins", "conveyor to bins", "conveyor to agv", "conveyor to agv",
                          "enable gripper on conveyor", "put on conveyor"],
}


def test_transit_table_section_3_3(fsm):
    table = transit_table(fsm)
    skills = TRACKS[:6]
    for state, row in TABLE_33.items():
        for track, cell in zip(skills, row.split()):
            kind, area = cell.split(":")
            assert table[(state, track)] == f"{kind}:{APPR[area]}", (state, track)
        assert table[(state, "withdraw")] == "marker direct->success"
    for state, targets in HUB_33.items():
        for track, target in zip(skills, targets):
            assert table[(state, track)] == f"S:{target}", (state, track)
        assert table[(state, "withdraw")] == "marker success->success"


@pytest.mark.parametrize("x", [r[0] for r in ROTATIONS])
def test_task_chains_and_withdraw(fsm, x):
    table = transit_table(fsm)
    pick = [f"approach {x}", f"enable gripper on {x}", f"grasp on {x}", f"record grasping pose on {x}",
            f"detach approach on {x} (pick)", f"raise on {x}", f"approach {x}"]
    for a, b in zip(pick[1:-1], pick[2:]):
        assert table[(a, f"{x}/pick")] == f"S:{b}"
    place = [f"approach {x}", f"put on {x}", f"release on {x}", f"detach approach on {x} (place)", f"escape {x}", f"approach {x}"]
    for a, b in zip(place[1:-1], place[2:]):
        assert table[(a, f"{x}/place")] == f"S:{b}"
    for s in pick[1:5]:
        assert table[(s, "withdraw")] == f"D:disable gripper on {x}"
    assert table[(f"raise on {x}", "withdraw")] == f"D:put back on {x}"
    assert table[(f"put back on {x}", "withdraw")] == f"S:disable gripper on {x}"
    assert table[(f"disable gripper on {x}", "withdraw")] == f"S:approach {x}"
    assert table[(f"put on {x}", "withdraw")] == f"D:approach {x}"
    refused = {(m.state, m.outcome) for m in fsm.markers if m.goals == ("withdraw",) and m.direct}
    for s in place[1:5]:
        assert (s, Status.FAILURE) in refused
    # each of the 42 states has a withdraw edge or marker: withdraw is never "not applicable"
    assert all(any((st.id, "withdraw") == k for k in table) for st in fsm.states)


def test_conveyor_overrides_and_preemptive_track(fsm):
    args = {s.id: dict(s.args) for s in fsm.states}
    assert args["approach conveyor"]["tolerance"] == "huge"
    assert args["raise on conveyor"]["tolerance"] == "huge"
    assert args["grasp on conveyor"]["shaking"] is False and args["grasp on bins"]["shaking"] is True
    pre = sorted(m.state for m in fsm.markers if m.goals == ("preemptive?",))
    assert pre == ["approach bins", "bins to agv"]


def test_shadowed_markers_are_warnings(model):
    shadowed = [el for el, text in model.warnings if "shadowed" in text]
    assert sorted(shadowed) == sorted(f"fsms.{MM}.markers.put on {x} [withdraw, direct] => failure" for x in ("bins", "agv", "conveyor"))


# --------------------------------------------------------------------- stub runs (3.8)
def _at(model, state, held=None, target=0):
    prog = model.program
    s = list(prog.initial)
    f, ids, tok, goal, (pslot,) = prog.fsm_info[prog.fsm_index[MM]]
    s[tok] = ids.index(state)
    s[goal] = 0 if held is None else f.goals.index(held) + 1
    s[pslot] = target
    return tuple(s)


def _run(model, state, goal, target, ticks):
    """Tick the FSM toward (goal, target) with all-succeeding stubs; record (token, reply)."""
    prog = model.program
    out = []
    for _ in range(ticks):
        step = prog.fsm_step(state, MM, goal, (target,), SucceedOracle())
        state = step.state
        out.append((prog.fsm_state(state, MM)[0], Status(step.status).name))
    return out, state


def test_bin_pick_from_rest_is_one_withdraw_tick_plus_six(model):
    trace, _ = _run(model, model.program.initial, "bins/pick", 1, 7)
    assert trace[-1] == ("approach bins", "SUCCESS")
    assert [r for _, r in trace] == ["RUNNING"] * 6 + ["SUCCESS"]
    assert trace[0][0] == "approach bins"  # the first tick only withdrew (and adopted the target)


def test_bins_to_agv_place_takes_seven_ticks(model):
    # target already adopted (a place of the part just picked): no withdraw tick
    trace, _ = _run(model, _at(model, "approach bins", target=3), "agv/place", 3, 7)
    assert trace[-1] == ("approach agv", "SUCCESS")
    # a new target costs one more tick, spent on withdraw
    trace, _ = _run(model, model.program.initial, "agv/place", 3, 8)
    assert trace[0] == ("approach bins", "RUNNING") and trace[-1] == ("approach agv", "SUCCESS")


def test_preempt_bin_pick_at_raise_takes_eleven_ticks(model):
    start = _at(model, "raise on bins", "bins/pick", target=1)
    trace, _ = _run(model, start, "conveyor/pick", 2, 11)
    tokens = [t for t, _ in trace]
    assert tokens[:3] == ["disable gripper on bins", "approach bins", "approach bins"]
    assert trace[-1] == ("approach conveyor", "SUCCESS")
    assert [r for _, r in trace[:-1]] == ["RUNNING"] * 10


def test_main_script_three_ticks_stop_with_the_gripper_enabled(model):
    trace, state = _run(model, model.program.initial, "bins/pick", 1, 3)
    assert trace[-1] == ("grasp on bins", "RUNNING")
    trace, _ = _run(model, state, "conveyor/pick", 2, 12)
    assert ("approach conveyor", "SUCCESS") in trace
    # disable gripper on bins runs, then approach bins (withdraw succeeds), then the pick goes on
    assert trace[:3] == [("approach bins", "RUNNING"), ("approach bins", "RUNNING"), ("bins to conveyor", "RUNNING")]


def test_preempt_in_transit_goes_back_to_where_it_began(model):
    start = _at(model, "bins to agv", "agv/place", target=3)
    trace, _ = _run(model, start, "conveyor/pick", 2, 2)
    assert trace[0] == ("bins to agv", "RUNNING")  # withdraw: direct SUCCESS marker, nothing runs
    assert trace[1] == ("bins to conveyor", "RUNNING")  # direct back to approach bins, run it, go on


@pytest.mark.parametrize("state", ["release on agv", "detach approach on agv (place)", "escape agv"])
def test_refused_withdraw_freezes_the_arm(model, state):
    start = _at(model, state, "agv/place", target=3)
    trace, end = _run(model, start, "conveyor/pick", 2, 20)
    assert trace == [(state, "RUNNING")] * 20  # the token never moves while the new target is asked
    prog = model.program
    assert prog.decode(end)[f"{MM}.target"] == 3  # the new target is never adopted


def test_same_target_wrong_state_is_not_applicable(model):
    start = _at(model, "grasp on bins", "bins/pick", target=1)
    trace, _ = _run(model, start, "agv/place", 1, 3)
    assert trace == [("grasp on bins", "FAILURE")] * 3


def test_failing_primitive_is_retried_silently(model):
    prog = model.program

    class FailGrasp(SucceedOracle):
        def outcome(self, site):
            if site.state == "grasp on bins":
                return [o[0] for o in site.outcomes].index(int(Status.FAILURE))
            return super().outcome(site)

    state = _at(model, "grasp on bins", "bins/pick", target=1)
    for _ in range(5):
        step = prog.fsm_step(state, MM, "bins/pick", (1,), FailGrasp())
        assert Status(step.status) == Status.RUNNING and step.state == state
        state = step.state


def test_executive_structure(model):
    tree = model.tree
    assert type(tree).__name__ == "Parallel"
    chain = tree.children[1]
    assert type(chain).__name__ == "MemoryFallback" and chain.name == "memsel_z"
    inner = chain.children[0].children[0]
    assert [c.name for c in inner.children] == ["X", "done"]
    pre = original_preemptive().tree.children[1]
    assert type(pre).__name__ == "ReactiveFallback" and pre.children[0].name == "X"
    assert set(TARGETS.values()) == {1, 2, 3, 4}


def test_runs_and_places_parts_with_random_outcomes():
    from btfsm.oracles import RandomOracle
    from btfsm.runtime import Runtime

    m = original(n_parts=2)
    for seed in range(8):
        rt = Runtime(m, fallback=RandomOracle(seed))
        for _ in range(600):
            rt.tick()
            if rt.vars["placed"] == 2:
                break
        assert rt.vars["placed"] == 2, seed


# --------------------------------------------------------------------- btfsm check
def _check(model):
    verify = importlib.import_module("btfsm.verify")
    return verify.check(model)


def _result(report, name):
    results = getattr(report, "properties", None) or report.results
    return next(r for r in results if r.name == name)


@pytest.fixture(scope="module")
def report(model):
    return _check(model)


def test_check_reports_the_freeze_as_unreachable_goal(report):
    r = _result(report, "goal-reachability")
    assert r.holds is False and r.counterexample is not None
    last = r.counterexample.steps[-1]["fsm"][MM][0]
    assert last.startswith(("release on", "detach approach on", "escape")), last
    assert "RUNNING" in r.counterexample.violation["text"]  # held and running, never succeeding


def test_check_reports_silent_retry_as_non_progress_cycle(report):
    r = _result(report, "no-dead-states")
    assert r.holds is False
    ce = r.counterexample
    assert ce.loop is not None and ce.violation["kind"] == "non-progress"
    cycle = ce.steps[ce.loop:]
    assert all(not st["fired"] for st in cycle)
    assert any(out == "failure" for st in cycle for _, out in st["outcomes"])


def test_check_reports_the_withdraw_tick_as_request_latency(report):
    r = _result(report, "request-latency")
    assert r.holds is False
    assert "withdraw" in r.counterexample.violation["text"]


def test_check_lints_name_the_shadowed_markers(report):
    notes = " ".join(str(n) for n in _result(report, "lints").notes)
    for x in ("bins", "agv", "conveyor"):
        assert f"put on {x} [withdraw, direct] => failure" in notes


def test_check_other_properties_hold(report):
    for name in ("workable-reachability", "determinism", "invariants", "contracts", "domain"):
        assert _result(report, name).holds is True, name


def test_preemptive_executive_reaches_the_freeze():
    r = _result(_check(original_preemptive()), "workable-reachability")
    assert r.holds is False
    end = r.counterexample.steps[-1]["fsm"][MM][0]
    assert end.startswith(("release on", "detach approach on", "escape")), end
