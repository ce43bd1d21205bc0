"""Promela (SPIN) export of a ``StepSpec`` and a small driver for SPIN's verifier.

The model becomes one ``active proctype`` whose body is a ``do`` loop of ``d_step``
options, one per combination of the step's choices: environment decisions (an event
happens or not, the option a choice takes), free inputs, requested goal, parameter
values (FSM level) and the outcome index of the primitive that runs. Each ``d_step`` is
one transition: its first statement is the guard "this combination can happen" (event and
option guards, with the effects of earlier environment entries substituted in), its body
runs the environment and the FSM tick of docs/semantics.md section 5 (direct chain,
direct marker, not applicable, run, marker, edge) exactly as ``btfsm.semantics`` does.
States therefore correspond one to one to the states ``btfsm.verify.explore`` stores, and
``spin -o2`` (which keeps write-only variables such as the held goal) counts the same
number of states.

Outcome index ``k`` runs outcome ``min(k, n - 1)`` of a primitive with ``n`` outcomes, so
primitives with fewer outcomes than the most have duplicate transitions (same target:
state counts are unaffected, transition counts are not). Invariants are ``assert``ed on
the state each ``d_step`` reaches (and on the initial state if it violates one); effects
that may leave their domain fail an ``assert`` (btfsm: a DomainError) and are then
clamped (so that SPIN's search stays finite after the error); a SkillRequest ``post``
contract is ``assert``ed after a SUCCESS reply. States where stopping is intended
(``terminal``) get a stutter option ``d_step { TERMINAL -> skip }`` rather than an end
label, so SPIN reports invalid end states exactly for btfsm's dead states without adding
states (an end label marks a control location, which would need one extra state per
terminal state).

>>> from btfsm.models.pickplace import pickplace
>>> from btfsm.verify.export import step_spec
>>> text = to_promela(step_spec(pickplace(3)))
>>> text.count("d_step {")
8
"""
from __future__ import annotations

import itertools
import os
import re
import shutil
import subprocess
import tempfile
import threading
import time
from dataclasses import dataclass
from typing import IO, cast

from btfsm.bt import SkillRequest
from btfsm.errors import ModelError
from btfsm.escape import comment_text
from btfsm.expr import (BOOL, INT, BinOp, BoolOp, Call, Compare, Const, IfElse, Name, Unary, check)
from btfsm.model import EnvChoice

from .stepspec import StepSpec, int_bounds, terminal_expr

__all__ = ["comment_text", "to_promela", "spin_available", "run_spin", "compile_pan", "run_pan", "parse_pan", "SpinResult", "MAX_OPTIONS", "Namer",
           "PROMELA_RESERVED"]

MAX_OPTIONS = 20_000

PROMELA_RESERVED = frozenset("""
active assert atomic bit bool break byte chan d_step D_proctype do else empty enabled eval false fi full
goto hidden if init inline int len local mtype nempty never nfull notrace np_ od of pc_value pid printf
printm priority proctype provided run short skip timeout true typedef unless unsigned xr xs c_code c_decl
c_expr c_state c_track select trace show ltl always eventually until weak stronguntil weakuntil release
implies equivalent unsigned get_priority set_priority
auto char const continue default double enum extern float for long register return signed sizeof static
struct switch union void volatile while case now
RUNNING SUCCESS FAILURE
""".split())

_STATUS_NAMES = ("RUNNING", "SUCCESS", "FAILURE")


_c = comment_text


class Namer:
    """Readable, unique identifiers for a target language (letters, digits, ``_``)."""

    def __init__(self, reserved=PROMELA_RESERVED):
        self.used = set(reserved)

    def __call__(self, text: str) -> str:
        base = re.sub(r"[^A-Za-z0-9_]", "_", str(text)) or "v"
        if base[0].isdigit() or base.startswith("_"):
            base = "v" + base if not base.startswith("_") else "v" + base
        name, k = base, 2
        while name in self.used:
            name = f"{base}_{k}"
            k += 1
        self.used.add(name)
        return name


