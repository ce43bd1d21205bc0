"""Exports: Promela structure and naming, SMV (parsed and *executed* by a small evaluator
of the subset the exporter emits: its reachable states, dead states, invariant verdicts
and AG EF workable must be btfsm's), dot, files and errors.

nuXmv is not installable here, so the SMV output is never run by nuXmv in these tests.
"""
from __future__ import annotations

import itertools
import operator
import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings

from btfsm import (FSM, Action, Bool, Edge, Enum, EnvEvent, Int, Marker, Model, ReactiveFallback, SkillRequest,
                   State, success)
from btfsm.errors import ModelError
from btfsm.expr import BOOL, compile_fn
from btfsm.models.pickplace import pickplace
from test_spin_crosscheck import SPIN_MISSING, feature_model, seeded_models, spin_verdicts
from btfsm.verify.explore import explore, explore_fsm
from btfsm.verify.export import DOT_MAX_STATES, export, step_spec, to_dot
from btfsm.verify.system import reverse_reach

# ---------------------------------------------------------------------- an SMV evaluator

_TOKEN = re.compile(r"\s*(?:(--[^\n]*)|(\d+)|([A-Za-z_][A-Za-z0-9_#$]*)|(\.\.|:=|->|!=|<=|>=|[-+*/()=<>!&|?:;{},]))")


def _tokens(text):
    pos, out = 0, []
    while pos < len(text):
        m = _TOKEN.match(text, pos)
        if not m or m.end() == pos:
            if text[pos:].strip() == "":
                break
            raise SyntaxError(f"bad character at {text[pos:pos + 20]!r}")
        pos = m.end()
        if m.group(1):
            continue
        if m.group(2) is not None:
            out.append(int(m.group(2)))
        else:
            out.append(m.group(3) or m.group(4))
    return out


class _Parser:
    """Expressions: ``-> ? | & comparisons + - * / mod ! -`` and ``case ... esac``."""

    def __init__(self, toks):
        self.t, self.i = toks, 0

    def peek(self):
        return self.t[self.i] if self.i < len(self.t) else None

    def take(self, want=None):
        tok = self.peek()
        if want is not None and tok != want:
            raise SyntaxError(f"expected {want!r}, got {tok!r} at token {self.i}")
        self.i += 1
        return tok

    def expr(self):
        a = self.ternary()
        if self.peek() == "->":
            self.take()
            return ("->", a, self.expr())
        return a

    def ternary(self):
        c = self.binary(0)
        if self.peek() == "?":
            self.take()
            a = self.ternary()
            self.take(":")
            return ("?", c, a, self.ternary())
        return c

    _LEVELS = (("|",), ("&",), ("=", "!=", "<", "<=", ">", ">="), ("+", "-"), ("*", "/", "mod"))

    def binary(self, level):
        if level == len(self._LEVELS):
            return self.unary()
        a = self.binary(level + 1)
        while self.peek() in self._LEVELS[level]:
            op = self.take()
            a = (op, a, self.binary(level + 1))
        return a

    def unary(self):
        tok = self.peek()
        if tok in ("!", "-"):
            self.take()
            return ("neg" if tok == "-" else "!", self.unary())
        if tok == "(":
            self.take()
            e = self.expr()
            self.take(")")
            return e
        if tok == "case":
            self.take()
            branches = []
            while self.peek() != "esac":
                c = self.expr()
                self.take(":")
                v = self.expr()
                self.take(";")
                branches.append((c, v))
            self.take("esac")
            return ("case", branches)
        self.take()
        if isinstance(tok, int):
            return ("int", tok)
        if tok in ("TRUE", "FALSE"):
            return ("bool", tok == "TRUE")
        return ("name", tok)


# SMV's comparison and arithmetic operators ('/' and 'mod' round toward zero: Smv.value)
_SMV_BINARY = {"=": operator.eq, "!=": operator.ne, "<": operator.lt, "<=": operator.le, ">": operator.gt,
               ">=": operator.ge, "+": operator.add, "-": operator.sub, "*": operator.mul}


