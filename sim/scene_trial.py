"""Run a model in a scene: the checked model drives the scene's world through the
runtime and the primitive library (``btfsm.sim.library``), with the scene's checks.

The BT ticks at the model's ``tick_rate`` in the one tick loop (``btfsm.sim.loop``:
0-based tick numbers, the world stepped to the next tick's time). A run ends when the model's ``terminal`` predicate holds,
at the time limit, or (with ``stop_at_first``) at the first mismatch: a runtime
conformance error (an outcome or event the model does not allow), a scene check that
fails (``abstraction``), a transition the checked system does not have (``path``, when a
``PathMonitor`` is given) or a broken part accounting invariant (``accounting``).
"""
from __future__ import annotations

from dataclasses import dataclass, field

from .loop import Hooks, run_loop, start

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


class _SceneHooks(Hooks):
    def __init__(self, terminal, on_tick):
        self.terminal, self.on_tick = terminal, on_tick

    def after(self, rt, world, step, before) -> None:
        if self.on_tick is not None:
            self.on_tick(rt, world)

    def done(self, rt, world, step) -> bool:
        return self.terminal is not None and self.terminal(list(step.state))


def run_scene(model, scene, seed: "int | None" = None, time_limit: "float | None" = None, *,
              monitor=None, check_invariant: bool = False, on_tick=None) -> SceneRun:
    """Run ``model`` in ``scene`` (a Scene) once; the first mismatch ends the run."""
    world, binding, rt = start(scene, model, seed)
    limit = scene.time_limit if time_limit is None else time_limit
    end = run_loop(rt, world, binding, limit, _SceneHooks(model.program.terminal, on_tick), monitor=monitor,
                   check_invariant=check_invariant)
    counts = {name: world.count(name) for name in scene.areas}
    return SceneRun(model.name, scene.name, world.seed, end.ticks, round(world.time, 6), end.reason == "done",
                    world.lost, counts, end.mismatch, world.digest())
