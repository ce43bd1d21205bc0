"""Explore a model into an explicit ``TransitionSystem`` (breadth-first, budgeted).

``explore(model)``: the whole model, one transition per BT tick (``Program.step``).
``explore_fsm(model, fsm)``: one FSM as an open system, one transition per request: free
inputs, the environment entries that matter to it, the requested goal and its parameter
values are chosen every possible way, then ``Program.fsm_step`` runs.

A state's successors are enumerated by a depth-first search over choice scripts: run the
step with a script prefix (``ScriptOracle`` answers 0 past its end), then push every other
answer at every choice point after the prefix. Each script is a distinct leaf of the
choice tree, so every successor is produced exactly once per distinct set of answers.

States are stored as one int64 each (a mixed radix over the slots' domains); the visited
set is a dict of those codes. Transitions are kept in flat arrays in source order.

>>> from btfsm import Model, Bool, EnvEvent
>>> m = Model("flip", variables=[Bool("x")], environment=[EnvEvent("on", "not x", {"x": True})])
>>> ts = explore(m)
>>> ts.n_states, ts.n_transitions, ts.labels
(2, 3, ((), (('env', 'on'),)))
"""
from __future__ import annotations

import time
from array import array
from collections import deque
from dataclasses import dataclass
from operator import mul

import numpy as np

from btfsm.bt import Action, Condition, Effects, Guard, SkillRequest, walk
from btfsm.errors import DomainError
from btfsm.expr import names_in
from btfsm.oracles import ScriptOracle, all_choices

from .system import DomainViolation, TransitionSystem

__all__ = ["explore", "explore_fsm", "OpenFSM", "open_fsm", "requests_of", "EnumOracle", "run_environment",
           "successor_scripts", "run_script", "script_of", "DEFAULT_MAX_STATES"]

DEFAULT_MAX_STATES = 5_000_000
_PROGRESS_EVERY = 4096
_STATUS = ("RUNNING", "SUCCESS", "FAILURE")


class EnumOracle(ScriptOracle):
    """A ``ScriptOracle`` that also keeps ``picks``: every answer in a state-independent
    form (``("env", i, 0|1)``, ``("choice", i, option)``, ``(site, outcome)`` for every
    primitive that ran, single-outcome ones included). ``picks`` name a transition.

    Same answers and records as ``ScriptOracle`` (script entry k answers choice point k, 0
    past the end; ``arities``, ``labels``, ``taken``); the bookkeeping is inlined because
    this is the innermost loop of exploration. Scripts are assumed valid (they are made
    from the arities recorded on the same prefix)."""

    __slots__ = ("picks",)

    def __init__(self, script=()):
        self.script, self.pos = script, 0
        self.arities, self.labels, self.taken, self.picks = [], [], [], []

    def env(self, i):
        k = self.pos
        self.pos = k + 1
        s = self.script
        c = s[k] if k < len(s) else 0
        self.arities.append(2)
        self.labels.append(("env", i))
        self.taken.append(c)
        self.picks.append(("env", i, c))
        return c == 1

    def choose(self, i, enabled):
        if len(enabled) == 1:
            return 0  # a lone option is no choice (as in ScriptOracle)
        k = self.pos
        self.pos = k + 1
        s = self.script
        c = s[k] if k < len(s) else 0
        self.arities.append(len(enabled))
        self.labels.append(("choice", i))
        self.taken.append(c)
        self.picks.append(("choice", i, enabled[c]))
        return c

    def outcome(self, site):
        n = len(site.outcomes)
        if n == 1:
            self.picks.append((site, 0))
            return 0
        k = self.pos
        self.pos = k + 1
        s = self.script
        c = s[k] if k < len(s) else 0
        self.arities.append(n)
        self.labels.append(site)
        self.taken.append(c)
        self.picks.append((site, c))
        return c


# ---------------------------------------------------------------------- FSM open system


