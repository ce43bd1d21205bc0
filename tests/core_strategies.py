"""Helpers and hypothesis strategies for the core tests (semantics table, expressions,
runtime, FSM validation).

Two halves:

* table helpers: ``act`` builds an Action whose outcomes are named after their statuses,
  ``TableOracle`` answers exactly the outcomes a test row scripts (and fails when any
  other primitive runs), ``run_rows`` ticks a model through rows of ``Tick`` and checks
  the root status, the running flags and the halts of each tick;
* strategies: well-typed random expressions (``typed_exprs``), parser-normal-form ASTs
  (``parser_form_exprs``), random trees (``trees``) and random whole models with skill
  FSMs and an environment (``models``), plus ``ModOracle`` (random oracle answers that
  shrink well) and ``pick_events`` (environment events a runtime may observe).

Every generated model is valid by construction: int effects are clamped into their
domain, direct FSM edges only go forward (no direct cycle), every environment choice
has an unguarded option, and no FSM subtree requests a skill.
"""
from __future__ import annotations

import random
from dataclasses import dataclass, replace

from memo_strategies import st

from btfsm import (FSM, Action, Bool, Condition, Edge, Effects, Enum, EnvChoice, EnvEvent,
                   ForceFailure, ForceSuccess, Guard, Int, Inverter, Marker, MemoryFallback,
                   MemorySequence, Model, Outcome, Parallel, ReactiveFallback, ReactiveSequence,
                   Repeat, Retry, SkillRequest, State, Status, walk)
from btfsm.expr import BOOL, INT, BinOp, BoolOp, Call, Compare, Const, IfElse, Name, Type, Unary
from btfsm.oracles import Oracle

__all__ = [
    "act", "Tick", "TableOracle", "ModOracle", "run_rows", "running_nodes", "slot_of",
    "events", "parents_of", "typed_exprs", "parser_form_exprs", "expr_env", "trees",
    "models", "variables", "to_reactive", "pick_events", "STATUS_LETTERS", "every_question_model",
]

STATUS_LETTERS = {"R": "running", "S": "success", "F": "failure"}
_STATUS_OF = {"R": Status.RUNNING, "S": Status.SUCCESS, "F": Status.FAILURE}


# --------------------------------------------------------------------------- table helpers


def act(name: str, statuses: str = "RSF", **effects) -> Action:
    """An Action with one inline outcome per status letter, named running/success/failure.

    ``effects`` maps a letter to that outcome's effects: ``act("a", "SF", S={"n": "n + 1"})``.

    >>> [o.name for o in act("a", "SF").outcomes]
    ['success', 'failure']
    """
    outs = [Outcome(_STATUS_OF[c], effects.get(c, ()), STATUS_LETTERS[c]) for c in statuses]
    return Action(name, outcomes=outs)


@dataclass(frozen=True)
class Tick:
    """One row of a table test.

    ``script``: ``"a:S b:R"``, the primitives that must run this tick, in order, and the
    outcome each has (a letter, or an outcome name). ``status``: the root status letter.
    ``running``: the nodes whose running flag must be set afterwards (None: unchecked).
    ``halts``: the nodes halted this tick, in order (None: unchecked). ``env``: the
    environment events (or choice options) that happen this tick.
    """

    script: str = ""
    status: str = ""
    running: "str | None" = None
    halts: "str | None" = None
    env: str = ""


