"""The checked ARIAC model running the cell: trials, experiment harness, conformance."""
import json
import os
import subprocess
import sys

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from btfsm.sim.cli import select_ks
from btfsm.sim.conformance import Scenario, random_scenarios, run_scenario
from btfsm.sim.experiment import (TrialSpec, format_table, plot_reaction_times, run_experiment, summarize,
                            trial_specs, write_results)
from btfsm.sim.trial import build_trial, run_trial

QUICK = dict(parts=4, time_limit=200.0)


def test_trial_completes_and_conforms():
    r = run_trial(TrialSpec("preemptive", 1, **QUICK))
    assert r.completed and r.tray == 4
    assert r.conformance_error == ""
    assert r.skills >= 8  # 4 picks and 4 places at least


def test_trial_is_deterministic():
    a = run_trial(TrialSpec("baseline", 7, **QUICK))
    b = run_trial(TrialSpec("baseline", 7, **QUICK))
    assert a == b


def test_same_seed_same_cell_digests():
    digests = []
    for _ in range(2):
        seen = []
        run_trial(TrialSpec("preemptive", 3, parts=2, time_limit=80.0),
                  on_tick=lambda rt, cell: seen.append(cell.digest()) if rt.clock.tick % 50 == 0 else None)
        digests.append(seen)
    assert digests[0] == digests[1] and len(digests[0]) > 3


def test_results_independent_of_workers():
    specs = trial_specs([2, 9], ("preemptive",), **QUICK)
    one = run_experiment(specs, workers=1, progress=False)
    two = run_experiment(specs, workers=2, progress=False)
    assert one == two


def test_preemption_happens_and_baseline_does_not_preempt():
    spec = dict(parts=6, time_limit=300.0)
    pre = run_trial(TrialSpec("preemptive", 1, **spec))
    base = run_trial(TrialSpec("baseline", 1, **spec))
    assert pre.preemptions > 0 and base.preemptions == 0
    assert pre.conveyor_arrivals > 0


@pytest.mark.slow
@pytest.mark.skipif(os.environ.get("BTFSM_SLOW_DOCS") == "1",
                    reason="README's experiment transcript (tests/test_readme.py, BTFSM_SLOW_DOCS=1) runs these 12 "
                           "trials among its 80 and shows the same: completed, no conformance line, 0 / 54 lost")
def test_headline_preemptive_loses_none_baseline_loses_some():
    """The paper's headline on a spread of k values (full 18-part trials); skipped where the
    README's transcript of the whole experiment (k = 1..40) runs, in CI."""
    results = run_experiment(trial_specs([1, 8, 15, 22, 29, 36]), workers=2, progress=False)
    s = summarize(results)
    assert s["preemptive"]["lost"] == 0
    assert s["baseline"]["lost"] > 0
    assert all(r.completed and not r.conformance_error for r in results)


def test_outputs(tmp_path):
    results = run_experiment(trial_specs([1], **QUICK), workers=1, progress=False)
    csv_path, json_path = write_results(results, str(tmp_path))
    rows = json.loads(open(json_path).read())
    assert len(rows) == 2 and {r["variant"] for r in rows} == {"preemptive", "baseline"}
    assert open(csv_path).read().splitlines()[0].startswith("variant,k,seed")
    png = plot_reaction_times(results, str(tmp_path / "rt.png"))
    assert os.path.getsize(png) > 1000
    table = format_table(summarize(results))
    assert "parts lost" in table and "(paper)" in table


def test_select_ks():
    assert select_ks([], None) == list(range(1, 41))
    assert select_ks([5, 5, 2], None) == [2, 5]
    assert select_ks([], 4) == [1, 14, 27, 40]
    with pytest.raises(Exception):
        select_ks([0], None)


def test_gripper_drop_is_a_conformance_mismatch():
    """The model declares no drops: a faulty gripper shows up at the tick it happens."""
    res = run_scenario(Scenario(detections=(40.0,), drop_regions=((0.0, -2.8, 0.6, -2.5),),
                                time_limit=120, parts=4))
    assert res.mismatch is not None and res.mismatch.kind == "abstraction"
    assert "gripper_full" in res.mismatch.what