@dataclass(frozen=True, eq=False)
class OpenFSM:
    """One FSM as an open system (see ``open_fsm``).

    ``kept``: program slots stored in states; ``inputs``: free inputs ``(slot, values)``
    chosen before every request and reset to their initial value after it; ``env``:
    indices of the environment entries that write a kept slot; ``goals``: goal indices
    that can be requested; ``pres``: per goal, the ``pre`` conditions of the tree's
    SkillRequests for it (None: always requestable); ``params``: ``(slot, values)``."""

    program: object
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
        rec = [] if record else None
        if not run_environment(prog.env, s, oracle, self.env, rec):
            return None
        goals = self.goals
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
        for slot in (info.flag, info.mem):
            if slot is not None:
                writes.add(slot)
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
            for e in (n.pre, n.post, *(x for _, x in n.params)):
                if e is not None:
                    reads |= _expr_slots(e, scope)
            r, w = _fsm_footprint(prog, n.fsm, seen)
            reads |= r
            writes |= w
    return reads, writes


def requests_of(model, fsm: str) -> list:
    """The SkillRequest nodes (anywhere in the model) that request FSM ``fsm``."""
    return [n for n in model.nodes() if isinstance(n, SkillRequest) and n.fsm == fsm]


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
            goal_idx = tuple(sorted(pres))
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


def explore(model, *, max_states=None, progress=None, start=None, engine: str = "auto") -> TransitionSystem:
    """Explore the whole model: one transition per BT tick. ``start``: a state tuple to
    start from instead of ``model.program.initial``. ``progress(states, transitions,
    seconds)`` is called every few thousand expanded states.

    ``engine``: ``"traced"`` runs ``btfsm.verify.traced`` (the step function traced once per
    path, then applied to whole batches with numpy); ``"scalar"`` runs the step once per
    transition here; ``"auto"`` (the default) is traced unless the tracer cannot follow
    the model (``btfsm.verify.traced.Untraceable``), then scalar. Both give the same system,
    numbering included (tests compare them).

    When the model has an environment, the scalar engine memoises the tree's results by
    the state after the environment (see ``_TreeCache``): a tick is the environment then
    the tree, and the tree's results depend on nothing else."""
    prog = model.program
    kept = tuple(range(len(prog.slots)))
    init = tuple(start) if start is not None else prog.initial
    return _explore_with(engine, model, "model", None, kept, prog.step, init, max_states, progress, None)


def explore_fsm(model, fsm, *, goals=None, max_states=None, progress=None, start=None,
                engine: str = "auto") -> TransitionSystem:
    """Explore one FSM as an open system (``open_fsm``): one transition per request.
    ``engine`` as for ``explore``."""
    op = open_fsm(model, fsm, goals)
    prog = model.program
    init = tuple(start) if start is not None else prog.initial
    init = tuple(prog.initial[k] if k in dict(op.inputs) else v for k, v in enumerate(init))
    return _explore_with(engine, model, "fsm", op.fsm, op.kept, op.run, init, max_states, progress, op)


def _explore_with(engine, model, kind, fsm, kept, run, init, max_states, progress, op) -> TransitionSystem:
    """One system, explored by the engine asked for (see ``explore``)."""
    if engine not in ("auto", "traced", "scalar"):
        raise ValueError(f"engine must be auto, traced or scalar, not {engine!r}")
    if engine != "scalar":
        from .traced import Untraceable, search

        try:
            return search(model, kind, fsm, kept, run, init, max_states, progress, op)
        except Untraceable:
            if engine == "traced":
                raise
    split = _TreeCache(model) if kind == "model" and model.environment and model.tree is not None else None
    return _search(model, kind, fsm, kept, run, init, max_states, progress, op, split)


def _codec(prog, kept):
    """(multipliers over all slots, offset, total): code = sum(s * mult) - offset."""
    mults = [0] * len(prog.slots)
    total, offset = 1, 0
    for k in reversed(kept):
        info = prog.slots[k]
        mults[k] = total
        offset += info.lo * total
        total *= max(info.size, 1)
    return tuple(mults), offset, total