class TableOracle(Oracle):
    """Answers exactly the scripted outcomes, in order; anything else fails the test.

    Records the sites the step function halted (``halted``, site labels), which
    environment events it asked about (``asked_env``) and ``log``: ("outcome", label)
    and ("halt", label) in the order they happened."""

    def __init__(self, program, script: str = "", env: str = ""):
        self.program = program
        self.expected = [_split(item) for item in script.split()]
        self.pos = 0
        self.env_names = set(env.split())
        self.halted: list = []
        self.asked_env: list = []
        self.log: list = []

    def env(self, i):
        name = self.program.env[i][0]
        self.asked_env.append(name)
        return name in self.env_names

    def choose(self, i, enabled):
        options = self.program.env[i][3]
        named = [k for k, opt in enumerate(enabled) if options[opt][0] in self.env_names]
        if not named and len(enabled) == 1:
            return 0  # the only enabled option is taken anyway
        assert len(named) == 1, f"choice {self.program.env[i][0]}: script names {len(named)} enabled options"
        return named[0]

    def outcome(self, site):
        assert self.pos < len(self.expected), f"{site.label} ran, but the script has no more outcomes"
        label, name = self.expected[self.pos]
        assert site.label == label, f"{site.label} ran where the script expects {label} (point {self.pos})"
        self.pos += 1
        self.log.append(("outcome", label))
        names = [o[2] for o in site.outcomes]
        assert name in names, f"{label} has no outcome {name!r} ({names})"
        return names.index(name)

    def halt(self, site):
        self.halted.append(site.label)
        self.log.append(("halt", site.label))

    def finished(self) -> None:
        rest = self.expected[self.pos:]
        assert not rest, f"scripted primitives did not run: {rest}"


def _split(item: str) -> tuple:
    label, _, out = item.rpartition(":")
    return label, STATUS_LETTERS.get(out, out)


class ModOracle(Oracle):
    """Random answers that shrink well: choice point k gets ``numbers[k] % arity``, cycling
    through ``numbers`` from ``offset`` (pass the last oracle's ``pos`` to go on). Records
    the choices (``taken``, a ScriptOracle script) and the halted sites (``halted``,
    labels). Only real choices (two or more options) consume a number."""

    def __init__(self, numbers=(), offset: int = 0):
        self.numbers, self.pos, self.halted, self.taken = tuple(numbers) or (0,), offset, [], []

    def _pick(self, n: int) -> int:
        c = self.numbers[self.pos % len(self.numbers)] % n
        self.pos += 1
        self.taken.append(c)
        return c

    def env(self, i):
        return self._pick(2) == 1

    def choose(self, i, enabled):
        return self._pick(len(enabled)) if len(enabled) > 1 else 0

    def outcome(self, site):
        return self._pick(len(site.outcomes)) if len(site.outcomes) > 1 else 0

    def halt(self, site):
        self.halted.append(site.label)


def every_question_model() -> Model:
    """A small model whose ticks ask an oracle every kind of question (the shared suites of
    the oracles and the engines use it): an environment event, an environment choice,
    primitives with several outcomes and a running one that a reactive fallback preempts
    (so ``halt`` is called)."""
    return Model("questions", variables=[Bool("part", False), Int("n", 0, 2)],
                 environment=[EnvEvent("arrive", "not part", {"part": True}),
                              EnvChoice("light", [EnvEvent("red", None, {"n": 0}),
                                                  EnvEvent("green", "n < 2", {"n": "n + 1"})])],
                 tree=ReactiveFallback("root", [Condition("full", "n == 2"),
                                                ReactiveSequence("seq", [Condition("has", "part"),
                                                                         act("pick", "RSF", S={"part": False})]),
                                                act("wait", "RS")]))


def slot_of(program, name: str) -> int:
    """Index of the state slot called ``name`` (``"a:running"``, ``"seq:child"``, ``"n"``)."""
    for i, info in enumerate(program.slots):
        if info.name == name:
            return i
    raise KeyError(name)


def running_nodes(program, state) -> set:
    """Names of the nodes whose running flag is set in ``state``."""
    return {info.name[: -len(":running")] for info, val in zip(program.slots, state)
            if info.kind == "flag" and val}


def events(step, *kinds) -> list:
    """The step's recorded events of the given kinds (all when none given)."""
    return [e for e in step.events if not kinds or e[0] in kinds]


def run_rows(model, rows, state=None):
    """Tick ``model`` through ``rows`` (Tick), checking each; returns (step, oracle) per tick."""
    program = model.program
    s = program.initial if state is None else state
    steps = []
    for k, row in enumerate(rows):
        oracle = TableOracle(program, row.script, row.env)
        step = program.step(s, oracle, record=True)
        oracle.finished()
        where = f"tick {k} ({row.script!r})"
        if row.status:
            assert step.status == int(_STATUS_OF[row.status]), \
                f"{where}: root {Status(step.status).name}, expected {_STATUS_OF[row.status].name}"
        if row.running is not None:
            assert running_nodes(program, step.state) == set(row.running.split()), \
                f"{where}: running {sorted(running_nodes(program, step.state))}, expected {row.running.split()}"
        if row.halts is not None:
            halted = [e[1] for e in step.events if e[0] == "halt"]
            assert halted == row.halts.split(), f"{where}: halted {halted}, expected {row.halts.split()}"
        steps.append((step, oracle))
        s = step.state
    return steps