@settings(max_examples=4, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), variant=st.sampled_from(["preemptive", "baseline"]))
def test_random_scenarios_conform(seed, variant):
    """The paper's models conform in the physical cell, except where physics did something
    the model has no outcome for (the mismatch then names it; the next test is one such
    finding, since fixed in the binding)."""
    for sc in random_scenarios(1, seed, variant, parts=3, time_limit=150.0):
        res = run_scenario(sc)
        assert res.mismatch is None or "physics in the last" in res.mismatch.what, str(res.mismatch)


def test_the_cup_takes_only_the_part_it_is_sent_for():
    """Found by the test above (seed 3501, baseline): the arm descends diagonally from the
    bins' hub toward a part it has just put back, its vacuum on, and its cup used to take
    another part it passed low over (4.8 cm off-centre), which then landed beside its tray
    slot (a physics-explained mismatch at tick 921). The kitting binding now aims the cup
    at its target (``World.aim``: that part only, centred within the grasp tolerance): the
    scenario conforms and fills the tray."""
    (sc,) = random_scenarios(1, 3501, "baseline", parts=3, time_limit=150.0)
    res = run_scenario(sc)
    assert res.mismatch is None, str(res.mismatch)
    assert res.completed


@pytest.mark.parametrize("variant", ["preemptive", "baseline"])
def test_path_monitor_accepts_runtime_paths(variant):
    explore = pytest.importorskip("btfsm.verify.explore").explore
    from btfsm.models import ariac
    from btfsm.sim.conformance import PathMonitor

    model = getattr(ariac, variant)(n_tray=3)
    ts = explore(model)
    monitor = PathMonitor(ts)
    for sc in random_scenarios(2, 5, variant, parts=3, time_limit=150.0):
        res = run_scenario(sc, model, monitor)
        assert res.mismatch is None, str(res.mismatch)


def test_path_monitor_rejects_a_foreign_step():
    explore = pytest.importorskip("btfsm.verify.explore").explore
    from btfsm.models import ariac
    from btfsm.sim.conformance import PathMonitor

    model = ariac.preemptive(n_tray=2)
    monitor = PathMonitor(explore(model))
    s0 = model.program.initial
    tray = model.program.scope["tray"].index
    jumped = tuple(2 if i == tray else v for i, v in enumerate(s0))
    assert monitor.check(s0, jumped) is not None


def test_cli_experiment(tmp_path):
    out = subprocess.run([sys.executable, "-m", "btfsm.cli", "experiment", "--k", "3", "--workers", "1",
                          "--variant", "preemptive", "--out", str(tmp_path), "--quiet"],
                         capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert "parts lost" in out.stdout and "figure:" in out.stdout
    assert (tmp_path / "reaction_times.png").exists()


def test_cli_experiment_bad_k():
    out = subprocess.run([sys.executable, "-m", "btfsm.cli", "experiment", "--k", "99"],
                         capture_output=True, text=True, timeout=60)
    assert out.returncode == 2 and "Traceback" not in out.stderr


def test_conform_without_a_time_limit_uses_the_kitting_cells_default(monkeypatch):
    # time_limit=None means the scene's own limit; in the kitting cell (no scene) the default
    from btfsm.models import ariac
    from btfsm.sim import conformance

    ran = []
    monkeypatch.setattr(conformance, "run_scenario", lambda sc, *a, **k: ran.append(sc) or sc)
    out = conformance.conform(ariac.preemptive(), scenarios=2, seed=3, time_limit=None, path=False)
    assert [sc.time_limit for sc in out.scenarios] == [conformance.KITTING_TIME_LIMIT] * 2 and ran == out.scenarios
    assert out.scenarios == random_scenarios(2, 3, "preemptive", parts=ran[0].parts, time_limit=700.0)
