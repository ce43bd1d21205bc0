"""The expression language (docs/semantics.md section 7): what the parser accepts and
rejects, the text round trip, type checking with element paths, and agreement of the
Python, numpy and z3 translations with a small reference evaluator written here."""
from __future__ import annotations

import os

import numpy as np
import pytest
import z3
from hypothesis import HealthCheck, given, settings
from memo_strategies import st

from btfsm import (FSM, Action, Bool, Condition, Edge, Enum, EnvEvent, Int, Marker, Model, ModelError,
                   SkillRequest, State, parse, success, to_text, v)
from btfsm.errors import DomainError
from btfsm.expr import (BOOL, INT, BinOp, BoolOp, Call, Compare, Const, IfElse, Name, Scope, Slot, Type, Unary,
                        check, check_effects, compile_effects, compile_fn, names_in, to_numpy_source, to_z3)

from core_strategies import expr_env, parser_form_exprs, typed_exprs

PROPS = settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])

VARS = [Bool("p"), Bool("q", True), Int("n", -3, 4), Int("m", 0, 5),
        Enum("mode", ("idle", "busy", "fault")), Enum("side", ("left", "right"))]
SCOPE = Scope.of(VARS)
ENV = expr_env(VARS)
MODE = Type("enum", ("idle", "busy", "fault"))


# --------------------------------------------------------------------------- parser: accepted


def cmp(op, a, b):
    return Compare(op, a, b)


N, P, Q, X = Name("n"), Name("p"), Name("q"), Name("x")

ACCEPTED = [
    ("queue > 0 and not holding", BoolOp("and", (cmp(">", Name("queue"), Const(0)), Unary("not", Name("holding"))))),
    ("p or q or x", BoolOp("or", (P, Q, X))),
    ("(p or q) or x", BoolOp("or", (P, Q, X))),  # flattened
    ("p and (q or x)", BoolOp("and", (P, BoolOp("or", (Q, X))))),
    ("not not p", Unary("not", Unary("not", P))),
    ("n == 1", cmp("==", N, Const(1))),
    ("n != 1", cmp("!=", N, Const(1))),
    ("1 < n <= 3", BoolOp("and", (cmp("<", Const(1), N), cmp("<=", N, Const(3))))),  # chains
    ("0 <= n < m >= 2", BoolOp("and", (cmp("<=", Const(0), N), cmp("<", N, Name("m")), cmp(">=", Name("m"), Const(2))))),
    ("n + 2 * m - 1", BinOp("-", BinOp("+", N, BinOp("*", Const(2), Name("m"))), Const(1))),
    ("n // 2 % 3", BinOp("%", BinOp("//", N, Const(2)), Const(3))),
    ("n - (m - 1)", BinOp("-", N, BinOp("-", Name("m"), Const(1)))),
    ("-3", Const(-3)),
    ("-n", Unary("-", N)),
    ("+n", N),
    ("- -3", Const(3)),
    ("min(n, 2) + max(n, m) + abs(n)", BinOp("+", BinOp("+", Call("min", (N, Const(2))), Call("max", (N, Name("m")))),
                                              Call("abs", (N,)))),
    ("n if p else 2", IfElse(P, N, Const(2))),
    ("a if p else b if q else c", IfElse(P, Name("a"), IfElse(Q, Name("b"), Name("c")))),
    ("mode in ('idle', 'busy')", BoolOp("or", (cmp("==", Name("mode"), Const("idle")), cmp("==", Name("mode"), Const("busy"))))),
    ("mode in ('idle',)", cmp("==", Name("mode"), Const("idle"))),
    ("mode not in ('idle', 'busy')", Unary("not", BoolOp("or", (cmp("==", Name("mode"), Const("idle")),
                                                                cmp("==", Name("mode"), Const("busy")))))),
    ("mode == 'busy'", cmp("==", Name("mode"), Const("busy"))),
    ('mode == "busy"', cmp("==", Name("mode"), Const("busy"))),
    ("true", Const(True)),
    ("false", Const(False)),
    ("True", Const(True)),
    ("FALSE", Const(False)),
    ("arm.state == 'home'", cmp("==", Name("arm.state"), Const("home"))),
    ("arm.goal != 'none'", cmp("!=", Name("arm.goal"), Const("none"))),
    ("arm.target", Name("arm.target")),
    ("  n  ", N),
]