def parents_of(model) -> dict:
    """Node name -> parent name (None for the tree root and FSM subtree roots)."""
    out = {}
    for _, root in model.roots():
        out[root.name] = None
        for node in walk(root):
            for child in node.children_of():
                out[child.name] = node.name
    return out


def to_reactive(node):
    """The same tree with every memory composite replaced by its reactive twin."""
    kids = node.children_of()
    if not kids:
        return node
    if isinstance(node, MemorySequence):
        return ReactiveSequence(node.name, [to_reactive(c) for c in kids])
    if isinstance(node, MemoryFallback):
        return ReactiveFallback(node.name, [to_reactive(c) for c in kids])
    if hasattr(node, "children"):
        return replace(node, children=tuple(to_reactive(c) for c in kids))
    return replace(node, child=to_reactive(node.child))


def pick_events(program, state, rng: random.Random, forced: bool = True) -> list:
    """Names of environment events (and choice options) to observe this tick, chosen with
    ``rng`` among those the model enables, evaluated in declaration order like a tick.

    ``forced=False`` leaves out a choice's option when it was the only enabled one (the
    tick takes it anyway)."""
    s = list(state)
    out = []
    for name, guard, eff, options in program.env:
        if options is not None:
            enabled = [o for o in options if o[1] is None or o[1](s)]
            if not enabled:
                return out  # blocked; the caller's tick will say so
            name, _, eff, _ = rng.choice(enabled)
            if len(enabled) == 1 and not forced:
                name = None
        elif not ((guard is None or guard(s)) and rng.random() < 0.5):
            continue
        if eff is not None:
            eff(s)
        if name is not None:
            out.append(name)
    return out


# --------------------------------------------------------------------------- expressions

# A typing environment is a tuple of (name, Type, lo, hi): what the generator may read.


def expr_env(variables) -> tuple:
    """The typing environment of some Vars."""
    return tuple((x.name, Type(x.kind, x.values) if x.kind == "enum" else Type(x.kind), x.lo, x.hi)
                 for x in variables)


def _names(env, t):
    return [e for e in env if e[1] == t]


def _gen(draw, env, t, depth, anchored=False):
    """A well-typed expression of type ``t``. ``anchored``: an enum expression that has a
    type of its own (contains a variable in a value position), as a comparison's left
    side or a top-level expression needs."""
    if t.kind == "enum":
        return _gen_enum(draw, env, t, depth, anchored)
    names = _names(env, t)
    stop = depth <= 0 or draw(st.integers(0, 4)) == 0
    if stop:
        if names and draw(st.booleans()):
            return Name(draw(st.sampled_from(names))[0])
        return Const(draw(st.booleans())) if t == BOOL else Const(draw(st.integers(-5, 5)))
    d = depth - 1
    if t == BOOL:
        kind = draw(st.sampled_from(["not", "and", "or", "cmp", "cmp", "eqb", "enum", "if"]))
        if kind == "not":
            return Unary("not", _gen(draw, env, BOOL, d))
        if kind in ("and", "or"):
            n = draw(st.integers(2, 3))
            return BoolOp(kind, tuple(_gen(draw, env, BOOL, d) for _ in range(n)))
        if kind == "cmp":
            op = draw(st.sampled_from(["==", "!=", "<", "<=", ">", ">="]))
            a, b = _gen(draw, env, INT, d), _gen(draw, env, INT, d)
            a = _in_domain(draw, env, a, b)
            b = _in_domain(draw, env, b, a)
            return Compare(op, a, b)
        if kind == "eqb":
            return Compare(draw(st.sampled_from(["==", "!="])), _gen(draw, env, BOOL, d), _gen(draw, env, BOOL, d))
        if kind == "enum":
            enums = sorted({e[1] for e in env if e[1].kind == "enum"}, key=str)
            if not enums:
                return _gen(draw, env, BOOL, d)
            et = draw(st.sampled_from(enums))
            op = draw(st.sampled_from(["==", "!="]))
            if draw(st.booleans()):
                return Compare(op, _gen(draw, env, et, d, True), _gen(draw, env, et, d))
            return Compare(op, Const(draw(st.sampled_from(et.values))), _gen(draw, env, et, d, True))
        return IfElse(_gen(draw, env, BOOL, d), _gen(draw, env, BOOL, d), _gen(draw, env, BOOL, d))
    kind = draw(st.sampled_from(["+", "-", "*", "//", "%", "neg", "min", "max", "abs", "if"]))
    if kind in ("+", "-", "*"):
        return BinOp(kind, _gen(draw, env, INT, d), _gen(draw, env, INT, d))
    if kind in ("//", "%"):
        return BinOp(kind, _gen(draw, env, INT, d), Const(draw(st.integers(1, 4))))
    if kind == "neg":
        return Unary("-", _gen(draw, env, INT, d))
    if kind in ("min", "max"):
        return Call(kind, (_gen(draw, env, INT, d), _gen(draw, env, INT, d)))
    if kind == "abs":
        return Call("abs", (_gen(draw, env, INT, d),))
    return IfElse(_gen(draw, env, BOOL, d), _gen(draw, env, INT, d), _gen(draw, env, INT, d))


