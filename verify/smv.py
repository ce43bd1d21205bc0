"""SMV (nuXmv / NuSMV) export of a ``StepSpec``: one ``MODULE main`` whose transition
relation is one step of the system (docs/semantics.md sections 1, 3 and 5).

* ``VAR``: the stored slots (bounded ranges; bools and running flags ``boolean``);
* ``IVAR``: the step's choices: each environment event (happens or not) and choice (its
  option), the free inputs, the requested goal and parameter values (FSM level) and the
  outcome index of the primitive that runs;
* ``DEFINE``: the step as a chain of stages in single-assignment form (``env1_x`` is x
  after the first environment entry, ``chain2_x`` after two direct edges, ``run_x`` after
  the primitive's outcome, ``edge_x`` after the edge), with ``reply`` the FSM's reply;
* ``ASSIGN``: ``init`` and ``next`` of every variable;
* ``TRANS``: which choices are possible (an event happens only when its guard holds, a
  choice takes an enabled option, a goal is requestable, the outcome index exists), so
  states where nothing is possible have no successor (btfsm's dead states);
* ``INVARSPEC`` per invariant (and per SkillRequest ``post`` contract, through a
  ``contract_ok`` variable), ``CTLSPEC AG EF workable``.

The output is checked by this project's tests with a small evaluator of the subset it
uses (tests/test_export.py), **not against nuXmv**, which could not be installed here.
Effects that leave a variable's domain make the assignment out of range (nuXmv stops
with a range error; btfsm reports a DomainError).

>>> from btfsm.models.pickplace import pickplace
>>> from btfsm.verify.export import step_spec
>>> text = to_smv(step_spec(pickplace(3)))
>>> "AG EF workable" in text and "INVARSPEC NAME inv_grasp_needs_part" in text
True
"""
from __future__ import annotations

from typing import cast

from btfsm.bt import SkillRequest
from btfsm.escape import comment_text as _c
from btfsm.expr import BOOL, INT, BinOp, BoolOp, Call, Compare, Const, IfElse, Name, Unary, check
from btfsm.model import EnvChoice

from .promela import Namer, SlotNames
from .stepspec import StepSpec, int_bounds, terminal_expr

__all__ = ["to_smv", "SMV_RESERVED"]

SMV_RESERVED = frozenset("""
MODULE VAR IVAR FROZENVAR DEFINE CONSTANTS ASSIGN INIT TRANS INVAR SPEC CTLSPEC LTLSPEC PSLSPEC INVARSPEC
COMPUTE FAIRNESS JUSTICE COMPASSION ISA PRED MIRROR MIN MAX TRUE FALSE case esac next init mod in union self
process array of boolean integer real word signed unsigned xor xnor A E F G X U V W AG AF AX EG EF EX AU EU
ABF EBF ABG EBG O H Y Z S T bool count toint swconst uwconst extend resize sizeof floor abs max min sin cos
exp tan ln pi word1 READ WRITE typeof set constarray clock running
RUNNING SUCCESS FAILURE reply outcome workable contract_ok domain_ok effects_in_domain terminal
""".split())

_STATUS_NAMES = ("RUNNING", "SUCCESS", "FAILURE")


