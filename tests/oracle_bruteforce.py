"""An independent brute-force checker, used only by the tests of ``verify``.

Plain Python sets and dicts and fixpoint iteration; no numpy and nothing imported from
``verify``. The only things shared with the checker are ``Program.step`` /
``Program.fsm_step`` (the one semantics) and ``ScriptOracle``. Successors are enumerated in
lexicographic order of the answer scripts (an odometer), not by the checker's
depth-first search, and the FSM-level open system is rebuilt here from the definition in
docs/verification.md for models without a tree (free inputs: world variables the FSM reads
that no effect anywhere writes; every environment event; every goal; every parameter value).
"""
from __future__ import annotations

import itertools

from btfsm.errors import DomainError
from btfsm.expr import names_in
from btfsm.oracles import ScriptOracle
from btfsm.status import Status

RUNNING, SUCCESS, FAILURE = int(Status.RUNNING), int(Status.SUCCESS), int(Status.FAILURE)


class _Watch(ScriptOracle):
    """A ScriptOracle that also notes the status of every primitive run."""

    __slots__ = ("statuses",)

    def __init__(self, script):
        ScriptOracle.__init__(self, script)
        self.statuses = []

    def outcome(self, site):
        k = ScriptOracle.outcome(self, site)
        self.statuses.append(site.outcomes[k][0])
        return k


def all_answers(run):
    """``[(result, oracle)]`` for every answer script; ``result`` is ``run(oracle)`` or
    ``("domain-error", var)``."""
    out, script = [], []
    while True:
        o = _Watch(script)
        try:
            res = run(o)
        except DomainError as exc:
            res = ("domain-error", exc.var)
        out.append((res, o))
        taken, ar = list(o.taken), o.arities
        k = len(taken) - 1
        while k >= 0 and taken[k] + 1 >= ar[k]:
            k -= 1
        if k < 0:
            return out
        script = taken[:k] + [taken[k] + 1]


def _is_error(res) -> bool:
    return isinstance(res, tuple) and res and res[0] == "domain-error"


def least_fixpoint(states, succ_ok, base) -> set:
    """The states that can reach ``base``: ``base`` plus, repeatedly, every state with a
    successor (as listed by ``succ_ok(s)``) already in the set."""
    good = set(base)
    changed = True
    while changed:
        changed = False
        for s in states:
            if s not in good and any(t in good for t in succ_ok(s)):
                good.add(s)
                changed = True
    return good


def greatest_cycle_set(states, succ) -> set:
    """The states from which an infinite path exists along ``succ``."""
    alive = set(states)
    changed = True
    while changed:
        changed = False
        for s in list(alive):
            if not any(t in alive for t in succ(s)):
                alive.discard(s)
                changed = True
    return alive


class ModelGraph:
    """The whole model, one edge per tick."""

    def __init__(self, model, limit: int = 20_000):
        prog = self.program = model.program
        self.model = model
        self.succ: dict = {}
        self.edges: set = set()
        self.errors: set = set()
        self.posts: set = set()
        seen, todo = {prog.initial}, [prog.initial]
        while todo:
            s = todo.pop()
            nxt = set()
            for res, _o in all_answers(lambda o, s=s: prog.step(s, o)):
                if _is_error(res):
                    self.errors.add(s)
                    continue
                if res.state is None:
                    continue
                nxt.add(res.state)
                self.edges.add((s, res.state))
                if any(v[0] == "post" for v in res.violations):
                    self.posts.add(s)
                if res.state not in seen:
                    seen.add(res.state)
                    todo.append(res.state)
                    if len(seen) > limit:
                        raise OverflowError("too many states for the brute-force oracle")
            self.succ[s] = nxt
        self.states = seen

    def terminal(self, s) -> bool:
        prog, model = self.program, self.model
        if prog.terminal is not None and prog.terminal(list(s)):
            return True
        if model.fsms and all(f.terminal for f in model.fsms):
            return all(prog.fsm_state(s, f.name)[0] in f.terminal for f in model.fsms)
        return False

    def dead(self) -> set:
        return {s for s in self.states if not self.succ[s] and s not in self.errors and not self.terminal(s)}

    def traps(self) -> set:
        workable = {s for s in self.states if self.program.workable(list(s))}
        return self.states - least_fixpoint(self.states, lambda s: self.succ[s], workable)

    def invariant_violations(self) -> dict:
        return {name: {s for s in self.states if not fn(list(s))} for name, fn in self.program.invariants}


