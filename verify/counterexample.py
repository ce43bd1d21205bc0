"""Counterexamples: shortest paths (or lassos) to a violation, for people and for tools.

A ``Counterexample`` holds the model name, the property, the level (``model``: BT ticks;
``fsm``: requests of one FSM; ``static``: no path, e.g. two overlapping guards), and one
record per step with the full choice script, the readable choices (environment events and
options, the requested goal/parameters/free inputs at FSM level, primitive outcomes), the
fired edges and markers, halts, the status, the changed slots and the state reached.
``loop`` marks where the cycle of a lasso starts; ``violation`` says what goes wrong at the
end. ``format_text`` prints it; ``to_json`` / ``from_json`` round-trip it.

``replay_counterexample(ce, model)`` re-executes a model-level path in the runtime
(``btfsm.runtime.Runtime`` with implementations that answer the recorded outcomes and
the recorded environment events), an FSM-level path through ``Program.fsm_step`` answered
from the recorded choices, and then confirms the final violation.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Sequence

from btfsm.errors import ConformanceError, DomainError
from btfsm.formats import FormatError, decode_utf8, json_path, jsonable, parse_json, printable, validate
from btfsm.status import Status

from .explore import run_script, script_of
from .labels import readable
from .search import EnumOracle

if TYPE_CHECKING:
    from btfsm.semantics import Site

__all__ = ["Counterexample", "path_counterexample", "static_counterexample", "replay_counterexample",
           "load_counterexample", "FORMAT"]

FORMAT = "btfsm-counterexample/1"
_NAMES = ("RUNNING", "SUCCESS", "FAILURE")
_CONFIRM_BUDGET = 200_000


@dataclass
class Counterexample:
    model: str
    property: str
    level: str  # "model" | "fsm" | "static"
    summary: str
    fsm: "str | None" = None
    initial: dict = field(default_factory=dict)
    steps: list = field(default_factory=list)
    loop: "int | None" = None
    violation: dict = field(default_factory=dict)
    extra: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        return {"format": FORMAT, "model": self.model, "property": self.property, "level": self.level,
                "fsm": self.fsm, "summary": self.summary, "initial": self.initial, "steps": self.steps,
                "loop": self.loop, "violation": self.violation, "extra": self.extra}

    @classmethod
    def from_json(cls, d: dict) -> "Counterexample":
        if not isinstance(d, dict) or d.get("format") != FORMAT:
            raise ValueError(f"not a {FORMAT} object")
        return cls(model=d["model"], property=d["property"], level=d["level"], summary=d.get("summary", ""),
                   fsm=d.get("fsm"), initial=d.get("initial", {}), steps=list(d.get("steps", [])),
                   loop=d.get("loop"), violation=d.get("violation", {}), extra=d.get("extra", {}))

    def format_text(self, max_steps: int = 60) -> str:
        """A readable account: one block per step, then the violation."""
        lines = [f"{self.property}: {self.summary}"]
        if self.level == "static":
            lines += [f"  {line}" for line in self.violation.get("text", "").splitlines()]
            return "\n".join(lines)
        where = f" (FSM {self.fsm} as an open system: one step = one request)" if self.level == "fsm" else ""
        lines.append(f"  path of {len(self.steps)} step(s){where}; initial: {_state_text(self.initial)}")
        steps = self.steps
        shown = steps if len(steps) <= max_steps else steps[: max_steps // 2] + [None] + steps[-max_steps // 2:]
        for st in shown:
            if st is None:
                lines.append(f"  ... {len(steps) - max_steps} steps left out ...")
                continue
            if self.loop is not None and st["tick"] == self.loop + 1:
                lines.append("  -- cycle starts here --")
            lines.append("  " + _step_text(st))
        if self.loop is not None:
            lines.append(f"  -- back to the state after step {self.loop} (the cycle repeats forever) --")
        text = self.violation.get("text")
        if text:
            lines += [f"  {line}" for line in text.splitlines()]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.format_text()

    def file_name(self) -> str:
        """``MODEL.PROPERTY.HASH.json``: what ``--counterexample-dir`` names this file. HASH is
        the first 10 hex digits of the SHA-256 of the canonical JSON, so two different
        violations never overwrite each other and the same one keeps its name. Characters
        other than letters, digits, ``_``, ``-`` and ``.`` in the model name become ``_``.

        >>> Counterexample("m/x", "contracts", "model", "s").file_name()[:-16]
        'm_x.contracts'
        """
        import hashlib
        import re

        text = json.dumps(self.to_json(), sort_keys=True, default=str, ensure_ascii=True)
        digest = hashlib.sha256(text.encode("ascii")).hexdigest()[:10]
        safe = re.sub(r"[^A-Za-z0-9_.-]", "_", self.model).lstrip(".") or "model"
        return f"{safe[:80]}.{self.property}.{digest}.json"


def _state_text(d: dict) -> str:
    return ", ".join(f"{k}={_v(v)}" for k, v in d.items() if not (":" in k)) or "(no variables)"


def _v(x) -> str:
    return "none" if x is None else (str(x).lower() if isinstance(x, bool) else str(x))


def _step_text(st: dict) -> str:
    parts = []
    req = st.get("request")
    if req:
        ps = "".join(f" {k}={_v(v)}" for k, v in req.get("params", {}).items())
        ins = ", ".join(f"{k}={_v(v)}" for k, v in req.get("inputs", {}).items())
        parts.append(f"request {req['goal']}{ps}" + (f" [inputs {ins}]" if ins else ""))
    if st.get("env"):
        parts.append("env " + ", ".join(st["env"]))
    if st.get("sequence") is not None:  # what happened, in order (files since issue 9)
        parts += _sequence_text(st["sequence"])
    elif st.get("outcomes"):
        parts.append("; ".join(f"{s} -> {o}" for s, o in st["outcomes"]))
    if st.get("sequence") is None:
        if st.get("halted"):
            parts.append("halted " + ", ".join(st["halted"]))
        if st.get("fired"):
            parts.append("fired " + ", ".join(f"{f}:{e}" for f, e in st["fired"]))
        if st.get("notes"):
            parts.append(", ".join(f"{k} {a} ({b})" for k, a, b in st["notes"]))
    status = st.get("status")
    head = f"step {st['tick']}: " + ("; ".join(parts) if parts else "(no choice)")
    if status:
        head += f" => {status}"
    if st.get("error"):
        head += f"  !! {st['error']}"
    ch = {k: v for k, v in st.get("changes", {}).items() if ":" not in k}
    if ch:
        head += "\n      changes: " + ", ".join(f"{k}={_v(v)}" for k, v in ch.items())
    if st.get("fsm") and not req:
        head += "\n      fsm: " + ", ".join(f"{f} at {s}" + (f" (goal {g})" if g else "") for f, (s, g) in st["fsm"].items())
    return head


def _sequence_text(seq) -> list:
    """Parts of a step line from its ordered events; runs of one kind are joined
    (``fired arm:a->b, arm:b->c``)."""
    parts, last = [], None
    for item in seq:
        kind = item[0]
        if kind == "outcome":
            text, group = f"{item[1]} -> {item[2]}", "outcome"
        elif kind == "halt":
            text, group = item[1], "halted"
        elif kind == "fire":
            text, group = f"{item[1]}:{item[2]}", "fired"
        else:
            text, group = f"{kind} {item[1]} ({item[2]})", "note"
        if group == last and group != "outcome":
            parts[-1] += ", " + text
        else:
            parts.append(text if group in ("outcome", "note") else f"{group} {text}")
        last = group
    return parts


# ---------------------------------------------------------------------- building


def _decode_full(prog, state, keep=None) -> dict:
    return {prog.slots[k].name: jsonable(prog.decode_slot(k, state[k]))
            for k in (keep if keep is not None else range(len(state)))}


def _step_record(ts, k, before, script, step, oracle, error=None) -> dict:
    prog = ts.model.program
    label = readable(prog, tuple(oracle.picks), ts.open)[0]
    rec = {"tick": k, "script": list(script), "choices": jsonable(label)}
    if ts.kind == "fsm":
        req: dict = {"goal": None, "params": {}, "inputs": {}}
        f = ts.model.fsm(ts.fsm)
        for item in label:
            if item[0] == "goal":
                req["goal"] = item[1]
            elif item[0] == "param":
                req["params"][item[1].split(".", 1)[1] if item[1].startswith(f.name + ".") else item[1]] = jsonable(item[2])
            elif item[0] == "input":
                req["inputs"][item[1]] = jsonable(item[2])
        rec["request"] = req
    rec["env"] = [it[1] for it in label if it[0] == "env"] + [it[2] for it in label if it[0] == "choice"]
    rec["outcomes"] = [[it[1], it[2]] for it in label if it[0] == "outcome"]
    if step is not None:
        ev = step.events or []
        env_seen = [e[1] for e in ev if e[0] == "env"]
        if env_seen:
            rec["env"] = env_seen
        rec["fired"] = [[e[1], e[2]] for e in ev if e[0] == "fire"]
        rec["halted"] = [e[1] for e in ev if e[0] == "halt"]
        rec["notes"] = [[e[0], e[1], e[2]] for e in ev if e[0] in _NOTES]
        rec["sequence"] = [_sequence_item(e) for e in ev if e[0] in _SEQUENCE]
        rec["status"] = _NAMES[step.status]
        after = step.state
        keep = range(len(after)) if ts.kind == "model" else ts.slots
        rec["changes"] = {prog.slots[i].name: jsonable(prog.decode_slot(i, after[i])) for i in keep if before[i] != after[i]}
        rec["fsm"] = {f.name: [ids[after[tok]], f.goals[after[g] - 1] if after[g] else None]
                      for f, ids, tok, g, _ in prog.fsm_info}
        rec["state"] = _decode_full(prog, after, keep)
        rec["violations"] = [list(v) for v in step.violations]
    if error is not None:
        rec["error"] = str(error)
    return rec


_NOTES = ("withdraw", "not-applicable", "busy", "handover", "violation")
_SEQUENCE = ("outcome", "halt", "fire") + _NOTES


def _sequence_item(e) -> list:
    """One event of a step, in the order it happened: [kind, ...] (outcome: site, outcome;
    halt: node; fire: fsm, element; notes: fsm, node)."""
    return [e[0]] + [jsonable(x) for x in e[1:3]]


def path_counterexample(ts, transitions, prop: str, summary: str, violation: dict, *, loop=None,
                        final_script=None, extra=None) -> Counterexample:
    """A counterexample following ``transitions`` (indices into ``ts``) from the initial
    state; ``final_script``: one more tick, from the last state, that raises (a domain
    error). ``loop`` (lassos): the number of prefix steps; the cycle is the rest."""
    prog = ts.model.program
    keep = range(len(prog.slots)) if ts.kind == "model" else ts.slots
    state = ts.full_state(0)
    ce = Counterexample(model=ts.model.name, property=prop, level=ts.kind, summary=summary, fsm=ts.fsm,
                        initial=_decode_full(prog, state, keep), loop=loop, violation=dict(violation),
                        extra=dict(extra or {}))
    for k, t in enumerate(transitions, 1):
        script = script_of(ts, int(t))
        step, o, err = run_script(ts, state, script)
        ce.steps.append(_step_record(ts, k, state, script, step, o, err))
        state = step.state
    if final_script is not None:
        step, o, err = run_script(ts, state, final_script)
        ce.steps.append(_step_record(ts, len(ce.steps) + 1, state, final_script, step, o, err))
    return ce


def static_counterexample(model, prop: str, summary: str, violation: dict, fsm=None, extra=None) -> Counterexample:
    return Counterexample(model=model.name, property=prop, level="static", summary=summary, fsm=fsm,
                          violation=dict(violation), extra=dict(extra or {}))


# ---------------------------------------------------------------------- replay


def load_counterexample(source, name: "str | None" = None) -> Counterexample:
    """From a path, a JSON string, a dict (a counterexample, or a ``btfsm check --json``
    report holding exactly one counterexample), or a Counterexample.

    The object is checked against ``btfsm/schema/counterexample.schema.json`` and for
    steps numbered 1..n and a ``loop`` within them; anything else raises a
    ``FormatError`` (a ValueError) naming the file, the JSON path and the problem.
    ``name``: the file name used in messages (default: the path, or ``<counterexample>``)."""
    if isinstance(source, Counterexample):
        return source
    if isinstance(source, dict):
        d, name = source, name or "<counterexample>"
    else:
        if isinstance(source, str) and source.lstrip().startswith("{"):
            text, name = source, name or "<counterexample>"
        else:
            name = name or os.fspath(source)
            with open(source, "rb") as fh:
                text = decode_utf8(fh.read(), name)
        d = parse_json(text, name)
    where = ""
    if isinstance(d, dict) and "format" not in d and "properties" in d:  # a btfsm check --json report
        props = d["properties"]
        if not isinstance(props, list) or not all(isinstance(p, dict) for p in props):
            raise FormatError(name, "properties", "expected a list of property results (btfsm check --json)")
        found = [(i, p["counterexample"]) for i, p in enumerate(props) if p.get("counterexample")]
        if len(found) != 1:
            raise FormatError(name, "", f"the report holds {len(found)} counterexamples; "
                                        "pass one (btfsm check --counterexample-dir)")
        where, d = f"properties[{found[0][0]}].counterexample", found[0][1]
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        raise FormatError(name, where, f"not a {FORMAT} object (its \"format\" must be \"{FORMAT}\")")
    validate(d, "counterexample", name, where)
    for k, st in enumerate(d["steps"]):
        if st["tick"] != k + 1:
            raise FormatError(name, _at(where, "steps", k, "tick"),
                              f"expected {k + 1} (steps are numbered from 1), got {printable(st['tick'], 40)}")
    if d["loop"] is not None and d["loop"] > len(d["steps"]):
        raise FormatError(name, _at(where, "loop"),
                          f"{printable(d['loop'], 40)} is past the last of the {len(d['steps'])} step(s)")
    if d["violation"].get("kind") == "non-progress" and d["loop"] is None:
        raise FormatError(name, _at(where, "loop"),
                          "a non-progress cycle needs its loop start (an integer), not null")
    return Counterexample.from_json(d)


def _at(where: str, *parts) -> str:
    return ".".join(p for p in (where, json_path(parts)) if p)


class _Recorded:
    """Implementations for the runtime that answer the recorded outcomes of each tick."""

    def __init__(self):
        self.queue: list = []
        self.error = None

    def __call__(self, call):
        label = call.site.label
        if not self.queue:
            self.error = f"{label} ran but the counterexample records no more outcomes"
            return 0
        want, name = self.queue.pop(0)
        if want != label:
            self.error = f"{label} ran where the counterexample has {want}"
        return name


def replay_counterexample(source, model) -> tuple:
    """Re-execute a counterexample and confirm its violation: ``(ok, text)``."""
    try:
        ce = load_counterexample(source)
    except (OSError, ValueError) as exc:  # FormatError is a ValueError
        return False, f"cannot read the counterexample: {exc}"
    if ce.model != model.name:
        return False, f"the counterexample is of model '{ce.model}', not '{model.name}'"
    try:
        if ce.level == "static":
            return _replay_static(ce, model)
        if ce.level == "model":
            return _replay_model(ce, model)
        return _replay_fsm(ce, model)
    except (KeyError, IndexError, TypeError, ValueError) as exc:
        return False, f"the counterexample does not fit the model: {type(exc).__name__}: {exc}"


def _same(prog, state, want: dict) -> "str | None":
    have = {prog.slots[k].name: jsonable(prog.decode_slot(k, state[k])) for k in range(len(state))}
    diff = [k for k, v in want.items() if have.get(k) != v]
    return None if not diff else ", ".join(f"{k}={_v(have.get(k))} (counterexample: {_v(want[k])})" for k in diff[:5])


def _replay_model(ce, model) -> tuple:
    from btfsm.runtime import Runtime

    prog = model.program
    impl = _Recorded()
    rt = Runtime(model, {name: impl for name in prog.prims}, record=True)
    bad = _same(prog, rt.state, ce.initial)
    if bad:
        return False, f"initial state differs: {bad}"
    last = None
    n = len(ce.steps)
    seen = [rt.state]  # the state after each step (for 'response', which looks at the whole run)
    for st in ce.steps:
        impl.queue = [tuple(x) for x in st.get("outcomes", [])]
        impl.error = None
        # the runtime is told the answers the step function asks for: events that happened
        # and options of choices with several enabled options (a lone option is not asked)
        events = [c[1] for c in st.get("choices", []) if c[0] == "env"] + \
                 [c[2] for c in st.get("choices", []) if c[0] == "choice"]
        try:
            last = rt.tick(events)
        except DomainError as exc:
            if st.get("error") and st["tick"] == n:
                return _confirm(ce, model, rt.state, None, exc)
            return False, f"step {st['tick']}: unexpected domain error: {exc}"
        except ConformanceError as exc:
            return False, f"step {st['tick']}: the runtime refused the recorded answers: {exc}"
        if impl.error:
            return False, f"step {st['tick']}: {impl.error}"
        if st.get("error"):
            return False, f"step {st['tick']}: the counterexample records '{st['error']}' but the runtime raised nothing"
        if last.state is None:
            return False, f"step {st['tick']}: the tick could not happen (blocked) in the runtime"
        bad = _same(prog, rt.state, st.get("state", {}))
        if bad:
            return False, f"step {st['tick']}: state differs: {bad}"
        if _NAMES[int(last.status)] != st.get("status"):
            return False, f"step {st['tick']}: status {_NAMES[int(last.status)]}, counterexample {st.get('status')}"
        seen.append(rt.state)
    if ce.violation.get("kind") == "response":
        return _confirm_response(ce, model, seen)
    return _confirm(ce, model, rt.state, last, None)


def _confirm_response(ce, model, states) -> tuple:
    """A 'response' violation: the trigger occurs at step k and the response holds in no
    state from there on, for more ticks than the bound, or around the lasso's cycle."""
    from btfsm.expr import BOOL, as_expr, compile_fn
    from btfsm.positions import copies_named, widen_to_copies

    prog = model.program
    v = ce.violation
    k = int(v["trigger_step"])
    written = as_expr(v["response"])
    resp = compile_fn(widen_to_copies(written, model), prog.scope, "response", BOOL)
    copies = copies_named(written, model)  # the response as written, and how many split copies it names
    shown = f"'{v['response']}'" + (f" ({len(copies)} split cop{'y' if len(copies) == 1 else 'ies'})" if copies else "")
    trig = v["trigger"]
    if trig.startswith("event:"):
        name = trig[len("event:"):]
        if k < 1 or ["env", name] not in [list(c[:2]) for c in ce.steps[k - 1].get("choices", [])]:
            return False, f"event '{name}' does not happen in step {k}"
    elif not compile_fn(widen_to_copies(as_expr(trig), model), prog.scope, "trigger", BOOL)(list(states[k])):
        return False, f"the trigger '{trig}' does not hold after step {k}"
    held = [i for i in range(k, len(states)) if resp(list(states[i]))]
    n = len(states) - 1
    bound = v.get("bound_ticks")
    if bound is None and ce.loop is None and v.get("worst_ticks") is not None:  # a worst-case witness (btfsm bound)
        if held == [n] and n - k == v["worst_ticks"]:
            return True, (f"confirmed: {shown} first holds {n - k} tick(s) ({(n - k) / model.tick_rate:g} s) "
                          f"after the trigger at step {k}")
        return False, f"{shown} holds after step(s) {held[:3]}, not only after step {n}"
    if held:
        return False, f"{shown} holds after step {held[0]}"
    if ce.loop is not None:
        if states[-1] != states[ce.loop]:
            return False, f"the run does not return to the state after step {ce.loop}"
        return True, (f"confirmed: after the trigger at step {k}, {shown} never holds: the run returns to "
                      f"the state after step {ce.loop} and repeats for ever")
    if bound is not None and n - k >= bound:
        return True, (f"confirmed: {shown} still does not hold {n - k} tick(s) ({(n - k) / model.tick_rate:g} s) "
                      f"after the trigger at step {k}; the bound is {bound / model.tick_rate:g} s")
    from .explore import explore

    ts = explore(model, start=states[-1], max_states=2)
    if ts.n_transitions == 0 and not ts.errors:
        return True, f"confirmed: after the trigger at step {k} the run stops (no tick can happen) before {shown}"
    return False, f"only {n - k} tick(s) after the trigger at step {k}; the bound is {bound} ticks"