@pytest.mark.parametrize("text, expected", ACCEPTED, ids=[t for t, _ in ACCEPTED])
def test_parser_accepts_documented_syntax(text, expected):
    assert repr(parse(text)) == repr(expected)


def test_builder_matches_parser():
    assert ((v.queue > 0) & ~v.holding).node == parse("queue > 0 and not holding")
    assert ((v.n + 1) * 2 >= v.m).node == parse("(n + 1) * 2 >= m")
    assert (v.p | v.q | v.x).node == parse("p or q or x")
    # beside a comparison a plain str is an enum value, not expression syntax
    assert (v["arm.state"] == "home").node == parse("arm.state == 'home'")
    assert v.mode.isin("idle", "busy").node == parse("mode in ('idle', 'busy')")
    assert (-v.n).node == parse("-n") and (3 - v.n).node == parse("3 - n")
    with pytest.raises(TypeError):
        bool(v.n > 1)  # Python's and/or/not cannot build expressions


# --------------------------------------------------------------------------- parser: rejected

SENTINEL = "/tmp/btfsm_expr_sentinel_must_not_exist"

REJECTED = [
    "foo(1)", "min(1)", "min(1, 2, 3)", "abs(n, m)", "max(n, m, key=n)", "min(*n)", "abs(*n)", "n.bit_length()",
    "a.b.c", "x.__class__.__mro__", "().__class__", "'a'.upper()", "(n + 1).real",
    "lambda: 1", "lambda x: x", "n[0]", "n[1:2]", "2 ** 3", "n ** 2", "f'{n}'", "f'x'", "(y := 3)",
    f"__import__('os').system('touch {SENTINEL}')", f"open('{SENTINEL}', 'w')", "exec('1')", "eval('1')",
    "[x for x in n]", "{x for x in n}", "(x for x in n)", "{1: 2}", "[1, 2]", "{1}", "(1, 2)", "()",
    "1.5", "1e3", "1j", "b'x'", "None", "...", "n if p", "a = 1", "import os", "n is m", "n is not m",
    "n / 2", "n << 1", "n >> 1", "n & m", "n | m", "n ^ m", "~n", "n @ m", "*n", "await n", "yield n",
    "mode in modes", "mode in ()", "mode in ('a',) < 1", "not", "", "   ", "n +", "(n", "n)",
    "\x00", "n\n+\n1", "# comment", "n; m", "if n: m",
]


@pytest.mark.parametrize("text", REJECTED)
def test_parser_rejects_everything_else(text):
    if os.path.exists(SENTINEL):
        os.remove(SENTINEL)
    with pytest.raises(ModelError) as err:
        parse(text)
    assert err.value.problem  # says what is wrong
    assert not os.path.exists(SENTINEL)  # nothing was executed


@pytest.mark.parametrize("text", ["(" * 500 + "n" + ")" * 500, "not " * 5000 + "p", "-" * 10000 + "1",
                                  "1" + " + 1" * 20000, "n" + " < n" * 3000])
def test_parser_survives_hostile_sizes(text):
    """Deep or long input is parsed or refused with a ModelError, never a crash."""
    try:
        e = parse(text)
    except ModelError:
        return
    assert names_in(e) <= {"n", "p"}


def test_parser_rejects_non_strings():
    for bad in (None, 3.5, b"n", ["n"]):
        with pytest.raises(ModelError):
            parse(bad)


def test_attribute_names_are_resolved_not_evaluated():
    """``a.b`` is one dotted name, looked up in the scope: ``p.__class__`` is unknown."""
    e = parse("p.__class__")
    assert e == Name("p.__class__")
    with pytest.raises(ModelError, match="unknown name"):
        check(e, SCOPE, "guard")


