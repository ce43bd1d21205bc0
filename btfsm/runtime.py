"""The deterministic tick executor: the step function driven by implementations.

``Runtime`` owns an explicit clock (tick k happens at time k / tick_rate), the current
state, and the implementations bound by primitive name. Each ``tick(events)`` calls
``Program.step`` once; what the implementations answer is checked against the model's
declared outcomes (the conformance check built into every run), and the tick is written
to the trace when one is attached.

An implementation is either a callable ``impl(call) -> outcome`` or an object with
``tick(call)`` and, optionally, ``halt(call)``. ``call.first`` is true on the first tick
of a run of that primitive at that site; ``call.vars`` reads world variables by name.
An outcome is returned as its name, a Status (when only one outcome has it), or an index.

>>> from btfsm import Model, Int, Action, success, running
>>> m = Model("demo", variables=[Int("n", 0, 9)],
...           tree=Action("count", outcomes=[running("busy"), success(n="n + 1")]))
>>> rt = Runtime(m, {"count": lambda call: "busy" if call.first else "success"})
>>> [rt.tick().status.name for _ in range(4)], rt.vars["n"]
(['RUNNING', 'SUCCESS', 'RUNNING', 'SUCCESS'], 2)
"""
from __future__ import annotations

from typing import Callable, Iterable, Mapping

from .errors import ConformanceError
from .status import Status
from .trace import TraceWriter, tick_record

__all__ = ["Runtime", "Call", "Clock"]


class Clock:
    """Explicit time: ``tick`` counts ticks, ``time`` is ``tick / rate`` seconds."""

    __slots__ = ("rate", "tick")

    def __init__(self, rate: float, tick: int = 0):
        self.rate, self.tick = float(rate), tick

    @property
    def time(self) -> float:
        return self.tick / self.rate


class _VarView(Mapping):
    """Read-only world variables of the current state, by name, as user values."""

    __slots__ = ("_rt",)

    def __init__(self, rt):
        self._rt = rt

    def __getitem__(self, name):
        prog = self._rt.program
        slot = prog.scope[name]
        return prog.decode_slot(slot.index, self._rt._live[slot.index])

    def __iter__(self):
        return iter(v.name for v in self._rt.program.model.variables)

    def __len__(self):
        return len(self._rt.program.model.variables)


class Call:
    """What an implementation sees: the site, whether this is a fresh start, the time."""

    __slots__ = ("site", "first", "vars", "time", "tick", "args")

    def __init__(self, site, first, vars, time, tick):
        self.site, self.first, self.vars, self.time, self.tick = site, first, vars, time, tick
        self.args = site.args


class _ImplOracle:
    """Answers the step function from implementations and observed events."""

    def __init__(self, rt, events):
        self.rt, self.events, self.used = rt, events, set()

    def env(self, i):
        name = self.rt.program.env[i][0]
        if name in self.events:
            self.used.add(name)
            return True
        return False

    def choose(self, i, enabled):
        name, _, _, options = self.rt.program.env[i]
        seen = [k for k, opt in enumerate(enabled) if options[opt][0] in self.events]
        if len(seen) != 1:
            names = ", ".join(options[opt][0] for opt in enabled)
            raise ConformanceError(f"tick {self.rt.clock.tick}: choice '{name}' needs exactly one observed option of ({names})")
        self.used.add(options[enabled[seen[0]]][0])
        return seen[0]

    def outcome(self, site):
        rt = self.rt
        impl = rt.implementations.get(site.primitive)
        if impl is None:
            if len(site.outcomes) == 1:
                return 0
            if rt.fallback is None:
                raise ConformanceError(f"{site.label}: primitive '{site.primitive}' has {len(site.outcomes)} outcomes and no implementation")
            return rt.fallback.outcome(site)
        first = site.index not in rt._busy
        call = Call(site, first, rt._view, rt.clock.time, rt.clock.tick)
        answer = impl(call) if callable(impl) else impl.tick(call)
        k = _outcome_index(site, answer)
        if site.outcomes[k][0] == Status.RUNNING:
            rt._busy.add(site.index)
        else:
            rt._busy.discard(site.index)
        return k

    def halt(self, site):
        rt = self.rt
        if site.index in rt._busy:
            rt._busy.discard(site.index)
            impl = rt.implementations.get(site.primitive)
            stop = getattr(impl, "halt", None)
            if stop is not None:
                stop(Call(site, False, rt._view, rt.clock.time, rt.clock.tick))