class _ChoiceOracle(EnumOracle):
    """Answers an FSM-level request from a step's recorded choices (not its script)."""

    def __init__(self, prog, step, fsm):
        EnumOracle.__init__(self, ())
        self.prog, self.fsm = prog, fsm
        req = step.get("request", {})
        self.goal, self.params, self.inputs = req.get("goal"), req.get("params", {}), req.get("inputs", {})
        self.env_names = set(step.get("env", []))
        self.outs = [tuple(x) for x in step.get("outcomes", [])]
        self.error = None

    def _choose(self, n, label):  # record the point like ScriptOracle, answer from the record
        self.arities.append(n)
        self.labels.append(label)
        return None

    def env(self, i: int) -> bool:
        self._choose(2, ("env", i))
        c = int(self.prog.env[i][0] in self.env_names)
        self.taken.append(c)
        self.picks.append(("env", i, c))
        return c == 1

    def choose(self, tag: int | tuple[Any, ...], enabled: Sequence[Any]) -> int:
        self._choose(len(enabled), ("choice", tag))
        prog = self.prog
        if isinstance(tag, int):
            names = [prog.env[tag][3][k][0] for k in enabled]
            hits = [k for k, nm in enumerate(names) if nm in self.env_names]
            c = hits[0] if len(hits) == 1 else None
        elif tag[0] == "goal":
            goals = prog.fsm_info[prog.fsm_index[self.fsm]][0].goals
            c = next((k for k, g in enumerate(enabled) if goals[g] == self.goal), None)
        else:
            src = self.inputs if tag[0] == "input" else self.params
            name = prog.slots[tag[1]].name
            want = src.get(name, src.get(name.split(".", 1)[-1]))
            c = next((k for k, v in enumerate(enabled) if jsonable(prog.decode_slot(tag[1], v)) == want), None)
        if c is None:
            self.error = f"no recorded answer fits choice {tag!r}"
            c = 0
        self.taken.append(c)
        self.picks.append(("choice", tag, enabled[c]))
        return c

    def outcome(self, site: Site) -> int:
        if not self.outs:
            self.error = f"{site.label} ran but the step records no more outcomes"
            k = 0
        else:
            label, name = self.outs.pop(0)
            if label != site.label:
                self.error = f"{site.label} ran where the step has {label}"
            k = next((i for i, o in enumerate(site.outcomes) if o[2] == name), 0)
        self.picks.append((site, k))
        return k