# --------------------------------------------------------------------------- text round trip


@PROPS
@given(parser_form_exprs())
def test_to_text_round_trips(e):
    assert repr(parse(to_text(e))) == repr(e)  # repr: Const(True) and Const(1) differ


@PROPS
@given(typed_exprs(ENV, max_depth=4))
def test_to_text_round_trips_typed(pair):
    e, t = pair
    back = parse(to_text(e))
    assert check(back, SCOPE, "x") == t
    # the same meaning (parse may flatten and/or and fold -constants)
    for state in ([0, 0, -3, 0, 0, 0], [1, 1, 4, 5, 2, 1], [1, 0, 0, 3, 1, 0]):
        assert compile_fn(back, SCOPE, "x")(state) == compile_fn(e, SCOPE, "x")(state)


# --------------------------------------------------------------------------- type checking

TYPE_ERRORS = [
    ("nope > 1", "unknown name 'nope'"),
    ("mode == busy", "unknown name 'busy'"),  # enum values are quoted
    ("mode == 'asleep'", "'asleep' is not one of idle, busy, fault"),
    ("'asleep' == mode", "'asleep' is not one of"),
    ("mode in ('idle', 'asleep')", "'asleep' is not one of"),
    ("n == 9", "outside the domain of n"),
    ("9 > n", "outside the domain of n"),
    ("n >= -4", "outside the domain of n"),
    ("p + 1 > 0", "expected int"),
    ("n and p", "expected bool"),
    ("not n", "expected bool"),
    ("-p > 0", "expected int"),
    ("mode < mode", "needs ints"),
    ("p < q", "needs ints"),
    ("p == 1", "cannot compare bool with int"),
    ("mode == side", "cannot compare"),
    ("mode == 1", "cannot compare"),
    ("'idle' == 'busy'", "can only be compared with or assigned to an enum"),
    ("n // m > 0", "positive integer constant"),
    ("n % 0 > 0", "positive integer constant"),
    ("n // -2 > 0", "positive integer constant"),
    ("min(p, 1) > 0", "expected int"),
    ("abs(mode) > 0", "expected int"),
    ("(p if q else n) > 0", "branches have different types"),
    ("(n if 1 else n) > 0", "expected bool"),
]


@pytest.mark.parametrize("text, problem", TYPE_ERRORS, ids=[t for t, _ in TYPE_ERRORS])
def test_type_errors_name_the_element(text, problem):
    with pytest.raises(ModelError) as err:
        check(parse(text), SCOPE, "fsms.arm.edges.a->b.guard")
    assert err.value.element == "fsms.arm.edges.a->b.guard"
    assert problem in err.value.problem


@pytest.mark.parametrize("text, problem", TYPE_ERRORS[:6] + TYPE_ERRORS[8:12], ids=[t for t, _ in TYPE_ERRORS[:6] + TYPE_ERRORS[8:12]])
def test_model_type_errors_name_the_element(text, problem):
    """Built into a model, the same errors name the node (file loading adds the file)."""
    with pytest.raises(ModelError) as err:
        Model("m", variables=VARS, tree=Condition("ready", text))
    assert err.value.element == "tree.ready.expr" and problem in err.value.problem


@pytest.mark.parametrize("text, kind", [("n", "int"), ("n + 1", "int"), ("mode", "enum"), ("min(n, m)", "int")])
def test_conditions_must_be_bool(text, kind):
    """A condition (guard, pre, post...) of another type is a type error when built."""
    with pytest.raises(ModelError) as err:
        Model("m", variables=VARS, tree=Condition("ready", text))
    assert err.value.element == "tree.ready.expr" and kind in err.value.problem
    with pytest.raises(ModelError) as err:
        compile_fn(parse(text), SCOPE, "guard", BOOL)
    assert err.value.element == "guard"


def test_skill_parameters_must_match_their_type():
    f = FSM("arm", states=[State("s")], goals=["g"], markers=[Marker("s", ["g"])], params=[Int("t", 0, 3)])
    with pytest.raises(ModelError) as err:
        Model("m", variables=VARS, fsms=[f], tree=SkillRequest("r", fsm="arm", goal="g", params={"t": "p"}))
    assert err.value.element == "tree.r.params.t"