def _in_domain(draw, env, e, other):
    """Replace an int constant compared with an int variable by one in its domain (the
    checker rejects the others, as docs/semantics.md section 7 says)."""
    negated = isinstance(e, Unary) and e.op == "-" and isinstance(e.arg, Const)  # -c is the constant -c
    if (isinstance(e, Const) or negated) and isinstance(other, Name):
        for name, t, lo, hi in env:
            if name == other.id and t == INT:
                return Const(draw(st.integers(lo, hi)))
    return e


def _gen_enum(draw, env, t, depth, anchored):
    names = _names(env, t)
    if depth <= 0 or draw(st.integers(0, 3)) == 0:
        if anchored or draw(st.booleans()):
            return Name(draw(st.sampled_from(names))[0])
        return Const(draw(st.sampled_from(t.values)))
    d = depth - 1
    cond = _gen(draw, env, BOOL, d)
    if anchored and draw(st.booleans()):  # a bare literal first, the type from the other side
        return IfElse(cond, Const(draw(st.sampled_from(t.values))), _gen_enum(draw, env, t, d, True))
    # the checker types a non-literal 'then' branch without context: anchor it
    return IfElse(cond, _gen_enum(draw, env, t, d, anchored), _gen_enum(draw, env, t, d, False))


@st.composite
def typed_exprs(draw, env, t=None, max_depth: int = 3):
    """(expression, its type) over the typing environment ``env``; ``t`` fixes the type."""
    if t is None:
        kinds = [BOOL, INT] + sorted({e[1] for e in env if e[1].kind == "enum"}, key=str)
        t = draw(st.sampled_from(kinds))
    return _gen(draw, env, t, draw(st.integers(0, max_depth)), anchored=True), t


_NAME_POOL = ("x", "y", "queue", "holding", "arm.state", "arm.goal", "arm.target", "mode_2", "_n")
_ENUM_POOL = ("busy", "idle", "a", "B_2", "it's")


@st.composite
def parser_form_exprs(draw, max_depth: int = 4):
    """Untyped ASTs in the form ``parse`` produces: and/or flattened with two or more
    arguments, no minus applied to an int literal (the parser folds it), calls with the
    right arity."""
    return _shape(draw, draw(st.integers(0, max_depth)))