class _Smv:
    """btfsm expression ASTs as SMV text (fully parenthesised)."""

    def __init__(self, names: SlotNames, bools: set):
        self.names, self.bools = names, bools

    def literal(self, slot, index) -> str:
        name = self.names.const.get((slot, index)) if slot is not None else None
        return name or (str(index) if index >= 0 else f"(-{-index})")

    def __call__(self, e, scope, ref, expected=None, hint=None) -> str:
        x = self.__call__
        if isinstance(e, Const):
            if isinstance(e.value, bool):
                return "TRUE" if e.value else "FALSE"
            if isinstance(e.value, int):
                return str(e.value) if e.value >= 0 else f"(-{-e.value})"
            return self.literal(hint, expected.values.index(e.value))
        if isinstance(e, Name):
            return ref(scope[e.id].index)
        if isinstance(e, Unary):
            return f"(!{x(e.arg, scope, ref, BOOL)})" if e.op == "not" else f"(-{x(e.arg, scope, ref, INT)})"
        if isinstance(e, BoolOp):
            return "(" + (" & " if e.op == "and" else " | ").join(x(a, scope, ref, BOOL) for a in e.args) + ")"
        if isinstance(e, Compare):
            lit_l = isinstance(e.left, Const) and isinstance(e.left.value, str)
            lt = None if lit_l else check(e.left, scope, "export")
            rt = check(e.right, scope, "export", lt)
            lt = lt or rt
            lh = scope[e.left.id].index if isinstance(e.left, Name) else None
            rh = scope[e.right.id].index if isinstance(e.right, Name) else None
            op = {"==": "=", "!=": "!="}.get(e.op, e.op)
            return f"({x(e.left, scope, ref, lt, rh)} {op} {x(e.right, scope, ref, rt, lh)})"
        if isinstance(e, BinOp):
            a, b = x(e.left, scope, ref, INT), x(e.right, scope, ref, INT)
            if e.op == "//":  # floor division by a positive constant, whatever '/' rounds to
                return f"(({a} >= 0) ? ({a} / {b}) : (-(({b} - 1 - {a}) / {b})))"
            if e.op == "%":
                return f"((({a} mod {b}) + {b}) mod {b})"
            return f"({a} {e.op} {b})"
        if isinstance(e, Call):
            args = [x(a, scope, ref, INT) for a in e.args]
            if e.fn == "abs":
                return f"(({args[0]} < 0) ? (-{args[0]}) : {args[0]})"
            a, b = args
            return f"(({a} <= {b}) ? {a} : {b})" if e.fn == "min" else f"(({a} >= {b}) ? {a} : {b})"
        if isinstance(e, IfElse):
            return f"({x(e.cond, scope, ref, BOOL)} ? {x(e.then, scope, ref, expected, hint)} : {x(e.other, scope, ref, expected, hint)})"
        raise TypeError(f"not an expression: {e!r}")


def _case(branches, default) -> str:
    """``case c1 : v1; ...; TRUE : default; esac`` (just ``default`` without branches)."""
    if not branches:
        return default
    return "case " + " ".join(f"{c} : {v};" for c, v in branches) + f" TRUE : {default}; esac"


def _any(parts) -> str:
    parts = [p for p in parts if p != "FALSE"]
    if "TRUE" in parts:
        return "TRUE"
    return parts[0] if len(parts) == 1 else ("(" + " | ".join(parts) + ")" if parts else "FALSE")


def _all(parts) -> str:
    parts = [p for p in parts if p != "TRUE"]
    if "FALSE" in parts:
        return "FALSE"
    return parts[0] if len(parts) == 1 else ("(" + " & ".join(parts) + ")" if parts else "TRUE")


def _not(x: str) -> str:
    return {"TRUE": "FALSE", "FALSE": "TRUE"}.get(x, f"!{x}")


