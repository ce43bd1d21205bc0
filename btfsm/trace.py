"""Structured traces (JSON Lines) and their exact replay.

Line 1 is a header ``{"format": "btfsm-trace/1", "model": ..., "tick_rate": ...,
"initial": {...}}``. Then one object per tick:

``tick``, ``time``, ``status`` (root), ``env`` (events that happened), ``outcomes``
([site, outcome] in the order primitives ran), ``changes`` ({node: status} for nodes whose
status changed, ``"halted"`` for halted ones), ``fired`` ([fsm, edge or marker id]),
``fsm`` ({name: [state, goal]}), ``writes`` ({variable: value}), ``violations``.

The format is written down as a JSON Schema, ``btfsm/schema/trace.schema.json``
(``$defs/header``, ``$defs/record``). ``read_trace`` checks every line against it and the
ticks for being consecutive from 0; a file that does not follow the format raises a
``btfsm.formats.FormatError`` naming the file, the line, the field and the problem.

``replay(lines, model)`` re-runs the model answering every choice from the trace and
returns the first tick whose regenerated record differs (None when all agree).

A trace written to a path goes to a temporary name in the same folder and is renamed
when the writer is closed, so a run that fails half-way leaves no half-written file
(a FIFO, a device such as ``/dev/stdout``, is written directly).
"""
from __future__ import annotations

import json
import os
from typing import TYPE_CHECKING, Any, Sequence

from .clock import Clock
from .outputs import atomic_writer
from .errors import DomainError
from .formats import FormatError, decode_utf8, parse_json, printable, validate
from .oracles import Oracle

if TYPE_CHECKING:
    from .semantics import Site

__all__ = ["TraceWriter", "tick_record", "read_trace", "replay", "ReplayOracle", "AnswerOracle",
           "render_answers", "FORMAT", "FormatError"]

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
    """Writes a header and tick records as JSON Lines to a path or a text stream.

    A path is written under a temporary name; ``close()`` renames it into place and
    ``discard()`` removes it (the path is then left as it was)."""

    def __init__(self, target, program, initial_state):
        self._own = not hasattr(target, "write")
        self._file = None
        if self._own:
            self.path = os.path.realpath(os.fspath(target))
            self._file = atomic_writer(self.path)  # btfsm.outputs: temporary name, renamed on close
            self.out = self._file.__enter__()
        else:
            self.path, self.out = None, target
        header = {"format": FORMAT, "model": program.model.name, "tick_rate": program.model.tick_rate,
                  "initial": _jsonable(program.decode(initial_state))}
        try:
            self.out.write(json.dumps(header) + "\n")
        except OSError as exc:
            self.discard()
            raise self._named(exc) from None
        except BaseException:
            self.discard()
            raise

    def write(self, record: dict) -> None:
        try:
            self.out.write(json.dumps(record) + "\n")
        except OSError as exc:
            raise self._named(exc) from None

    def _named(self, exc: OSError) -> OSError:
        """The error with the trace's path as its file name (not the temporary one)."""
        if self.path is None or exc.errno is None:
            return exc
        return type(exc)(exc.errno, exc.strerror, self.path)

    def close(self) -> None:
        """Finish the trace: a path is complete and in place afterwards."""
        if not self._own:
            self.out.flush()
            return
        if self._file is None:
            return
        file, self._file = self._file, None
        file.__exit__(None, None, None)  # renames into place; a failure leaves no temporary file

    def discard(self) -> None:
        """Drop a trace written to a path (its temporary file); the path keeps what it had."""
        if not self._own or self._file is None:
            return
        file, self._file = self._file, None
        file.__exit__(_Discarded, _Discarded(), None)


class _Discarded(Exception):
    """Thrown into the atomic writer to drop the temporary file."""


def _jsonable(d: dict) -> dict:
    return {k: (v if isinstance(v, (bool, int, str)) or v is None else str(v)) for k, v in d.items()}