def _shape(draw, depth):
    if depth <= 0 or draw(st.integers(0, 4)) == 0:
        kind = draw(st.sampled_from(["bool", "int", "str", "name"]))
        if kind == "bool":
            return Const(draw(st.booleans()))
        if kind == "int":
            return Const(draw(st.integers(-1000, 1000)))
        if kind == "str":
            return Const(draw(st.sampled_from(_ENUM_POOL)))
        return Name(draw(st.sampled_from(_NAME_POOL)))
    d = depth - 1
    kind = draw(st.sampled_from(["not", "neg", "and", "or", "cmp", "bin", "call", "if"]))
    if kind == "not":
        return Unary("not", _shape(draw, d))
    if kind == "neg":
        arg = _shape(draw, d)
        if isinstance(arg, Const) and type(arg.value) is int:
            arg = Name("x")
        return Unary("-", arg)
    if kind in ("and", "or"):
        args = []
        for _ in range(draw(st.integers(2, 3))):
            a = _shape(draw, d)
            args.append(a.args[0] if isinstance(a, BoolOp) and a.op == kind else a)
        return BoolOp(kind, tuple(args))
    if kind == "cmp":
        return Compare(draw(st.sampled_from(["==", "!=", "<", "<=", ">", ">="])), _shape(draw, d), _shape(draw, d))
    if kind == "bin":
        return BinOp(draw(st.sampled_from(["+", "-", "*", "//", "%"])), _shape(draw, d), _shape(draw, d))
    if kind == "call":
        fn = draw(st.sampled_from(["min", "max", "abs"]))
        return Call(fn, tuple(_shape(draw, d) for _ in range(1 if fn == "abs" else 2)))
    return IfElse(_shape(draw, d), _shape(draw, d), _shape(draw, d))


# --------------------------------------------------------------------------- models


class _Names:
    """Fresh node names n0, n1, ... (node names are unique in a model)."""

    def __init__(self, prefix="n"):
        self.prefix, self.k = prefix, 0

    def __call__(self) -> str:
        self.k += 1
        return f"{self.prefix}{self.k - 1}"


@st.composite
def variables(draw):
    """1-3 bools, 0-2 ints, 0-1 enum."""
    out = [Bool(f"b{i}", draw(st.booleans())) for i in range(draw(st.integers(1, 3)))]
    for i in range(draw(st.integers(0, 2))):
        lo = draw(st.integers(-2, 1))
        hi = lo + draw(st.integers(1, 3))
        out.append(Int(f"i{i}", lo, hi, draw(st.integers(lo, hi))))
    if draw(st.booleans()):
        vals = ("red", "green", "blue")[: draw(st.integers(2, 3))]
        out.append(Enum("e0", vals, draw(st.sampled_from(vals))))
    return out


def _by_name(x):
    return x.name


def _effects(draw, env, writable, max_n=2):
    """Random effects that always stay in their variables' domains."""
    targets = draw(st.lists(st.sampled_from(writable), max_size=max_n, unique_by=_by_name)) if writable else []
    out = []
    for var in targets:
        if var.kind == "bool":
            e = _gen(draw, env, BOOL, 1)
        elif var.kind == "int":  # clamp: in domain whatever the value
            e = Call("min", (Call("max", (_gen(draw, env, INT, 1), Const(var.lo))), Const(var.hi)))
        else:
            e = _gen(draw, env, Type("enum", var.values), 1)
        out.append((var.name, e))
    return tuple(out)


_PROFILES = ("RSF", "SF", "RS", "S", "F", "RF", "R")  # rich first: hypothesis favours them


def _outcomes(draw, env, writable, statuses: str):
    """One outcome per status of a random profile (within ``statuses``), sometimes a
    second one with the same status; names are unique."""
    profiles = [p for p in _PROFILES if set(p) <= set(statuses)]
    chosen = list(draw(st.sampled_from(profiles)))
    if draw(st.integers(0, 3)) == 3:
        chosen.append(draw(st.sampled_from(chosen)))
    out = []
    for k, c in enumerate(chosen):
        out.append(Outcome(_STATUS_OF[c], _effects(draw, env, writable, 1), f"{STATUS_LETTERS[c]}{k}"))
    return tuple(out)


