"""Hypothesis strategies shared by the test suite.

``random_models()``: valid ``btfsm.Model`` objects that use every kind of element the
modelling API has (bool/enum/int variables, declared and inline primitives, FSMs with
parameters, direct edges, markers, guards and effects, every BT node type, environment
events and choices, invariants, workable and terminal predicates, every semantics profile). Expressions are drawn
as strings or as plain bool/int constants, the forms a model file can hold.
"""
from __future__ import annotations

from memo_strategies import st

from btfsm import (FSM, Action, Condition, Edge, EnvChoice, EnvEvent, Marker, Model, ModelError,
                   Outcome, Primitive, State)
from btfsm.bt import NODE_TYPES, SkillRequest, walk
from btfsm.profiles import SEMANTICS
from btfsm.world import Bool, Enum, Int

__all__ = ["random_models", "timed_models"]
_NAV2 = ("PipelineSequence", "RecoveryNode", "RoundRobin")

_ENUM_VALUES = ["idle", "busy", "bins", "agv", "belt", "it's", "a b"]
_STATE_IDS = ["home", "approach bins", "grasp", "raise on X", "s4", "état", "put-on"]
_GOALS = ["pick", "place", "withdraw", "go"]
_TEXT = st.text(st.characters(blacklist_categories=("Cs",)), max_size=20)
_LABEL = st.text(st.characters(blacklist_categories=("Cs", "Cc", "Cf", "Co", "Cn", "Zl", "Zp")), min_size=1, max_size=20).filter(str.isprintable)


def _const_of(draw, var):
    """A constant in the domain of ``var`` as a string or a native value."""
    if var.kind == "bool":
        b = draw(st.booleans())
        return draw(st.sampled_from([b, "true" if b else "false"]))
    if var.kind == "enum":
        return repr(draw(st.sampled_from(var.values)))
    c = draw(st.integers(var.lo, var.hi))
    return draw(st.sampled_from([c, str(c)]))


def _atom(draw, variables, extra):
    """A bool atom over the variables (and ``extra`` (name, Var) pairs such as parameters)."""
    pool = [(v.name, v) for v in variables] + list(extra)
    if not pool or draw(st.integers(0, 9)) == 0:
        return draw(st.sampled_from(["true", "false"]))
    name, var = draw(st.sampled_from(pool))
    if var.kind == "bool":
        return draw(st.sampled_from([name, f"not {name}"]))
    if var.kind == "enum":
        a, b = draw(st.sampled_from(var.values)), draw(st.sampled_from(var.values))
        return draw(st.sampled_from([f"{name} == {a!r}", f"{name} != {b!r}", f"{name} in ({a!r}, {b!r})"]))
    c = draw(st.integers(var.lo, var.hi))
    op = draw(st.sampled_from(["==", "!=", "<", "<=", ">", ">="]))
    return draw(st.sampled_from([f"{name} {op} {c}", f"{name} + 1 {op} {c}", f"max({name}, {var.lo}) {op} {c}",
                                 f"{var.lo} <= {name} <= {var.hi}"]))


def _bool_expr(draw, variables, extra=(), depth=2):
    if depth == 0 or draw(st.integers(0, 2)) == 0:
        return _atom(draw, variables, extra)
    kind = draw(st.sampled_from(["and", "or", "not", "if"]))
    a = _bool_expr(draw, variables, extra, depth - 1)
    b = _bool_expr(draw, variables, extra, depth - 1)
    if kind == "not":
        return f"not ({a})"
    if kind == "if":
        c = _bool_expr(draw, variables, extra, depth - 1)
        return f"({a}) if ({c}) else ({b})"
    return f"({a}) {kind} ({b})"


def _value_expr(draw, var, variables):
    """An expression to assign to ``var``."""
    choice = draw(st.integers(0, 3))
    if choice == 0 or var.kind == "enum" and choice == 1:
        return _const_of(draw, var)
    if var.kind == "bool":
        return _bool_expr(draw, variables, depth=1)
    if var.kind == "enum":
        a, b = draw(st.sampled_from(var.values)), draw(st.sampled_from(var.values))
        return f"{a!r} if {_atom(draw, variables, ())} else {b!r}"
    return draw(st.sampled_from([f"min({var.name} + 1, {var.hi})", f"max({var.name} - 1, {var.lo})",
                                 f"{var.lo} if {_atom(draw, variables, ())} else {var.hi}"]))


def _by_name(v):
    return v.name