class Smv:
    """A parsed module: variables with domains, inputs, defines, init/next, constraints."""

    def __init__(self, text):
        self.vars, self.ivars, self.defines, self.init, self.next = {}, {}, {}, {}, {}
        self.trans, self.invarspecs, self.ctlspecs = [], {}, {}
        section = None
        for stmt in self._statements(text):
            head = stmt[0]
            if head in ("MODULE",):
                continue
            if head in ("VAR", "IVAR", "DEFINE", "ASSIGN"):
                section, stmt = head, stmt[1:]
                if not stmt:
                    continue
                head = stmt[0]
            if head == "TRANS":
                self.trans.append(_Parser(stmt[1:]).expr())
                section = None
            elif head == "INVARSPEC":
                assert stmt[1] == "NAME" and stmt[3] == ":="
                self.invarspecs[stmt[2]] = _Parser(stmt[4:]).expr()
            elif head == "CTLSPEC":
                assert stmt[1] == "NAME" and stmt[3] == ":="
                self.ctlspecs[stmt[2]] = stmt[4:]
            elif section in ("VAR", "IVAR"):
                name, colon, *typ = stmt
                assert colon == ":", stmt
                (self.vars if section == "VAR" else self.ivars)[name] = self._domain(typ)
            elif section == "DEFINE":
                name, eq, *rest = stmt
                assert eq == ":=", stmt
                assert name not in self.defines, f"{name} defined twice"
                self.defines[name] = _Parser(rest).expr()
            elif section == "ASSIGN":
                kind, _, name, _, eq, *rest = stmt
                assert kind in ("init", "next") and eq == ":=", stmt
                (self.init if kind == "init" else self.next)[name] = _Parser(rest).expr()
            else:
                raise SyntaxError(f"statement outside a section: {stmt[:6]}")

    @staticmethod
    def _statements(text):
        toks = _tokens(text)
        cur, depth = [], 0
        for tok in toks:
            if tok in ("VAR", "IVAR", "DEFINE", "ASSIGN", "MODULE") and not cur:
                yield [tok] if tok != "MODULE" else ["MODULE"]
                continue
            if tok == "main" and not cur:
                continue
            if tok == "case":
                depth += 1
            elif tok == "esac":
                depth -= 1
            if tok == ";" and depth == 0:
                yield cur
                cur = []
            else:
                cur.append(tok)
        assert not cur, f"unterminated statement {cur[:8]}"

    @staticmethod
    def _domain(typ):
        if typ == ["boolean"]:
            return (False, True)
        if typ[0] == "{":
            return tuple(x for x in typ[1:-1] if x != ",")
        cut = typ.index("..")

        def num(toks):
            return -toks[1] if toks[0] == "-" else toks[0]
        return tuple(range(num(typ[:cut]), num(typ[cut + 1:]) + 1))

    # ------------------------------------------------------------ evaluation
    def value(self, e, env, memo):
        kind = e[0]
        if kind == "int" or kind == "bool":
            return e[1]
        if kind == "name":
            n = e[1]
            if n in env:
                return env[n]
            if n not in memo:
                memo[n] = self.value(self.defines[n], env, memo)
            return memo[n]
        op = _SMV_BINARY.get(kind)
        if op is not None:
            return op(self.value(e[1], env, memo), self.value(e[2], env, memo))
        if kind == "!":
            return not self.value(e[1], env, memo)
        if kind == "neg":
            return -self.value(e[1], env, memo)
        if kind == "case":
            for c, v in e[1]:
                if self.value(c, env, memo):
                    return self.value(v, env, memo)
            raise ValueError("case without a true branch")
        if kind == "?":
            return self.value(e[2] if self.value(e[1], env, memo) else e[3], env, memo)
        if kind == "->":
            return (not self.value(e[1], env, memo)) or bool(self.value(e[2], env, memo))
        a, b = self.value(e[1], env, memo), self.value(e[2], env, memo)
        if kind == "&":
            return bool(a) and bool(b)
        if kind == "|":
            return bool(a) or bool(b)
        if kind == "/":
            q = abs(a) // abs(b)
            return q if (a >= 0) == (b > 0) else -q
        if kind == "mod":
            return a - b * self.value(("/", ("int", a), ("int", b)), env, memo)
        raise ValueError(f"unknown operator {kind!r}")

    def initial(self):
        s = {n: self.value(self.init[n], {}, {}) for n in self.vars}
        return tuple(s[n] for n in self.vars)

    def successors(self, state):
        env0 = dict(zip(self.vars, state))
        names = list(self.ivars)
        out = []
        for combo in itertools.product(*(self.ivars[n] for n in names)):
            env = dict(env0, **dict(zip(names, combo)))
            memo = {}
            if all(self.value(t, env, memo) for t in self.trans):
                nxt = tuple(self.value(self.next[n], env, memo) for n in self.vars)
                for n, v in zip(self.vars, nxt):
                    assert v in self.vars[n], f"next({n}) = {v} is outside {self.vars[n]}"
                out.append(nxt)
        return out

    def reach(self, limit=5000):
        init = self.initial()
        seen, order, edges = {init: 0}, [init], []
        i = 0
        while i < len(order):
            for t in self.successors(order[i]):
                if t not in seen:
                    seen[t] = len(order)
                    order.append(t)
                    assert len(order) <= limit
                edges.append((i, seen[t]))
            i += 1
        return order, edges

    def holds(self, expr, state):
        return bool(self.value(expr, dict(zip(self.vars, state)), {}))


