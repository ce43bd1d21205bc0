"""Structured traces (JSON Lines) and their exact replay.

Line 1 is a header ``{"format": "btfsm-trace/1", "model": ..., "tick_rate": ...,
"initial": {...}}``. Then one object per tick:

``tick``, ``time``, ``status`` (root), ``env`` (events that happened), ``outcomes``
([site, outcome] in the order primitives ran), ``changes`` ({node: status} for nodes whose
status changed, ``"halted"`` for halted ones), ``fired`` ([fsm, edge or marker id]),
``fsm`` ({name: [state, goal]}), ``writes`` ({variable: value}), ``violations``.

``replay(lines, model)`` re-runs the model answering every choice from the trace and
returns the first tick whose regenerated record differs (None when all agree).
"""
from __future__ import annotations

import io
import json
from typing import Iterable

from .clock import Clock
from .status import Status

__all__ = ["TraceWriter", "tick_record", "read_trace", "replay", "ReplayOracle", "AnswerOracle",
           "render_answers", "FORMAT"]

FORMAT = "btfsm-trace/1"
_NAMES = ("RUNNING", "SUCCESS", "FAILURE")


def _slot_names(program) -> tuple:
    """(name, decode) per slot, computed once per program."""
    cached = program.__dict__.get("_trace_slots")
    if cached is None:
        cached = tuple((info.name, (lambda v, i=i: program.decode_slot(i, v))) for i, info in enumerate(program.slots))
        program._trace_slots = cached
    return cached


def tick_record(program, clock, step, last_status: dict) -> dict:
    """The trace object of one tick (``last_status`` is updated in place)."""
    env, outcomes, fired, writes, changes, violations = [], [], [], {}, {}, []
    slots = _slot_names(program)
    get = last_status.get
    for ev in step.events or ():
        kind = ev[0]
        if kind == "status":
            name, st = ev[1], _NAMES[ev[2]]
            if get(name) != st:
                changes[name] = st
                last_status[name] = st
        elif kind == "outcome":
            outcomes.append([ev[1], ev[2]])
        elif kind == "write":
            name, decode = slots[ev[1]]
            writes[name] = decode(ev[2])
        elif kind == "halt":
            changes[ev[1]] = "halted"
            last_status[ev[1]] = "halted"
        elif kind == "fire":
            fired.append([ev[1], ev[2]])
        elif kind == "env":
            env.append(ev[1])
        elif kind in ("violation", "busy"):
            violations.append([kind, ev[1], ev[2]])
        elif kind in ("not-applicable", "withdraw"):
            fired.append([ev[1], f"<{kind}>"])
    fsm = {}
    s = step.state
    for f, ids, tok, goal, _ in program.fsm_info:
        fsm[f.name] = [ids[s[tok]], f.goals[s[goal] - 1] if s[goal] else None]
    return {"tick": clock.tick, "time": round(clock.time, 9), "status": _NAMES[step.status], "env": env,
            "outcomes": outcomes, "changes": changes, "fired": fired, "fsm": fsm, "writes": writes,
            "violations": violations}


class TraceWriter:
    """Writes a header and tick records as JSON Lines to a path or a text stream."""

    def __init__(self, target, program, initial_state):
        self._own = not hasattr(target, "write")
        self.out = open(target, "w", encoding="utf-8") if self._own else target
        header = {"format": FORMAT, "model": program.model.name, "tick_rate": program.model.tick_rate,
                  "initial": _jsonable(program.decode(initial_state))}
        self.out.write(json.dumps(header) + "\n")

    def write(self, record: dict) -> None:
        self.out.write(json.dumps(record) + "\n")

    def close(self) -> None:
        if self._own:
            self.out.close()
        else:
            self.out.flush()


def _jsonable(d: dict) -> dict:
    return {k: (v if isinstance(v, (bool, int, str)) or v is None else str(v)) for k, v in d.items()}