def _effects(draw, variables):
    if not variables:
        return ()
    targets = draw(st.lists(st.sampled_from(variables), unique_by=_by_name, max_size=2))
    pairs = tuple((v.name, _value_expr(draw, v, variables)) for v in targets)
    return dict(pairs) if draw(st.booleans()) else pairs


def _var(draw, name):
    kind = draw(st.sampled_from(["bool", "enum", "int"]))
    if kind == "bool":
        return Bool(name, draw(st.booleans()))
    if kind == "enum":
        values = draw(st.lists(st.sampled_from(_ENUM_VALUES), min_size=1, max_size=4, unique=True))
        return Enum(name, values, draw(st.sampled_from(values)))
    lo = draw(st.integers(-2, 2))
    hi = draw(st.integers(lo, lo + 4))
    return Int(name, lo, hi, draw(st.integers(lo, hi)))


def _outcomes(draw, variables):
    statuses = draw(st.lists(st.sampled_from(["success", "failure", "running"]), min_size=1, max_size=3))
    out, names = [], set()
    for k, s in enumerate(statuses):
        name = s if s not in names and draw(st.booleans()) else f"{s}_{k}"
        names.add(name)
        out.append(Outcome(s, _effects(draw, variables), "" if name == s else name))
    return tuple(out)


def _args(draw):
    items = draw(st.lists(st.tuples(st.sampled_from(["to", "speed", "tolerance", "shaking"]),
                                    st.one_of(st.sampled_from(["bins", "agv", "fine"]), st.integers(-3, 3),
                                              st.floats(0, 2, allow_nan=False), st.booleans())),
                          unique_by=lambda p: p[0], max_size=2))
    return dict(items) if draw(st.booleans()) else tuple(items)


class _Names:
    def __init__(self):
        self.n = 0

    def __call__(self, prefix):
        self.n += 1
        return f"{prefix}{self.n}"


def _node(draw, ctx, depth, leaves_only_fsm=False):
    names, variables, prims, fsms = ctx["names"], ctx["variables"], ctx["prims"], ctx["fsms"]
    # Nav2's controls (docs/semantics.md 8.3) have no BehaviorTree.CPP or py_trees counterpart
    # to export to; tests/test_nav2.py covers them
    kinds = [k for k in NODE_TYPES if k not in _NAV2] if depth > 0 else ["Condition", "Action", "SkillRequest"]
    if leaves_only_fsm or not fsms:
        kinds = [k for k in kinds if k != "SkillRequest"]
    t = draw(st.sampled_from(kinds))
    cls, name = NODE_TYPES[t], names("n")
    if t in ("ReactiveSequence", "MemorySequence", "ReactiveFallback", "MemoryFallback", "Parallel",
             "SequenceWithMemory", "ParallelAll", "IfThenElse", "WhileDoElse"):
        lo = 2 if t in ("IfThenElse", "WhileDoElse") else 1
        kids = [_node(draw, ctx, depth - 1, leaves_only_fsm) for _ in range(draw(st.integers(lo, 3)))]
        n = len(kids)
        if t == "Parallel":  # negative thresholds count from the end (-1: all children)
            s = draw(st.one_of(st.none(), st.integers(1, n), st.integers(-n, -1)))
            # py_trees' options (docs/semantics.md 8.2): synchronise, SuccessOnSelected (not under btcpp)
            selected = () if s is not None or ctx.get("semantics") == "btcpp" or not draw(st.booleans()) else tuple(
                draw(st.lists(st.sampled_from([k.name for k in kids]), min_size=1, unique=True)))
            return cls(name, kids, s, draw(st.one_of(st.integers(1, n), st.integers(-n, -1))), draw(st.booleans()),
                       selected)
        if t == "ParallelAll":
            return cls(name, kids, draw(st.one_of(st.integers(1, n), st.integers(-n, -1))))
        return cls(name, kids)
    if t in ("Inverter", "ForceSuccess", "ForceFailure", "Retry", "Repeat", "Guard", "Effects",
             "KeepRunningUntilFailure", "RunOnce", "FailureIsRunning", "RunningIsFailure", "RunningIsSuccess", "SubTree"):
        child = _node(draw, ctx, depth - 1, leaves_only_fsm)
        if t == "RunOnce":
            return cls(name, child, then_skip=False)  # then_skip: true (SKIPPED) is refused
        if t == "Retry":
            return cls(name, child, draw(st.integers(1, 3)))
        if t == "Repeat":
            return cls(name, child, draw(st.integers(1, 3)))
        if t == "Guard":
            return cls(name, child, _bool_expr(draw, variables, depth=1))
        if t == "Effects":
            return cls(name, child, *(_effects(draw, variables) for _ in range(4)))
        return cls(name, child)
    if t == "Condition":
        return Condition(name, _bool_expr(draw, variables))
    if t == "Action":
        if prims and draw(st.booleans()):
            p = draw(st.sampled_from(prims))
            return Action(name, p.name, args=_args(draw))
        inline = names("ip")
        return Action(name, draw(st.sampled_from(["", inline])), _outcomes(draw, variables), _args(draw))
    f = draw(st.sampled_from(fsms))
    params = {p.name: _const_of(draw, p) for p in f.params}
    pre = draw(st.one_of(st.none(), st.just(_bool_expr(draw, variables, depth=1))))
    post = draw(st.one_of(st.none(), st.just(_bool_expr(draw, variables, depth=1))))
    return NODE_TYPES["SkillRequest"](name, f.name, draw(st.sampled_from(f.goals)), params, pre, post)


