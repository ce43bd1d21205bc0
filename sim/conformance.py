"""Runtime conformance: does the scene world, driven by the runtime, behave as the checked model?

Two checks run after every tick:

* **path**: the runtime's (state before, state after) is a transition of the compiled
  transition system that ``btfsm check`` explored (``PathMonitor``);
* **abstraction**: the model's variables agree with what the world physically did (the
  binding's ``after_tick``: the scene's ``checks``; for the ARIAC models
  ``KittingBinding.abstraction_errors``: gripper contents, tray count, belt queue).

Every step the part accounting invariant is checked too (``accounting``).
``run_scenario`` runs one ARIAC scenario (variant, arrival schedule, seed, optional
gripper drop regions) in the ARIAC scene and returns the first mismatch with its tick,
or None; other models run seeded scenarios of their own scene.
"""
from __future__ import annotations

import random
from dataclasses import dataclass, field
from typing import cast

from .protocol import Mismatch

__all__ = ["PathMonitor", "Scenario", "Mismatch", "run_scenario", "random_scenarios", "Conformance",
           "conform", "variant_of", "is_kitting_model"]


class PathMonitor:
    """Checks that consecutive runtime states are transitions of an explored system."""

    def __init__(self, ts):
        import numpy as np

        if ts.kind != "model":
            raise ValueError("the path monitor needs a whole-model transition system")
        self.ts = ts
        self.slots = np.asarray(ts.slots)
        self.index = {tuple(int(v) for v in row): i for i, row in enumerate(ts.states)}
        succ: dict = {}
        for a, b in zip(ts.src.tolist(), ts.dst.tolist()):
            succ.setdefault(a, set()).add(b)
        self.succ = succ

    def _key(self, state) -> tuple:
        return tuple(state[i] for i in self.ts.slots)

    def check(self, before, after) -> "str | None":
        a, b = self.index.get(self._key(before)), self.index.get(self._key(after))
        if a is None:
            return "the state before the tick is not a reachable state of the checked model"
        if b is None:
            return "the state after the tick is not a reachable state of the checked model"
        if b not in self.succ.get(a, ()):
            return f"no transition {a} -> {b} in the checked model"
        return None


@dataclass(frozen=True)
class Scenario:
    variant: str = "preemptive"
    seed: int = 0
    detections: tuple = ()  # times (s) at which belt parts reach the sensor
    drop_regions: tuple = ()  # faulty gripper: ((x_min, y_min, x_max, y_max), ...)
    time_limit: float = 300.0
    parts: int = 18


@dataclass
class ScenarioResult:
    scenario: Scenario
    ticks: int
    completed: bool
    mismatch: "Mismatch | None" = None
    lost: int = 0
    notes: list = field(default_factory=list)


def run_scenario(scenario: Scenario, model=None, monitor: "PathMonitor | None" = None, on_tick=None) -> ScenarioResult:
    """Run the scenario in the ARIAC scene; stop at the first mismatch. ``on_tick(rt,
    world)``: called after each tick that conforms."""
    from .experiment import TrialSpec
    from .trial import run_kitting

    spec = TrialSpec(scenario.variant, 0, parts=scenario.parts, time_limit=scenario.time_limit)
    world, binding, _hooks, end = run_kitting(spec, model, seed=scenario.seed, detections=scenario.detections,
                                              faults=tuple(scenario.drop_regions), monitor=monitor,
                                              check_invariant=True, stop_at_mismatch=True, on_tick=on_tick)
    if end.mismatch is not None:
        return ScenarioResult(scenario, end.ticks, False, end.mismatch)
    return ScenarioResult(scenario, end.ticks, binding.tray_count() >= scenario.parts, None, world.lost)


def random_scenarios(n: int, seed: int = 0, variant: str = "preemptive", parts: int = 4,
                     time_limit: float = 150.0, drops: bool = False) -> list:
    """``n`` seeded random scenarios: arrival schedules, seeds, optional drop regions."""
    rng = random.Random(seed)
    out = []
    for _ in range(n):
        t, times = 17.0, []
        while t < time_limit:
            t += rng.uniform(4.0, 40.0)
            times.append(round(t, 2))
        regions: tuple = ()
        if drops and rng.random() < 0.5:
            x, y = rng.uniform(-0.2, 0.8), rng.uniform(-3.0, 0.0)
            regions = ((x, y, x + 0.15, y + 0.15),)
        out.append(Scenario(variant, rng.randrange(10**6), tuple(times), regions, time_limit, parts))
    return out


def is_kitting_model(model) -> bool:
    """True when the kitting binding of the ARIAC scene can run ``model`` (an ARIAC dialect)."""
    from .binding import dialect_of

    return dialect_of(model) is not None


def variant_of(model) -> str:
    """Which experiment variant a model is (the kitting binding runs the ARIAC models);
    UsageError naming what is missing when the kitting cell cannot run it."""
    from btfsm.errors import UsageError

    from .binding import check_outcomes, unsupported

    missing = unsupported(model)
    if missing:
        raise UsageError(f"{model.name}: the kitting cell cannot run this model ({missing})")
    check_outcomes(model)  # ModelError naming the primitive and the outcome the cell reports
    return "baseline" if model.name.endswith("baseline") or model.name == "original" else "preemptive"


