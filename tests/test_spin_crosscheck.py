"""SPIN cross-checks of the Promela export: the states SPIN stores, its invalid end states
and its assertion violations must agree with btfsm's own exploration (``verify.explore``)
for the pick/place benchmark and for random models.

Each SPIN run is ``spin -o2 -a``, ``gcc -O0 -DSAFETY -DNOCLAIM`` and ``./pan -c0`` in a
temporary folder (``-O0``: the same verifier, compiled in a quarter of the time ``-O2`` takes,
which is most of a small model's cross-check; the 6-part pick/place reference is compiled as
btfsm compiles it, ``-O2``): once with ``-A`` (assertions ignored: ``errors`` counts invalid end
states) and once with ``-E`` (invalid end states ignored: ``errors`` counts assertion
violations). Skipped when spin or gcc is missing.

``random_models`` (also used by tests/test_vector.py) draws small, valid models: a few
bool/int/enum variables, one FSM ``f`` with inline primitives (several outcomes with
effects), status and direct edges (direct ones only go forward), direct and status
markers, optional parameters (immediate or withdraw retargeting), environment events and
choices (choices may block: dead states), invariants that may fail, terminal
predicates, and optionally a tree that is a single SkillRequest with pre/post/params.
"""
from __future__ import annotations

import random
import shutil
import tempfile

import pytest
from hypothesis import HealthCheck, Phase, given, settings
from memo_strategies import st

from btfsm import (FSM, Bool, Edge, Enum, EnvChoice, EnvEvent, Int, Marker, Model, Outcome, SkillRequest, State,
                   failure, success)
from btfsm.errors import ModelError
from btfsm.status import Status
from btfsm.verify.explore import explore, explore_fsm
from btfsm.verify.export import export, step_spec, terminal_expr

SPIN_MISSING = None
try:
    from btfsm.verify.promela import compile_pan, run_pan, spin_available

    SPIN_MISSING = spin_available()
except ImportError as exc:  # pragma: no cover
    SPIN_MISSING = str(exc)

# each example runs spin and gcc: report a failure as drawn instead of shrinking it for minutes
_NO_SHRINK = (Phase.explicit, Phase.reuse, Phase.generate)

needs_spin = pytest.mark.skipif(SPIN_MISSING is not None, reason=f"SPIN cross-check needs spin and gcc: {SPIN_MISSING}")


# ---------------------------------------------------------------------- random models


class _Draws:
    """Choices from a hypothesis ``draw`` (shrinkable)."""

    def __init__(self, draw):
        self.draw = draw

    def int(self, a, b):
        return self.draw(st.integers(a, b))

    def pick(self, seq):
        return self.draw(st.sampled_from(list(seq)))

    def flip(self):
        return self.draw(st.booleans())

    def subset(self, seq, lo, hi):
        return self.draw(st.lists(st.sampled_from(list(seq)), min_size=lo, max_size=hi, unique=True))


class _Seeded(_Draws):
    """The same choices from a seeded ``random.Random`` (uniform: hypothesis draws start
    from minimal examples, which makes expensive tests see many trivial models)."""

    def __init__(self, seed):
        self.rng = random.Random(seed)

    def int(self, a, b):
        return self.rng.randint(a, b)

    def pick(self, seq):
        return self.rng.choice(list(seq))

    def flip(self):
        return self.rng.random() < 0.5

    def subset(self, seq, lo, hi):
        seq = list(seq)
        return self.rng.sample(seq, self.rng.randint(lo, min(hi, len(seq))))


def _variables(c):
    out = []
    for k in range(c.int(2, 4)):
        kind = c.pick(["int", "enum", "bool", "sint"])
        if kind == "bool":
            out.append(Bool(f"b{k}", c.flip()))
        elif kind == "int":
            hi = c.int(1, 4)
            out.append(Int(f"n{k}", 0, hi, c.int(0, hi)))
        elif kind == "sint":
            out.append(Int(f"z{k}", -2, 1, c.int(-2, 1)))
        else:
            vals = ("red", "green", "blue")[: c.int(2, 3)]
            out.append(Enum(f"c{k}", vals, c.pick(vals)))
    return out