def _tree(draw, ctx, depth, root=False):
    """A random (sub)tree. ``ctx``: dict with env, writable, names, statuses (leaf
    statuses allowed), skills (list of (fsm, goals, params) or empty), allow_running.
    ``root``: make it a composite (when depth allows)."""
    name = ctx["names"]()
    env = ctx["env"]
    # hypothesis favours the first entries of sampled_from: put the rich ones first
    leaf_kinds = (["skill"] if ctx["skills"] else []) + ["act", "cond", "act"]
    composites = ["rfb", "mseq", "par", "rseq", "mfb", "rfb", "mseq"]
    if root and depth > 0:
        kind = draw(st.sampled_from(composites))
    elif depth <= 0 or draw(st.integers(0, 2)) == 2:
        kind = draw(st.sampled_from(leaf_kinds))
    else:
        kind = draw(st.sampled_from(composites + ["inv", "fs", "ff", "retry", "repeat", "guard", "effects"]))
    d = depth - 1
    if kind == "cond":
        return Condition(name, _gen(draw, env, BOOL, draw(st.sampled_from([0, 1, 2]))))
    if kind == "act":
        return Action(name, outcomes=_outcomes(draw, env, ctx["writable"], ctx["statuses"]))
    if kind == "skill":
        fsm, goals, params = draw(st.sampled_from(ctx["skills"]))
        pvals = {}
        for p in params:
            pvals[p.name] = Call("min", (Call("max", (_gen(draw, env, INT, 1), Const(p.lo))), Const(p.hi)))
        pre = _gen(draw, env, BOOL, 1) if draw(st.integers(0, 2)) == 2 else None
        post = _gen(draw, env, BOOL, 1) if draw(st.integers(0, 2)) == 2 else None
        return SkillRequest(name, fsm=fsm, goal=draw(st.sampled_from(goals)), params=pvals, pre=pre, post=post)
    if kind in ("rseq", "mseq", "rfb", "mfb", "par"):
        kids = [_tree(draw, ctx, d) for _ in range(draw(st.sampled_from([2, 3, 1])))]
        bools = [e[0] for e in env if e[1] == BOOL]
        if bools and draw(st.booleans()):  # the common idiom: a condition first
            flag = Name(draw(st.sampled_from(bools)))
            kids.insert(0, Condition(ctx["names"](), flag if draw(st.booleans()) else Unary("not", flag)))
        if kind == "par":
            n = len(kids)
            s = draw(st.one_of(st.none(), st.integers(1, n)))
            return Parallel(name, kids, success_threshold=s, failure_threshold=draw(st.integers(1, n)))
        cls = {"rseq": ReactiveSequence, "mseq": MemorySequence, "rfb": ReactiveFallback, "mfb": MemoryFallback}[kind]
        return cls(name, kids)
    child = _tree(draw, ctx, d)
    if kind in ("inv", "fs", "ff"):
        return {"inv": Inverter, "fs": ForceSuccess, "ff": ForceFailure}[kind](name, child)
    if kind in ("retry", "repeat"):
        k = draw(st.integers(1, 3)) if ctx["allow_running"] else 1
        return Retry(name, child, attempts=k) if kind == "retry" else Repeat(name, child, times=k)
    if kind == "guard":
        return Guard(name, child, condition=_gen(draw, env, BOOL, 2))
    eff = {f: _effects(draw, env, ctx["writable"], 1) for f in ("on_start", "on_success", "on_failure", "on_halt")}
    return Effects(name, child, **eff)


@st.composite
def trees(draw, variables_list, statuses: str = "SFR", depth: int = 3, allow_running: bool = True, prefix: str = "n"):
    """A random tree over ``variables_list`` (no skill requests)."""
    env = expr_env(variables_list)
    ctx = dict(env=env, writable=list(variables_list), names=_Names(prefix), statuses=statuses,
               skills=[], allow_running=allow_running)
    return _tree(draw, ctx, depth, root=True)