def _fsm(draw, ctx, index):
    variables, prims, names = ctx["variables"], ctx["prims"], ctx["names"]
    ids = draw(st.lists(st.sampled_from(_STATE_IDS), min_size=1, max_size=4, unique=True))
    goals = draw(st.lists(st.sampled_from(_GOALS), min_size=1, max_size=3, unique=True))
    params = tuple(_var(draw, f"q{index}_{k}") for k in range(draw(st.integers(0, 1))))
    extra = [(p.name, p) for p in params]
    states = []
    for sid in ids:
        kind = draw(st.sampled_from(["pass", "prim", "inline", "subtree"] if prims else ["pass", "inline", "subtree"]))
        if kind == "pass":
            states.append(State(sid))
        elif kind == "prim":
            states.append(State(sid, draw(st.sampled_from(prims)).name, _args(draw)))
        elif kind == "inline":
            # an empty primitive names it after the state id: unique only within the first FSM
            prim = draw(st.sampled_from(["", names("ip")])) if index == 0 else names("ip")
            states.append(State(sid, prim, outcomes=_outcomes(draw, variables)))
        else:
            states.append(State(sid, subtree=_node(draw, ctx, 1, leaves_only_fsm=True)))

    def goal_list():
        return draw(st.one_of(st.just("*"), st.lists(st.sampled_from(goals), min_size=1, unique=True)))

    def guard():
        return draw(st.one_of(st.none(), st.just(_bool_expr(draw, variables, extra, depth=1))))

    edges = []
    for k in range(draw(st.integers(0, 6))):
        i, j = draw(st.integers(0, len(ids) - 1)), draw(st.integers(0, len(ids) - 1))
        direct = i < j and draw(st.booleans())  # direct edges only go forward: no direct cycle
        edges.append(Edge(ids[i], ids[j], goal_list(), draw(st.sampled_from(["success", "failure", "running"])),
                          guard(), direct, _effects(draw, variables), draw(st.sampled_from(["", f"e{k}"]))))
    markers = []
    for k in range(draw(st.integers(0, 4))):
        markers.append(Marker(draw(st.sampled_from(ids)), goal_list(), draw(st.sampled_from(["success", "failure", "running"])),
                              draw(st.sampled_from(["success", "failure"])), guard(), draw(st.booleans()),
                              draw(st.sampled_from(["", f"m{k}"]))))
    retarget = draw(st.sampled_from(["immediate", "withdraw"]))
    withdraw_goal = draw(st.sampled_from(goals)) if retarget == "withdraw" or draw(st.booleans()) else ""
    return FSM(f"f{index}", tuple(states), draw(st.sampled_from(ids)), tuple(goals), tuple(edges), tuple(markers), params,
               retarget, withdraw_goal, tuple(draw(st.lists(st.sampled_from(ids), unique=True, max_size=2))))


def _event(draw, name, variables):
    guard = draw(st.one_of(st.none(), st.just(_bool_expr(draw, variables, depth=1))))
    return EnvEvent(name, guard, _effects(draw, variables))


def _resources(draw, tree, fsms) -> tuple:
    """Up to two resources over the Action and SkillRequest leaves (tree and FSM subtrees)."""
    roots = [tree] if tree is not None else []
    roots += [stt.subtree for f in fsms for stt in f.states if stt.subtree is not None]
    leaves = [n.name for r in roots for n in walk(r) if isinstance(n, (Action, SkillRequest))]
    if not leaves or draw(st.integers(0, 2)) == 0:
        return ()
    return tuple((f"r{k}", tuple(draw(st.lists(st.sampled_from(leaves), min_size=1, max_size=4, unique=True))))
                 for k in range(draw(st.integers(1, 2))))