def _atom(c, variables, extra):
    """One bool-valued comparison over the variables (and ``extra`` names: (name, kind, domain))."""
    pool = [(v.name, v.kind, v.values if v.kind == "enum" else (v.lo, v.hi)) for v in variables] + list(extra)
    name, kind, dom = c.pick(pool)
    if kind == "bool":
        return c.pick([name, f"not {name}"])
    if kind in ("enum", "state"):
        return f"{name} {c.pick(['==', '!='])} {c.pick(dom)!r}"
    lo, hi = dom
    form = c.int(0, 5)
    op = c.pick(["==", "!=", "<", "<=", ">", ">="])
    if form == 0:
        return f"{name} % 2 == {c.int(0, 1)}"
    if form == 1:
        return f"{name} // 2 {op} {c.int(-1, 1)}"
    if form == 2:
        return f"abs({name}) {op} {c.int(0, 2)}"
    if form == 3:
        n2 = c.pick([p for p in pool if p[1] == "int"])[0]
        return f"min({name}, {n2}) + 1 {op} {c.int(lo, hi)}"
    return f"{name} {op} {c.int(lo, hi)}"


def _guard(c, variables, extra, allow_none=True):
    if allow_none and c.int(0, 2) == 2:
        return None
    atoms = [_atom(c, variables, extra) for _ in range(c.int(1, 2))]
    if len(atoms) == 1:
        return atoms[0]
    return f" {c.pick(['and', 'or'])} ".join(f"({a})" for a in atoms)


def _value(c, var, variables, wild=False):
    """A right-hand side for ``var`` that stays in its domain (``wild``: may leave it)."""
    if var.kind == "bool":
        return c.pick(["true", "false", f"not {var.name}", _atom(c, variables, ())])
    if var.kind == "enum":
        a, b = c.pick(var.values), c.pick(var.values)
        return c.pick([repr(a), f"{a!r} if {_atom(c, variables, ())} else {b!r}"])
    lo, hi = var.lo, var.hi
    if wild and c.int(0, 2) == 0:
        return c.pick([f"{var.name} + 1", f"{var.name} - 1", f"2 * {var.name}"])
    return c.pick([str(c.int(lo, hi)), f"min({var.name} + 1, {hi})", f"max({var.name} - 1, {lo})",
                   f"({var.name} - {lo} + 1) % {hi - lo + 1} + {lo}",
                   f"{c.int(lo, hi)} if {_atom(c, variables, ())} else {var.name}"])


def _effects(c, variables, max_n=2, min_n=0, wild=False):
    return {v.name: _value(c, v, variables, wild) for v in c.subset(variables, min_n, max_n)}


def _param_value(c, p):
    """A constant of parameter ``p``'s type (parameters are not in the tree's scope)."""
    if p.kind == "bool":
        return c.pick(["true", "false"])
    if p.kind == "enum":
        return repr(c.pick(p.values))
    return str(c.int(p.lo, p.hi))