def run_environment(env, s, oracle, indices=None, rec=None) -> bool:
    """Apply the environment entries ``env`` (``Program.env``; only those at ``indices``
    when given) to the state list ``s`` in place, asking ``oracle`` like ``Program.step``
    does (docs/semantics.md, tick step 1); ``rec`` collects env and write events.
    Returns False when a choice has no enabled option (the tick cannot happen)."""
    for i in (range(len(env)) if indices is None else indices):
        name, guard, eff, options = env[i]
        if options is not None:
            enabled = [k for k, o in enumerate(options) if o[1] is None or o[1](s)]
            if not enabled:
                return False
            name, _, eff, _ = options[enabled[oracle.choose(i, enabled)] if len(enabled) > 1 else enabled[0]]
        elif not ((guard is None or guard(s)) and oracle.env(i)):
            continue
        if eff is not None:
            eff(s)
        if rec is not None:
            rec.append(("env", name))
            if eff is not None:
                rec.extend(("write", k, s[k]) for k in eff.targets)
    return True


class _TreeCache:
    """The tree's results per state reached after the environment.

    ``Program.step`` applies the environment to the tick's state list and then ticks the
    root on the same context; nothing but the state passes from one phase to the other
    (the per-tick FSM records start empty, the environment adds no violation). So the
    results of a tick are the environment's results followed by the results of a tick
    of the same model without environment from the state the environment left, and those
    can be computed once per such state. The choice script of a tick is the environment's
    answers followed by the tree's, as ``Program.step`` asks them."""

    # entries per generation, at most two generations kept: BFS revisits recent states, and
    # the measured hit rates at 10,000 equal those of an unbounded cache
    LIMIT = 20_000

    def __init__(self, model, limit: "int | None" = None):
        import dataclasses

        self.env = model.program.env
        self.tree = dataclasses.replace(model, environment=()).program
        self.limit = limit or self.LIMIT
        self.cache: dict = {}  # this generation
        self.old: dict = {}  # the previous one: entries used again move up
        self.tree_ids: dict = {}
        self.tree_keys: list = []
        self.hits = self.misses = 0

    def results(self, post, mults, small, kept):
        """``[(tree key id, code, state, status, violations, taken, error)]`` of ``post``."""
        res = self.cache.get(post)
        if res is not None:
            self.hits += 1
            return res
        res = self.old.pop(post, None)
        if res is not None:
            self.hits += 1
            self._keep(post, res)
            return res
        self.misses += 1
        res = []
        stack = [()]
        step = self.tree.step
        while stack:
            script = stack.pop()
            o = EnumOracle(script)
            err = st = None
            try:
                st = step(post, o)
            except DomainError as exc:
                err = exc
            ar = o.arities
            k0 = len(script)
            if len(ar) > k0:
                taken = o.taken
                for k in range(k0, len(ar)):
                    base = tuple(taken[:k])
                    for c in range(1, ar[k]):
                        stack.append(base + (c,))
            key = tuple(o.picks)
            tid = self.tree_ids.get(key)
            if tid is None:
                tid = self.tree_ids[key] = len(self.tree_keys)
                self.tree_keys.append(key)
            if err is not None:
                res.append((tid, None, None, None, None, tuple(o.taken), err))
                continue
            ns = st.state
            code = sum(map(mul, ns, mults)) if small else tuple(ns[k] for k in kept)
            res.append((tid, code, ns, st.status, tuple(st.violations) if st.violations else None, None, None))
        self._keep(post, res)
        return res

    def _keep(self, post, res):
        if len(self.cache) >= self.limit:
            self.old, self.cache = self.cache, {}
        self.cache[post] = res


