"""The tests every binding passes, whatever binds the model to the world (the pattern of
dd's ``tests/common.py``): ``test_sim_binding.py`` runs :class:`BindingTests` once per
binding (``KittingBinding`` in the ARIAC scene, ``SceneBinding`` in the two-area scene),
each subclass saying which model, which scene and where a faulty gripper drops a part.

What is tested is the contract of ``btfsm.sim.protocol.Binding`` and of the one tick loop
(``btfsm.sim.loop.run_loop``) over it: 0-based tick numbers, the world at each tick's
time, the path and abstraction checks, a recorded interrupt, determinism.
"""
from __future__ import annotations

import signal

import pytest

from btfsm import signals
from btfsm.errors import Terminated
from btfsm.sim.library import bind_model
from btfsm.sim.loop import Hooks, run_loop, start
from btfsm.sim.protocol import Binding
from btfsm.sim.scene import World


class _Record(Hooks):
    """Every tick's number, the world's time before it and the events the model got."""

    def __init__(self, terminal=None):
        self.ticks, self.times, self.terminal = [], [], terminal

    def before(self, rt, world):
        self.ticks.append(rt.clock.tick)
        self.times.append(world.time)

    def done(self, rt, world, step):
        return self.terminal is not None and self.terminal(rt, world, step)


class _Spy:
    """A binding of its own (not a subclass) that passes the events of another on and
    records them: the loop needs nothing but the protocol."""

    def __init__(self, inner):
        self.inner, self.given = inner, []

    def implementations(self):
        return self.inner.implementations()

    def events(self, state):
        out = self.inner.events(state)
        self.given.extend(out)
        return out

    def after_tick(self, rt):
        return self.inner.after_tick(rt)


class BindingTests:
    """Subclasses set ``binding_class`` and define ``model()``, ``scene(faults=(), dt=None)``,
    ``fault`` (a region on the robot's path where a held part drops), ``time_limit``
    and ``finished(rt, world, step)`` (the run's goal is reached)."""

    binding_class: type = None
    fault: tuple = ()
    time_limit: float = 0.0

    def model(self):
        raise NotImplementedError

    def scene(self, faults=(), dt=None):
        raise NotImplementedError

    def finished(self, rt, world, step) -> bool:
        raise NotImplementedError

    def _run(self, faults=(), seed=1, **kw):
        model = self.model()
        world, binding, rt = start(self.scene(faults), model, seed, record=True)
        hooks = _Record(self.finished)
        end = run_loop(rt, world, binding, self.time_limit, hooks, **kw)
        return world, binding, rt, hooks, end

    # ---------------------------------------------------------------- the protocol
    def test_the_binding_is_declared_against_the_protocol(self):
        assert Binding in self.binding_class.__mro__  # declared, not only structurally alike
        scene = self.scene()
        b = bind_model(scene, self.model(), World(scene))
        assert type(b) is self.binding_class and isinstance(b, Binding)

    def test_implementations_are_for_model_primitives(self):
        model = self.model()
        _, binding, _ = start(self.scene(), model)
        impls = binding.implementations()
        assert impls and set(impls) <= set(model.all_primitives())
        assert all(callable(i) or callable(getattr(i, "tick", None)) for i in impls.values())

    def test_a_run_reaches_its_goal_on_the_checked_paths(self):
        """Every tick is a transition of the explored system, the binding's checks agree,
        the part accounting holds, every event given is one of the model's."""
        from btfsm.sim.conformance import PathMonitor
        from btfsm.verify.explore import explore

        model = self.model()
        world, binding, rt = start(self.scene(), model, 1)
        spy = _Spy(binding)
        hooks = _Record(self.finished)
        end = run_loop(rt, world, spy, self.time_limit, hooks, monitor=PathMonitor(explore(model)),
                       check_invariant=True)
        assert end.mismatch is None and end.reason == "done", str(end.mismatch)
        names = {ev.name for ev in model.environment}
        names |= {o.name for ev in model.environment for o in (getattr(ev, "options", None) or ())}
        assert spy.given and set(spy.given) <= names

    # ---------------------------------------------------------------- the loop over it
    def test_ticks_are_numbered_from_0_at_the_world_time_of_the_tick(self):
        world, _b, rt, hooks, end = self._run()
        n = len(hooks.ticks)
        assert hooks.ticks == list(range(n)) and end.ticks == n == rt.clock.tick
        rate, dt = rt.model.tick_rate, world.dt
        assert all(abs(t - k / rate) <= dt / 2 + 1e-9 for k, t in zip(hooks.ticks, hooks.times))
        assert world.time == pytest.approx(hooks.times[-1])  # done: the world is not stepped past the last tick

    @pytest.mark.parametrize("dt", [0.03, 0.07])  # 3.33 and 1.43 world steps per 10 Hz tick
    def test_the_world_keeps_to_the_tick_clock_whatever_its_step(self, dt):
        world, binding, rt = start(self.scene(dt=dt), self.model(), 1)
        hooks = _Record()
        end = run_loop(rt, world, binding, 20.0, hooks)
        rate = rt.model.tick_rate
        assert end.reason == "time" and hooks.ticks == list(range(end.ticks))
        assert all(abs(t - k / rate) <= dt / 2 + 1e-9 for k, t in zip(hooks.ticks, hooks.times))
        assert abs(world.time - end.ticks / rate) <= dt / 2 + 1e-9

    def test_a_dropped_part_is_an_abstraction_mismatch_at_its_tick(self):
        *_, hooks, end = self._run(faults=(self.fault,))
        m = end.mismatch
        assert end.reason == "mismatch" and m is not None and m.kind == "abstraction" and end.ended_by is m
        assert m.tick == hooks.ticks[-1] and end.ticks == m.tick + 1  # the tick ran; the run ends with it
        *_, hooks2, go_on = self._run(faults=(self.fault,), stop_at_mismatch=False)
        assert go_on.mismatch == m and go_on.ended_by is None and go_on.ticks > end.ticks  # kept, the run went on

    def test_a_recorded_interrupt_stops_the_loop_before_any_tick(self, monkeypatch):
        model = self.model()
        world, binding, rt = start(self.scene(), model, 1)
        monkeypatch.setitem(signals._state, "received", signal.SIGTERM)
        with pytest.raises(Terminated):
            run_loop(rt, world, binding, self.time_limit)
        assert rt.clock.tick == 0 and world.time == 0

    def test_same_seed_same_run(self):
        a, b = self._run(seed=5), self._run(seed=5)
        assert a[0].digest() == b[0].digest() and a[4] == b[4] and a[3].times == b[3].times