def _lines_of(source) -> tuple:
    """(file name for messages, [(line number, text)]) of a path, stream or list of lines."""
    if isinstance(source, (list, tuple)):
        return "<trace>", [(i, str(line)) for i, line in enumerate(source, 1)]
    if hasattr(source, "read"):
        name, data = str(getattr(source, "name", "<trace>")), source.read()
    else:
        name = os.fspath(source)
        with open(name, "rb") as fh:
            data = fh.read()
    if isinstance(data, bytes):
        data = decode_utf8(data, name)
    return name, [(i, line.rstrip("\r")) for i, line in enumerate(data.split("\n"), 1)]


_RECORD_KEYS = frozenset(("tick", "time", "status", "env", "outcomes", "changes", "fired", "fsm", "writes",
                          "violations"))
_CHANGED = frozenset(("RUNNING", "SUCCESS", "FAILURE", "halted"))


def _names_pairs(xs) -> bool:
    return type(xs) is list and all(type(p) is list and len(p) == 2 and type(p[0]) is str and type(p[1]) is str
                                    for p in xs)


def plain_record(r) -> bool:
    """A fast check that ``r`` follows ``$defs/record`` of the trace schema; it accepts a
    subset of what the schema accepts (tested), so long traces need not go through
    ``jsonschema`` line by line. What it does not accept is judged by the schema."""
    if type(r) is not dict or r.keys() != _RECORD_KEYS:
        return False
    tick, time, status = r["tick"], r["time"], r["status"]
    env, changes, fsm, writes, violations = r["env"], r["changes"], r["fsm"], r["writes"], r["violations"]
    return (type(tick) is int and tick >= 0 and type(time) in (int, float) and time >= 0
            and type(status) is str and status in _NAMES
            and type(env) is list and all(type(e) is str for e in env)
            and _names_pairs(r["outcomes"]) and _names_pairs(r["fired"])
            and type(changes) is dict and all(type(v) is str and v in _CHANGED for v in changes.values())
            and type(fsm) is dict and all(type(v) is list and len(v) == 2 and type(v[0]) is str
                                          and (v[1] is None or type(v[1]) is str) for v in fsm.values())
            and type(writes) is dict and all(v is None or type(v) in (bool, int, str) for v in writes.values())
            and type(violations) is list and all(type(v) is list and len(v) >= 2 and all(type(x) is str for x in v)
                                                 for v in violations))


def read_trace(source) -> tuple[dict, list]:
    """(header, tick records) from a path, a text stream or a list of lines, each line
    checked against the format (``btfsm/schema/trace.schema.json``); blank lines are
    skipped. Raises ``FormatError`` (a ValueError) naming the file, line and field."""
    name, lines = _lines_of(source)
    records: list
    header, records = None, []
    for no, line in lines:
        if not line.strip():
            continue
        obj = parse_json(line, name, line=no)
        if header is None:
            if not isinstance(obj, dict) or obj.get("format") != FORMAT:
                raise FormatError(name, f"line {no}", f"not a {FORMAT} trace: the first line must be its header "
                                                      f'{{"format": "{FORMAT}", "model": ..., "tick_rate": ..., "initial": ...}}')
            validate(obj, "trace", name, f"line {no}", "header")
            header = obj
            continue
        if not plain_record(obj):  # the schema decides, and words the problem
            validate(obj, "trace", name, f"line {no}", "record")
        if obj["tick"] != len(records):
            raise FormatError(name, f"line {no}: tick", f"expected {len(records)} (ticks are consecutive from 0), "
                                                        f"got {printable(obj['tick'], 40)}")
        records.append(obj)
    if header is None:
        raise FormatError(name, "", f"empty: not a {FORMAT} trace (the first line must be its header)")
    return header, records