def _replay_fsm(ce, model) -> tuple:
    from .explore import open_fsm

    prog = model.program
    goals = ce.extra.get("goals")
    op = open_fsm(model, ce.fsm, goals)
    state = prog.initial
    bad = _same(prog, state, ce.initial)
    if bad:
        return False, f"initial state differs: {bad}"
    step = None
    for st in ce.steps:
        o = _ChoiceOracle(prog, st, ce.fsm)
        try:
            step = op.run(state, o, True)
        except DomainError as exc:
            if st.get("error") and st is ce.steps[-1]:
                return True, f"confirmed: step {st['tick']} raises: {exc}"
            return False, f"step {st['tick']}: unexpected domain error: {exc}"
        if o.error:
            return False, f"step {st['tick']}: {o.error}"
        if step is None:
            return False, f"step {st['tick']}: the request could not happen"
        state = step.state
        bad = _same(prog, state, st.get("state", {}))
        if bad:
            return False, f"step {st['tick']}: state differs: {bad}"
        if _NAMES[step.status] != st.get("status"):
            return False, f"step {st['tick']}: reply {_NAMES[step.status]}, counterexample {st.get('status')}"
    return _confirm(ce, model, state, step, None)


def _replay_static(ce, model) -> tuple:
    from .determinism import confirm_overlap

    return confirm_overlap(model, ce.violation)


