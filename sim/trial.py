"""One trial of the experiment: the checked ARIAC model driving the ARIAC scene.

The cell is ``models/scenes/ariac.yaml`` with the trial's parameters written into it
(:func:`ariac_scene`: the step, the belt's speed and end, the arrival times) and the
kitting binding (``btfsm.sim.binding.KittingBinding``). The BT ticks at the model's
``tick_rate`` (10 Hz) through ``btfsm.runtime.Runtime`` in the one tick loop
(``btfsm.sim.loop.run_loop``); the world steps at ``physics_rate`` (240 Hz, 24 steps per
tick). After every tick the binding's abstraction check compares the model's variables
with the world.
"""
from __future__ import annotations

from functools import lru_cache

from btfsm.bt import SkillRequest

from .loop import Hooks, run_loop, start
from .protocol import TrialResult, TrialSpec
from .scene import LOST

__all__ = ["run_trial", "run_kitting", "KittingHooks", "build_trial", "build_model", "ariac_scene", "ARIAC_SCENE"]

ARIAC_SCENE = "ariac"  # models/scenes/ariac.yaml


@lru_cache(maxsize=1)
def _ariac_data() -> dict:
    """The shipped scene's data, checked once per process (shared: never changed in place)."""
    from btfsm.files import load_data

    from .scene import builtin_scene, scene_from_data

    path = builtin_scene(ARIAC_SCENE)
    data = load_data(path, file_name=path)
    scene_from_data(data, path)
    return data


_WRITTEN = ("belts", "dt", "time_limit", "seed", "faults")  # the sections a trial writes into the scene


def ariac_scene(spec: TrialSpec, detections=None, faults=()):
    """The ARIAC scene for ``spec``: step ``1 / physics_rate``, the belt at
    ``spec.belt_speed``, its end ``pick_window`` seconds of travel past the sensor, and
    belt parts that reach the sensor every ``arrival_period`` seconds (or at the given
    ``detections`` times); ``faults``: regions where a held part drops."""
    from .scene import scene_from_data

    base = _ariac_data()
    belt = dict(base["belts"]["conveyor"])
    data = dict(base, belts=dict(base["belts"], conveyor=belt))
    beam = data["sensors"]["beam"]["region"]
    y_detect = beam[3]  # parts move towards -y: they enter the beam at its +y edge
    spawn_y = belt["from"][1]
    belt["speed"] = spec.belt_speed
    belt["to"] = [belt["from"][0], y_detect - spec.belt_speed * spec.pick_window]
    delay = (spawn_y - y_detect) / spec.belt_speed
    if detections is None:
        period = spec.arrival_period
        detections = [j * period for j in range(1, int(spec.time_limit / period) + 2)]
    belt["arrivals"] = {"schedule": [t - delay for t in detections if t >= delay]}
    data["dt"] = 1.0 / spec.physics_rate
    data["time_limit"] = spec.time_limit
    data["seed"] = spec.seed
    if faults:
        data["faults"] = {f"drop{i}": {"region": list(r), "probability": 1.0} for i, r in enumerate(faults)}
    # the shipped data was checked (``_ariac_data``): the schema checks what the trial wrote
    return scene_from_data(data, f"{ARIAC_SCENE} scene ({spec.variant} k={spec.k})", check=_WRITTEN)


def build_model(spec: TrialSpec):
    """The checked ARIAC model of ``spec``'s variant (built and compiled once per process:
    models are immutable, and every trial of a variant runs the same one)."""
    return _ariac_model(spec.variant, spec.parts)


@lru_cache(maxsize=8)
def _ariac_model(variant: str, parts: int):
    from btfsm.models import ariac

    make = {"preemptive": ariac.preemptive, "baseline": ariac.baseline}[variant]
    return make(n_tray=parts)


def build_trial(spec: TrialSpec, model=None, *, seed: "int | None" = None, detections=None, faults=(), wrap=None):
    """(model, world, binding, runtime) for a trial, ready to run; ``wrap`` wraps each
    primitive implementation (``loop.start``)."""
    model = model or build_model(spec)
    scene = ariac_scene(spec, detections, faults)
    world, binding, runtime = start(scene, model, spec.seed if seed is None else seed, record=True, wrap=wrap)
    return model, world, binding, runtime


class KittingHooks(Hooks):
    """A kitting run's counts: skills started and halted (preempted); done once the
    model's tray variable and the tray both hold ``parts``; ``on_tick(rt, world)`` after
    every tick."""

    def __init__(self, model, binding, parts: int, on_tick=None):
        prog = model.program
        self.binding, self.parts, self.on_tick = binding, parts, on_tick
        self.tray_slot = prog.scope[binding.d.tray_var].index
        self.skills = {n.name: prog.nodes[n.name].flag for n in model.nodes() if isinstance(n, SkillRequest)}
        self.starts = self.halts = 0

    def after(self, rt, world, step, before) -> None:
        skills = self.skills
        for ev in step.events:
            if ev[1] in skills:  # (most events are about other nodes)
                if ev[0] == "status" and not before[skills[ev[1]]]:
                    self.starts += 1
                elif ev[0] == "halt":
                    self.halts += 1
        if self.on_tick is not None:
            self.on_tick(rt, world)

    def done(self, rt, world, step) -> bool:
        return step.state[self.tray_slot] >= self.parts and self.binding.tray_count() >= self.parts


def run_kitting(spec: TrialSpec, model=None, *, seed: "int | None" = None, detections=None, faults=(),
                monitor=None, check_invariant: bool = False, stop_at_mismatch: bool = False, on_tick=None):
    """Run ``spec`` in the ARIAC scene: (world, binding, KittingHooks, LoopEnd)."""
    model, world, binding, rt = build_trial(spec, model, seed=seed, detections=detections, faults=faults)
    hooks = KittingHooks(model, binding, spec.parts, on_tick)
    end = run_loop(rt, world, binding, spec.time_limit, hooks, monitor=monitor, check_invariant=check_invariant,
                   stop_at_mismatch=stop_at_mismatch)
    return world, binding, hooks, end


def run_trial(spec: TrialSpec, model=None, on_tick=None) -> TrialResult:
    """Run one trial to completion (``parts`` on the tray) or to the time limit. The
    first abstraction mismatch is recorded in ``conformance_error`` and the trial goes
    on; a conformance error (the runtime refuses a tick) ends it and is recorded too."""
    world, binding, h, end = run_kitting(spec, model, on_tick=on_tick)
    error = str(end.mismatch or "")
    if end.ended_by is not None and end.ended_by is not end.mismatch:
        error += f"; then {end.ended_by}"
    return trial_result(spec, world, binding, h.starts, h.halts, end.ticks, error)


def trial_result(spec, world, binding, starts, halts, ticks, error) -> TrialResult:
    """The figures of a finished trial: reactions run from a belt part's detection to the
    step it leaves the belt in the gripper; lost parts are detected parts that were lost."""
    detected = dict(binding.detections)
    reactions = [t - detected[pid] for t, pid, src, dst in world.log
                 if src is not None and src.kind == "BELT" and dst.kind == "GRIPPER" and pid in detected]
    lost = sum(1 for pid in world.parts_in(LOST) if pid in detected)
    tray = binding.tray_count()
    return TrialResult(spec.variant, spec.k, spec.seed, tray >= spec.parts, round(world.time, 6),
                       tray, starts, halts, len(detected), len(reactions), lost,
                       [round(r, 4) for r in reactions], ticks, error)