def read_trace(source) -> tuple[dict, list]:
    """(header, tick records) from a path, a text stream or a list of lines."""
    if isinstance(source, (list, tuple)):
        lines = list(source)
    elif hasattr(source, "read"):
        lines = source.read().splitlines()
    else:
        with open(source, encoding="utf-8") as fh:
            lines = fh.read().splitlines()
    objs = [json.loads(line) for line in lines if line.strip()]
    if not objs or objs[0].get("format") != FORMAT:
        raise ValueError(f"not a {FORMAT} trace (first line must be its header)")
    return objs[0], objs[1:]


class _NamedEvents:
    """Environment answers by event name, for oracles that replay what was recorded.
    Replay drives no implementation, so there is nothing to halt."""

    def env(self, i):
        return self.program.env[i][0] in self.events

    def _named(self, i, enabled):
        options = self.program.env[i][3]
        return next((k for k, opt in enumerate(enabled) if options[opt][0] in self.events), None)

    def halt(self, site):
        return None


class ReplayOracle(_NamedEvents):
    """Answers from one tick record: events by name, outcomes in recorded order."""

    def __init__(self, program, record: dict):
        self.program = program
        self.events = set(record.get("env", ()))
        self.outcomes = list(record.get("outcomes", ()))
        self.pos = 0
        self.error = None

    def choose(self, i, enabled):
        k = self._named(i, enabled)
        if k is None:
            self.error = f"choice '{self.program.env[i][0]}': the trace names none of its enabled options"
            return 0
        return k

    def outcome(self, site):
        if self.pos >= len(self.outcomes):
            self.error = f"{site.label} ran but the trace records no more outcomes"
            return 0
        label, name = self.outcomes[self.pos]
        self.pos += 1
        if label != site.label:
            self.error = f"{site.label} ran where the trace has {label}"
        for k, o in enumerate(site.outcomes):
            if o[2] == name:
                return k
        self.error = f"{site.label}: outcome '{name}' is not declared"
        return 0


class AnswerOracle(_NamedEvents):
    """Answers from an answer log entry: the observed event names and, in order, the
    outcome indices the primitives had (what ``Runtime`` keeps in deferred trace mode)."""

    __slots__ = ("program", "events", "it")

    def __init__(self, program, events, outcome_indices):
        self.program, self.events, self.it = program, events, iter(outcome_indices)

    def choose(self, i, enabled):
        k = self._named(i, enabled)
        return 0 if k is None else k  # a lone option may go unreported: it is forced

    def outcome(self, site):
        return next(self.it)


def render_answers(program, initial, answers, writer: "TraceWriter", first_tick: int = 0, last_status=None):
    """Write the tick records of an answer log by re-running the pure step function.
    Returns (state, last_status) after the last tick, to continue rendering later."""
    s, clock = tuple(initial), Clock(program.model.tick_rate, first_tick)
    last = {} if last_status is None else last_status
    for events, outcome_indices in answers:
        step = program.step(s, AnswerOracle(program, events, outcome_indices), True)
        writer.write(tick_record(program, clock, step, last))
        s = step.state
        clock.tick += 1
    return s, last


def replay(source, model, state=None) -> "tuple[int, str] | None":
    """Re-run a trace; return ``(tick, why)`` at the first difference, or None."""
    header, records = read_trace(source)
    program = model.program
    if header.get("model") != model.name:
        return (0, f"trace is of model '{header.get('model')}', not '{model.name}'")
    if state is None:
        try:
            state = program.encode(header.get("initial") or {})
        except (KeyError, ValueError, IndexError) as exc:
            return (0, f"the trace's initial state does not fit this model ({exc})")
    s = tuple(state)
    clock, last = Clock(model.tick_rate), {}
    for rec in records:
        oracle = ReplayOracle(program, rec)
        step = program.step(s, oracle, True)
        if oracle.error:
            return (rec["tick"], oracle.error)
        mine = tick_record(program, clock, step, last)
        if mine != rec:
            diff = sorted(k for k in rec if mine.get(k) != rec.get(k))
            return (rec["tick"], f"regenerated record differs in {', '.join(diff)}")
        s = step.state
        clock.tick += 1
    return None