def test_element_paths_across_a_model():
    """Every place an expression lives names itself in the error."""
    def err_of(**kw):
        with pytest.raises(ModelError) as err:
            Model("m", variables=VARS, **kw)
        return err.value.element

    assert err_of(tree=Action("a", outcomes=[success(n="n + p")])) == "tree.a.outcomes.success.n"
    assert err_of(tree=Action("a", outcomes=[success(n="9")])) == "tree.a.outcomes.success.n"
    assert err_of(tree=Condition("c", "p"), environment=[EnvEvent("e", "zz", {})]) == "environment.e.guard"
    assert err_of(tree=Condition("c", "p"), environment=[EnvEvent("e", None, {"mode": "'off'"})]) == "environment.e.effects.mode"
    arm = FSM("arm", states=[State("a"), State("b")], goals=["g"], edges=[Edge("a", "b", ["g"], guard="n > m + p")])
    assert err_of(fsms=[arm]) == "fsms.arm.edges.a->b.guard"
    arm = FSM("arm", states=[State("a")], goals=["g"], markers=[Marker("a", ["g"], guard="arm.state == 'c'")])
    assert err_of(fsms=[arm]) == "fsms.arm.markers.a:success.guard"
    assert err_of(tree=Condition("c", "p"), invariants={"safe": "n < 99"}) == "invariants.safe"


def test_effects_are_checked():
    for effects, element, problem in [
        ((("zz", Const(1)),), "e.zz", "unknown variable"),
        ((("n", Const(1)), ("n", Const(2))), "e.n", "assigned twice"),
        ((("n", Const(True)),), "e.n", "assigns bool to n"),
        ((("n", Const(5)),), "e.n", "outside the domain"),
        ((("mode", Const("off")),), "e.mode", "'off' is not one of"),
        ((("p", Name("mode")),), "e.p", "assigns enum"),
    ]:
        with pytest.raises(ModelError) as err:
            check_effects(effects, SCOPE, "e")
        assert err.value.element == element and problem in err.value.problem, (effects, err.value)
    ro = Scope(SCOPE)
    ro["arm.state"] = Slot(9, MODE, 0, 2, writable=False)
    with pytest.raises(ModelError, match="cannot be assigned"):
        check_effects((("arm.state", Const("idle")),), ro, "e")


def test_effects_out_of_domain_at_run_time():
    apply = compile_effects((("n", parse("n + m")),), SCOPE, "tree.a.outcomes.go")
    s = [0, 0, 3, 1, 0, 0]
    apply(s)
    assert s[2] == 4
    with pytest.raises(DomainError) as err:
        apply(s)
    assert (err.value.var, err.value.value, err.value.where) == ("n", 5, "tree.a.outcomes.go")
    assert s[2] == 4  # nothing written


# --------------------------------------------------------------------------- translations agree