class SlotNames:
    """Variable and constant names of a spec's slots."""

    def __init__(self, spec: StepSpec, reserved=PROMELA_RESERVED):
        prog = spec.program
        self.namer = Namer(reserved)
        self.var = {}
        for k in spec.stored:
            self.var[k] = self.namer(prog.slots[k].name.replace(":running", "_running").replace(":", "_"))
        self.const = {}  # (slot, value index) -> name
        for k in spec.stored:
            values = self.values_of(prog, k)
            if values is None:
                continue
            info = prog.slots[k]
            base = info.name.replace(".state", "").replace(".goal", "_g") if info.kind in ("token", "goal") else info.name
            for i, val in enumerate(values):
                self.const[(k, i)] = self.namer(f"{base}_{val}")

    @staticmethod
    def values_of(prog, k):
        """The names of an enum-like slot's values (enum variable, token, held goal)."""
        info = prog.slots[k]
        if info.kind == "var":
            var = prog.model.var(info.name)
            return var.values if var.kind == "enum" else None
        if info.kind in ("token", "goal"):
            slot = prog.scope.get(info.name)
            return slot.type.values if slot is not None else None
        if info.kind == "param":
            slot = prog.scope.get(info.name)
            return slot.type.values if slot is not None and slot.type.kind == "enum" else None
        return None


# ---------------------------------------------------------------------- expressions


class _Expr:
    """btfsm expression ASTs as Promela (C-like) expression text."""

    def __init__(self, names: SlotNames):
        self.names = names

    def __call__(self, e, scope, ref, expected=None, hint=None) -> str:
        return self._x(e, scope, ref, expected, hint)

    def literal(self, slot, index) -> str:
        name = self.names.const.get((slot, index)) if slot is not None else None
        return name or str(int(index))

    def _x(self, e, scope, ref, expected, hint) -> str:
        x = self._x
        if isinstance(e, Const):
            if isinstance(e.value, bool):
                return "true" if e.value else "false"
            if isinstance(e.value, int):
                return str(e.value) if e.value >= 0 else f"({e.value})"
            return self.literal(hint, expected.values.index(e.value))
        if isinstance(e, Name):
            return ref(scope[e.id].index)
        if isinstance(e, Unary):
            if e.op == "not":
                return f"!({x(e.arg, scope, ref, BOOL, None)})"
            return f"(-{x(e.arg, scope, ref, INT, None)})"
        if isinstance(e, BoolOp):
            op = " && " if e.op == "and" else " || "
            return "(" + op.join(x(a, scope, ref, BOOL, None) for a in e.args) + ")"
        if isinstance(e, Compare):
            lt, rt, lh, rh = _sides(e, scope)
            return f"({x(e.left, scope, ref, lt, rh)} {e.op} {x(e.right, scope, ref, rt, lh)})"
        if isinstance(e, BinOp):
            a, b = x(e.left, scope, ref, INT, None), x(e.right, scope, ref, INT, None)
            if e.op == "//":  # floor division by a positive constant
                return f"({a} >= 0 -> {a} / {b} : -(({b} - 1 - {a}) / {b}))"
            if e.op == "%":
                return f"((({a} % {b}) + {b}) % {b})"
            return f"({a} {e.op} {b})"
        if isinstance(e, Call):
            args = [x(a, scope, ref, INT, None) for a in e.args]
            if e.fn == "abs":
                return f"({args[0]} < 0 -> -{args[0]} : {args[0]})"
            a, b = args
            return f"({a} <= {b} -> {a} : {b})" if e.fn == "min" else f"({a} >= {b} -> {a} : {b})"
        if isinstance(e, IfElse):
            return (f"({x(e.cond, scope, ref, BOOL, None)} -> {x(e.then, scope, ref, expected, hint)}"
                    f" : {x(e.other, scope, ref, expected, hint)})")
        raise TypeError(f"not an expression: {e!r}")


