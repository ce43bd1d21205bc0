"""One test suite for both bindings (``binding_common.BindingTests``) and the one tick loop.

``KittingBinding`` runs the 2-part preemptive ARIAC model in the ARIAC scene (one belt
part), ``SceneBinding`` the two-area model in its scene; each class says where a faulty
gripper drops a held part on the robot's path.
"""
from __future__ import annotations

import copy
import re
import inspect

import pytest

from binding_common import BindingTests
from btfsm.errors import ModelError
from btfsm.files import load_data, load_model
from btfsm.models import ariac
from btfsm.sim import conformance, replay, scene_trial, trial
from btfsm.sim.binding import KittingBinding
from btfsm.sim.library import SceneBinding, bind_model
from btfsm.sim.protocol import TrialSpec
from btfsm.sim.scene import World, builtin_scene, scene_from_data

TWO_AREA = builtin_scene("two_area")


class TestKittingBinding(BindingTests):
    binding_class = KittingBinding
    fault = (0.0, -2.8, 0.6, -2.5)  # between the bins and the tray
    time_limit = 120.0

    def model(self):
        return ariac.preemptive(n_tray=2)

    def scene(self, faults=(), dt=None):
        spec = TrialSpec("preemptive", 1, parts=2, time_limit=self.time_limit, physics_rate=1 / dt if dt else 240.0)
        return trial.ariac_scene(spec, (20.0,), faults)

    def finished(self, rt, world, step):
        return rt.vars["tray"] >= 2 and world.count("tray") >= 2


class TestSceneBinding(BindingTests):
    binding_class = SceneBinding
    fault = (0.45, 0.3164, 0.55, 0.4164)  # on the way to the output area
    time_limit = 300.0

    def model(self):
        return load_model("two-area")

    def scene(self, faults=(), dt=None):
        data = copy.deepcopy(load_data(TWO_AREA))
        if dt:
            data["dt"] = dt
        for i, r in enumerate(faults):
            data.setdefault("faults", {})[f"drop{i}"] = {"region": list(r), "probability": 1.0}
        return scene_from_data(data, TWO_AREA)

    def finished(self, rt, world, step):
        return rt.model.program.terminal(list(step.state))


def test_the_five_runs_are_callers_of_one_loop():
    """None of them has a loop of its own: each hands its hooks to ``loop.run_loop``."""
    for fn in (trial.run_trial, conformance.run_scenario, scene_trial.run_scene, replay.replay_in_cell,
               replay.replay_in_scene):
        src = inspect.getsource(fn)
        assert "while " not in src and "world.step" not in src and "rt.tick" not in src, fn.__name__
    assert "run_loop(" in inspect.getsource(trial.run_kitting)
    for fn in (scene_trial.run_scene, replay.replay_in_cell, replay.replay_in_scene):
        assert "run_loop(" in inspect.getsource(fn), fn.__name__
    assert "run_kitting(" in inspect.getsource(trial.run_trial) + inspect.getsource(conformance.run_scenario)


def test_a_python_binding_without_the_protocol_is_refused(tmp_path, monkeypatch):
    (tmp_path / "halfbinding.py").write_text(
        "class Half:\n"
        "    def __init__(self, scene, model, world):\n"
        "        pass\n"
        "    def implementations(self):\n"
        "        return {}\n", encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    data = copy.deepcopy(load_data(TWO_AREA))
    data.pop("bind", None)
    data["binding"] = {"python": "halfbinding:Half"}
    scene = scene_from_data(data, "half.yaml")
    with pytest.raises(ModelError) as info:
        bind_model(scene, load_model("two-area"), World(scene))
    assert str(info.value) == ("half.yaml: binding.python: 'halfbinding:Half' made an object without events, "
                               "after_tick (a binding needs implementations(), events(state) and after_tick(runtime))")


def test_a_tick_the_runtime_refuses_ends_a_trial_with_its_number(monkeypatch):
    """Durations declared far too short: the runtime refuses a primitive's answer; the
    trial ends there and reports it, numbered as the runtime numbers it (0-based: the
    ticks before it ran, it did not)."""
    monkeypatch.setattr(ariac, "ARM_DURATIONS", {s: 0.3 for s in ariac.ARM_DURATIONS})
    r = trial.run_trial(TrialSpec("preemptive", 1, parts=2, time_limit=60.0),
                        ariac.timed(ariac.preemptive(n_tray=2), durations="measured"))
    m = re.match(r"tick (\d+) \(t = ([\d.]+) s\): conformance mismatch: tick (\d+): ", r.conformance_error)
    assert m, r.conformance_error
    assert m.group(1) == m.group(3) and int(m.group(1)) == r.ticks and not r.completed
    assert float(m.group(2)) == pytest.approx(r.ticks / 10) and r.sim_time == pytest.approx(r.ticks / 10)
