"""Run a model in a scene: the checked model drives the scene's world through the
runtime and the primitive library (``btfsm.sim.library``), with the scene's checks.

The BT ticks at the model's ``tick_rate``; between two ticks the world takes
``1 / (tick_rate * dt)`` steps. A run ends when the model's ``terminal`` predicate holds,
at the time limit, or (with ``stop_at_first``) at the first mismatch: a runtime
conformance error (an outcome or event the model does not allow), a scene check that
fails (``abstraction``), a transition the checked system does not have (``path``, when a
``PathMonitor`` is given) or a broken part accounting invariant (``accounting``).
"""
from __future__ import annotations

from btfsm.signals import check as check_signals

from dataclasses import dataclass, field

__all__ = ["SceneRun", "run_scene", "scene_for"]


@dataclass
class SceneRun:
    model: str
    scene: str
    seed: int
    ticks: int
    time: float
    completed: bool
    lost: int
    counts: dict = field(default_factory=dict)
    mismatch: "object | None" = None
    digest: str = ""


def scene_for(model, model_ref: "str | None" = None) -> "str | None":
    """The default scene of a model: ``FILE.scene.yaml`` beside its file, else a scene
    shipped with btfsm named after the model (``two-area`` -> ``models/scenes/two_area.yaml``)."""
    import os

    from .scene import builtin_scene

    if model_ref:
        path = model_ref.split(":")[0] if ".py:" in model_ref else model_ref
        stem, _ = os.path.splitext(path)
        for cand in (stem + ".scene.yaml", stem + ".scene.yml", stem + ".scene.json"):
            if os.path.isfile(cand):
                return cand
    return builtin_scene(model.name.replace("-", "_"))


def run_scene(model, scene, seed: "int | None" = None, time_limit: "float | None" = None, *,
              monitor=None, check_invariant: bool = False, on_tick=None) -> SceneRun:
    """Run ``model`` in ``scene`` (a Scene) once; the first mismatch ends the run."""
    from btfsm.errors import ConformanceError, DomainError
    from btfsm.runtime import Runtime

    from .protocol import Mismatch
    from .library import bind_model
    from .scene import World

    world = World(scene, seed)
    binding = bind_model(scene, model, world)
    rt = Runtime(model, binding.implementations())
    limit = scene.time_limit if time_limit is None else time_limit
    steps = max(1, round(1.0 / (model.tick_rate * scene.dt)))
    terminal = model.program.terminal
    ticks, mismatch, done = 0, None, False
    while world.time < limit:
        check_signals()  # an interrupt swallowed in a destructor still stops the trial
        before = rt.state
        try:
            step = rt.tick(binding.events(before))
        except (ConformanceError, DomainError) as exc:
            mismatch = Mismatch(ticks, world.time, "conformance", str(exc))
            break
        problems = binding.after_tick(rt)
        if problems:
            mismatch = Mismatch(ticks, world.time, "abstraction", "; ".join(problems))
            break
        if monitor is not None:
            why = monitor.check(before, step.state)
            if why:
                mismatch = Mismatch(ticks, world.time, "path", why)
                break
        ticks += 1
        if on_tick is not None:
            on_tick(rt, world)
        if terminal is not None and terminal(list(step.state)):
            done = True
            break
        world.step(steps)
        if check_invariant:
            try:
                world.check_invariant()
            except AssertionError as exc:
                mismatch = Mismatch(ticks, world.time, "accounting", str(exc))
                break
    counts = {name: world.count(name) for name in scene.areas}
    return SceneRun(model.name, scene.name, world.seed, ticks, round(world.time, 6), done, world.lost,
                    counts, mismatch, world.digest())