def _btfsm_projection(ts, smv):
    """Our states as tuples in the SMV variables' order (bools as bools)."""
    spec = step_spec(ts.model, ts.fsm)
    prog = ts.model.program
    names = [n for n in smv.vars if n not in ("contract_ok", "domain_ok")]
    assert len(names) == len(spec.stored)
    out = set()
    for row in ts.states:
        vals = []
        for k, v in zip(spec.stored, row):
            info = prog.slots[k]
            is_bool = info.kind == "flag" or (info.kind == "var" and prog.model.var(info.name).kind == "bool")
            vals.append(bool(v) if is_bool else int(v))
        out.add(tuple(vals))
    return names, out


def check_smv_against_btfsm(model, fsm):
    ts = explore_fsm(model, fsm) if fsm else explore(model)
    text = export(model, "smv", fsm=fsm)
    smv = Smv(text)
    spec = step_spec(model, fsm)
    prog = model.program
    # ranges match the model's domains
    for k in spec.stored:
        info = prog.slots[k]
        name = next(n for n in smv.vars if n == _var_name(text, info.name))
        dom = smv.vars[name]
        assert len(dom) == info.size and (dom == (False, True) or (dom[0], dom[-1]) == (info.lo, info.lo + info.size - 1))
    order, edges = smv.reach()
    names, ours = _btfsm_projection(ts, smv)
    idx = [list(smv.vars).index(n) for n in names]
    proj = {tuple(s[i] for i in idx) for s in order}
    bad_smv = any(not smv.holds(e, s) for e in smv.invarspecs.values() for s in order)
    bad_ours = bool(ts.violations) or bool(ts.errors) or any(
        not all(fn(list(ts.full_state(i))) for _, fn in prog.invariants) for i in range(ts.n_states))
    assert bad_smv == bad_ours, f"invariant verdicts: smv {bad_smv}, btfsm {bad_ours}\n{text}"
    if ts.errors:
        return  # SMV clamps the value and goes on (flagged by domain_ok); btfsm stops
    assert proj == ours, f"states: smv-only {sorted(proj - ours)[:3]}, btfsm-only {sorted(ours - proj)[:3]}\n{text}"
    assert len(order) == ts.n_states or any(n in smv.vars for n in ("contract_ok",))
    has_succ = {a for a, _ in edges}
    dead = {tuple(order[i][j] for j in idx) for i in range(len(order)) if i not in has_succ}
    assert len(dead) == len(ts.dead)  # projected: contract_ok may split a state in two
    # AG EF workable: the same verdict as backward reachability on btfsm's graph
    work = smv.defines["workable"]
    w_smv = np.array([smv.holds(work, s) for s in order])
    back = _backward(len(order), edges, w_smv)
    w_ours_fn = compile_fn(model.workable, prog.scope, "workable", BOOL) if model.workable is not None else prog.workable
    w_ours = np.array([bool(w_ours_fn(list(ts.full_state(i)))) for i in range(ts.n_states)])
    assert back.all() == reverse_reach(ts, w_ours).all()