def _search(model, kind, fsm, kept, run, initial, max_states, progress, op, split=None) -> TransitionSystem:
    t0 = time.perf_counter()
    prog = model.program
    mults, offset, total = _codec(prog, kept)
    small = total < (1 << 62)
    budget = DEFAULT_MAX_STATES * 1000 if max_states is None else max(int(max_states), 1)
    visited: dict = {}
    codes = array("q") if small else []
    tuples = None if small else []
    parent = array("q", [-1])
    src, dst, lab, stat = array("q"), array("q"), array("q"), array("b")
    label_ids: dict = {}
    readable_ids: dict = {}
    labels: list = []
    label_goal: list = []
    errors, violations = [], []
    s0 = tuple(initial)
    c0 = sum(map(mul, s0, mults)) if small else tuple(s0[k] for k in kept)
    visited[c0] = 0
    if small:
        codes.append(c0)
    else:
        tuples.append(c0)
    queue = deque([s0])
    n, i, complete, nt = 1, -1, True, 0
    Oracle = EnumOracle
    last = 0

    def label_of(key):
        readable, g = _readable(prog, key, op)
        li = readable_ids.get(readable)
        if li is None:
            li = readable_ids[readable] = len(labels)
            labels.append(readable)
            label_goal.append(g)
        return li

    # bound methods as locals: these loops run once per transition
    src_add, dst_add, lab_add, stat_add = src.append, dst.append, lab.append, stat.append
    code_add = codes.append if small else tuples.append
    parent_add, queue_add, pop = parent.append, queue.append, queue.popleft
    vget, lget = visited.get, label_ids.get
    env_ids: dict = {}
    while queue:
        s = pop()
        i += 1
        if progress is not None and i - last >= _PROGRESS_EVERY:
            last = i
            progress(n, nt, time.perf_counter() - t0)
        stack = [()]
        if split is not None:  # environment answers here, tree results from the cache
            env = split.env
            while stack:
                script = stack.pop()
                o = Oracle(script)
                post = list(s)
                try:
                    ok = run_environment(env, post, o)
                except DomainError as exc:
                    errors.append(DomainViolation(i, tuple(o.taken), _readable(prog, tuple(o.picks), op)[0],
                                                  exc.var, exc.value, exc.where, str(exc)))
                    ok = False
                ar = o.arities
                k0 = len(script)
                if len(ar) > k0:
                    taken = o.taken
                    for k in range(k0, len(ar)):
                        base = tuple(taken[:k])
                        for c in range(1, ar[k]):
                            stack.append(base + (c,))
                if not ok:
                    continue
                ekey = tuple(o.picks)
                row = env_ids.get(ekey)
                if row is None:
                    row = env_ids[ekey] = {}
                for tid, c, ns, status, viol, ttaken, err in split.results(tuple(post), mults, small, kept):
                    if err is not None:
                        full = ekey + split.tree_keys[tid]
                        errors.append(DomainViolation(i, tuple(o.taken) + ttaken, _readable(prog, full, op)[0],
                                                      err.var, err.value, err.where, str(err)))
                        continue
                    li = row.get(tid)
                    if li is None:
                        li = row[tid] = label_of(ekey + split.tree_keys[tid])
                    j = vget(c)
                    if j is None:
                        if n >= budget:
                            complete = False
                            break
                        j = n
                        n += 1
                        visited[c] = j
                        code_add(c)
                        parent_add(nt)
                        queue_add(ns)
                    src_add(i)
                    dst_add(j)
                    lab_add(li)
                    stat_add(status)
                    if viol is not None:
                        violations.append((nt, viol))
                    nt += 1
                if not complete:
                    break
        else:
            while stack:
                script = stack.pop()
                o = Oracle(script)
                try:
                    st = run(s, o)
                except DomainError as exc:
                    errors.append(DomainViolation(i, tuple(o.taken), _readable(prog, tuple(o.picks), op)[0],
                                                  exc.var, exc.value, exc.where, str(exc)))
                    st = None
                ar = o.arities
                k0 = len(script)
                if len(ar) > k0:
                    taken = o.taken
                    for k in range(k0, len(ar)):
                        base = tuple(taken[:k])
                        for c in range(1, ar[k]):
                            stack.append(base + (c,))
                if st is None:
                    continue
                ns = st.state
                if ns is None:
                    continue
                key = tuple(o.picks)
                li = lget(key)
                if li is None:
                    li = label_ids[key] = label_of(key)
                c = sum(map(mul, ns, mults)) if small else tuple(ns[k] for k in kept)
                j = vget(c)
                if j is None:
                    if n >= budget:
                        complete = False
                        break
                    j = n
                    n += 1
                    visited[c] = j
                    code_add(c)
                    parent_add(nt)
                    queue_add(ns)
                src_add(i)
                dst_add(j)
                lab_add(li)
                stat_add(st.status)
                if st.violations:
                    violations.append((nt, tuple(st.violations)))
                nt += 1
        if not complete:
            break
    expanded = i + 1 if complete else i
    del visited
    states = _decode(prog, kept, codes, offset, mults) if small else _rows(prog, kept, tuples)
    # numpy views of the arrays' buffers (no copy: peak memory stays one copy of the edges)
    src_a = np.frombuffer(src, dtype=np.int64) if nt else np.zeros(0, np.int64)
    dst_a = np.frombuffer(dst, dtype=np.int64) if nt else np.zeros(0, np.int64)
    lab_a = np.frombuffer(lab, dtype=np.int64) if nt else np.zeros(0, np.int64)
    stat_a = np.frombuffer(stat, dtype=np.int8) if nt else np.zeros(0, np.int8)
    goal_a = np.asarray(label_goal, dtype=np.int64)[lab_a] if kind == "fsm" else None
    seconds = time.perf_counter() - t0
    if progress is not None:
        progress(n, nt, seconds)
    return TransitionSystem(model=model, kind=kind, fsm=fsm, slots=tuple(kept), states=states, src=src_a, dst=dst_a,
                            label=lab_a, labels=tuple(labels), parent=np.frombuffer(parent, dtype=np.int64),
                            complete=complete, seconds=seconds, status=stat_a, goal=goal_a, expanded=expanded,
                            errors=tuple(errors), violations=tuple(violations), open=op)