def _sides(e, scope):
    """(left type, right type, left slot hint, right slot hint) of a checked comparison."""
    lit_l = isinstance(e.left, Const) and isinstance(e.left.value, str)
    lt = None if lit_l else check(e.left, scope, "export")
    rt = check(e.right, scope, "export", lt)
    lt = lt or rt
    lh = scope[e.left.id].index if isinstance(e.left, Name) else None
    rh = scope[e.right.id].index if isinstance(e.right, Name) else None
    return lt, rt, lh, rh


# ---------------------------------------------------------------------- the generator


class _Gen:
    def __init__(self, spec: StepSpec):
        self.spec = spec
        self.prog = spec.program
        self.names = SlotNames(spec)
        self.x = _Expr(self.names)
        self.fixed = spec.fixed()
        self.temps = 0  # hidden int temporaries needed
        self.fscope = self.prog.fsm_scope(spec.fsm_obj)
        self.scope = self.prog.scope

    # references to slots: variables, or constants for slots a state does not store
    def var_ref(self, inputs=None):
        names, fixed = self.names.var, self.fixed
        inputs = inputs or {}

        def ref(k):
            if k in inputs:
                return _lit(inputs[k])
            name = names.get(k)
            return name if name is not None else _lit(fixed[k])
        return ref

    def cond(self, guard, scope, ref) -> str:
        return "true" if guard is None else self.x(guard, scope, ref, BOOL)

    # ------------------------------------------------------------ statements
    def risky(self, value, slot) -> bool:
        """Whether an int value may leave ``slot``'s domain (static bounds)."""

        if slot.type != INT:
            return False
        b = int_bounds(value, self.scope)
        return b is None or b[0] < slot.lo or b[1] > slot.hi

    def assign(self, effects, ref, out, ind, what):
        """Simultaneous assignment of ``effects`` to stored slots. An int value that may
        leave its domain fails an ``assert`` there (btfsm raises DomainError) and is then
        clamped, so that SPIN, which goes on after an error with ``-c0``, stays finite."""
        if not effects:
            return
        scope = self.scope
        if len(effects) == 1 and not self.risky(effects[0][1], scope[effects[0][0]]):
            name, value = effects[0]
            slot = scope[name]
            out.append(f"{ind}{ref(slot.index)} = {self.x(value, scope, ref, slot.type, slot.index)};")
            return
        self.temps = max(self.temps, len(effects))
        targets = []
        for k, (name, value) in enumerate(effects):
            slot = scope[name]
            out.append(f"{ind}_t{k} = {self.x(value, scope, ref, slot.type, slot.index)};")
            risky = self.risky(value, slot)
            if risky:
                out.append(f"{ind}assert({slot.lo} <= _t{k} && _t{k} <= {slot.hi}); /* {_c(what)}: {_c(name)} in {slot.lo}..{slot.hi} */")
            targets.append((slot, risky))
        for k, (slot, risky) in enumerate(targets):
            value = f"(_t{k} < {_lit(slot.lo)} -> {_lit(slot.lo)} : (_t{k} > {slot.hi} -> {slot.hi} : _t{k}))" if risky else f"_t{k}"
            out.append(f"{ind}{ref(slot.index)} = {value};")

    def cascade(self, items, ref, out, ind, body, default=None):
        """The first enabled item in declaration order (``items``: ``(guard, payload)``),
        as nested ``if :: guard -> ... :: else -> ... fi``; ``default`` when none is."""
        if not items:
            if default:
                default(out, ind)
            return
        guard, payload = items[0]
        if guard is None:  # always enabled: the later ones never fire
            body(payload, out, ind)
            return
        out.append(f"{ind}if")
        out.append(f"{ind}:: {self.cond(guard, self.fscope, ref)} ->")
        body(payload, out, ind + "     ")
        out.append(f"{ind}:: else ->")
        before = len(out)
        self.cascade(items[1:], ref, out, ind + "     ", body, default)
        if len(out) == before:
            out.append(f"{ind}     skip;")
        out.append(f"{ind}fi;")

    def drive(self, g, K, ref, out, ind):
        """docs/semantics.md section 5, steps 1-6, for goal ``g``, outcome index ``K``."""
        spec, rows = self.spec, self.spec.rows
        tok = ref(spec.token)
        fsm = spec.fsm_obj
        ids = [st.id for st in fsm.states]

        def move(payload, out, ind):
            target, effects, eid = payload
            out.append(f"{ind}{tok} = {self.x.literal(spec.token, target)}; /* edge {_c(eid)} */")
            self.assign(effects, ref, out, ind, f"edge {eid}")

        direct = [(s, rows[s][g].dedges) for s in range(len(ids)) if rows[s][g].dedges]
        if direct:
            out.append(f"{ind}do /* 1. direct edges for goal {_c(fsm.goals[g])} */")
            for s, dedges in direct:
                out.append(f"{ind}:: {tok} == {self.x.literal(spec.token, s)} ->")
                self.cascade([(gd, (t, eff, eid)) for gd, t, eff, eid in dedges], ref, out, ind + "     ", move,
                             default=lambda out, ind: out.append(f"{ind}break;"))
            out.append(f"{ind}:: else -> break")
            out.append(f"{ind}od;")
        out.append(f"{ind}if")
        for s in range(len(ids)):
            out.append(f"{ind}:: {tok} == {self.x.literal(spec.token, s)} ->")
            self.after_chain(rows[s][g], K, ref, out, ind + "     ", move)
        out.append(f"{ind}fi;")

    def after_chain(self, row, K, ref, out, ind, move):
        def reply(outcome):
            return lambda payload, out, ind: out.append(f"{ind}_reply = {_STATUS_NAMES[payload]};")

        def rest(out, ind):
            if not row.applicable:
                out.append(f"{ind}_reply = FAILURE; /* 3. goal not applicable here */")
                return
            k = min(K, len(row.outcomes) - 1)
            status, effects, oname = row.outcomes[k]
            out.append(f"{ind}/* 4. run {_c(row.site)}: outcome {_c(oname)} ({_STATUS_NAMES[status]}) */")
            self.assign(effects, ref, out, ind, f"outcome {row.site}:{oname}")
            self.cascade([(gd, o) for gd, o, _ in row.markers[status]], ref, out, ind, reply(None),
                         default=lambda out, ind: out.append(f"{ind}_reply = RUNNING;"))
            self.cascade([(gd, (t, eff, eid)) for gd, t, eff, eid in row.edges[status]], ref, out, ind, move)

        self.cascade([(gd, o) for gd, o, _ in row.dmarkers], ref, out, ind, reply(None), default=rest)

    def tick(self, g, pvals, K, ref, out, ind):
        """One FSM request (section 5, 'Requests, goals and parameters')."""
        spec = self.spec
        pslots = spec.param_slots
        wd = spec.withdraw
        if pslots and wd is not None:
            pvals = [_lit(v) for v in pvals]
            differ = " || ".join(f"{ref(p)} != {v}" for p, v in zip(pslots, pvals))
            out.append(f"{ind}if")
            out.append(f"{ind}:: {differ} -> /* retarget: withdraw first */")
            self.drive(wd, K, ref, out, ind + "     ")
            out.append(f"{ind}     if")
            out.append(f"{ind}     :: _reply == SUCCESS -> " + " ".join(f"{ref(p)} = {v};" for p, v in zip(pslots, pvals)))
            out.append(f"{ind}     :: else -> skip")
            out.append(f"{ind}     fi;")
            out.append(f"{ind}     _reply = RUNNING;")
            out.append(f"{ind}:: else ->")
            self.drive(g, K, ref, out, ind + "     ")
            out.append(f"{ind}fi;")
        else:
            for p, v in zip(pslots, pvals):
                out.append(f"{ind}{ref(p)} = {_lit(v)}; /* parameter */")
            self.drive(g, K, ref, out, ind)
        out.append(f"{ind}{ref(spec.goal_slot)} = (_reply == RUNNING -> {g + 1} : 0);")

    # ------------------------------------------------------------ combinations
    def env_options(self):
        """Per environment entry of the spec: the list of its decisions ``(label, guard,
        effects)`` (an event: not happening, happening; a choice: each option)."""
        out = []
        for i in self.spec.env:
            ev = self.spec.model.environment[i]
            if isinstance(ev, EnvChoice):
                out.append([(f"{ev.name}={o.name}", o.guard if o.guard is not None else "always", o.effects) for o in ev.options])
            else:
                out.append([(None, None, ()), (ev.name, ev.guard if ev.guard is not None else "always", ev.effects)])
        return out

    def substitute(self, effects, ref):
        """ref after ``effects``, as expressions of the step's start (for guards)."""
        new = {}
        for name, value in effects:
            slot = self.scope[name]
            new[slot.index] = "(" + self.x(value, self.scope, ref, slot.type, slot.index) + ")"
        if not new:
            return ref
        return lambda k, new=new, ref=ref: new[k] if k in new else ref(k)

    def combos(self):
        spec = self.spec
        inputs = [[(slot, v) for v in vals] for slot, vals in spec.inputs]
        goals = spec.goals
        pcombos = list(itertools.product(*[vals for _, vals in spec.params])) if spec.kind == "fsm" else [()]
        K = max(len(r[0].outcomes) for r in spec.rows)
        env = self.env_options()
        total = len(goals) * len(pcombos) * K
        for opts in env:
            total *= len(opts)
        for vals in inputs:
            total *= len(vals)
        if total > MAX_OPTIONS:
            raise ModelError(f"fsms.{spec.fsm}" if spec.kind == "fsm" else "tree",
                             f"the Promela export would need {total} d_step options (more than {MAX_OPTIONS}): "
                             "too many environment/input/parameter combinations")
        return inputs, goals, pcombos, K, env

    def generate(self) -> str:
        spec = self.spec
        inputs, goals, pcombos, K, env = self.combos()
        options = []
        for ins in itertools.product(*inputs):
            in_map = dict(ins)
            base = self.var_ref(in_map)
            for decisions in itertools.product(*env):
                conds, ref, labels = [], base, []
                for label, guard, effects in decisions:
                    if label is None:
                        continue
                    labels.append(label)
                    if guard != "always":
                        conds.append(self.cond(guard, self.scope, ref))
                    ref = self.substitute(effects, ref)
                for g in goals:
                    gconds = list(conds)
                    if g in spec.pres:
                        gconds.append("(" + " || ".join(self.cond(p, self.scope, ref) for p in spec.pres[g]) + ")")
                    for pv in pcombos:
                        for k in range(K):
                            options.append(self.option(in_map, decisions, g, pv, k, gconds, labels))
        return self.document(options)

    def option(self, in_map, decisions, g, pvals, K, conds, labels) -> list:
        spec, prog = self.spec, self.prog
        f = spec.fsm_obj
        ref = self.var_ref(in_map)
        what = [f"{prog.slots[s].name}={prog.decode_slot(s, v)}" for s, v in in_map.items()] + labels
        if spec.kind == "fsm":
            what.append(f"goal {f.goals[g]}")
            what += [f"{prog.slots[s].name}={prog.decode_slot(s, v)}" for s, v in zip(spec.param_slots, pvals)]
        if K:
            what.append(f"outcome {K}")
        ind = "       "
        out = [f"  :: d_step {{ /* {_c(', '.join(what)) or 'no choice'} */", f"{ind}{' && '.join(conds) or 'true'} ->"]
        for label, _, effects in decisions:
            if label is not None and effects:
                self.assign(effects, ref, out, ind, f"environment {label}")
        if spec.kind == "fsm":
            self.tick(g, pvals, K, ref, out, ind)
        else:
            self.request(K, ref, out, ind)
        after = self.var_ref()  # free inputs are reset after the step
        for name, inv in spec.model.invariants:
            out.append(f"{ind}assert({self.cond(inv, self.scope, after)}); /* invariant {_c(name)} */")
        out.append("     }")
        return out

    def request(self, K, ref, out, ind):
        """The tree's single SkillRequest (docs/semantics.md section 3)."""
        spec, scope = self.spec, self.scope
        node = spec.request
        flag = ref(spec.flag)
        pre = node.pre
        body = []
        pvals = []
        for j, (slot, expr) in enumerate(spec.params):
            info = scope[self.prog.slots[slot].name]
            body.append(f"{ind}_p{j} = {self.x(expr, scope, ref, info.type, slot)};")
            if self.risky(expr, info):
                body.append(f"{ind}assert({info.lo} <= _p{j} && _p{j} <= {info.hi}); /* parameter {_c(self.prog.slots[slot].name)} in domain */")
                body.append(f"{ind}_p{j} = (_p{j} < {_lit(info.lo)} -> {_lit(info.lo)} : (_p{j} > {info.hi} -> {info.hi} : _p{j}));")
            pvals.append(f"_p{j}")
        self.params_needed = max(getattr(self, "params_needed", 0), len(spec.params))
        self.tick(spec.goals[0], pvals, K, ref, body, ind)
        if pre is None:
            out.extend(body)
        else:
            out.append(f"{ind}if")
            out.append(f"{ind}:: !({self.cond(pre, scope, ref)}) -> /* pre fails: FAILURE; a running request withdraws its goal */")
            out.append(f"{ind}     if")
            out.append(f"{ind}     :: {flag} -> {ref(spec.goal_slot)} = 0")
            out.append(f"{ind}     :: else -> skip")
            out.append(f"{ind}     fi;")
            out.append(f"{ind}     _reply = FAILURE;")
            out.append(f"{ind}:: else ->")
            out.extend("     " + line for line in body)
            out.append(f"{ind}fi;")
        if node.post is not None:
            out.append(f"{ind}assert(_reply != SUCCESS || {self.cond(node.post, scope, ref)}); /* post of {_c(node.name)} */")
        out.append(f"{ind}{flag} = (_reply == RUNNING);")

    # ------------------------------------------------------------ the document
    def document(self, options) -> str:
        spec, prog, names = self.spec, self.prog, self.names
        model = spec.model
        level = f"FSM {spec.fsm} as an open system" if spec.kind == "fsm" else f"the whole model (tree: SkillRequest {cast(SkillRequest, spec.request).name})"
        head = [f"/* btfsm model '{_c(model.name)}': {_c(level)}.",
                " * Generated by btfsm.verify.export (btfsm); one d_step = one "
                + ("request of the FSM." if spec.kind == "fsm" else "BT tick."),
                " * Verify: spin -o2 -a FILE.pml && gcc -O2 -DSAFETY -DNOCLAIM -o pan pan.c && ./pan -m100000",
                " * (-o2 keeps write-only variables, so SPIN stores exactly btfsm's states).",
                " * Terminal states (if any) stutter instead of carrying an end label. */", ""]
        head += ["#define RUNNING 0", "#define SUCCESS 1", "#define FAILURE 2"]
        for (k, i), cname in names.const.items():
            head.append(f"#define {cname} {i} /* {_c(prog.slots[k].name)} = {_c(SlotNames.values_of(prog, k)[i])} */")
        head.append("")
        init = prog.initial
        for k in spec.stored:
            info = prog.slots[k]
            head.append(f"{_ptype(prog, info)} {names.var[k]} = {self.x.literal(k, init[k]) if (k, init[k]) in names.const else init[k]}; /* {_c(info.name)} ({info.kind}) */")
        fixed = [f"{prog.slots[k].name} = {v}" for k, v in self.fixed.items() if k not in dict(spec.inputs)]
        if fixed:
            head.append(f"/* not stored (constant at their initial value): {_c(', '.join(fixed))} */")
        if spec.inputs:
            head.append("/* free inputs (a value chosen per step, then reset): "
                        + _c(", ".join(f"{prog.slots[s].name} in {min(v)}..{max(v)}" for s, v in spec.inputs)) + " */")
        head.append("hidden byte _reply;")
        if self.temps:
            head.append("hidden int " + ", ".join(f"_t{k}" for k in range(self.temps)) + ";")
        if getattr(self, "params_needed", 0):
            head.append("hidden int " + ", ".join(f"_p{k}" for k in range(self.params_needed)) + ";")
        head.append("")
        proc = [f"active proctype {names.namer(spec.fsm if spec.kind == 'fsm' else model.name)}() {{"]
        ref = self.var_ref()
        bad0 = [n for n, fn in prog.invariants if not fn(list(init))]
        if bad0:
            proc.append("  /* the initial state violates an invariant */")
            for name, inv in model.invariants:
                if name in bad0:
                    proc.append(f"  assert({self.cond(inv, self.scope, ref)}); /* invariant {_c(name)} */")
        proc.append("  do")
        for opt in options:
            proc.extend(opt)
        term = terminal_expr(spec)
        if term is not None:
            proc.append(f"  :: d_step {{ {self.cond(term, self.scope, ref)} -> skip }} /* terminal: stopping here is intended */")
        proc += ["  od", "}"]
        return "\n".join(head + proc) + "\n"