def encode_state(program, values: dict) -> tuple:
    """The state tuple of readable ``values`` ({slot: value}, as ``Program.decode`` gives
    them; missing slots keep their initial value), checked slot by slot: a ValueError
    names the first slot that the model does not have or whose value it cannot hold."""
    names = {info.name for info in program.slots}
    unknown = [k for k in values if k not in names]
    if unknown:
        raise ValueError(f"'{printable(unknown[0], 60)}' is not a variable or slot of {program.model.name}")
    state = list(program.initial)
    for i, info in enumerate(program.slots):
        if info.name not in values:
            continue
        val = values[info.name]
        try:
            code = program.encode({info.name: val})[i]
        except (KeyError, ValueError, IndexError, TypeError, OverflowError):
            code = None
        back = None if code is None or not info.lo <= code < info.lo + info.size else program.decode_slot(i, code)
        if back is None or back != val or isinstance(back, bool) != isinstance(val, bool):
            raise ValueError(f"{info.name} = {printable(json.dumps(val), 40)} is not a value it can hold")
        state[i] = code
    return tuple(state)


class _NamedEvents(Oracle):
    """Environment answers by event name, for oracles that replay what was recorded.
    Replay drives no implementation, so there is nothing to halt."""

    program: Any  # the Program replayed
    events: Any  # the names of the events that happened (a set or another collection)

    def env(self, i: int) -> bool:
        return self.program.env[i][0] in self.events

    def _named(self, i, enabled):
        options = self.program.env[i][3]
        return next((k for k, opt in enumerate(enabled) if options[opt][0] in self.events), None)

    def halt(self, site: Site) -> None:
        return None


class ReplayOracle(_NamedEvents):
    """Answers from one tick record: events by name, outcomes in recorded order."""

    def __init__(self, program, record: dict):
        self.program = program
        self.events = set(record.get("env", ()))
        self.outcomes = list(record.get("outcomes", ()))
        self.pos = 0
        self.error: "str | None" = None

    def choose(self, i: int | tuple[Any, ...], enabled: Sequence[Any]) -> int:
        k = self._named(i, enabled)
        if k is None:
            self.error = f"choice '{self.program.env[i][0]}': the trace names none of its enabled options"
            return 0
        return k

    def outcome(self, site: Site) -> int:
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

    def choose(self, i: int | tuple[Any, ...], enabled: Sequence[Any]) -> int:
        k = self._named(i, enabled)
        return 0 if k is None else k  # a lone option may go unreported: it is forced

    def outcome(self, site: Site) -> int:
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
    """Re-run a trace; return ``(tick, why)`` at the first difference, or None. A trace
    that does not follow the format raises ``FormatError`` (see ``read_trace``)."""
    header, records = read_trace(source)
    program = model.program
    if header["model"] != model.name:
        return (0, f"trace is of model '{printable(header['model'], 80)}', not '{model.name}'")
    if header["tick_rate"] != model.tick_rate:
        return (0, f"trace has tick rate {header['tick_rate']:g}, {model.name} has {model.tick_rate:g}")
    if state is None:
        try:
            state = encode_state(program, header["initial"])
        except ValueError as exc:
            return (0, f"the trace's initial state does not fit this model ({exc})")
    s = tuple(state)
    last: dict
    clock, last = Clock(model.tick_rate), {}
    for rec in records:
        oracle = ReplayOracle(program, rec)
        try:
            step = program.step(s, oracle, True)
        except DomainError as exc:
            return (rec["tick"], oracle.error or f"the model fails here: {exc}")
        if oracle.error:
            return (rec["tick"], oracle.error)
        if step.state is None:
            v = step.violations[0]
            if v[0] == "timing":
                return (rec["tick"], f"the model cannot take this tick: {v[2]} (the declared duration)")
            return (rec["tick"], "the model cannot take this tick (an environment choice has no enabled option)")
        mine = tick_record(program, clock, step, last)
        if mine != rec:
            diff = sorted(k for k in rec if mine.get(k) != rec.get(k))
            return (rec["tick"], f"regenerated record differs in {', '.join(diff)}")
        s = step.state
        clock.tick += 1
    return None