def _backward(n, edges, targets):
    seen = targets.copy()
    preds = [[] for _ in range(n)]
    for a, b in edges:
        preds[b].append(a)
    todo = list(np.flatnonzero(seen))
    while todo:
        j = todo.pop()
        for i in preds[j]:
            if not seen[i]:
                seen[i] = True
                todo.append(i)
    return seen


def _var_name(text, slot_name):
    m = re.search(rf"^  (\w+) : [^;]+; -- {re.escape(slot_name)} \(", text, re.M)
    return m.group(1)


# ---------------------------------------------------------------------- SMV tests


def test_smv_pickplace_runs_like_btfsm():
    check_smv_against_btfsm(pickplace(1), None)
    check_smv_against_btfsm(pickplace(1, dead=True), "skill")


@pytest.mark.parametrize("fsm", [None, "arm"])
def test_smv_hand_written_features_run_like_btfsm(fsm):
    check_smv_against_btfsm(feature_model(), fsm)


def test_smv_pickplace_bug_is_an_invariant_violation():
    smv = Smv(export(pickplace(1, bug=True), "smv"))
    order, _ = smv.reach()
    assert any(not smv.holds(smv.invarspecs["inv_grasp_needs_part"], s) for s in order)


def test_smv_sections_and_ranges():
    text = export(pickplace(3), "smv")
    smv = Smv(text)
    assert {"area", "goal", "grip", "queue", "skill_state", "robot_step_running"} <= set(smv.vars)
    assert smv.vars["queue"] == (0, 1, 2, 3) and smv.vars["grip"] == (False, True)
    assert set(smv.ivars) == {"choice_request", "event_arrive"}
    assert set(smv.invarspecs) >= {"inv_grasp_needs_part", "inv_release_needs_part"}
    assert list(smv.ctlspecs.values()) == [["AG", "EF", "workable"]]
    assert "nuXmv" in text.splitlines()[1]  # says it is untested against nuXmv


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(seeded_models(tree=False))
def test_smv_random_fsm_level_runs_like_btfsm(model):
    check_smv_against_btfsm(model, "f")


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(seeded_models(tree=True, wild=True))
def test_smv_random_whole_models_run_like_btfsm(model):
    check_smv_against_btfsm(model, None)


# ---------------------------------------------------------------------- Promela


def test_promela_one_d_step_per_combination():
    text = export(pickplace(3), "promela")
    assert text.count(":: d_step {") == 4 * 2  # 4 goal options x (arrival or not) x 1 outcome
    assert "active proctype pickplace3()" in text and "assert(" in text
    fsm_text = export(pickplace(3), "promela", fsm="skill")
    assert "active proctype skill()" in fsm_text and fsm_text.count(":: d_step {") == 8


def _awkward_model():
    """Names that are Promela/SMV keywords or collide once escaped."""
    arm = FSM("do", states=[State("od", outcomes=[success(skip="min(skip + 1, 2)")]), State("if")], goals=["timeout"],
              edges=[Edge("od", "if", ["timeout"], guard="skip == 2"), Edge("if", "od", ["timeout"])],
              markers=[Marker("if", ["timeout"])])
    return Model("int", variables=[Int("skip", 0, 2), Bool("len"), Enum("esac", ("case", "next"))], fsms=[arm],
                 tree=SkillRequest("run", fsm="do", goal="timeout"),
                 environment=[EnvEvent("init", "not len", {"len": True, "esac": "'next'"})])


