"""The paper's reaction-time claim on the timed ARIAC models (issues 12.3 and 21; docs/verification.md 2.1).

``ariac.timed`` splits the arm FSM by goal class and entry (the position abstraction) and
declares each copy's slowest run derived from the scene (``models/ariac_timing.json``),
belt arrivals at least 30 s apart and the requirement ``reach`` (a detected belt part is
reached within dt* = 16 s). The checker proves the exact worst case; the cell runs the
same timed model, the runtime refusing any primitive answer outside the declared
durations, and every reaction measured there must lie within the proved worst case.
"""
from __future__ import annotations

import json
import multiprocessing as mp
import os

import pytest

from btfsm.cli import main
from btfsm.models import ariac
from btfsm.models.registry import load_builtin
from btfsm.verify import replay_counterexample
from btfsm.verify.report import check


@pytest.fixture(scope="module")
def proved():
    """{variant: (worst-case reach in seconds, the response result)} on the 2-part models."""
    out = {}
    for v in ("preemptive", "baseline"):
        res = check(load_builtin(f"ariac-{v}-timed"), ["response"]).results[0]
        out[v] = (res.info["responses"]["reach"]["worst_seconds"], res)
    return out


def test_worst_cases_are_proved_and_exceed_the_window(proved):
    # figures printed by `btfsm check ariac-{preemptive,baseline}-timed --property response --json`
    # (37.1 s and 51.1 s with the measured context-free durations, ``timed(m, "measured")``;
    # 29.4 s and 42.9 s with one state of history in the position abstraction; 26.6 s and
    # 33.8 s with two states of history that did not see through the instant states)
    assert proved["preemptive"][0] == pytest.approx(26.6)
    assert proved["baseline"][0] == pytest.approx(32.9)
    info = {v: proved[v][1].info["responses"]["reach"] for v in proved}
    assert info["preemptive"]["first_late_seconds"] == pytest.approx(25.1)
    assert info["baseline"]["first_late_seconds"] == pytest.approx(30.5)
    for v in ("preemptive", "baseline"):
        res = proved[v][1]
        assert res.holds is False and res.counterexample is not None


def test_the_violations_replay(proved):
    for v in ("preemptive", "baseline"):
        ok, text = replay_counterexample(proved[v][1].counterexample.to_json(), load_builtin(f"ariac-{v}-timed"))
        assert ok, text
        assert "still does not hold 160 tick(s) (16 s)" in text


@pytest.mark.parametrize("variant", ["preemptive", "baseline"])
def test_the_two_phase_search_gives_the_ordinary_system(monkeypatch, variant):
    """The traced engine explores the timed models in two phases (the code graph with the
    timers' runs guessed ahead, then the numbering; docs/verification.md 5): the same
    system, field by field, as its ordinary breadth-first search, and the same figures."""
    import btfsm.verify.traced as traced
    from btfsm.verify.explore import explore
    from test_verify_traced import assert_same

    m = load_builtin(f"ariac-{variant}-timed")
    fast = explore(m, engine="traced")
    monkeypatch.setattr(traced, "_timer_slots", lambda *a: ())
    assert_same(fast, explore(m, engine="traced"))