def _lit(v) -> str:
    """An int constant (negative ones in parentheses: ``--`` is an operator)."""
    return v if isinstance(v, str) else (str(int(v)) if v >= 0 else f"({int(v)})")


def _ptype(prog, info) -> str:
    """The smallest Promela type holding a slot's values."""
    if info.kind == "flag" or (info.kind == "var" and prog.model.var(info.name).kind == "bool"):
        return "bool"
    lo, hi = info.lo, info.lo + info.size - 1
    if 0 <= lo and hi <= 255:
        return "byte"
    if -32768 <= lo and hi <= 32767:
        return "short"
    return "int"


def to_promela(spec: StepSpec) -> str:
    """Promela text of a step description (``btfsm.verify.export.step_spec``)."""
    return _Gen(spec).generate()


# ---------------------------------------------------------------------- running SPIN


def spin_available() -> "str | None":
    """None when ``spin`` and ``gcc`` are on PATH, else what is missing."""
    missing = [t for t in ("spin", "gcc") if shutil.which(t) is None]
    return f"{' and '.join(missing)} not installed" if missing else None


@dataclass
class SpinResult:
    """What one ``pan`` run printed (``None`` where pan did not say)."""

    states: "int | None"
    transitions: "int | None"
    errors: int
    assertion: bool
    invalid_end: bool
    seconds: "float | None"
    memory_states_mb: "float | None"
    memory_total_mb: "float | None"
    vector_bytes: "int | None"
    output: str
    wall: float = 0.0
    rss_mb: "float | None" = None