def _fsm(draw, fname, world, env, writable, names):
    """A random goal-driven FSM over the world; guards may read its parameters."""
    n = draw(st.integers(2, 4))
    ids = [f"{fname}_s{i}" for i in range(n)]  # unique across FSMs: inline primitives are named by state id
    goals = [f"{fname}_g{i}" for i in range(draw(st.integers(1, 3)))]
    params = []
    if draw(st.booleans()):
        params.append(Int(f"{fname}_p", 0, draw(st.integers(1, 2))))
    fenv = env + expr_env(params) + ((f"{fname}.state", Type("enum", tuple(ids)), 0, n - 1),)
    states = []
    for sid in ids:
        if draw(st.integers(0, 5)) == 0:
            ctx = dict(env=env, writable=writable, names=names, statuses="SFR", skills=[], allow_running=True)
            states.append(State(sid, subtree=_tree(draw, ctx, 1)))
        elif draw(st.integers(0, 5)) == 0:
            states.append(State(sid))  # the built-in pass
        else:
            states.append(State(sid, outcomes=_outcomes(draw, env, writable, "SFR")))
    edges, markers = [], []
    statuses = ["success", "running", "failure"]

    def guard():
        return _gen(draw, fenv, BOOL, 1) if draw(st.booleans()) else None

    for sid in ids:  # most states serve most goals
        for g in goals:
            kind = draw(st.sampled_from(["both", "edge", "marker", "none"]))
            if kind in ("both", "edge"):
                edges.append(Edge(sid, draw(st.sampled_from(ids)), [g], on=draw(st.sampled_from(statuses)),
                                  guard=guard(), effects=_effects(draw, env, writable, 1)))
            if kind in ("both", "marker"):
                markers.append(Marker(sid, [g], on=draw(st.sampled_from(statuses)),
                                      outcome=draw(st.sampled_from(["success", "failure"])), guard=guard()))
    for _ in range(draw(st.integers(0, n))):  # extra elements serving several goals, direct ones
        a, b = draw(st.integers(0, n - 1)), draw(st.integers(0, n - 1))
        gs = draw(st.lists(st.sampled_from(goals), min_size=1, max_size=len(goals), unique=True))
        if draw(st.booleans()):
            direct = a < b and draw(st.booleans())  # forward only: no direct cycle
            edges.append(Edge(ids[a], ids[b], gs, on=draw(st.sampled_from(statuses)), guard=guard(), direct=direct,
                              effects=_effects(draw, env, writable, 1)))
        else:
            markers.append(Marker(ids[a], gs, on=draw(st.sampled_from(statuses)), guard=guard(),
                                  outcome=draw(st.sampled_from(["success", "failure"])), direct=draw(st.integers(0, 3)) == 3))
    retarget = draw(st.sampled_from(["immediate", "withdraw"])) if params else "immediate"
    return FSM(fname, states=states, initial=ids[0], goals=goals, edges=edges, markers=markers, params=params,
               retarget=retarget, withdraw_goal=goals[0] if retarget == "withdraw" else "")


@st.composite
def models(draw, fsms: bool = True, environment: bool = True, depth: int = 3):
    """A random valid model: variables, 0-2 skill FSMs, a tree, an environment."""
    world = draw(variables())
    env = expr_env(world)
    names = _Names("n")
    count = draw(st.sampled_from([1, 2, 0])) if fsms else 0
    fsm_list = [_fsm(draw, f"f{i}", world, env, world, names) for i in range(count)]
    skills = [(f.name, f.goals, f.params) for f in fsm_list]
    ctx = dict(env=env, writable=world, names=names, statuses="SFR", skills=skills, allow_running=True)
    tree = _tree(draw, ctx, depth, root=True)
    events_ = []
    if environment:
        for var in world:  # sensors flipping: what makes preemption happen
            if var.kind == "bool" and draw(st.integers(0, 3)) < 3:
                events_.append(EnvEvent(f"flip_{var.name}", None, {var.name: f"not {var.name}"}))
        for i in range(draw(st.integers(0, 2))):
            guard = _gen(draw, env, BOOL, 1) if draw(st.booleans()) else None
            events_.append(EnvEvent(f"ev{i}", guard, _effects(draw, env, world, 2)))
        if draw(st.integers(0, 2)) == 0:
            opts = [EnvEvent("opt0", _gen(draw, env, BOOL, 1), _effects(draw, env, world, 1)),
                    EnvEvent("opt1", None, _effects(draw, env, world, 1))]
            events_.append(EnvChoice("pick", opts))
    return Model("random", variables=world, fsms=fsm_list, tree=tree, environment=events_)