def build_model(c, tree=None, env=True, wild=False) -> Model:
    """A small random model with FSM ``f`` (``tree``: True forces a SkillRequest tree,
    False none, None either), from the choices of ``c``; ``wild``: int effects may
    leave their domain (DomainErrors)."""
    variables = _variables(c)
    # a sensor nothing writes: at FSM level a free input (any value each step)
    sensors = [c.pick([Bool("sensor"), Int("level", 0, 2)])] if c.int(0, 2) == 0 else []
    n_states = c.int(3, 5)
    sids = [f"s{i}" for i in range(n_states)]
    goals = ["g0", "g1"][: c.int(1, 2)]
    params = [c.pick([Bool("p"), Int("p", 0, 2), Enum("p", ("lo", "hi"))])] if c.int(0, 3) == 0 else []
    retarget = "withdraw" if params and c.flip() else "immediate"
    extra = [("f.state", "state", tuple(sids))] + [(p.name, p.kind, p.values if p.kind == "enum" else (p.lo, p.hi)) for p in params]
    extra += [(x.name, x.kind, (x.lo, x.hi)) for x in sensors]
    states = []
    for sid in sids:
        statuses = [c.pick(["success", "failure", "running"]) for _ in range(c.int(1, 3))]
        outs = [Outcome(x, _effects(c, variables, 2, 1 if j == 0 else 0, wild), f"o{j}") for j, x in enumerate(statuses)]
        states.append(State(sid, outcomes=outs))
    edges = []
    for _ in range(c.int(n_states, 3 * n_states)):
        a = c.int(0, n_states - 1)
        direct = a < n_states - 1 and c.int(0, 3) == 0
        b = c.int(a + 1, n_states - 1) if direct else c.int(0, n_states - 1)
        edges.append(Edge(sids[a], sids[b], c.subset(goals, 1, len(goals)), on=c.pick(["success", "failure", "running"]),
                          guard=_guard(c, variables, extra), direct=direct, effects=_effects(c, variables, 2, 0, wild)))
    markers = [Marker(c.pick(sids), c.subset(goals, 1, len(goals)), on=c.pick(["success", "failure"]),
                      outcome=c.pick(["success", "failure"]), guard=_guard(c, variables, extra), direct=c.int(0, 3) == 0)
               for _ in range(c.int(1, n_states))]
    terminal = tuple(c.subset(sids, 0, 1))
    f = FSM("f", states=states, initial="s0", goals=goals, edges=edges, markers=markers, params=params,
            retarget=retarget, withdraw_goal=goals[0] if retarget == "withdraw" else "", terminal=terminal)
    environment = []
    if env:
        for k in range(c.int(1, 3)):
            if c.flip():
                environment.append(EnvEvent(f"e{k}", _guard(c, variables, extra[:1]), _effects(c, variables, 2, 1)))
            else:
                environment.append(EnvChoice(f"e{k}", [EnvEvent(f"e{k}o{j}", _guard(c, variables, extra[:1], allow_none=False),
                                                                 _effects(c, variables, 2, 1)) for j in range(c.int(2, 3))]))
    invariants = {"inv": _guard(c, variables, extra[:1], allow_none=False)} if c.flip() else {}
    term = _guard(c, variables, extra[:1], allow_none=False) if c.int(0, 3) == 0 else None
    node = None
    if (c.flip() if tree is None else tree):
        pexprs = {p.name: f"{_param_value(c, p)} if {_atom(c, variables, ())} else {_param_value(c, p)}" for p in params}
        node = SkillRequest("req", fsm="f", goal=c.pick(goals), params=tuple(pexprs.items()),
                            pre=_guard(c, variables, extra[:1]), post=_guard(c, variables, extra[:1]))
    try:
        return Model("rnd", variables=variables + sensors, fsms=[f], tree=node, environment=environment,
                     invariants=invariants, terminal=term)
    except ModelError as exc:
        raise AssertionError(f"strategy built an invalid model: {exc}") from None


@st.composite
def random_models(draw, tree=None, env=True, wild=False):
    """Random models from hypothesis draws (shrinkable; starts from small examples)."""
    return build_model(_Draws(draw), tree, env, wild)


def seeded_models(tree=None, env=True, wild=False):
    """Random models from a drawn seed (uniformly varied from the first example)."""
    return st.integers(0, 2**32 - 1).map(lambda seed: build_model(_Seeded(seed), tree, env, wild))


def feature_model():
    """Direct chain (two moves), direct marker, a goal not applicable somewhere, withdraw
    retargeting with a parameter computed by the tree, pre and post contracts."""
    arm = FSM("arm", states=[State("home", outcomes=[success()]),
                             State("mid"),
                             State("far", outcomes=[success("ok", n="min(n + 1, 3)"), failure("slip", n="max(n - 1, 0)")]),
                             State("back", outcomes=[success()])],
              goals=["go", "rest"], params=[Int("speed", 0, 2)], retarget="withdraw", withdraw_goal="rest",
              edges=[Edge("home", "mid", ["go"], direct=True, guard="n < 3"),
                     Edge("mid", "far", ["go"], direct=True, effects={"flag": "not flag"}),
                     Edge("far", "back", ["go", "rest"], on="failure"),
                     Edge("far", "home", ["rest"], guard="speed > 0"),
                     Edge("back", "home", ["go", "rest"])],
              markers=[Marker("home", ["rest"], direct=True),
                       Marker("far", ["go"], on="success"),
                       Marker("back", ["go"], on="success", outcome="failure", guard="flag")])
    return Model("features", variables=[Int("n", 0, 3), Bool("flag"), Int("want", 0, 2)], fsms=[arm],
                 tree=SkillRequest("req", fsm="arm", goal="go", params=(("speed", "want"),), pre="n != 2 or flag", post="n > 1"),
                 environment=[EnvEvent("retarget", None, {"want": "(want + 1) % 3"})])



# ---------------------------------------------------------------------- our verdicts


def verdicts(ts):
    """(states, dead non-terminal states, any assertion-like violation, domain errors)."""
    prog = ts.model.program
    spec_fsm = ts.fsm if ts.kind == "fsm" else None
    spec = step_spec(ts.model, spec_fsm)
    term = terminal_expr(spec)
    from btfsm.expr import BOOL, compile_fn

    is_term = compile_fn(term, prog.scope, "terminal", BOOL) if term is not None else (lambda s: False)
    dead = [int(i) for i in ts.dead if not is_term(list(ts.full_state(int(i))))]
    bad = bool(ts.violations) or bool(ts.errors)
    for i in range(ts.n_states):
        s = list(ts.full_state(i))
        if not all(fn(s) for _, fn in prog.invariants):
            bad = True
            break
    return ts.n_states, len(dead), bad, len(ts.errors)


