"""The one tick loop: a checked model drives a scene world through its binding.

Every run of a model in a cell goes through :func:`run_loop`: a trial of the experiment
(``trial.run_trial``), a conformance scenario (``conformance.run_scenario``), a scene run
(``scene_trial.run_scene``) and the two counterexample replays (``replay.replay_in_cell``,
``replay.replay_in_scene``). What differs between them is what they count, which are
:class:`Hooks`; the loop itself decides, once for all of them (docs/cell.md, "The tick
loop"):

* **tick numbers** are 0-based: tick ``n`` is the runtime's ``clock.tick`` when it runs,
  the ``tick`` field of its trace record and the number in the runtime's own
  ``ConformanceError`` text; it runs at world time ``n / tick_rate`` (within half a world
  step). A mismatch is reported with the number of the tick that showed it (an
  ``accounting`` mismatch: of the tick whose world steps broke the invariant).
* **world steps per tick**: after tick ``n`` the world is stepped until it has taken
  ``round((n + 1) / (tick_rate * dt))`` steps in all (:func:`steps_after`), so world time
  tracks the BT's clock without drift whatever the ratio; when the ratio is an integer
  (every shipped scene) that is the same number of steps after every tick.
* **signals**: a Ctrl-C or SIGTERM swallowed in a destructor is raised again before every
  tick (``btfsm.signals.check``).
* **order** of one tick: signals; ``hooks.before``; the binding's events; the runtime's
  tick (a ``ConformanceError`` or ``DomainError`` ends the run: the model cannot take
  the tick); the binding's ``after_tick`` (abstraction) and the path monitor (path);
  ``hooks.after``; ``hooks.done`` (ends the run without stepping the world further);
  the world's steps; the part accounting invariant (when asked).
* a run ends when ``hooks.done`` says so, at the first mismatch (unless
  ``stop_at_mismatch`` is false: then only a conformance or accounting mismatch ends it and
  the first mismatch is kept), or when the world's time reaches ``time_limit``.

``ticks`` of a run counts the ticks the runtime took: one that showed an abstraction or
path mismatch is counted (it ran), one the runtime refused is not.
"""
from __future__ import annotations

from dataclasses import dataclass

from btfsm.errors import ConformanceError, DomainError
from btfsm.signals import check as check_signals

from .protocol import Binding, Mismatch

__all__ = ["Binding", "Hooks", "LoopEnd", "run_loop", "start", "steps_after"]


class Hooks:
    """What a caller of :func:`run_loop` counts; every method may be left as it is."""

    def before(self, rt, world) -> None:
        """Before a tick (``rt.state`` is the state the tick starts from)."""

    def after(self, rt, world, step, before) -> None:
        """After a tick that the runtime took and no stopping mismatch ended; ``step`` is
        the runtime's step, ``before`` the state the tick started from; the world has not
        been stepped yet."""

    def done(self, rt, world, step) -> bool:
        """True ends the run after this tick (the world is not stepped further)."""
        return False


@dataclass
class LoopEnd:
    """How a run ended: the ticks taken, why (``done``, ``time`` or ``mismatch``), the
    first mismatch seen, and the mismatch that ended the run (None unless ``mismatch``)."""

    ticks: int
    reason: str
    mismatch: "Mismatch | None" = None
    ended_by: "Mismatch | None" = None


def steps_after(tick: int, tick_rate: float, dt: float) -> int:
    """World steps taken in all once tick ``tick`` (0-based) is over: the world's time
    then is the next tick's time, to the nearest step.

    >>> [steps_after(n, 10.0, 1 / 240) for n in range(3)]
    [24, 48, 72]
    >>> [steps_after(n, 3.0, 0.1) for n in range(3)]  # 3.33 steps per tick, no drift
    [3, 7, 10]
    """
    return round((tick + 1) / (tick_rate * dt))


def start(scene, model, seed: "int | None" = None, *, record: bool = False, wrap=None, arrivals: bool = True):
    """(world, binding, runtime) for a run of ``model`` in ``scene``: the world seeded
    with ``seed`` (the scene's seed when None), without the scene's belt arrivals unless
    ``arrivals``; ``wrap(implementation)`` wraps every implementation the binding gives."""
    from btfsm.runtime import Runtime

    from .library import bind_model
    from .scene import World

    world = World(scene, seed)
    if not arrivals:
        for name in world.arrivals:
            world.arrivals[name] = []
    binding = bind_model(scene, model, world)
    impls = binding.implementations()
    if wrap is not None:
        impls = {k: wrap(v) for k, v in impls.items()}
    return world, binding, Runtime(model, impls, record=record)


_NO_HOOKS = Hooks()


def run_loop(rt, world, binding: Binding, time_limit: float, hooks: "Hooks | None" = None, *,
             monitor=None, check_invariant: bool = False, stop_at_mismatch: bool = True) -> LoopEnd:
    """Tick ``rt`` against ``world`` through ``binding`` until ``hooks.done``, a mismatch
    or ``time_limit`` (world seconds); see the module text for the order of one tick.
    ``monitor``: an object with ``check(before, after) -> problem or None`` (the path
    check, ``conformance.PathMonitor``); ``check_invariant``: check the part accounting
    after the world steps of every tick."""
    hooks = hooks or _NO_HOOKS
    rate, dt = rt.model.tick_rate, world.dt
    per_tick = rate * dt  # (``steps_after``, inlined)
    first = rt.clock.tick
    taken = n = 0  # world steps this loop took; ticks this loop ran
    mismatch = None
    while world.time < time_limit:
        check_signals()  # an interrupt swallowed in a destructor still stops the run
        tick = rt.clock.tick
        hooks.before(rt, world)
        before = rt.state
        found: "Mismatch | None"
        try:
            step = rt.tick(binding.events(before))
        except (ConformanceError, DomainError) as exc:
            found = Mismatch(tick, world.time, "conformance", str(exc))
            return LoopEnd(rt.clock.tick - first, "mismatch", mismatch or found, found)
        problems = binding.after_tick(rt)
        found = None
        if problems:
            found = Mismatch(tick, world.time, "abstraction", "; ".join(problems))
        elif monitor is not None:
            why = monitor.check(before, step.state)
            if why:
                found = Mismatch(tick, world.time, "path", why)
        if found is not None:
            mismatch = mismatch or found
            if stop_at_mismatch:
                return LoopEnd(rt.clock.tick - first, "mismatch", mismatch, found)
        hooks.after(rt, world, step, before)
        if hooks.done(rt, world, step):
            return LoopEnd(rt.clock.tick - first, "done", mismatch)
        target = round((n + 1) / per_tick)  # steps_after(n, rate, dt)
        world.step(target - taken)
        taken, n = target, n + 1
        if check_invariant:
            try:
                world.check_invariant()
            except AssertionError as exc:
                found = Mismatch(tick, world.time, "accounting", str(exc))
                return LoopEnd(rt.clock.tick - first, "mismatch", mismatch or found, found)
    return LoopEnd(rt.clock.tick - first, "time", mismatch)