@dataclass
class Conformance:
    """The outcome of ``conform``: every scenario's result, or an incomplete path check."""

    model: str
    scenarios: list
    results: list
    checked_states: "int | None" = None
    incomplete: bool = False  # exploring the model for the path monitor hit max_states

    @property
    def failed(self) -> list:
        return [r for r in self.results if r.mismatch is not None]

    @property
    def conforms(self) -> bool:
        return not self.incomplete and not self.failed

    def first_mismatch(self) -> "tuple | None":
        """(scenario index, Mismatch) of the first scenario that did not conform."""
        for i, r in enumerate(self.results):
            if r.mismatch is not None:
                return i, r.mismatch
        return None


#: Simulated seconds of each kitting-cell scenario of ``conform`` (``btfsm conform --time``'s default).
KITTING_TIME_LIMIT = 700.0


def conform(model, scenarios: int = 10, seed: int = 0, time_limit: "float | None" = KITTING_TIME_LIMIT, drops: bool = False,
            path: bool = True, max_states: "int | None" = 2_000_000, on_explored=None, on_result=None,
            scene=None, views=None) -> Conformance:
    """Run ``scenarios`` seeded random scenarios of ``model`` in the cell under the
    conformance monitor (the path check against the explored system unless ``path`` is
    false). ``on_explored(states)`` is called once the checked system is explored,
    ``on_result(index, scenario, result)`` after each scenario.

    ``scene`` (a Scene or a scene file) runs the model in that scene instead of the
    kitting cell; a model the kitting cell cannot run uses its default scene
    (``scene_trial.scene_for``) when it has one. In a scene each scenario is a seed (the
    seed of the scene's random arrivals and faults); ``time_limit`` None means the
    scene's ``time_limit`` (in the kitting cell, ``KITTING_TIME_LIMIT``); ``drops`` adds, to about half the scenarios, a fault region
    (10 cm square, drop probability 1) on the straight line between two of the scene's
    frames, where the robot is likely to carry parts. ``views(index)``: an ``on_tick(rt,
    world)`` callback for that scenario, or None (``cell_view.ConformViews``)."""
    if scene is None and not is_kitting_model(model):
        from .scene_trial import scene_for

        scene = scene_for(model)
    if scene is not None:
        return _conform_scene(model, scene, scenarios, seed, time_limit, path, max_states, on_explored, on_result,
                              drops, views)
    variant = variant_of(model)
    monitor, checked, incomplete = _explore_monitor(model, path, max_states, on_explored)
    if incomplete:
        return Conformance(model.name, [], [], None, incomplete=True)
    from .binding import Dialect, dialect_of

    parts = model.var(cast(Dialect, dialect_of(model)).tray_var).hi
    limit = KITTING_TIME_LIMIT if time_limit is None else time_limit
    cases = random_scenarios(scenarios, seed, variant, parts=parts, time_limit=limit, drops=drops)
    results = []
    for i, sc in enumerate(cases):
        res = run_scenario(sc, model, monitor, on_tick=views(i) if views is not None else None)
        results.append(res)
        if on_result is not None:
            on_result(i, sc, res)
    return Conformance(model.name, cases, results, checked)


def _explore_monitor(model, path, max_states, on_explored):
    """(monitor, checked states, incomplete) for the path check."""
    if not path:
        return None, None, False
    from btfsm.verify.explore import explore

    ts = explore(model, max_states=max_states)
    if not ts.complete:
        return None, None, True
    if on_explored is not None:
        on_explored(ts.n_states)
    return PathMonitor(ts), ts.n_states, False


def _conform_scene(model, scene, scenarios, seed, time_limit, path, max_states, on_explored, on_result,
                   drops=False, views=None):
    import copy

    from .library import bind_model
    from .scene import World, load_scene, scene_from_data
    from .scene_trial import run_scene

    if isinstance(scene, str):
        scene = load_scene(scene)
    bind_model(scene, model, World(scene))  # a binding that does not fit is an error before anything runs
    monitor, checked, incomplete = _explore_monitor(model, path, max_states, on_explored)
    if incomplete:
        return Conformance(model.name, [], [], None, incomplete=True)
    rng = random.Random(seed)
    limit = scene.time_limit if time_limit is None else time_limit
    frames = list(scene.frames.values())
    cases, scenes = [], []
    for _ in range(scenarios):
        regions, where = (), scene
        if drops and len(frames) >= 2 and rng.random() < 0.5:
            (ax, ay), (bx, by) = rng.sample(frames, 2)
            t = rng.uniform(0.2, 0.8)
            x, y = ax + (bx - ax) * t, ay + (by - ay) * t
            regions = ((round(x - 0.05, 4), round(y - 0.05, 4), round(x + 0.05, 4), round(y + 0.05, 4)),)
            data = copy.deepcopy(scene.data)
            data.setdefault("faults", {})["conform_drop"] = {"region": list(regions[0]), "probability": 1.0}
            where = scene_from_data(data, scene.file)
        cases.append(Scenario("scene", rng.randrange(10**6), (), regions, limit, 0))
        scenes.append(where)
    results = []
    for i, sc in enumerate(cases):
        run = run_scene(model, scenes[i], sc.seed, limit, monitor=monitor, check_invariant=True,
                        on_tick=views(i) if views is not None else None)
        res = ScenarioResult(sc, run.ticks, run.completed, run.mismatch, run.lost)
        results.append(res)
        if on_result is not None:
            on_result(i, sc, res)
    return Conformance(model.name, cases, results, checked)