@st.composite
def random_models(draw, max_vars: int = 4, max_fsms: int = 2, tree_depth: int = 3):
    """Valid random Models exercising every field of the modelling API."""
    names = _Names()
    variables = tuple(_var(draw, f"v{i}") for i in range(draw(st.integers(0, max_vars))))
    prims = tuple(Primitive(f"p{i}", _outcomes(draw, variables)) for i in range(draw(st.integers(0, 3))))
    ctx = {"names": names, "variables": variables, "prims": prims, "fsms": (),
           "semantics": draw(st.sampled_from(SEMANTICS))}
    ctx["fsms"] = tuple(_fsm(draw, ctx, i) for i in range(draw(st.integers(0, max_fsms))))
    tree = _node(draw, ctx, tree_depth) if draw(st.integers(0, 4)) else None
    env = []
    for _ in range(draw(st.integers(0, 3))):
        if draw(st.booleans()):
            env.append(_event(draw, names("e"), variables))
        else:
            cname = names("c")
            env.append(EnvChoice(cname, tuple(_event(draw, names("o"), variables) for _ in range(draw(st.integers(1, 3))))))
    state_refs = [(f"{f.name}.state", Enum("_", tuple(s.id for s in f.states))) for f in ctx["fsms"]]
    invariants = draw(st.lists(st.tuples(_LABEL, st.just(None)), unique_by=lambda p: p[0], max_size=2))
    invariants = tuple((k, _bool_expr(draw, variables, state_refs)) for k, _ in invariants)
    workable = draw(st.one_of(st.none(), st.just(_bool_expr(draw, variables, state_refs))))
    terminal = draw(st.one_of(st.none(), st.just(_bool_expr(draw, variables, state_refs))))
    tick_rate = draw(st.one_of(st.just(10.0), st.integers(1, 100), st.floats(0.01, 1e4, allow_nan=False)))
    resources = _resources(draw, tree, ctx["fsms"])
    try:
        return Model(draw(st.sampled_from(["m", "two area", "cell-1"])), variables, prims, ctx["fsms"], tree, tuple(env),
                     invariants, workable, terminal, tick_rate, draw(_TEXT), ctx["semantics"],
                     resources=resources)
    except ModelError as exc:  # a combination the strategy does not rule out; say which
        raise AssertionError(f"random_models built an invalid model: {exc}") from None


def _duration_for(draw, statuses):
    """A duration the primitive can honour: a lower bound only with a RUNNING outcome, an
    upper bound only with an outcome that ends the run (docs/semantics.md section 6.1)."""
    ends = any(s != "running" for s in statuses)
    runs = "running" in statuses
    lo = draw(st.sampled_from([0, 0.1, 0.2, 0.35])) if runs else 0
    hi = draw(st.sampled_from([None, lo, lo + 0.1, lo + 0.3])) if ends else None
    if not runs and hi is not None:
        hi = 0 if lo == 0 else hi
    return None if (lo == 0 and hi is None) else (lo, hi)


@st.composite
def timed_models(draw, **kw):
    """``random_models`` with durations on declared primitives and FSM states, minimum
    intervals on environment events, and a tick rate of 10 or 20 Hz."""
    import dataclasses

    from btfsm.status import Status

    m = draw(random_models(**kw))
    prims = tuple(dataclasses.replace(p, duration=_duration_for(draw, {o.status.name.lower() for o in p.outcomes}))
                  if draw(st.booleans()) else p for p in m.primitives)
    declared = {p.name: p for p in prims}
    fsms = []
    for f in m.fsms:
        states = []
        for s in f.states:
            outs = s.outcomes if s.outcomes is not None else (declared[s.primitive].outcomes if s.primitive in declared else None)
            if outs is not None and s.subtree is None and draw(st.booleans()):
                s = dataclasses.replace(s, duration=_duration_for(draw, {Status(o.status).name.lower() for o in outs}))
            states.append(s)
        fsms.append(dataclasses.replace(f, states=tuple(states)))
    env = tuple(dataclasses.replace(e, min_interval=draw(st.sampled_from([None, 0.1, 0.2, 0.5])))
                if isinstance(e, EnvEvent) else e for e in m.environment)
    return dataclasses.replace(m, primitives=prims, fsms=tuple(fsms), environment=env,
                               tick_rate=draw(st.sampled_from([10.0, 20.0])))