def _dtype(prog, kept):
    lo = min((prog.slots[k].lo for k in kept), default=0)
    hi = max((prog.slots[k].lo + prog.slots[k].size - 1 for k in kept), default=0)
    for dt in (np.int8, np.int16, np.int32):
        info = np.iinfo(dt)
        if info.min <= lo and hi <= info.max:
            return dt
    return np.int64


def _decode(prog, kept, codes, offset, mults) -> np.ndarray:
    c = np.frombuffer(codes, dtype=np.int64) - offset
    out = np.empty((len(c), len(kept)), dtype=_dtype(prog, kept))
    for col, k in enumerate(kept):
        info = prog.slots[k]
        out[:, col] = (c // mults[k]) % max(info.size, 1) + info.lo
    return out


def _rows(prog, kept, tuples) -> np.ndarray:
    return np.array(tuples, dtype=_dtype(prog, kept)).reshape(len(tuples), len(kept))


def _readable(prog, key, op) -> tuple:
    """(hashable readable label, requested goal index or -1) of a picks key."""
    out, goal = [], -1
    env = prog.env
    for p in key:
        head = p[0]
        if head == "env":
            if p[2]:
                out.append(("env", env[p[1]][0]))
        elif head == "choice":
            tag, val = p[1], p[2]
            if isinstance(tag, int):
                out.append(("choice", env[tag][0], env[tag][3][val][0]))
            elif tag[0] == "goal":
                goal = val
                f = prog.fsm_info[op.index][0]
                out.append(("goal", f.goals[val]))
            else:  # ("input", slot) or ("param", slot)
                out.append((tag[0], prog.slots[tag[1]].name, prog.decode_slot(tag[1], val)))
        else:  # (site, outcome index)
            site, k = p
            status, _, oname = site.outcomes[k]
            out.append(("outcome", site.label, oname, _STATUS[status]))
    return tuple(out), goal


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
    for taken, st, o in all_choices(lambda s, o: run(s, o, True), tuple(state), EnumOracle, (DomainError,)):
        if isinstance(st, DomainError):
            st = None
        elif st is not None and st.state is None:
            continue  # a blocked tick
        out.append((taken, st, o))
    return out


def script_of(ts, t: int) -> tuple:
    """The choice script of transition ``t`` (found by re-enumerating its source's successors)."""
    i, j, li = int(ts.src[t]), int(ts.dst[t]), int(ts.label[t])
    want_state = ts.full_state(j)
    want_label = ts.labels[li]
    prog = ts.model.program
    for script, st, o in successor_scripts(ts, ts.full_state(i)):
        if st is None or st.state != want_state:
            continue
        if _readable(prog, tuple(o.picks), ts.open)[0] == want_label:
            return script
    raise LookupError(f"transition {t} cannot be re-enumerated (is the model the one explored?)")