# ---------------------------------------------------------------------- confirming the end


def _confirm(ce, model, state, last, error) -> tuple:
    """Check that the violation named in ``ce.violation`` happens at the end of the replay."""
    from btfsm.expr import BOOL, compile_fn

    prog = model.program
    kind = ce.violation.get("kind")
    n = len(ce.steps)
    if error is not None:
        if kind == "domain" and error.var == ce.violation.get("var"):
            return True, f"confirmed: the last tick writes {error.var} = {error.value}, outside its domain ({error.where})"
        return False, f"the replay raised a different error: {error}"
    if kind == "invariant":
        name = ce.violation["name"]
        expr = dict(model.invariants)[name]
        if not compile_fn(expr, prog.scope, f"invariants.{name}", BOOL)(list(state)):
            return True, f"confirmed: after {n} tick(s) invariant '{name}' is false"
        return False, f"invariant '{name}' holds at the end of the replay"
    if kind == "contract":
        node = ce.violation["node"]
        if last is not None and ("post", node) in [tuple(v) for v in last.violations]:
            return True, f"confirmed: tick {n}: '{node}' replied SUCCESS while its post-condition is false"
        return False, f"no contract violation of '{node}' at the last tick"
    if kind == "tick-loop":
        if last is not None and ("tick-loop", ce.violation.get("node")) in [tuple(v) for v in last.violations]:
            return True, f"confirmed: tick {n}: tickOnce() re-ticks '{ce.violation.get('node')}' in a loop"
        return False, "the last tick returns"
    if kind == "conflict":
        node = ce.violation["node"]
        if last is not None and ("busy", node, ce.violation.get("fsm")) in [tuple(v) for v in last.violations]:
            return True, f"confirmed: tick {n}: '{node}' was refused because another request used FSM '{ce.violation.get('fsm')}'"
        return False, f"no conflict on '{node}' at the last tick"
    if kind == "exclusive":
        v = ce.violation
        want = ("exclusive", v.get("resource"), v.get("node"), v.get("other"), v.get("when"))
        if last is not None and want in [tuple(x) for x in last.violations]:
            how = "started while '{}' was running" if want[4] == "start" else "and '{}' are both running"
            return True, f"confirmed: tick {n}: '{want[2]}' {how.format(want[3])} (resource '{want[1]}')"
        return False, f"'{v.get('node')}' and '{v.get('other')}' do not run at once at the last tick"
    if kind == "dead-branch":  # a tree-coverage lint's run: its last tick shows the dead node
        v, events = ce.violation, (last.events or ()) if last is not None else ()
        status = {e[1]: e[2] for e in events if e[0] == "status"}
        node, parent = v.get("node"), v.get("parent")
        if parent is not None and parent in status and node not in status:
            return True, f"confirmed: tick {n} ticks '{parent}' and not '{node}'"
        if parent is None and node in status and status[node] != 1:
            return True, f"confirmed: tick {n} ticks '{node}' and it does not succeed"
        return False, f"the last tick does not show '{node}' {'skipped' if parent is not None else 'failing'}"
    if kind == "sink":
        return _confirm_sink(ce, model, state)
    if kind == "goal-tree":
        from .explore import explore
        from .treegoals import tree_goal_failures

        ts = explore(model, start=state, max_states=_CONFIRM_BUDGET)
        if not ts.complete:
            return False, f"could not confirm within {_CONFIRM_BUDGET} states"
        key = (ce.violation.get("fsm"), ce.violation.get("goal"))
        bad = tree_goal_failures(ts).get(key)
        if bad is not None and int(bad[0]) == 0:
            return True, (f"confirmed: after {n} tick(s) the tree can request '{key[1]}' of FSM {key[0]} and no run "
                          "from there gets SUCCESS for it")
        return False, f"'{key[1]}' can succeed from the final state (or is not requested there)"
    if kind == "dead":
        from .explore import explore

        ts = explore(model, start=state, max_states=2)
        if ts.n_transitions == 0 and not ts.errors:
            return True, f"confirmed: after {n} tick(s) no tick can happen (dead state)"
        return False, "the final state has a successor"
    if kind == "trap":
        from .explore import explore

        ts = explore(model, start=state, max_states=_CONFIRM_BUDGET)
        if not ts.complete:
            return False, f"reached the trap state; could not confirm within {_CONFIRM_BUDGET} states that it is a trap"
        if not any(prog.workable(list(ts.full_state(i))) for i in range(ts.n_states)):
            return True, f"confirmed: after {n} tick(s) no workable state is reachable ({ts.n_states} states explored from there)"
        return False, "a workable state is reachable from the final state"
    if kind in ("goal", "non-progress", "latency"):
        return _confirm_fsm(ce, model, state, kind)
    return False, f"unknown violation kind {kind!r}"