class FSMGraph:
    """One FSM of a model WITHOUT a tree, as an open system; one edge per request."""

    def __init__(self, model, fsm: str, limit: int = 20_000):
        assert model.tree is None, "the brute-force FSM level is defined for models without a tree"
        prog = self.program = model.program
        f = self.fsm = model.fsm(fsm)
        fi = prog.fsm_index[fsm]
        self.token = prog.fsm_info[fi][2]
        scope = prog.fsm_scope(f)
        reads, written = set(), set()
        for e in f.edges:
            reads |= names_in(e.guard)
            for name, val in e.effects:
                reads |= names_in(val)
        for m in f.markers:
            reads |= names_in(m.guard)
        prims = prog.prims
        for st in f.states:
            prim = prims[st.primitive or (st.id if st.outcomes is not None else "pass")]
            for o in prim.outcomes:
                for name, val in o.effects:
                    reads |= names_in(val)
        for g in model.fsms:  # every effect anywhere
            for e in g.edges:
                written |= {n for n, _ in e.effects}
            for st in g.states:
                prim = prims[st.primitive or (st.id if st.outcomes is not None else "pass")]
                written |= {n for o in prim.outcomes for n, _ in o.effects}
        for ev in model.environment:
            for opt in getattr(ev, "options", None) or (ev,):
                written |= {n for n, _ in opt.effects}
        self.inputs = [(scope[v.name].index, list(range(v.lo, v.hi + 1))) for v in model.variables
                       if v.name in reads and v.name not in written and v.hi > v.lo]
        self.params = [list(range(p.lo, p.hi + 1)) for p in f.params]
        self.edges: dict = {}  # state -> set of (next, goal, status, progress)
        self.errors: set = set()
        start = prog.initial
        seen, todo = {start}, [start]
        while todo:
            s = todo.pop()
            out = set()
            for s2 in self._pre(s):  # (self._current: the state being expanded, for errors)
                for g in range(len(f.goals)):
                    for pv in itertools.product(*self.params):
                        for res, o in all_answers(lambda o, s2=s2, g=g, pv=pv: prog.fsm_step(s2, fi, g, pv, o)):
                            if _is_error(res):
                                self.errors.add(s)
                                continue
                            nxt = list(res.state)
                            for slot, _ in self.inputs:
                                nxt[slot] = start[slot]
                            nxt = tuple(nxt)
                            progress = (nxt[self.token] != s[self.token] or res.status != RUNNING
                                        or RUNNING in o.statuses)
                            out.add((nxt, g, res.status, progress))
                            if nxt not in seen:
                                seen.add(nxt)
                                todo.append(nxt)
                                if len(seen) > limit:
                                    raise OverflowError("too many states for the brute-force oracle")
            self.edges[s] = out
        self.states = seen

    def _pre(self, s):
        """Every state after choosing free inputs and running the environment events."""
        prog = self.program
        self._current = tuple(s)
        firsts = []
        for vals in itertools.product(*(v for _, v in self.inputs)):
            x = list(s)
            for (slot, _), val in zip(self.inputs, vals):
                x[slot] = val
            firsts.append(x)
        out = []
        for x in firsts:
            out += self._env(x, 0)
        return out

    def _env(self, s, i):
        env = self.program.env
        if i == len(env):
            return [s]
        name, guard, eff, options = env[i]
        assert options is None, "the brute-force FSM level takes environment events only"
        out = self._env(list(s), i + 1)  # the event does not happen
        if guard is None or guard(s):
            y = list(s)
            try:
                if eff is not None:
                    eff(y)
            except DomainError:
                self.errors.add(self._current)
                return out
            out += self._env(y, i + 1)
        return out

    def goal_failures(self) -> set:
        """(state, goal) pairs: the goal can be requested but never succeeds."""
        bad = set()
        for g in range(len(self.fsm.goals)):
            base = {s for s in self.states if any(e[1] == g and e[2] == SUCCESS for e in self.edges[s])}
            good = least_fixpoint(self.states, lambda s: [e[0] for e in self.edges[s] if e[1] == g and e[2] == RUNNING], base)
            bad |= {(s, g) for s in self.states if s not in good and any(e[1] == g for e in self.edges[s])}
        return bad

    def sink(self) -> bool:
        """Is a state reachable whose token is on an FSM state with no edge and no marker
        that is not terminal (every request fails there forever)?"""
        ids = self.program.fsm_info[self.program.fsm_index[self.fsm.name]][1]
        f = self.fsm
        for s in self.states:
            sid = ids[s[self.token]]
            if (sid not in f.terminal and not any(e.source == sid for e in f.edges)
                    and not any(m.state == sid for m in f.markers)):
                return True
        return False

    def non_progress(self) -> bool:
        """Is there a cycle of requests of one goal without progress?"""
        for g in range(len(self.fsm.goals)):
            if greatest_cycle_set(self.states, lambda s: [e[0] for e in self.edges[s]
                                                          if e[1] == g and not e[3]]):
                return True
        return False