def _num(pattern, text, cast=float):
    m = re.search(pattern, text, re.M)
    return cast(m.group(1).replace(",", "")) if m else None


def parse_pan(output: str) -> SpinResult:
    """Parse the summary of a ``pan`` run."""
    return SpinResult(
        states=_num(r"^\s*([\d.e+]+) states, stored", output, lambda s: int(float(s))),
        transitions=_num(r"^\s*([\d.e+]+) transitions \(", output, lambda s: int(float(s))),
        errors=_num(r"errors: (\d+)", output, int) or 0,
        assertion="assertion violated" in output,
        invalid_end=re.search(r"pan:\d+: invalid end state", output) is not None,
        seconds=_num(r"elapsed time ([\d.e+]+)", output),
        memory_states_mb=_num(r"^\s*([\d.]+)\s+actual memory usage for states", output),
        memory_total_mb=_num(r"^\s*([\d.]+)\s+total actual memory usage", output),
        vector_bytes=_num(r"State-vector (\d+) byte", output, int),
        output=output,
    )


def compile_pan(text: str, workdir: str, *, spin_flags=(), cc_flags=("-DSAFETY", "-DNOCLAIM"),
                timeout: float = 600.0, name: str = "model") -> str:
    """Write ``text`` to ``workdir``, run ``spin -o2 [spin_flags] -a`` and ``gcc -O2
    [cc_flags]``; return the path of the ``pan`` verifier. RuntimeError when a tool fails."""
    path = os.path.join(workdir, f"{name}.pml")
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(text)
    _run(["spin", "-o2", *spin_flags, "-a", f"{name}.pml"], workdir, timeout, "spin")
    _run(["gcc", "-O2", *cc_flags, "-o", "pan", "pan.c"], workdir, timeout, "gcc")
    return os.path.join(workdir, "pan")


