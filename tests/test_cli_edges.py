"""Edges of the command line found by the hostile battery (issue 18, point 6) and by
trying btfsm as a new user would (point 7): each ends with the documented exit code and
one line."""
from __future__ import annotations

import pytest

import btfsm.cli as cli
from btfsm.files import dump_model, load_model


def _err(argv, capsys):
    """(exit code, stderr) of a command that ends without SystemExit."""
    return cli.main([str(a) for a in argv]), capsys.readouterr().err


# ---------------------------------------------------------------- kitting binding: outcome sets

def _ariac_with(tmp_path, old, new):
    pytest.importorskip("numpy")
    path = tmp_path / "m.yaml"
    dump_model(load_model("ariac-preemptive"), path)
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))
    return path


@pytest.mark.parametrize("old, new, message", [
    ("  - success: {gripper_full: true}\n    name: attached\n", "  - failure: {gripper_full: true}\n    name: attached\n",
     "primitives.grasp: declares no success outcome, but the kitting binding reports success when the part attaches"),
    ("  record_pose:\n  - success: {}\n", "  record_pose:\n  - failure: {}\n",
     "primitives.record_pose: declares no success outcome"),
    ("  move:\n  - running: {}\n    name: moving\n", "  move:\n",
     "primitives.move: declares no running outcome, but the kitting binding reports running while the arm moves"),
], ids=["grasp-no-success", "record-pose-only-failure", "move-no-running"])
@pytest.mark.parametrize("command", ["sim", "conform"])
def test_kitting_binding_refuses_outcome_sets_it_cannot_serve(tmp_path, capsys, old, new, message, command):
    path = _ariac_with(tmp_path, old, new)
    code, err = _err([command, path], capsys)
    assert code == 2, err
    assert message in err and len(err.strip().splitlines()) == 1, err


def test_the_paper_models_pass_the_outcome_check():
    pytest.importorskip("numpy")
    from btfsm.sim.binding import check_outcomes
    for name in ("ariac-preemptive", "ariac-baseline", "original"):
        check_outcomes(load_model(name))  # no error


# ---------------------------------------------------------------- validate btfsm's own entry point

@pytest.mark.parametrize("ref", ["btfsm.cli:main", "btfsm.__main__:main", "btfsm.cli:_main"])
def test_validate_of_btfsms_own_command_line_is_one_line(capsys, ref):
    code, err = _err(["validate", ref], capsys)
    assert code == 2
    assert err.strip() == f"btfsm validate: error: {ref}: {ref.split(':')[1]}() is btfsm's own command line, " \
                          "not a function that returns a Model"


# ---------------------------------------------------------------- optional packages, checked first

@pytest.fixture
def without(monkeypatch):
    """without("matplotlib", ...): those packages look uninstalled to ``find_spec``; no
    trial may run (a command that checks its packages first never gets there)."""
    import importlib.util

    from btfsm.sim import experiment, sweep, trial

    real = importlib.util.find_spec

    def hide(*names):
        monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name in names else real(name, *a))

    def no_work(*a, **k):
        raise AssertionError("the command started its work before checking its packages")
    for mod, fn in ((experiment, "run_experiment"), (sweep, "run_sweep"), (trial, "run_trial")):
        monkeypatch.setattr(mod, fn, no_work)
    return hide


@pytest.mark.parametrize("argv, missing", [
    (["experiment", "--trials", "1", "--out", "{tmp}/x"], "matplotlib"),
    (["sweep", "--engine", "inline", "--out", "{tmp}/s"], "matplotlib"),
    (["sweep", "--scheduler", "tcp://127.0.0.1:1", "--out", "{tmp}/s"], "distributed"),
    (["sim", "ariac-preemptive", "--render", "{tmp}/a.png"], "matplotlib"),
    (["sim", "ariac-preemptive", "--gif", "{tmp}/a.gif"], "PIL"),
    (["replay", "{tmp}/ce.json", "ariac-preemptive", "--cell", "--render", "{tmp}/a.png"], "matplotlib"),
], ids=["experiment", "sweep", "sweep-scheduler", "sim-render", "sim-gif", "replay-render"])
def test_optional_packages_are_checked_before_any_work(tmp_path, capsys, without, argv, missing):
    pytest.importorskip("numpy")
    without(missing)
    code, err = _err([a.replace("{tmp}", str(tmp_path)) for a in argv], capsys)
    assert code == 2, err
    assert f"needs the Python package '{missing}'" in err and len(err.strip().splitlines()) == 1, err


def test_sweep_without_dask_says_it_runs_processes(tmp_path, capsys, without):
    pytest.importorskip("numpy")
    without("distributed")
    code, err = _err(["sweep", "--out", tmp_path / "s", "--workers", "2"], capsys)
    assert code == 70 and "started its work" in err  # the stub stopped the run itself
    assert "on processes (2 worker(s); Dask is not installed" in err and "Dask cluster" not in err


# ---------------------------------------------------------------- scene replay: events in time order

def test_scene_replay_prints_its_events_in_time_order():
    pytest.importorskip("numpy")
    from btfsm.sim.replay import SceneReplay

    r = SceneReplay("m", "s", ["a", "b"], injected=[(0.0, {"arm": "x"}, "a", 1), (4.3, {"arm": "y"}, "b", 2)],
                    taken=[(0.5, 1)], lost=[(0.3, 7), (4.3, 2)])
    times = [float(line.split("=")[1].split("s:")[0]) for line in r.text().splitlines() if line.startswith("  t =")]
    assert times == [0.0, 0.3, 0.5, 4.3, 4.3]
    assert r.text().index("'b' (part 2") < r.text().index("part 2 LOST")  # the injection first at a tie