def test_promela_escapes_keywords():
    text = export(_awkward_model(), "promela")
    decls = re.findall(r"^(?:bool|byte|short|int) (\w+) =", text, re.M)
    from btfsm.verify.promela import PROMELA_RESERVED

    assert decls and not set(decls) & PROMELA_RESERVED
    assert len(set(decls)) == len(decls)
    if SPIN_MISSING is None:
        ts = explore(_awkward_model())
        assert spin_verdicts(text)[:2] == (ts.n_states, 0)


def test_smv_escapes_keywords():
    check_smv_against_btfsm(_awkward_model(), None)
    text = export(_awkward_model(), "smv")
    from btfsm.verify.smv import SMV_RESERVED

    assert not set(Smv(text).vars) & SMV_RESERVED


# ---------------------------------------------------------------------- dot, files, errors


def test_dot_of_a_small_system():
    arm = FSM("arm", states=[State("a", outcomes=[success(n="min(n + 1, 2)")])], goals=["go"], edges=[Edge("a", "a", ["go"])],
              markers=[Marker("a", ["go"])])
    m = Model("count", variables=[Int("n", 0, 2)], fsms=[arm], tree=SkillRequest("r", fsm="arm", goal="go"))
    text = export(m, "dot")
    assert text.startswith('digraph "count" {') and text.rstrip().endswith("}")
    assert len(re.findall(r"^  s\d+ \[label=", text, re.M)) == explore(m).n_states == 3
    assert "s0 -> s1" in text and "arm/a:success" in text
    fsm_text = export(m, "dot", fsm="arm")
    assert 'digraph "count: FSM arm"' in fsm_text


def test_dot_marks_dead_states():
    ts = explore(pickplace(1, dead=True))
    text = to_dot(ts)
    assert text.count("doubleoctagon") == len(ts.dead) > 0


def test_dot_refuses_large_systems():
    with pytest.raises(ModelError, match=f"at most {DOT_MAX_STATES} states"):
        export(pickplace(3), "dot")


def test_export_writes_the_file(tmp_path):
    out = tmp_path / "pp.pml"
    text = export(pickplace(3), "promela", output=str(out))
    assert out.read_text() == text
    from btfsm.errors import UsageError

    export(pickplace(3), "smv", output=str(tmp_path / "missing" / "x.smv"))  # folders are created (btfsm.outputs)
    assert (tmp_path / "missing" / "x.smv").read_text().startswith("--")
    with pytest.raises(UsageError, match="cannot write"):  # a path under a file
        export(pickplace(3), "smv", output=str(out / "x.smv"))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["missing", "pp.pml"]  # nothing half-written


def test_export_errors_name_the_problem():
    m = pickplace(3)
    with pytest.raises(ModelError, match="unknown export format"):
        export(m, "prism")
    with pytest.raises(ModelError, match="no FSM named 'arm'"):
        export(m, "promela", fsm="arm")
    arm = FSM("arm", states=[State("a")], goals=["go"], edges=[Edge("a", "a", ["go"])])
    tree = ReactiveFallback("root", [Action("act", outcomes=[success()]), SkillRequest("r", fsm="arm", goal="go")])
    with pytest.raises(ModelError, match=r"tree: .*single SkillRequest.*ReactiveFallback"):
        export(Model("t", fsms=[arm], tree=tree), "smv")
    assert "active proctype arm()" in export(Model("t", fsms=[arm], tree=tree), "promela", fsm="arm")
    sub = FSM("sub", states=[State("a", subtree=Action("inner", outcomes=[success()]))], goals=["go"])
    with pytest.raises(ModelError, match=r"fsms\.sub\.states\.a\.subtree"):
        export(Model("s", fsms=[sub]), "promela")