def run_pan(pan: str, pan_flags=("-m100000",), timeout: float = 600.0) -> SpinResult:
    """Run a compiled verifier and parse its summary (``wall``: its wall time,
    ``rss_mb``: its peak resident memory)."""
    t0 = time.perf_counter()
    out, rss = _run_measured([os.path.abspath(pan), *pan_flags], os.path.dirname(os.path.abspath(pan)), timeout)
    wall = time.perf_counter() - t0
    res = parse_pan(out)
    res.wall, res.rss_mb = wall, rss
    if res.states is None:
        raise RuntimeError(f"pan printed no state count:\n{out[-2000:]}")
    if "max search depth too small" in out:
        raise RuntimeError("pan: max search depth too small (raise -m)")
    return res


def run_spin(text: str, *, workdir: "str | None" = None, spin_flags=(), cc_flags=("-DSAFETY", "-DNOCLAIM"),
             pan_flags=("-m100000",), timeout: float = 600.0, name: str = "model") -> SpinResult:
    """Generate, compile and run SPIN's verifier for Promela ``text``; parse its summary.

    ``spin -o2 [spin_flags] -a``, ``gcc -O2 [cc_flags]``, ``./pan [pan_flags]`` in
    ``workdir`` (a fresh temporary folder, removed afterwards, by default)."""
    own = workdir is None
    work: str = tempfile.mkdtemp(prefix="btfsm_spin_") if own else cast(str, workdir)
    try:
        pan = compile_pan(text, work, spin_flags=spin_flags, cc_flags=cc_flags, timeout=timeout, name=name)
        return run_pan(pan, pan_flags, timeout)
    finally:
        if own:
            shutil.rmtree(work, ignore_errors=True)


def _run_measured(cmd, cwd, timeout) -> tuple:
    """(output, peak RSS in MB or None) of a command, reaped with ``os.wait4``."""
    proc = subprocess.Popen(cmd, cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    timer = threading.Timer(timeout, proc.kill)
    timer.start()
    try:
        stdout = cast(IO[str], proc.stdout)  # (stdout=PIPE)
        out = stdout.read()
        stdout.close()
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
    finally:
        timer.cancel()
    if proc.returncode < 0:
        raise RuntimeError(f"{cmd[0]} was killed (signal {-proc.returncode}; timeout {timeout} s?)")
    return out, usage.ru_maxrss / 1024


def _run(cmd, cwd, timeout, what):
    proc = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=timeout)
    if proc.returncode != 0:
        raise RuntimeError(f"{what} failed ({' '.join(cmd)}):\n{(proc.stdout + proc.stderr)[-3000:]}")
