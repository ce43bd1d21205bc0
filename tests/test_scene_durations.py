"""Durations of a user's scene (issue 21: "a user's scene gets derived durations and a
``response`` verdict through a documented command"): ``btfsm check MODEL --timed
[--scene S]`` and ``btfsm bound MODEL --timed`` give every primitive the scene's bind
table drives a duration derived from the scene (``btfsm.sim.durations.derive_scene``).

The shipped two-area and machine-tending scenes get finite worst cases; the derived
durations contain every run the cell makes (runs of the timed model in the scene, each
run's length measured, the runtime refusing any answer outside a declared duration); a
wait the scene cannot bound is named, and a duration the model declares is kept.
"""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from btfsm.cli import main
from btfsm.files import load_data, load_model
from btfsm.sim.durations import derive_scene, measure_scene, timed_in_scene
from btfsm.sim.scene import load_scene, scene_from_data
from btfsm.timing import seconds_to_ticks

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "models" / "scenes"
MT_MODEL = str(ROOT / "models" / "examples" / "machine_tending.yaml")
CYCLE = "in_machine == 1 and not machined and held == 'none'"  # a loaded part waits for its cycle


@pytest.mark.parametrize("scene_file", ["two_area.yaml", "machine_tending.yaml"])
def test_every_primitive_that_can_run_gets_a_finite_derived_duration(scene_file):
    scene = load_scene(SCENES / scene_file)
    model = load_model(scene.model)
    table = derive_scene(model, scene)
    running = {s.index for s in model.program.sites if any(o[0] == 0 for o in s.outcomes)}
    assert set(table) == running  # every site that can answer RUNNING, and only those
    for d in table.values():
        assert d.source == "derived" and d.duration is not None and 0 <= d.duration[0] <= d.duration[1] < 10, d


def test_two_area_reach_holds_with_a_finite_worst_case(capsys):
    """A reported part is grasped (or the job is done) within 20 s: worst case 16.4 s."""
    argv = ["check", "two-area", "--timed", "--property", "response", "--trigger", "event:arrive",
            "--response", "arm.state == 'grasp_in' or placed == 3", "--within", "20"]
    assert main(argv + ["--json"]) == 0
    cap = capsys.readouterr()
    res = json.loads(cap.out)["properties"][0]
    assert res["verdict"] == "holds"
    assert res["info"]["responses"]["cli"]["worst_seconds"] == 16.4 and not res["info"]["responses"]["cli"]["unbounded"]
    # the table goes to stderr with --json
    assert "arm.grasp_in                 [0, 0.211] s  grip(wait=True): grip waits for a part: a part sensor at_end" in cap.err


def test_machine_tending_cycle_bound_and_its_counterexample(capsys, tmp_path):
    """A loaded part is machined within 12.9 s (retreat, door 1.5 s, cycle 6 s): ``bound``
    prints it; ``check --within 12`` fails with a counterexample that replays."""
    assert main(["bound", MT_MODEL, "--timed", "--trigger", CYCLE, "--response", "machined"]) == 0
    out = capsys.readouterr().out
    assert "run_cycle                  [5.9, 6.011] s  wait(seconds=6.0): waits 6 s" in out
    assert "worst case: 129 ticks = 12.9 s" in out
    assert main(["check", MT_MODEL, "--timed", "--scene", str(SCENES / "machine_tending.yaml"), "--property",
                 "response", "--trigger", CYCLE, "--response", "machined", "--within", "12",
                 "--counterexample-dir", str(tmp_path)]) == 1
    assert "the response can take 12.9 s > 12 s" in capsys.readouterr().out
    (ce,) = tmp_path.glob("*.json")
    # the counterexample is a run of the timed model (the durations are the derived ones)
    timed = timed_in_scene(load_model(MT_MODEL), load_scene(SCENES / "machine_tending.yaml"))
    from btfsm.verify.counterexample import replay_counterexample

    ok, text = replay_counterexample(str(ce), timed)
    assert ok, text


@pytest.mark.parametrize("scene_file,seeds", [("two_area.yaml", (0, 1)), ("machine_tending.yaml", (0, 1))])
def test_derived_durations_contain_every_run_of_the_cell(scene_file, seeds):
    """The timed model runs in the scene: the runtime refuses no answer, and every run of
    every site (ticks from its start to its answer) lies within the derived maximum."""
    scene = load_scene(SCENES / scene_file)
    model = load_model(scene.model)
    table = derive_scene(model, scene)
    longest, problems = measure_scene(timed_in_scene(model, scene, (), table), scene, seeds)
    assert problems == []
    assert set(table) <= set(longest)  # every timed site ran: the comparison is not vacuous
    rate = model.tick_rate
    for i, d in table.items():
        secs, (lo, hi) = longest[i], d.duration
        assert secs <= seconds_to_ticks(hi, rate) / rate, (table[i].label, secs, hi)


