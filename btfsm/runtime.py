"""The deterministic tick executor: the step function driven by implementations.

``Runtime`` owns an explicit clock (tick k happens at time k / tick_rate), the current
state, and the implementations bound by primitive name. Each ``tick(events)`` calls
``Program.step`` once; what the implementations answer is checked against the model's
declared outcomes (the conformance check built into every run), and the tick is written
to the trace when one is attached.

An implementation is either a callable ``impl(call) -> outcome`` or an object with
``tick(call)`` and, optionally, ``halt(call)``; ``Constant(name)`` always answers
``name``. ``call.first`` is true on the first tick of a run of that primitive at that
site; ``call.vars`` reads world variables by name.
An outcome is returned as its name, a Status (when only one outcome has it), or an index.

>>> from btfsm import Model, Int, Action, success, running
>>> m = Model("demo", variables=[Int("n", 0, 9)],
...           tree=Action("count", outcomes=[running("busy"), success(n="n + 1")]))
>>> rt = Runtime(m, {"count": lambda call: "busy" if call.first else "success"})
>>> [rt.tick().status.name for _ in range(4)], rt.vars["n"]
(['RUNNING', 'SUCCESS', 'RUNNING', 'SUCCESS'], 2)
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable, Iterable, Mapping, Sequence

from .errors import ConformanceError
from .oracles import Oracle
from .clock import Clock
from .semantics import Step
from .status import Status
from .trace import TraceWriter, render_answers, tick_record

if TYPE_CHECKING:
    from .semantics import Site

__all__ = ["Runtime", "Call", "Clock", "Constant"]

_RUNNING = int(Status.RUNNING)
_STATUS = tuple(sorted(Status, key=int))  # int status -> Status, without Status(x)
_NO_EVENTS: frozenset = frozenset()


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
    """What an implementation sees: the site, whether this is a fresh start, the time, and
    for an FSM state the goal the FSM is driven toward (``goal``, else None). ``vars``
    reads the world as it was at the start of the tick (before this tick's effects)."""

    __slots__ = ("site", "first", "vars", "time", "tick", "args", "goal")

    def __init__(self, site, first, vars, time, tick, goal=None):
        self.site, self.first, self.vars, self.time, self.tick = site, first, vars, time, tick
        self.args = site.args
        self.goal = goal


class Constant:
    """An implementation that always answers ``answer`` (an outcome name, say of an
    instant bookkeeping primitive); the runtime answers it without building a Call.

    >>> from btfsm import Model, Action, running, success
    >>> m = Model("c", tree=Action("log", outcomes=[running("busy"), success("done")]))
    >>> Runtime(m, {"log": Constant("done")}).tick().status.name
    'SUCCESS'
    """

    __slots__ = ("answer",)

    def __init__(self, answer: str):
        self.answer = answer

    def __call__(self, call) -> str:
        return self.answer


class _ImplOracle(Oracle):
    """Answers the step function from implementations and observed events.

    One per Runtime, reset each tick (no per-tick allocation); it caches, per site, the
    outcome index of each outcome name so a named answer costs one dict lookup."""

    __slots__ = ("rt", "events", "used", "names", "log", "goals")

    def __init__(self, rt, events=frozenset()):
        self.rt, self.events, self.used = rt, events, set()
        self.names: dict = {}  # site index -> {outcome name: index}
        self.log = None  # list of outcome indices this tick (deferred tracing)
        self.goals: dict = {}  # FSM name -> goal it is driven toward now

    def reset(self, events):
        self.events = events
        if self.used:
            self.used = set()

    def env(self, i: int) -> bool:
        name = self.rt.program.env[i][0]
        if name in self.events:
            self.used.add(name)
            return True
        return False

    def request(self, fsm_index, goal_index):
        f = self.rt.program.fsm_info[fsm_index][0]
        self.goals[f.name] = f.goals[goal_index]

    def choose(self, i: int | tuple[Any, ...], enabled: Sequence[Any]) -> int:
        name, _, _, options = self.rt.program.env[i]
        seen = [k for k, opt in enumerate(enabled) if options[opt][0] in self.events]
        if not seen and len(enabled) == 1:
            return 0  # the only enabled option happens whether a sensor reports it or not
        if len(seen) != 1:
            names = ", ".join(options[opt][0] for opt in enabled)
            raise ConformanceError(f"tick {self.rt.clock.tick}: choice '{name}' needs exactly one observed option of ({names})")
        self.used.add(options[enabled[seen[0]]][0])
        return seen[0]

    def outcome(self, site: Site) -> int:
        k: Any
        rt = self.rt
        impl = rt.implementations.get(site.primitive)
        if impl is None:
            if len(site.outcomes) == 1:
                k = 0
            elif rt.fallback is None:
                raise ConformanceError(f"{site.label}: primitive '{site.primitive}' has {len(site.outcomes)} outcomes and no implementation")
            else:
                k = rt.fallback.outcome(site)
            if self.log is not None:
                self.log.append(k)
            return k
        index, busy = site.index, rt._busy
        if type(impl) is Constant:
            answer = impl.answer
        else:
            clock = rt.clock
            call = Call(site, index not in busy, rt._view, clock.time, clock.tick,
                        self.goals.get(site.fsm) if site.fsm is not None else None)
            answer = impl(call) if callable(impl) else impl.tick(call)
        k = None
        if type(answer) is str:  # the common case: an outcome name
            names = self.names.get(index)
            if names is None:
                names = self.names[index] = {o[2]: j for j, o in enumerate(site.outcomes)}
            k = names.get(answer)
        if k is None:
            k = _outcome_index(site, answer)  # Status, index, or an error
        if site.outcomes[k][0] == _RUNNING:
            busy.add(index)
        else:
            busy.discard(index)
        if self.log is not None:
            self.log.append(k)
        return k

    def halt(self, site: Site) -> None:
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


class _Ask:
    """A question the step function asked (``ask(*args)``, a method of the runtime's
    oracle) and what came next after each answer (``_Ask`` or ``_Done``)."""

    __slots__ = ("ask", "args", "next")

    def __init__(self, ask, args):
        self.ask, self.args, self.next = ask, args, {}


class _Done:
    """What the step function returned after the answers on the path to it."""

    __slots__ = ("state", "status", "events", "violations")

    def __init__(self, step):
        self.state, self.status, self.violations = step.state, step.status, tuple(step.violations)
        self.events = None if step.events is None else tuple(step.events)


class _Tape:
    """The oracle a memoized tick gives the step function: it answers the first questions
    with ``given`` (the answers the live oracle already gave while the memo was followed),
    asks the live oracle the rest, and logs every question with its answer."""

    __slots__ = ("live", "given", "log", "request")

    def __init__(self, live, given):
        self.live, self.given, self.log = live, given, []
        if hasattr(live, "request"):
            self.request = self._request

    def _ask(self, ask, args):
        i = len(self.log)
        answer = self.given[i] if i < len(self.given) else ask(*args)
        self.log.append((ask, args, answer))
        return answer

    def env(self, i):
        return self._ask(self.live.env, (i,))

    def choose(self, i, enabled):
        return self._ask(self.live.choose, (i, enabled))

    def outcome(self, site):
        return self._ask(self.live.outcome, (site,))

    def halt(self, site):
        return self._ask(self.live.halt, (site,))

    def _request(self, fsm_index, goal_index):
        return self._ask(self.live.request, (fsm_index, goal_index))


class Runtime:
    """Runs a model tick by tick.

    ``implementations``: primitive name -> implementation. ``fallback``: an oracle for
    nondeterministic primitives without implementation (e.g. ``RandomOracle(seed)``);
    without one they are an error. ``trace``: a path or text stream for JSON Lines.

    ``trace_mode="deferred"`` (default) keeps only each tick's answers (observed events,
    outcome indices) while running and writes the full records by re-running the pure
    step function every ``flush_every`` ticks and on ``close()``: the same file as
    ``"live"``, which builds and writes each record during the tick. ``record=True``
    makes every step keep its events (``runtime.last.events``); ``runtime.last_record``
    is the trace record of the last tick when the trace is written live (else None: a
    record costs a tenth of a cell trial's runtime, and the cell loops read the events).
    """

    FLUSH_EVERY = 4096
    MEMO_STATES = 4096  # states whose ticks are memoized (``_step``); later ones are not

    def __init__(self, model, implementations: "Mapping | None" = None, *, fallback=None,
                 trace=None, state=None, record: "bool | None" = None, trace_mode: str = "deferred"):
        self.model = model
        self.program = model.program
        self.implementations = dict(implementations or {})
        self.fallback = fallback
        self.clock = Clock(model.tick_rate)
        self.state = tuple(state) if state is not None else self.program.initial
        self._live = self.state
        self._busy: set = set()
        self._view = _VarView(self)
        self._var_slots = tuple((v.name, self.program.scope[v.name].index) for v in self.model.variables)
        self.trace = None
        if trace_mode not in ("deferred", "live"):
            raise ValueError("trace_mode must be 'deferred' or 'live'")
        if trace is not None:
            self.trace = trace if isinstance(trace, TraceWriter) else TraceWriter(trace, self.program, self.state)
        self.deferred = self.trace is not None and trace_mode == "deferred"
        self.record = (self.trace is not None and not self.deferred) if record is None else record
        self._last_status: dict = {}
        self._oracle = _ImplOracle(self)
        self._memo: dict = {}  # state -> _Ask or _Done: the ticks taken from that state (``_step``)
        self._answers: list = []
        self._render_from: tuple = (self.state, 0, {})  # state, tick and statuses where rendering resumes
        self.last = None
        self.last_record: "dict | None" = None

    @property
    def vars(self) -> dict:
        """World variables of the current state, by name."""
        decode, state = self.program.decode_slot, self.state
        return {name: decode(i, state[i]) for name, i in self._var_slots}

    def fsm_state(self, fsm: str) -> tuple:
        """(state id, held goal or None) of an FSM now."""
        return self.program.fsm_state(self.state, fsm)

    def tick(self, events: Iterable[str] = ()):
        """One tick. ``events``: names of environment events observed since the last tick."""
        if isinstance(events, str):
            raise TypeError("events is a collection of event names, not one string")
        events = frozenset(events) if events else _NO_EVENTS
        oracle = self._oracle
        oracle.reset(events)
        if self.deferred:
            oracle.log = []
        self._live = self.state
        step = self._step(self.state, oracle)
        if step.state is None:
            v = step.violations[0]
            if v[0] == "timing":  # an answer outside a declared duration (docs/semantics.md section 6.1)
                raise ConformanceError(f"tick {self.clock.tick}: {v[2]} (the declared duration)")
            raise ConformanceError(f"tick {self.clock.tick}: environment choice '{v[1]}' has no "
                                   "enabled option: the model cannot take this tick")
        if events:
            unknown = events - oracle.used
            if unknown:
                raise ConformanceError(f"tick {self.clock.tick}: observed event(s) {sorted(unknown)} not enabled by the model in this state")
        record = None
        if self.record and self.trace is not None and not self.deferred:  # only a live trace needs the record
            record = tick_record(self.program, self.clock, step, self._last_status)
            self.trace.write(record)
        if self.deferred:
            self._answers.append((events, oracle.log))
            if len(self._answers) >= self.FLUSH_EVERY:
                self.flush_trace()
        self.state = self._live = step.state
        self.clock.tick += 1
        self.last = step
        step.status = _STATUS[step.status]
        self.last_record = record
        return step

    def _step(self, state, oracle):
        """``Program.step(state, oracle, self.record)``, memoized. The step function is pure
        in the state and the oracle's answers, and which question it asks next depends only
        on them: so a tick from a state seen before asks the live oracle the questions that
        tick asked (the implementations run as they would, in the same order), and while
        every answer is one seen before, the result is the one recorded then; at the first
        new answer the step function runs on from the answers given so far. A cell trial
        starts most ticks from the state of the tick before (an arm that moves, a part on
        its way); the memo keeps the ticks of the first ``MEMO_STATES`` states."""
        memo = self._memo
        node = memo.get(state)
        given: list = []
        if node is None:
            if len(memo) >= self.MEMO_STATES:
                return self.program.step(state, oracle, self.record)
        else:
            while type(node) is _Ask:
                answer = node.ask(*node.args)
                given.append(answer)
                node = node.next.get(answer)
            if node is not None:
                return Step(node.state, node.status, None if node.events is None else list(node.events),
                            list(node.violations))
        tape = _Tape(oracle, given)
        step = self.program.step(state, tape, self.record)
        self._remember(state, tape.log, step)
        return step

    def _remember(self, state, log, step) -> None:
        """Put the path of questions and answers ``log`` that led to ``step`` into the memo."""
        done = _Done(step)
        if not log:
            self._memo[state] = done
            return
        node = self._memo.get(state)
        if node is None:
            node = self._memo[state] = _Ask(log[0][0], log[0][1])
        for j, (_ask, _args, answer) in enumerate(log):
            if type(node) is not _Ask:
                return  # not the path seen before (an oracle whose questions are not repeatable): keep the old
            nxt = node.next.get(answer)
            if nxt is None:
                nxt = node.next[answer] = done if j + 1 == len(log) else _Ask(log[j + 1][0], log[j + 1][1])
            node = nxt

    def run(self, ticks: int, events: "Callable[[Runtime], Iterable[str]] | None" = None):
        """Tick ``ticks`` times; ``events(runtime)`` supplies each tick's observed events."""
        step = None
        for _ in range(ticks):
            step = self.tick(events(self) if events else ())
        return step

    def flush_trace(self):
        """Write the records of the ticks logged so far (deferred mode)."""
        if not self.deferred or not self._answers:
            return
        state, tick, last = self._render_from
        state, last = render_answers(self.program, state, self._answers, self.trace, tick, last)
        self._render_from = (state, tick + len(self._answers), last)
        self._answers = []

    def close(self):
        if self.trace is not None:
            self.flush_trace()
            self.trace.close()