class _Gen:
    def __init__(self, spec: StepSpec):
        self.spec, self.prog = spec, spec.program
        prog = self.prog
        self.names = SlotNames(spec, SMV_RESERVED)
        self.namer: Namer = self.names.namer
        self.bools = {k for k in spec.stored if prog.slots[k].kind == "flag"
                      or (prog.slots[k].kind == "var" and prog.model.var(prog.slots[k].name).kind == "bool")}
        self.x = _Smv(self.names, self.bools)
        self.scope = prog.scope
        self.fscope = prog.fsm_scope(spec.fsm_obj)
        self.fixed = spec.fixed()
        self.defines: list = []
        self.trans: list = []
        self.ivars: list = []
        self.domain_checks: list = []  # "this effect's value is in range when applied"
        self.risky: set = set()  # slots some effect may push out of range

    # ------------------------------------------------------------ helpers
    def const(self, k, v) -> str:
        if k in self.bools or self._is_bool(k):
            return "TRUE" if v else "FALSE"
        return self.x.literal(k, v) if (k, v) in self.names.const else (str(v) if v >= 0 else f"(-{-v})")

    def _is_bool(self, k) -> bool:
        info = self.prog.slots[k]
        return info.kind == "flag" or (info.kind == "var" and self.prog.model.var(info.name).kind == "bool")

    def define(self, base: str, text: str) -> str:
        name = self.namer(base)
        self.defines.append((name, text))
        return name

    def ref_of(self, cur: dict):
        return lambda k: cur[k]

    def cond(self, guard, scope, cur) -> str:
        return "TRUE" if guard is None else self.x(guard, scope, self.ref_of(cur), BOOL)

    def value(self, name, value, cur, when="TRUE") -> str:
        """The text of an effect's value; one that may leave its domain (static bounds)
        adds the check "``when`` implies it is in range" to ``effects_in_domain``."""
        slot = self.scope[name]
        text = self.x(value, self.scope, self.ref_of(cur), slot.type, slot.index)
        if slot.type == INT and self._risky(value, slot):
            self.domain_checks.append(f"({_not(when)} | (({text}) >= {slot.lo} & ({text}) <= {slot.hi}))"
                                      if when != "TRUE" else f"(({text}) >= {slot.lo} & ({text}) <= {slot.hi})")
            self.risky.add(slot.index)
        return text

    def _risky(self, value, slot) -> bool:

        b = int_bounds(value, self.scope)
        return b is None or b[0] < slot.lo or b[1] > slot.hi

    def stage(self, prefix: str, cur: dict, changes: dict) -> dict:
        """Define ``prefix_x`` for every changed slot; the new ``cur``."""
        new = dict(cur)
        for k, text in changes.items():
            new[k] = self.define(f"{prefix}_{self.prog.slots[k].name}", text)
        return new

    def ivar(self, base: str, typ: str) -> str:
        name = self.namer(base)
        self.ivars.append((name, typ))
        return name

    # ------------------------------------------------------------ the step
    def generate(self) -> str:
        spec, prog = self.spec, self.prog
        cur = {}
        for k in range(len(prog.slots)):
            cur[k] = self.names.var[k] if k in self.names.var else self.const(k, self.fixed[k])
        for slot, values in spec.inputs:  # free inputs: any value this step
            typ = "boolean" if self._is_bool(slot) else f"{min(values)}..{max(values)}"
            cur[slot] = self.ivar(f"in_{prog.slots[slot].name}", typ)
        cur = self.environment(cur)
        if spec.kind == "fsm":
            final, reply = self.fsm_request(cur)
            post = None
        else:
            final, reply, post = self.tree_request(cur)
        return self.document(final, reply, post)

    def environment(self, cur):
        for n, i in enumerate(self.spec.env, 1):
            ev = self.spec.model.environment[i]
            if isinstance(ev, EnvChoice):
                opts = ev.options
                var = self.ivar(f"choice_{ev.name}", f"0..{len(opts) - 1}") if len(opts) > 1 else None
                changes = {}
                for k, o in enumerate(opts):
                    pick = f"({var} = {k})" if var else "TRUE"
                    self.trans.append(f"{pick} -> {self.cond(o.guard, self.scope, cur)}")
                    for name, value in o.effects:
                        slot = self.scope[name].index
                        changes.setdefault(slot, []).append((pick, self.value(name, value, cur, pick)))
                cur = self.stage(f"env{n}", cur, {k: _case(br, cur[k]) for k, br in changes.items()})
            else:
                var = self.ivar(f"event_{ev.name}", "boolean")
                self.trans.append(f"{var} -> {self.cond(ev.guard, self.scope, cur)}")
                changes = {self.scope[name].index: _case([(var, self.value(name, value, cur, var))], cur[self.scope[name].index])
                           for name, value in ev.effects}
                cur = self.stage(f"env{n}", cur, changes)
        return cur

    def fsm_request(self, cur):
        spec, prog = self.spec, self.prog
        goals = spec.goals
        if len(goals) > 1:
            gv = self.ivar("request_goal", "{" + ", ".join(str(g) for g in goals) + "}")
        else:
            gv = str(goals[0])
        for g, pres in spec.pres.items():
            self.trans.append(f"({gv} = {g}) -> {_any([self.cond(p, self.scope, cur) for p in pres])}")
        pvals = []
        for slot, values in spec.params:
            typ = "boolean" if self._is_bool(slot) else f"{min(values)}..{max(values)}"
            pvals.append(self.ivar(f"request_{prog.slots[slot].name}", typ) if len(values) > 1 else self.const(slot, values[0]))
        return self.tick(cur, gv, pvals)

    def tree_request(self, cur):
        spec, prog = self.spec, self.prog
        node = spec.request
        pre = self.define("pre_ok", self.cond(node.pre, self.scope, cur)) if node.pre is not None else "TRUE"
        pvals = []
        for slot, expr in spec.params:
            info = self.scope[prog.slots[slot].name]
            v = self.define(f"request_{prog.slots[slot].name}", self.x(expr, self.scope, self.ref_of(cur), info.type, slot))
            if info.type == INT and self._risky(expr, info):  # btfsm: a DomainError
                self.domain_checks.append(f"({_not(pre)} | ({v} >= {info.lo} & {v} <= {info.hi}))")
                self.risky.add(slot)
            pvals.append(v)
        n_checks = len(self.domain_checks)
        after, reply = self.tick(cur, str(spec.goals[0]), pvals)
        if pre != "TRUE":  # the FSM's effects only happen when the request passes its pre
            self.domain_checks[n_checks:] = [f"({_not(pre)} | {c})" for c in self.domain_checks[n_checks:]]
        gs, flag = spec.goal_slot, spec.flag
        final = {}
        for k in range(len(prog.slots)):
            if k == gs:  # pre fails: a running request withdraws its goal
                final[k] = f"({pre} ? {after[k]} : ({cur[flag]} ? 0 : {cur[k]}))"
            elif after[k] != cur[k]:
                final[k] = f"({pre} ? {after[k]} : {cur[k]})"
            else:
                final[k] = cur[k]
        status = self.define("status", f"({pre} ? {reply} : FAILURE)")
        final[flag] = f"({status} = RUNNING)"
        post = None
        if node.post is not None:
            post = f"!(({status} = SUCCESS) & !{self.cond(node.post, self.scope, final)})"
        return final, status, post

    def tick(self, cur, gv, pvals):
        """One FSM request of goal ``gv`` with parameter values ``pvals`` (texts)."""
        spec = self.spec
        pslots = spec.param_slots
        wd = spec.withdraw
        gs = spec.goal_slot
        if pslots:
            differ = self.define("retarget", _any([f"({cur[p]} != {v})" for p, v in zip(pslots, pvals)]))
        if pslots and wd is None:  # immediate: adopt, then drive
            cur = self.stage("params", cur, dict(zip(pslots, pvals)))
        dg = gv
        if pslots and wd is not None:
            dg = self.define("driven_goal", f"({differ} ? {wd} : {gv})")
        after, reply = self.drive(cur, dg)
        if pslots and wd is not None:  # withdraw: adopt once the withdraw goal succeeded
            after = dict(after)
            for p, v in zip(pslots, pvals):
                after[p] = f"(({differ} & ({reply} = SUCCESS)) ? {v} : {after[p]})"
            reply = self.define("reply", f"({differ} ? RUNNING : {reply})")
        after = dict(after)
        after[gs] = f"(({reply} = RUNNING) ? ({gv} + 1) : 0)"
        return after, reply

    def drive(self, cur, dg):
        """Steps 1-6 of docs/semantics.md section 5 for the goal ``dg`` (a text)."""
        spec, rows = self.spec, self.spec.rows
        f = spec.fsm_obj
        tok = spec.token
        n = len(f.states)
        goals = range(len(f.goals))
        eorder = {e.id: i for i, e in enumerate(f.edges)}
        morder = {m.id: i for i, m in enumerate(f.markers)}

        def serves(edge_goals):
            gs = sorted(edge_goals)
            return _any([f"({dg} = {g})" for g in gs]) if len(gs) < len(f.goals) else "TRUE"

        def at(s, c=None):
            return f"({(c or cur)[tok]} = {self.x.literal(tok, s)})"

        # 1. direct edges, unrolled: a chain has at most n - 1 moves
        dedges = [(s, [(e, [g for g in goals if e in rows[s][g].dedges]) for e in _unique(
            (item for g in goals for item in rows[s][g].dedges), eorder)]) for s in range(n)]
        if any(items for _, items in dedges):
            for k in range(1, n):
                fires, tchanges, vchanges = [], [], {}
                for s, items in dedges:
                    earlier = []
                    for (guard, target, effects, eid), gs in items:
                        en = _all([serves(gs), self.cond(guard, self.fscope, cur)])
                        fire = self.define(f"chain{k}_{eid}", _all([at(s), *[_not(e) for e in earlier], en]))
                        earlier.append(en)
                        fires.append(fire)
                        tchanges.append((fire, self.x.literal(tok, target)))
                        moved = dict(cur)
                        moved[tok] = self.x.literal(tok, target)
                        for name, value in effects:
                            vchanges.setdefault(self.scope[name].index, []).append((fire, self.value(name, value, moved, fire)))
                changes = {tok: _case(tchanges, cur[tok])}
                changes.update({kk: _case(br, cur[kk]) for kk, br in vchanges.items()})
                cur = self.stage(f"chain{k}", cur, changes)
        # 2. direct markers
        dm_fires, dm_values = [], []
        for s in range(n):
            items = [(m, [g for g in goals if m in rows[s][g].dmarkers]) for m in _unique(
                (item for g in goals for item in rows[s][g].dmarkers), morder)]
            earlier = []
            for (guard, outcome, mid), gs in items:
                en = _all([serves(gs), self.cond(guard, self.fscope, cur)])
                fire = self.define(f"direct_{mid}", _all([at(s), *[_not(e) for e in earlier], en]))
                earlier.append(en)
                dm_fires.append(fire)
                dm_values.append((fire, _STATUS_NAMES[outcome]))
        has_dm = self.define("direct_reply", _any(dm_fires)) if dm_fires else "FALSE"
        # 3. applicable here?
        app_parts = []
        for s in range(n):
            gs = [g for g in goals if rows[s][g].applicable]
            if gs:
                app_parts.append(_all([at(s), serves(gs)]))
        applicable = self.define("applicable", _any(app_parts))
        runs = self.define("runs", _all([_not(has_dm), applicable]))
        # 4. run the state once: outcome effects and status
        K = max(len(rows[s][0].outcomes) for s in range(n))
        ov = self.ivar("outcome", f"0..{K - 1}") if K > 1 else None
        nout = _case([(at(s), str(len(rows[s][0].outcomes))) for s in range(n)], "1")
        if ov:
            self.trans.append(f"({runs} -> ({ov} < {nout})) & (!{runs} -> ({ov} = 0))")
        status_br, vchanges = [], {}
        for s in range(n):
            for k, (status, effects, _) in enumerate(rows[s][0].outcomes):
                pick = _all([at(s)] + ([f"({ov} = {k})"] if ov else []))
                status_br.append((pick, _STATUS_NAMES[status]))
                for name, value in effects:
                    when = _all([runs, pick])
                    vchanges.setdefault(self.scope[name].index, []).append((when, self.value(name, value, cur, when)))
        status = self.define("run_status", _case(status_br, "SUCCESS"))
        cur = self.stage("run", cur, {kk: _case(br, cur[kk]) for kk, br in vchanges.items()})
        # 5. markers and 6. edges on the status
        m_values, tchanges, vchanges = [], [], {}
        for s in range(n):
            for st in range(3):
                items = [(m, [g for g in goals if m in rows[s][g].markers[st]]) for m in _unique(
                    (item for g in goals for item in rows[s][g].markers[st]), morder)]
                earlier = []
                for (guard, outcome, mid), gs in items:
                    en = _all([serves(gs), self.cond(guard, self.fscope, cur)])
                    fire = self.define(f"marker_{mid}", _all([runs, at(s), f"({status} = {_STATUS_NAMES[st]})",
                                                              *[_not(e) for e in earlier], en]))
                    earlier.append(en)
                    m_values.append((fire, _STATUS_NAMES[outcome]))
                items = [(e, [g for g in goals if e in rows[s][g].edges[st]]) for e in _unique(
                    (item for g in goals for item in rows[s][g].edges[st]), eorder)]
                earlier = []
                for (guard, target, effects, eid), gs in items:
                    en = _all([serves(gs), self.cond(guard, self.fscope, cur)])
                    fire = self.define(f"edge_{eid}", _all([runs, at(s), f"({status} = {_STATUS_NAMES[st]})",
                                                            *[_not(e) for e in earlier], en]))
                    earlier.append(en)
                    tchanges.append((fire, self.x.literal(tok, target)))
                    moved = dict(cur)
                    moved[tok] = self.x.literal(tok, target)
                    for name, value in effects:
                        vchanges.setdefault(self.scope[name].index, []).append((fire, self.value(name, value, moved, fire)))
        reply = self.define("fsm_reply", _case(dm_values + [(_not(applicable), "FAILURE")] + m_values, "RUNNING"))
        changes = {tok: _case(tchanges, cur[tok])}
        changes.update({kk: _case(br, cur[kk]) for kk, br in vchanges.items()})
        cur = self.stage("edge", cur, changes)
        return cur, reply

    # ------------------------------------------------------------ the module
    def document(self, final, reply, post) -> str:
        spec, prog, names = self.spec, self.prog, self.names
        model = spec.model
        level = f"FSM {spec.fsm} as an open system" if spec.kind == "fsm" else f"the whole model (tree: SkillRequest {cast(SkillRequest, spec.request).name})"
        out = [f"-- btfsm model '{_c(model.name)}': {_c(level)}; one transition = one "
               + ("request of the FSM." if spec.kind == "fsm" else "BT tick."),
               "-- Generated by btfsm.verify.export (btfsm). Not tested against nuXmv (not installable here);",
               "-- checked by btfsm's tests with an evaluator of this subset. Run: nuXmv -int, then",
               "-- go; check_invar; check_ctlspec  (or NuSMV FILE.smv).",
               "MODULE main"]
        out.append("VAR")
        init = prog.initial
        for k in spec.stored:
            info = prog.slots[k]
            typ = "boolean" if self._is_bool(k) else f"{info.lo}..{info.lo + info.size - 1}"
            out.append(f"  {names.var[k]} : {typ}; -- {_c(info.name)} ({info.kind})")
        if post is not None:
            out.append("  contract_ok : boolean; -- no SkillRequest post contract broken so far")
        if self.domain_checks:
            out.append("  domain_ok : boolean; -- no effect has left its variable's domain so far")
        if self.ivars:
            out.append("IVAR")
            for name, typ in self.ivars:
                out.append(f"  {name} : {typ};")
        checks = self.domain_checks
        for k in sorted(k for k in self.risky if k in names.var):  # clamp: next() stays in range
            lo, hi = prog.slots[k].lo, prog.slots[k].lo + prog.slots[k].size - 1
            v = self.define(f"next_{prog.slots[k].name}", final[k])
            final = dict(final)
            final[k] = f"(({v} < {lo}) ? {lo} : (({v} > {hi}) ? {hi} : {v}))"
        if checks:
            self.defines.append(("effects_in_domain", _all(checks)))
        out.append("DEFINE")
        out += ["  RUNNING := 0;", "  SUCCESS := 1;", "  FAILURE := 2;"]
        for (k, i), cname in names.const.items():
            out.append(f"  {cname} := {i}; -- {_c(prog.slots[k].name)} = {_c(SlotNames.values_of(prog, k)[i])}")
        for name, text in self.defines:
            out.append(f"  {name} := {text};")
        ref = lambda k: names.var[k] if k in names.var else self.const(k, self.fixed[k])  # noqa: E731
        work = model.workable
        from btfsm.expr import Compare, Name, BoolOp

        if work is None:  # default: every FSM token on its initial state
            parts = [Compare("==", Name(f"{f.name}.state"), Const(f.initial)) for f in model.fsms]
            work = parts[0] if len(parts) == 1 else (BoolOp("and", tuple(parts)) if parts else Const(True))
        out.append(f"  workable := {self.x(work, self.scope, ref, BOOL)};")
        term = terminal_expr(spec)
        if term is not None:
            out.append(f"  terminal := {self.x(term, self.scope, ref, BOOL)}; -- stopping here is intended")
        out.append("ASSIGN")
        for k in spec.stored:
            out.append(f"  init({names.var[k]}) := {self.const(k, init[k])};")
            out.append(f"  next({names.var[k]}) := {final[k]};")
        if checks:
            out.append("  init(domain_ok) := TRUE;")
            out.append("  next(domain_ok) := domain_ok & effects_in_domain;")
        if post is not None:
            out.append("  init(contract_ok) := TRUE;")
            out.append(f"  next(contract_ok) := contract_ok & {post};")
        for t in self.trans:
            out.append(f"TRANS {t};")
        for name, inv in model.invariants:
            out.append(f"INVARSPEC NAME {self.namer('inv_' + name)} := {self.x(inv, self.scope, ref, BOOL)};")
        if post is not None:
            out.append(f"INVARSPEC NAME {self.namer('post_' + cast(SkillRequest, spec.request).name)} := contract_ok;")
        if self.domain_checks:
            out.append(f"INVARSPEC NAME {self.namer('effects_in_domain')} := domain_ok;")
        out.append(f"CTLSPEC NAME {self.namer('agef_workable')} := AG EF workable;")
        return "\n".join(out) + "\n"


def _unique(items, order: dict) -> list:
    """Edges or markers (tuples ending with their id) without repeats, in declaration
    order (``order``: id -> index), so "the first enabled one" means what it does in btfsm."""
    seen: dict = {}
    for it in items:
        seen.setdefault(it[-1], it)
    return sorted(seen.values(), key=lambda it: order[it[-1]])


def to_smv(spec: StepSpec) -> str:
    """nuXmv/NuSMV text of a step description (``btfsm.verify.export.step_spec``)."""
    return _Gen(spec).generate()