def _confirm_sink(ce, model, state) -> tuple:
    name, sid = ce.violation.get("fsm"), ce.violation.get("state")
    f = model.fsm(name)
    at = model.program.fsm_state(state, name)[0]
    used = {e.source for e in f.edges} | {m.state for m in f.markers}
    if at == sid and sid not in used and sid not in f.terminal:
        return True, f"confirmed: after {len(ce.steps)} step(s) FSM {name} is in '{sid}', which has no edge, no marker and is not terminal"
    return False, f"FSM {name} ends in '{at}', not in the sink '{sid}'"


def _confirm_fsm(ce, model, state, kind) -> tuple:
    from .explore import explore_fsm

    prog = model.program
    n = len(ce.steps)
    if kind == "non-progress":
        loop = ce.loop
        start = ce.initial if loop == 0 else ce.steps[loop - 1]["state"]
        if _same(prog, state, start) is not None:
            return False, "the cycle does not return to its first state"
        fi = prog.fsm_index[ce.fsm]
        tok = prog.fsm_info[fi][2]
        tok_name = prog.slots[tok].name
        goals = {st["request"]["goal"] for st in ce.steps[loop:]}
        for st in ce.steps[loop:]:
            moved = tok_name in st.get("changes", {})
            running = any(_status_of(prog, s, o) == Status.RUNNING for s, o in st.get("outcomes", []))
            if moved or st.get("status") != "RUNNING" or running:
                return False, f"step {st['tick']} of the cycle makes progress"
        if len(goals) != 1:
            return False, "the cycle requests more than one goal"
        return True, (f"confirmed: steps {loop + 1}..{n} request '{goals.pop()}' and come back to the same state "
                      "with no progress (token still, reply RUNNING, no primitive RUNNING)")
    if kind == "goal":
        goal = ce.violation["goal"]
        import numpy as np

        from .system import reverse_reach

        ts = explore_fsm(model, ce.fsm, goals=ce.extra.get("goals"), start=state, max_states=_CONFIRM_BUDGET)
        if not ts.complete:
            return False, f"could not confirm within {_CONFIRM_BUDGET} states"
        g = model.fsm(ce.fsm).goals.index(goal)
        is_g = ts.goal == g
        ok = np.zeros(ts.n_states, bool)
        ok[ts.src[is_g & (ts.status == int(Status.SUCCESS))]] = True
        good = reverse_reach(ts, ok, is_g & (ts.status == int(Status.RUNNING)))
        if not good[0]:
            return True, f"confirmed: from the final state no request sequence of '{goal}' gets SUCCESS while the goal is held"
        return False, f"'{goal}' can succeed from the final state"
    if kind == "latency":
        from .explore import open_fsm
        from .retarget import late_requests

        op = open_fsm(model, ce.fsm, ce.extra.get("goals"))
        want = ce.violation["request"]
        for req in late_requests(model, op, state):
            goal = next(it[1] for it in req if it[0] == "goal")
            params = {it[1].split(".", 1)[1]: jsonable(it[2]) for it in req if it[0] == "param"}
            if goal == want["goal"] and params == want["params"]:
                return True, (f"confirmed: after {n} request(s), requesting '{goal}' with new parameters is not "
                              "served in the same tick (its results differ from a tick toward that goal)")
        return False, "the request is served in the same tick"
    return False, f"unknown violation kind {kind!r}"


def _status_of(prog, site_label, outcome_name):
    for site in prog.sites:
        if site.label == site_label:
            for status, _, name in site.outcomes:
                if name == outcome_name:
                    return status
    return None
