"""Explore a model into an explicit ``TransitionSystem`` (breadth-first, budgeted).

``explore(model)``: the whole model, one transition per BT tick (``Program.step``).
``explore_fsm(model, fsm)``: one FSM as an open system, one transition per request: free
inputs, the environment entries that matter to it, the requested goal and its parameter
values are chosen every possible way, then ``Program.fsm_step`` runs.

The engines are siblings: ``btfsm.verify.traced`` (the default) and ``btfsm.verify.scalar``
(and ``btfsm.verify.vector`` for the systems ``step_spec`` describes), over the shared
``btfsm.verify.codec`` (states as int codes), ``btfsm.verify.labels`` (readable labels) and
``btfsm.verify.search`` (the enumerating oracle, the environment step, budgets). This
module describes the systems (``open_fsm``) and picks the engine.

>>> from btfsm import Model, Bool, EnvEvent
>>> m = Model("flip", variables=[Bool("x")], environment=[EnvEvent("on", "not x", {"x": True})])
>>> ts = explore(m)
>>> ts.n_states, ts.n_transitions, ts.labels
(2, 3, ((), (('env', 'on'),)))
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, cast

from btfsm.bt import Action, Condition, Effects, Guard, SkillRequest, walk
from btfsm.errors import DomainError
from btfsm.expr import names_in
from btfsm.oracles import all_choices

from . import scalar, traced
from .labels import readable
from .search import DEFAULT_MAX_STATES, DEFAULT_MAX_TRANSITIONS, Budget, EnumOracle, SearchTask, run_environment
from .system import TransitionSystem

__all__ = ["AUTO_SCALAR_STATES", "AUTO_NARROW_LEVEL", "explore", "explore_fsm", "OpenFSM", "open_fsm", "requests_of", "EnumOracle", "run_environment",
           "successor_scripts", "run_script", "script_of", "DEFAULT_MAX_STATES",
           "DEFAULT_MAX_TRANSITIONS", "Budget"]

# ---------------------------------------------------------------------- FSM open system


@dataclass(frozen=True, eq=False)
class OpenFSM:
    """One FSM as an open system (see ``open_fsm``).

    ``kept``: program slots stored in states; ``inputs``: free inputs ``(slot, values)``
    chosen before every request and reset to their initial value after it; ``env``:
    indices of the environment entries that write a kept slot; ``goals``: goal indices
    that can be requested; ``pres``: per goal, the ``pre`` conditions of the tree's
    SkillRequests for it (None: always requestable); ``params``: ``(slot, values)``."""

    program: Any  # btfsm.semantics.Program
    fsm: str
    index: int
    kept: tuple
    inputs: tuple
    env: tuple
    goals: tuple
    pres: dict
    params: tuple

    def run(self, state, oracle, record: bool = False, adopt: bool = False):
        """One request: inputs, environment, goal, parameters, then ``Program.fsm_step``.
        Returns the Step (None when an environment choice has no enabled option, or no
        goal can be requested). ``adopt``: write the requested parameter values into the
        state just before the FSM steps (the reference run of ``request-latency``)."""
        prog = self.program
        s = list(state)
        picks = oracle.picks
        for slot, vals in self.inputs:
            s[slot] = vals[oracle.choose(("input", slot), vals)]
        rec: "list | None" = [] if record else None
        if not run_environment(prog, s, oracle, self.env, rec):
            return None
        goals: Any = self.goals
        if self.pres:
            goals = [g for g in goals if _requestable(self.pres.get(g), s)]
            if not goals:
                return None
        if len(goals) > 1:
            g = goals[oracle.choose(("goal",), goals)]
        else:
            g = goals[0]
            picks.append(("choice", ("goal",), g))
        pvals = []
        for slot, vals in self.params:
            if len(vals) > 1:
                pvals.append(vals[oracle.choose(("param", slot), vals)])
            else:
                pvals.append(vals[0])
                picks.append(("choice", ("param", slot), vals[0]))
        if adopt:
            for (slot, _), val in zip(self.params, pvals):
                s[slot] = val
        step = prog.fsm_step(s, self.index, g, pvals, oracle, record)
        if step.state is None:  # an answer the declared timing does not allow
            return None
        if self.inputs:
            ns = list(step.state)
            init = prog.initial
            for slot, _ in self.inputs:
                ns[slot] = init[slot]
            step.state = tuple(ns)
        if rec:
            step.events = rec + (step.events or [])
        return step


def _requestable(pres, s) -> bool:
    if pres is None:
        return True
    return any(p is None or p(s) for p in pres)


def _expr_slots(expr, scope) -> set:
    return {scope[n].index for n in names_in(expr)}


def _effect_slots(effects, scope) -> tuple:
    """(reads, writes) of ``((var, expr), ...)``."""
    reads, writes = set(), set()
    for name, value in effects:
        writes.add(scope[name].index)
        reads |= _expr_slots(value, scope)
    return reads, writes


def _fsm_footprint(prog, fname, seen=None) -> tuple:
    """(reads, writes) of everything FSM ``fname`` runs, its subtrees and the FSMs they request."""
    seen = set() if seen is None else seen
    if fname in seen:
        return set(), set()
    seen.add(fname)
    fi = prog.fsm_index[fname]
    f, _, tok, goal, pslots = prog.fsm_info[fi]
    scope, fscope = prog.scope, prog.fsm_scope(f)
    reads, writes = set(), {tok, goal, *pslots}
    for e in f.edges:
        if e.guard is not None:
            reads |= _expr_slots(e.guard, fscope)
        r, w = _effect_slots(e.effects, scope)
        reads |= r
        writes |= w
    for m in f.markers:
        if m.guard is not None:
            reads |= _expr_slots(m.guard, fscope)
    writes |= {s.timer for s in prog.sites if s.kind == "state" and s.fsm == fname and s.timer is not None}
    for st in f.states:
        if st.subtree is not None:
            r, w = _tree_footprint(prog, st.subtree, seen)
        else:
            prim = prog.prims.get(st.primitive or (st.id if st.outcomes is not None else "pass"))
            r, w = _outcomes_footprint(prim, scope)
        reads |= r
        writes |= w
    return reads, writes


def _outcomes_footprint(prim, scope) -> tuple:
    reads, writes = set(), set()
    for o in (prim.outcomes if prim is not None else ()):
        r, w = _effect_slots(o.effects, scope)
        reads |= r
        writes |= w
    return reads, writes


def _tree_footprint(prog, root, seen) -> tuple:
    scope = prog.scope
    reads, writes = set(), set()
    for n in walk(root):
        info = prog.nodes[n.name]
        writes.update(info.state_slots())
        if isinstance(n, Condition):
            reads |= _expr_slots(n.expr, scope)
        elif isinstance(n, Guard):
            reads |= _expr_slots(n.condition, scope)
        elif isinstance(n, Effects):
            for effs in (n.on_start, n.on_success, n.on_failure, n.on_halt):
                r, w = _effect_slots(effs, scope)
                reads |= r
                writes |= w
        elif isinstance(n, Action):
            r, w = _outcomes_footprint(prog.prims.get(n.primitive), scope)
            reads |= r
            writes |= w
        elif isinstance(n, SkillRequest):
            for e in (n.pre, n.post, *(x for _, x in cast("tuple[tuple[str, Any], ...]", n.params))):
                if e is not None:
                    reads |= _expr_slots(e, scope)
            r, w = _fsm_footprint(prog, n.fsm, seen)
            reads |= r
            writes |= w
    return reads, writes


def requests_of(model, fsm: str) -> list:
    """The SkillRequest nodes (anywhere in the model) that request FSM ``fsm``."""
    return model.requests_of(fsm)


def open_fsm(model, fsm: str, goals=None) -> OpenFSM:
    """Describe FSM ``fsm`` as an open system.

    Kept slots: what the FSM (its edges, markers, primitives' outcomes, subtrees and the FSMs
    those request) reads or writes, its token, held goal and parameters, plus the slots of
    the environment entries that write any of them (to a fixed point). Free inputs: slots
    the FSM itself reads (or the ``pre`` of its requests) that nothing in the open system
    writes: world variables written by no effect anywhere, those only the tree or other
    FSMs write, and other FSMs' token/goal/parameters. A slot only the environment reads and
    nothing writes keeps its initial value.
    Goals: ``goals`` if given, else those some SkillRequest requests (each guarded by the
    requests' ``pre``), else all the FSM's goals."""
    prog = model.program
    if fsm not in prog.fsm_index:
        raise KeyError(f"no FSM named '{fsm}' (have: {', '.join(f.name for f in model.fsms)})")
    fi = prog.fsm_index[fsm]
    f, _, tok, goal_slot, pslots = prog.fsm_info[fi]
    reads, writes = _fsm_footprint(prog, fsm)
    pres: dict = {}
    if goals is None:
        reqs = requests_of(model, fsm)
        if reqs:
            from btfsm.expr import BOOL, compile_fn

            for n in reqs:
                g = f.goals.index(n.goal)
                fn = None if n.pre is None else compile_fn(n.pre, prog.scope, f"tree.{n.name}.pre", BOOL)
                pres.setdefault(g, []).append(fn)
                if n.pre is not None:
                    reads |= _expr_slots(n.pre, prog.scope)
            goal_idx: Any = tuple(sorted(pres))
            pres = {g: (None if any(p is None for p in ps) else tuple(ps)) for g, ps in pres.items()}
            if all(p is None for p in pres.values()):
                pres = {}
        else:
            goal_idx = tuple(range(len(f.goals)))
    else:
        goal_idx = []
        for g in goals:
            if isinstance(g, str):
                if g not in f.goals:
                    raise KeyError(f"'{g}' is not a goal of {fsm} ({', '.join(f.goals)})")
                g = f.goals.index(g)
            goal_idx.append(int(g))
        goal_idx = tuple(goal_idx)
    own_reads = set(reads)
    # environment entries writing a kept slot, and what they read, to a fixed point
    env_idx: set = set()
    kept = reads | writes
    changed = True
    while changed:
        changed = False
        for i, ev in enumerate(model.environment):
            if i in env_idx:
                continue
            r, w = _env_footprint(ev, prog.scope)
            if i in prog.env_timers:  # its spacing counter (rule 'Event spacing') goes with it
                r, w = r | {prog.env_timers[i][0]}, w | {prog.env_timers[i][0]}
            if w & kept:
                env_idx.add(i)
                writes |= w
                kept |= r | w
                changed = True
    inputs = []
    for slot in sorted(own_reads - writes):
        info = prog.slots[slot]
        if info.size > 1:
            inputs.append((slot, tuple(range(info.lo, info.lo + info.size))))
    input_slots = {s for s, _ in inputs}
    stored = tuple(sorted(s for s in kept if s not in input_slots))
    params = tuple((s, tuple(range(prog.slots[s].lo, prog.slots[s].lo + prog.slots[s].size))) for s in pslots)
    return OpenFSM(prog, fsm, fi, stored, tuple(inputs), tuple(sorted(env_idx)), goal_idx, pres, params)


def _env_footprint(ev, scope) -> tuple:
    reads, writes = set(), set()
    for opt in getattr(ev, "options", None) or (ev,):
        if opt.guard is not None:
            reads |= _expr_slots(opt.guard, scope)
        r, w = _effect_slots(opt.effects, scope)
        reads |= r
        writes |= w
    return reads, writes


# ---------------------------------------------------------------------- the search


def explore(model, *, max_states=None, max_transitions=None, max_seconds=None, progress=None, start=None,
            engine: str = "auto") -> TransitionSystem:
    """Explore the whole model: one transition per BT tick. ``start``: a state tuple to
    start from instead of ``model.program.initial``. ``progress(states, transitions,
    seconds)`` is called every few thousand expanded states.

    Budgets (None: unbounded): ``max_states`` states numbered, ``max_transitions``
    transitions kept, ``max_seconds`` of wall time (a monotonic clock, read by the engine
    only). The first one hit stops the search: the system comes back with ``complete``
    False and ``stopped`` naming the budget (``btfsm.verify.search.Budget``). Without a time
    budget the result does not depend on the clock; state and transition budgets cut
    both engines at the same transition.

    ``engine``: ``"traced"`` runs ``btfsm.verify.traced`` (the step function traced once per
    path, then applied to whole batches with numpy); ``"scalar"`` runs the step once per
    transition (``btfsm.verify.scalar``); ``"auto"`` (the default) is scalar for systems of
    at most ``AUTO_SCALAR_STATES`` states, else traced, unless the tracer cannot follow the
    model (``btfsm.verify.traced.Untraceable``), then scalar. Both give the same system,
    numbering included (tests compare them).

    When the model has an environment, the scalar engine memoises the tree's results by
    the state after the environment (see ``btfsm.verify.scalar.TreeCache``): a tick is the environment then
    the tree, and the tree's results depend on nothing else."""
    prog = model.program
    kept = tuple(range(len(prog.slots)))
    init = tuple(start) if start is not None else prog.initial
    budget = Budget(max_states, max_transitions, max_seconds)
    return _explore_with(engine, SearchTask(model, "model", None, kept, prog.step, init, progress), budget)


def explore_fsm(model, fsm, *, goals=None, max_states=None, max_transitions=None, max_seconds=None, progress=None,
                start=None, engine: str = "auto") -> TransitionSystem:
    """Explore one FSM as an open system (``open_fsm``): one transition per request.
    ``engine`` and the budgets as for ``explore``."""
    op = open_fsm(model, fsm, goals)
    prog = model.program
    init = tuple(start) if start is not None else prog.initial
    init = tuple(prog.initial[k] if k in dict(op.inputs) else v for k, v in enumerate(init))
    budget = Budget(max_states, max_transitions, max_seconds)
    return _explore_with(engine, SearchTask(model, "fsm", op.fsm, op.kept, op.run, init, progress, op), budget)


#: ``engine="auto"``: systems up to this many states are explored by the scalar engine. The
#: traced engine pays for tracing each path once; below a few thousand states that costs
#: more than it saves (ARIAC, 1,605 states: scalar 0.04 s, traced 0.14 s; pick/place at 3,
#: 10,288 states: scalar 0.32 s, traced 0.06 s). The probe is what a larger system pays
#: first (1,024 states of pick/place: about 0.02 s; it was 4,096 states, 0.1 s, until
#: issue 24): 1,024 states tell a wide system from a narrow one as 4,096 did on every
#: built-in model, and a narrow one goes on with the scalar engine anyway.
AUTO_SCALAR_STATES = 1024
#: ... a model whose kept timers alone span more values than this skips the probe (``_long_timers``)
AUTO_TIMER_SPAN = 4096
#: ... and past the probe, systems whose breadth-first levels hold fewer states than this on
#: average (over the probe) stay with the scalar engine: the traced engine pays numpy's
#: per-call costs once per level (ARIAC with 40 tray parts and a queue of 8, 11,319 states
#: in levels of about 18: scalar 0.22 s, traced 0.38 s; pick/place at 3, levels of about 93:
#: traced 5x faster).
AUTO_NARROW_LEVEL = 32


def _long_timers(prog, kept) -> bool:
    """Whether the kept timers' domains (docs/semantics.md 6.1) multiply past
    ``AUTO_TIMER_SPAN``: timers count one tick at a time, so such a system is
    expected to be large and ``auto`` goes to the traced engine without the scalar probe
    (a guess about speed only: both engines give the same system)."""
    span = 1
    for k in kept:
        if prog.slots[k].kind == "timer":
            span *= max(prog.slots[k].size, 1)
    return span > AUTO_TIMER_SPAN


def _explore_with(engine, task: SearchTask, budget: Budget) -> TransitionSystem:
    """One system, explored by the engine asked for (see ``explore``). With ``auto``, the
    scalar engine first explores up to ``AUTO_SCALAR_STATES`` states (tracing does not pay
    off on small systems); a system that is larger is explored again, from the start, by
    the traced engine under the same budget (its clock included), or by the scalar engine
    when the probe's breadth-first levels averaged fewer than ``AUTO_NARROW_LEVEL`` states; a model whose timers
    alone span more values than that skips the probe (``_long_timers``), and so does a model whose
    environment answers multiply past ``btfsm.verify.traced.ENV_WIDE`` per state (each state
    has that many successors: the scalar engine runs the step once per transition). A traced search whose
    paths multiply (``TooManyPaths``) goes on with the scalar engine; ``traced`` then stops
    at a "paths" budget."""
    if engine not in ("auto", "traced", "scalar"):
        raise ValueError(f"engine must be auto, traced or scalar, not {engine!r}")
    model, kind = task.model, task.kind
    split = scalar.TreeCache(model) if kind == "model" and model.environment and model.tree is not None else None
    wide = kind == "model" and traced.env_width(model.program) >= traced.ENV_WIDE
    if engine == "auto" and not wide and not _long_timers(model.program, task.kept):
        small = AUTO_SCALAR_STATES if budget.max_states is None else min(budget.max_states, AUTO_SCALAR_STATES)
        probe = Budget(small, budget.max_transitions, budget.max_seconds)
        probe.start = budget.start
        ts = scalar.search(task, probe, split)
        if ts.complete or probe.hit != "states" or small == budget.max_states:
            budget.hit = probe.hit  # the whole system, or the cut the user's budget makes (the same in both engines)
            return ts
        if ts.n_states < AUTO_NARROW_LEVEL * (int(ts.depth().max()) + 1):
            engine = "scalar"  # narrow levels: tracing would not pay off
    if engine != "scalar":
        try:
            return traced.search(task, budget, fallback=engine == "auto")
        except traced.Untraceable:
            if engine == "traced":
                raise
    return scalar.search(task, budget, split)


# ---------------------------------------------------------------------- re-running transitions


def _runner(ts):
    if ts.kind == "model":
        prog = ts.model.program
        return lambda s, o, record=False: prog.step(s, o, record)
    return ts.open.run


def run_script(ts, state, script, record: bool = True):
    """Re-run one transition of ``ts``'s kind from ``state`` answering with ``script``.
    Returns ``(step or None, oracle, error)``; ``error`` is the DomainError raised, if any."""
    o = EnumOracle(script)
    try:
        return _runner(ts)(tuple(state), o, record), o, None
    except DomainError as exc:
        return None, o, exc


def successor_scripts(ts, state) -> list:
    """Every ``(script, step, oracle)`` from ``state`` (steps recorded), in search order.
    Blocked ticks are left out; DomainErrors appear with ``step`` None."""
    run = _runner(ts)
    out = []
    if ts.kind == "model" and ts.model.program.merge_points:
        choices = _merged_choices(lambda s, o: run(s, o, True), tuple(state))
    else:
        choices = all_choices(lambda s, o: run(s, o, True), tuple(state), EnumOracle, (DomainError,))
    for taken, st, o in choices:
        if isinstance(st, DomainError):
            st = None
        elif st is not None and st.state is None:
            continue  # a blocked tick
        out.append((taken, st, o))
    return out


def _merged_choices(run, state):
    """``all_choices`` with in-tick retries merged (``EnumOracle.merge``), in the scalar
    engine's order, so that it gives the transitions that engine keeps."""
    stack, seen = [()], {}
    while stack:
        script = stack.pop()
        o = EnumOracle(script, seen)
        try:
            result = run(state, o)
        except DomainError as exc:
            result = exc
        taken = tuple(o.taken)
        for k in range(len(script), len(o.arities) if o.cut is None else max(o.cut, len(script))):
            for c in range(1, o.arities[k]):
                stack.append(taken[:k] + (c,))
        yield taken, result, o


def script_of(ts, t: int) -> tuple:
    """The choice script of transition ``t`` (found by re-enumerating its source's successors)."""
    i, j, li = ts.source(t), int(ts.dst[t]), ts.label_of(t)
    want_state = ts.full_state(j)
    want_label = ts.labels[li]
    prog = ts.model.program
    for script, st, o in successor_scripts(ts, ts.full_state(i)):
        if st is None or st.state != want_state:
            continue
        if readable(prog, tuple(o.picks), ts.open)[0] == want_label:
            return script
    raise LookupError(f"transition {t} cannot be re-enumerated (is the model the one explored?)")