def _outcome_index(site, answer) -> int:
    outs = site.outcomes
    if isinstance(answer, Status):
        ks = [k for k, o in enumerate(outs) if o[0] == answer]
        if len(ks) == 1:
            return ks[0]
        what = "none" if not ks else "several"
        raise ConformanceError(f"{site.label}: '{site.primitive}' returned {answer.name}; {what} of its declared outcomes "
                               f"({', '.join(o[2] for o in outs)}) have that status")
    if isinstance(answer, str):
        for k, o in enumerate(outs):
            if o[2] == answer:
                return k
        raise ConformanceError(f"{site.label}: '{site.primitive}' returned '{answer}', not a declared outcome "
                               f"({', '.join(o[2] for o in outs)})")
    if isinstance(answer, int) and not isinstance(answer, bool) and 0 <= answer < len(outs):
        return answer
    raise ConformanceError(f"{site.label}: '{site.primitive}' returned {answer!r}, not an outcome")


class Runtime:
    """Runs a model tick by tick.

    ``implementations``: primitive name -> implementation. ``fallback``: an oracle for
    nondeterministic primitives without implementation (e.g. ``RandomOracle(seed)``);
    without one they are an error. ``trace``: a path or text stream for JSON Lines.
    """

    def __init__(self, model, implementations: "Mapping | None" = None, *, fallback=None,
                 trace=None, state=None, record: "bool | None" = None):
        self.model = model
        self.program = model.program
        self.implementations = dict(implementations or {})
        self.fallback = fallback
        self.clock = Clock(model.tick_rate)
        self.state = tuple(state) if state is not None else self.program.initial
        self._live = self.state
        self._busy: set = set()
        self._view = _VarView(self)
        self.trace = None
        if trace is not None:
            self.trace = trace if isinstance(trace, TraceWriter) else TraceWriter(trace, self.program, self.state)
        self.record = self.trace is not None if record is None else record
        self._last_status: dict = {}
        self.last = None

    @property
    def vars(self) -> dict:
        """World variables of the current state, by name."""
        d = self.program.decode(self.state)
        return {v.name: d[v.name] for v in self.model.variables}

    def fsm_state(self, fsm: str) -> tuple:
        """(state id, held goal or None) of an FSM now."""
        return self.program.fsm_state(self.state, fsm)

    def tick(self, events: Iterable[str] = ()):
        """One tick. ``events``: names of environment events observed since the last tick."""
        events = set(events)
        oracle = _ImplOracle(self, events)
        self._live = self.state
        step = self.program.step(self.state, oracle, self.record)
        unknown = events - oracle.used
        if unknown:
            raise ConformanceError(f"tick {self.clock.tick}: observed event(s) {sorted(unknown)} not enabled by the model in this state")
        record = None
        if self.record:
            record = tick_record(self.program, self.clock, step, self._last_status)
            if self.trace is not None:
                self.trace.write(record)
        self.state = self._live = step.state
        self.clock.tick += 1
        self.last = step
        step.status = Status(step.status)
        self.last_record = record
        return step

    def run(self, ticks: int, events: "Callable[[Runtime], Iterable[str]] | None" = None):
        """Tick ``ticks`` times; ``events(runtime)`` supplies each tick's observed events."""
        step = None
        for _ in range(ticks):
            step = self.tick(events(self) if events else ())
        return step

    def close(self):
        if self.trace is not None:
            self.trace.close()