def spin_verdicts(text, optimize=False):
    work = tempfile.mkdtemp(prefix="btfsm_xcheck_")
    try:  # a later -O wins over compile_pan's -O2
        pan = compile_pan(text, work, cc_flags=("-DSAFETY", "-DNOCLAIM") + (() if optimize else ("-O0",)))
        ends = run_pan(pan, ("-m100000", "-c0", "-A"))
        asserts = run_pan(pan, ("-m100000", "-c0", "-E"))
        return ends.states, ends.errors, asserts.errors > 0
    finally:
        shutil.rmtree(work, ignore_errors=True)


def crosscheck(model, fsm):
    ts = explore_fsm(model, fsm) if fsm is not None else explore(model)
    assert ts.complete
    n, dead, bad, domain_errors = verdicts(ts)
    text = export(model, "promela", fsm=fsm)
    s_states, s_ends, s_bad = spin_verdicts(text)
    init_bad = not all(fn(list(model.program.initial)) for _, fn in model.program.invariants)
    assert s_bad == bad, f"assertion verdict: spin {s_bad}, btfsm {bad}\n{text}"
    if not domain_errors:  # SPIN wraps out-of-domain values and goes on; btfsm stops
        assert s_states == n + (1 if init_bad else 0), f"states: spin {s_states}, btfsm {n}\n{text}"
        assert s_ends == dead, f"invalid end states: spin {s_ends}, btfsm dead {dead}\n{text}"
    return n


# ---------------------------------------------------------------------- tests


@needs_spin
@pytest.mark.parametrize("kw, states, dead, bad", [
    ({}, 10_288, 0, False),
    ({"dead": True}, 8_624, 1_024, False),
    ({"bug": True}, 10_384, 0, True),
])
@pytest.mark.parametrize("level", ["model", "fsm"])
def test_pickplace_matches_spin(kw, states, dead, bad, level):
    from btfsm.models.pickplace import pickplace

    m = pickplace(3, **kw)
    fsm = "skill" if level == "fsm" else None
    ts = explore_fsm(m, fsm) if fsm else explore(m)
    assert verdicts(ts)[:3] == (states, dead, bad)
    assert spin_verdicts(export(m, "promela", fsm=fsm)) == (states, dead, bad)


@needs_spin
@pytest.mark.parametrize("fsm", [None, "arm"])
def test_hand_written_features_match_spin(fsm):
    assert crosscheck(feature_model(), fsm) > 10


@needs_spin
def test_pickplace_size6_matches_spin_reference():
    """The exported model reproduces SPIN's count of the hand-written pickplace.pml."""
    from btfsm.models.pickplace import SPIN_STATES, pickplace

    assert spin_verdicts(export(pickplace(6), "promela"), optimize=True)[:2] == (SPIN_STATES[6], 0)


@needs_spin
@settings(max_examples=14, deadline=None, phases=_NO_SHRINK, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(seeded_models(tree=False))
def test_random_fsm_level_matches_spin(model):
    crosscheck(model, "f")


@needs_spin
@settings(max_examples=10, deadline=None, phases=_NO_SHRINK, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(seeded_models(tree=True))
def test_random_whole_model_matches_spin(model):
    crosscheck(model, None)


def test_random_models_are_varied():
    """The strategy reaches the features the cross-check is meant to cover."""
    seen = set()

    @settings(max_examples=60, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])
    @given(random_models())
    def probe(m):
        f = m.fsms[0]
        seen.update(k for k, on in [("direct", any(e.direct for e in f.edges)), ("params", bool(f.params)),
                                    ("withdraw", f.retarget == "withdraw"), ("choice", any(isinstance(e, EnvChoice) for e in m.environment)),
                                    ("tree", m.tree is not None), ("invariant", bool(m.invariants)),
                                    ("multi-outcome", any(len(s.outcomes) > 1 for s in f.states)),
                                    ("running", any(o.status == Status.RUNNING for s in f.states for o in s.outcomes))] if on)
    probe()
    assert seen >= {"direct", "params", "choice", "tree", "invariant", "multi-outcome", "running"}