def reference(e, env):
    """A tiny direct evaluator over user values (bool, int, enum value strings)."""
    if isinstance(e, Const):
        return e.value
    if isinstance(e, Name):
        return env[e.id]
    if isinstance(e, Unary):
        x = reference(e.arg, env)
        return (not x) if e.op == "not" else -x
    if isinstance(e, BoolOp):
        vals = [bool(reference(a, env)) for a in e.args]
        return all(vals) if e.op == "and" else any(vals)
    if isinstance(e, Compare):
        a, b = reference(e.left, env), reference(e.right, env)
        return {"==": a == b, "!=": a != b, "<": a < b, "<=": a <= b, ">": a > b, ">=": a >= b}[e.op]
    if isinstance(e, BinOp):
        a, b = reference(e.left, env), reference(e.right, env)
        return {"+": a + b, "-": a - b, "*": a * b, "//": a // b if b else None, "%": a % b if b else None}[e.op]
    if isinstance(e, Call):
        args = [reference(a, env) for a in e.args]
        return {"min": min, "max": max, "abs": abs}[e.fn](*args)
    return reference(e.then, env) if reference(e.cond, env) else reference(e.other, env)


def _states():
    return st.tuples(*[st.integers(x.lo, x.hi) for x in VARS])


def _user(t, raw):
    """A translation's raw result as a user value of type t."""
    if t == BOOL:
        assert raw in (True, False), f"bool result {raw!r}"
        return bool(raw)
    if t == INT:
        return int(raw)
    return t.values[int(raw)]


@PROPS
@given(typed_exprs(ENV, max_depth=4), st.lists(_states(), min_size=1, max_size=8))
def test_translations_agree(pair, states):
    """Python closure, numpy over a batch of states and z3 (substituted, simplified) all
    agree with the reference evaluator on random well-typed expressions."""
    e, t = pair
    assert check(e, SCOPE, "x") == t
    expected = [reference(e, {x.name: x.decode(val) for x, val in zip(VARS, s)}) for s in states]
    fn = compile_fn(e, SCOPE, "x", t)
    assert [_user(t, fn(list(s))) for s in states] == expected
    cols = np.array(states, dtype=np.int64).T
    got = np.broadcast_to(np.asarray(eval(to_numpy_source(e, SCOPE), {"np": np, "c": cols})), (len(states),))  # noqa: S307
    assert [_user(t, x.item()) for x in got] == expected
    zv = {x.name: z3.Int(x.name) for x in VARS}
    term = to_z3(e, SCOPE, zv)
    for s, want in zip(states, expected):
        r = z3.simplify(z3.substitute(term, *[(zv[x.name], z3.IntVal(val)) for x, val in zip(VARS, s)]))
        raw = z3.is_true(r) if t == BOOL else r.as_long()
        if t == BOOL:
            assert z3.is_true(r) or z3.is_false(r), r
        assert _user(t, raw) == want


@pytest.mark.parametrize("text", ["not true", "false == (not true)", "not (1 > 2)", "(not false) and p"])
def test_numpy_negates_constants(text):
    """Minimal case of the agreement property: ``not`` of a constant in numpy."""
    e = parse(text)
    cols = np.array([[0], [1], [0], [0], [0], [0]], dtype=np.int64)
    want = compile_fn(e, SCOPE, "x", BOOL)([0, 1, 0, 0, 0, 0])
    got = np.asarray(eval(to_numpy_source(e, SCOPE), {"np": np, "c": cols})).ravel()[0]  # noqa: S307
    assert got in (True, False) and bool(got) == bool(want)


def test_compile_fn_reads_fsm_names():
    """``arm.state`` / ``arm.goal`` / parameters compile against a model's scope."""
    arm = FSM("arm", states=[State("home"), State("work")], goals=["go"], params=[Int("t", 0, 2)],
              edges=[Edge("home", "work", ["go"], guard="t == 2 and arm.goal == 'go'")], markers=[Marker("work", ["go"])])
    m = Model("m", variables=[Bool("p")], fsms=[arm], tree=Condition("c", "arm.state == 'work' and arm.t >= 1"))
    p = m.program
    fn = compile_fn(parse("arm.state == 'work' and arm.t >= 1"), p.scope, "x", BOOL)
    s = list(p.initial)
    assert fn(s) is False
    s[p.scope["arm.state"].index], s[p.scope["arm.t"].index] = 1, 1
    assert fn(s) is True


def test_negated_constant_is_checked_like_the_folded_one():
    """``-(4)`` built by hand and ``-4`` parsed (folded to one constant) give the same verdict
    (hypothesis found ``not n == -4`` passing as a tree and failing after a round trip)."""
    from btfsm.expr import Compare, Const, Name, Unary

    for e in (Compare("==", Name("n"), Unary("-", Const(4))), parse("n == -4")):
        with pytest.raises(ModelError, match="outside the domain of n"):
            check(e, SCOPE, "x")
    assert check(Compare("==", Name("n"), Unary("-", Const(3))), SCOPE, "x") == BOOL