def test_a_wait_the_scene_cannot_bound_is_named_and_a_declared_duration_is_kept(capsys):
    """Without the sensor nothing says when a part comes under the cup: the grasp is
    unbounded (named, with what to do), so is the worst case; a duration the model
    declares on the state is kept and bounds it again."""
    data = load_data(str(SCENES / "two_area.yaml"))
    del data["sensors"]
    scene = scene_from_data(data, "no-sensor")
    model = load_model("two-area")
    table = {d.label: d for d in derive_scene(model, scene).values()}
    grasp = table["arm.grasp_in"]
    assert grasp.source == "unbounded" and grasp.duration is None
    assert "no part rests or is reported arriving at (-0.43, 0.5)" in grasp.how
    arm = model.fsm("arm")
    states = tuple(dataclasses.replace(s, duration=(0.0, 0.5)) if s.id == "grasp_in" else s for s in arm.states)
    declared = dataclasses.replace(model, fsms=(dataclasses.replace(arm, states=states),))
    table = {d.label: d for d in derive_scene(declared, scene).values()}
    assert table["arm.grasp_in"].source == "declared" and table["arm.grasp_in"].duration == (0.0, 0.5)
    assert timed_in_scene(declared, scene).fsm("arm").states[4].duration == (0.0, 0.5)


def test_bad_timed_usage_exits_2(capsys):
    assert main(["check", "two-area", "--scene", str(SCENES / "two_area.yaml")]) == 2
    assert "--scene goes with --timed" in capsys.readouterr().err
    assert main(["bound", "ariac-preemptive", "--timed", "--scene", str(SCENES / "ariac.yaml"), "--trigger",
                 "event:arrive", "--response", "arm.goal == 'none'"]) == 2
    err = capsys.readouterr().err
    assert "Python binding" in err and "Traceback" not in err


# ------------------------------------------------------------ the proved limit belt speed
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from btfsm.sim.speed_limit import grid_speeds, limit_index, limit_speed  # noqa: E402


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 80), st.data())
def test_bisection_finds_the_threshold_of_a_monotone_predicate(n, data):
    """Against a brute-force scan: the last index that holds, in at most ceil(log2(n + 1))
    checks."""
    t = data.draw(st.integers(-1, n - 1))
    i, checked = limit_index(lambda k: k <= t, n)
    assert i == max([k for k in range(n) if k <= t], default=-1)
    assert len(checked) <= (n + 1 - 1).bit_length()


@settings(max_examples=60, deadline=None)
@given(st.lists(st.booleans(), min_size=1, max_size=60))
def test_bisection_returns_a_boundary_of_any_predicate(verdicts):
    """Without monotony it still returns a boundary: the index holds (or is -1) and the
    next fails (or is the last)."""
    i, checked = limit_index(lambda k: verdicts[k], len(verdicts))
    assert i == -1 or verdicts[i]
    assert i == len(verdicts) - 1 or not verdicts[i + 1]
    assert all(verdicts[k] == v for k, v in checked.items())


def _belt_model(speed):
    """A belt part is reported (at most one every 30 s); the arm reaches it in a move whose
    slowest run depends on the belt (2 s, 0.1 m / speed to catch up, 60 s^2/m * speed to
    go along); the window is 3.2 m / speed: it holds up to 0.21 m/s."""
    from btfsm import Action, Bool, EnvEvent, Model, Primitive, ReactiveSequence, Condition, running, success
    from btfsm.timing import Response

    return Model("belt", variables=[Bool("part")],
                 primitives=[Primitive("reach", (running(), success(part="False")),
                                       duration=(0.0, round(2.0 + 0.1 / speed + 60 * speed, 3)))],
                 tree=ReactiveSequence("root", [Condition("has", "part"), Action("go", primitive="reach")]),
                 environment=[EnvEvent("arrive", "not part", {"part": "True"}, min_interval=30.0)],
                 responses=(Response("reach", "event:arrive", "not part", 3.2 / speed),), tick_rate=2.0)


def _belt_check(speed):
    from btfsm.verify.explore import explore
    from btfsm.verify.properties.response import ResponseBound

    m = _belt_model(speed)
    rb = ResponseBound(explore(m), m.responses[0])
    return rb.worst <= rb.bound_ticks(), rb.seconds(rb.worst), 3.2 / speed


def test_the_limit_speed_of_a_small_timed_model_agrees_with_a_scan():
    """The bisection over the real response check of a small timed model (its duration and
    its window both depend on the belt speed) finds the speed a brute-force scan of every
    grid speed finds: the last of the speeds that hold from the slowest."""
    speeds = grid_speeds(0.3, 0.025)
    verdicts = [_belt_check(v)[0] for v in speeds]
    scan = next((speeds[k - 1] for k in range(len(speeds)) if not verdicts[k]), speeds[-1])
    assert verdicts[0] and not verdicts[-1]  # the limit lies inside the grid
    lim = limit_speed(_belt_check, 0.3, 0.025, "belt")
    assert lim.speed == scan == 0.2 and not lim.above and len(lim.checks) <= 4
    assert "m/s (worst case" in lim.describe()


def test_sweep_limit_line_prints_the_limit_and_draws_it(tmp_path, capsys, monkeypatch):
    """``btfsm sweep --limit-line``: the bisection's result is printed under the table (the
    ARIAC check itself, a few minutes, is replaced by a fast one here)."""
    import btfsm.sim.speed_limit as sl

    fake = lambda variant, hi, step=0.005, n_tray=2: limit_speed(  # noqa: E731
        lambda v: (v <= 0.15, 10.0 * v, 3.2 / v), hi, step, variant)
    monkeypatch.setattr(sl, "proved_limit", fake)
    out = tmp_path / "sw"
    assert main(["sweep", "--belt-speed", "0.2", "--variant", "preemptive", "--time", "30", "--engine", "inline",
                 "--quiet", "--limit-line", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "proved limit belt speed, preemptive: 0.15 m/s (worst case 1.5 s <= dt* 21.33 s); at 0.155 m/s" in text
    assert (out / "lost_vs_belt_speed.png").stat().st_size > 0