def test_cli_prints_the_proved_worst_case(capsys, tmp_path):
    assert main(["check", "ariac-preemptive-timed", "--property", "response", "--json"]) == 1
    info = json.loads(capsys.readouterr().out)["properties"][0]["info"]["responses"]["reach"]
    assert info["worst_seconds"] == pytest.approx(26.6) and info["bound_ticks"] == 160
    out = tmp_path / "late.json"
    # grasp_conveyor is split by entry (grasp_conveyor@enable_gripper_conveyor@...): the
    # expression names its copies (positions.widen_to_copies)
    assert not any(s.id == "grasp_conveyor" for s in load_builtin("ariac-preemptive-timed").fsms[0].states)
    assert main(["bound", "ariac-preemptive-timed", "--trigger", "event:arrive", "--response",
                 "arm.state == 'grasp_conveyor'", "--within", "16", "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "worst case: 266 ticks = 26.6 s" in text
    assert "worst first late response (every earlier trigger answered within 16 s): 251 ticks = 25.1 s" in text
    assert json.loads(out.read_text())["violation"]["kind"] == "response"
    assert main(["replay", str(out), "ariac-preemptive-timed"]) == 0  # a run of the model, as it says
    assert "first holds 251 tick(s)" in capsys.readouterr().out
    assert main(["replay", str(out), "ariac-preemptive-timed", "--cell", "--pace", "phase", "--time", "60"]) == 0
    text = capsys.readouterr().out
    assert "before the arrivals' minimum interval allows a part: not sent" in text  # not a run of the cell


def _trial(args):
    from btfsm.sim.protocol import TrialSpec
    from btfsm.sim.trial import run_trial

    v, k = args
    r = run_trial(TrialSpec(v, k), model=ariac.timed(getattr(ariac, v)(n_tray=18)))
    return v, k, r.reaction_times, r.lost, r.conformance_error


def test_every_reaction_of_the_trials_is_within_the_proved_worst_case(proved):
    """The experiment's trials run the timed 18-part models in the cell: no primitive
    answers outside its derived duration (the runtime would raise a ConformanceError),
    and every measured reaction (detection to the part attached) is at most the proved
    worst-case reach plus the two grasp attempts' declared durations and their gripper
    ticks (reach ends where the grasp starts). One trial per variant (k = 1); all 80 with
    BTFSM_LONG=1 (docs/verification.md 2.1 gives their figures)."""
    table = ariac.derived_timing()["table"]
    grasp = max(hi for c, rows in table.items() if c.startswith("grasp_conveyor") for _, hi in rows.values())
    grasps = 2 * (grasp + 0.2)
    ks = range(1, 41) if os.environ.get("BTFSM_LONG") == "1" else (1,)
    jobs = [(v, k) for v in ("preemptive", "baseline") for k in ks]
    with mp.get_context("fork").Pool(2) as pool:
        results = pool.map(_trial, jobs)
    for v, k, reactions, lost, error in results:
        assert not error, (v, k, error)
        assert all(t <= proved[v][0] + grasps for t in reactions), (v, k, max(reactions))
    assert sum(r[3] for r in results if r[0] == "preemptive") == 0  # the paper's headline, with time declared


def _first_late(name):
    from btfsm.verify.explore import explore
    from btfsm.verify.properties.response import ResponseBound, counterexample

    m = load_builtin(name)
    rb = ResponseBound(explore(m), m.responses[0])
    worst, path, k = rb.first_late(160)
    return m, worst, counterexample(rb, path, k, None, "first late", 160).to_json()


def test_the_preemptive_first_late_scenario_is_not_a_run_of_the_cell():
    """Issue 21.3, measured and NOT met (docs/verification.md 2.1 decomposes the gap). The
    worst first late response (25.1 s) answers a part that arrives while the arm carries
    the previous belt part to the tray, 30 s after that part's detection: the checker got
    there by taking every earlier state's slowest run and a missed grasp. The cell, sent
    the parts at the counterexample's FSM phase (its state, as many ticks into the visit;
    the arm unpaced), is in that phase 13 s after the first part, before the arrivals'
    30 s spacing allows the second: the scenario is not a run of the cell. Sent at the
    counterexample's ticks instead, the cell reaches the second part in 8.2 s."""
    from btfsm.sim.replay import replay_in_cell

    m, worst, ce = _first_late("ariac-preemptive-timed")
    assert worst == 251
    r = replay_in_cell(m, ce, pace="phase")
    assert r.at_phase and len(r.injected) == 1 and r.too_soon and not r.lost and not r.mismatch, r.text()
    assert r.too_soon[0][0] < 30.0 and "before the arrivals' minimum interval allows a part" in r.text()
    r = replay_in_cell(m, ce, pace="times")
    assert r.at_ticks and not r.lost and not r.mismatch, r.text()
    reach = dict(r.reaches)[r.injected[-1][2]]
    assert reach == pytest.approx(8.2, abs=0.3)  # the cell; the proof says 25.1 s
    # the spacing lifted (a diagnosis): the cell in the counterexample's situation reacts in
    # 10.9 s; the decomposition says where the 14.2 s between them went
    r = replay_in_cell(m, ce, pace="phase", lift_spacing=True)
    assert len(r.injected) == 2 and not r.too_soon and not r.lost and not r.mismatch, r.text()
    assert dict(r.responses)[r.injected[-1][2]] == pytest.approx(10.9, abs=0.3)
    parts = {st: (c, x) for st, c, x in r.decomposition}
    assert sum(c for c, _ in parts.values()) == pytest.approx(25.1)
    assert parts["approach_conveyor"] == pytest.approx((10.0, 4.2), abs=0.25)
    assert parts["bins_to_conveyor"] == pytest.approx((4.0, 1.7), abs=0.25)


def test_the_baseline_first_late_scenario_loses_the_part_in_the_cell():
    """Issue 21.4: the baseline's violation is a run of the cell. Its worst first late
    response (30.5 s) starts with a part detected as the arm leaves the tray for a bin
    pick; the cell, sent the part at that phase with the arm at its own speed (unpaced,
    no outcome forced), finishes the bin pick, puts the part back to free the gripper,
    and reaches the belt only after the part rode past the end of the belt: lost, 16 s
    after its detection. The counterexample's missed grasp after the part's arrival is
    forced on the cell (the gripper lets the bin part go). The baseline's loss (the
    paper's point) is a run the checker found and the cell makes, not only a figure of
    random trials."""
    from btfsm.sim.replay import replay_in_cell

    m, worst, ce = _first_late("ariac-baseline-timed")
    assert worst == 305
    r = replay_in_cell(m, ce, pace="phase")
    assert r.at_phase and not r.too_soon and not r.mismatch, r.text()
    assert [pid for _, pid in r.lost] == [pid for _, _, pid in r.injected], r.text()
    assert 15.9 <= r.lost[0][0] - r.injected[0][0] <= 16.3 and "the cell shows the late response" in r.text()
    assert [site.split("@")[0] for _, site, out in r.forced] == ["arm/grasp_bins"]  # the counterexample's missed grasp
    # the cell's response (its next belt grasp starts) 23.4 s after the detection: the proof
    # (30.5 s) is 1.30 times it; where the 7 s went, per FSM state
    assert dict(r.responses)[r.injected[0][2]] == pytest.approx(23.4, abs=0.3)
    parts = {st: (c, x) for st, c, x in r.decomposition}
    assert sum(c for c, _ in parts.values()) == pytest.approx(30.5)
    assert parts["approach_conveyor"] == pytest.approx((4.0, 0.2), abs=0.15)
    assert parts["grasp_bins"] == pytest.approx((2.1, 1.3), abs=0.15)  # two grasps; 3.0 s before the instants' split
    assert parts["agv_to_bins"] == pytest.approx((6.3, 6.3), abs=0.15)


def test_the_cell_replay_paced_to_the_counterexample_loses_the_part():
    """Paced to the worst-case witness of the measured context-free durations
    (``timed(m, "measured")``; each FSM state lasts at least as long as in the
    counterexample: the arm waits where its move ended), the cell loses the belt part;
    unpaced, the cell's own (faster) motions pick it in time. (The derived model's witness
    does not replay paced: the cell's FSM leaves the witness's path, see
    docs/verification.md 2.1.)"""
    from btfsm.sim.replay import replay_in_cell

    m = ariac.timed(ariac.preemptive(n_tray=2), durations="measured")
    res = check(m, ["response"]).results[0]
    assert res.info["responses"]["reach"]["worst_seconds"] == pytest.approx(37.1)
    ce = res.counterexample.to_json()
    r = replay_in_cell(m, ce)
    assert r.kind == "response" and r.paced > 160 and r.held > 0
    assert [pid for _, pid in r.lost] == [pid for _, _, pid in r.injected], r.text()
    assert "the cell shows the late response" in r.text()
    t_lost, t_in = r.lost[0][0], r.injected[0][0]
    assert 15.9 <= t_lost - t_in <= 16.3  # lost at the end of the pick window
    r = replay_in_cell(m, ce, pace=False)
    assert r.lost == [] and r.paced == 0 and "does not show the late response" in r.text()


def test_pacing_holds_each_visit_at_least_as_long_as_the_counterexample():
    from btfsm.sim.replay import _Pacer

    p = _Pacer(["a", "a", "a", "b", "c", "c"])
    assert p.visits == [["a", 3], ["b", 1], ["c", 2]] and p.ticks == 5
    assert p.position(1) == (0, 0) and p.position(3) == (0, 2) and p.position(4) == (1, 0) and p.position(5) == (2, 0)
    p.now = "a"
    assert p.hold()  # the cell would leave 'a' on its first tick there: held
    p.after("a")
    assert p.hold()
    p.after("a")
    assert not p.hold()  # the third tick may leave 'a'
    p.after("a")  # the cell is slower: it stays a fourth tick, nothing to hold
    assert not p.hold()
    p.after("b")
    assert (p.v, p.c) == (1, 0) and not p.hold()
    p.after("x")  # the counterexample goes to 'c': pacing stops there
    assert p.diverged == (5, "c", "x") and not p.active() and not p.hold()


def test_the_preemptive_worst_first_arrival_in_the_cell():
    """A first arrival is a scenario the cell can always be put in (no spacing to keep):
    the preemptive model with the arrival allowed once proves 21.3 s; the cell, sent the
    part at the witness's phase, reaches it in 7.6 s (docs/verification.md 2.1: where the
    time went). Issue 21.3's 10 % is far: measured, not met. BTFSM_LONG=1 (about 10 s)."""
    import dataclasses

    from btfsm.expr import to_text
    from btfsm.sim.replay import replay_in_cell
    from btfsm.verify.explore import explore
    from btfsm.verify.properties.response import ResponseBound, counterexample
    from btfsm.world import Bool

    if os.environ.get("BTFSM_LONG") != "1":
        pytest.skip("explores and replays for about 10 s (BTFSM_LONG=1)")
    m = load_builtin("ariac-preemptive-timed")
    ev = m.environment[0]
    once = dataclasses.replace(ev, guard=f"({to_text(ev.guard)}) and not once",
                               effects=tuple(ev.effects) + (("once", "true"),))
    m = dataclasses.replace(m, variables=tuple(m.variables) + (Bool("once"),), environment=(once,))
    rb = ResponseBound(explore(m), m.responses[0])
    assert rb.worst == 213
    path, k, loop = rb.worst_witness()
    r = replay_in_cell(m, counterexample(rb, path, k, loop, "the worst first arrival", 160).to_json(), pace="phase")
    assert r.at_phase and len(r.injected) == 1 and not r.too_soon and not r.lost and not r.mismatch, r.text()
    assert dict(r.responses)[r.injected[0][2]] == pytest.approx(7.6, abs=0.3)
    parts = {st: (c, x) for st, c, x in r.decomposition}
    assert parts["approach_bins"] == pytest.approx((9.8, 2.2), abs=0.25)
