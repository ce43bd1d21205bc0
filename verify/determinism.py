"""Determinism of goal-driven guards, decided with z3.

For every FSM, every (state, goal) and every firing point (direct edges, direct markers,
edges on status s, markers on status s, for the statuses the state can return), no two
elements may have guards that can be true together. The semantics would take the first in
declaration order, so an overlap means the later element is silently shadowed for some
inputs. Each FSM gets one incremental solver with every slot's domain asserted once; each
pair is a push/check/pop, after a syntactic pre-filter (``x == 'a'`` vs ``x == 'b'``, ``x``
vs ``not x``). z3 terms are cached per guard.

Gaps are reported as information: inputs for which no edge fires on a status the state can
return while edges exist for it (``uncovered``, with z3's witness), and SUCCESS/FAILURE
statuses with neither an edge nor a marker (``no-edge``: the status is swallowed, the token
stays and the state runs again). RUNNING without an edge is polling, by design.

>>> from btfsm import FSM, State, Edge, Model, Bool
>>> f = FSM("f", states=[State("a"), State("b")], goals=["g"],
...         edges=[Edge("a", "b", ["g"], guard="x"), Edge("a", "a", ["g"], guard="x or y")])
>>> m = Model("m", variables=[Bool("x"), Bool("y")], fsms=[f])
>>> overlaps, gaps = analyse(m)
>>> [(o["a"], o["b"], o["values"]["x"]) for o in overlaps]
[('a->b', 'a->a', True)]
"""
from __future__ import annotations

from btfsm.expr import BOOL, BoolOp, Compare, Const, Name, Unary, compile_fn, names_in, to_text, to_z3
from btfsm.status import Status

__all__ = ["analyse", "overlap_pairs", "confirm_overlap", "statuses_of_state"]

_POINTS = ("direct",) + tuple(f"on {s.name.lower()}" for s in Status)


def statuses_of_state(prog, st) -> tuple:
    """Statuses a state's run can return (all three for a subtree)."""
    if st.subtree is not None:
        return tuple(Status)
    prim = prog.prims.get(st.primitive or (st.id if st.outcomes is not None else "pass"))
    return tuple(s for s in Status if prim is not None and s in prim.statuses())


class _Solver:
    """One incremental z3 solver per FSM: slot domains asserted once, cached guard terms."""

    def __init__(self, prog, f):
        import z3

        self.z3, self.prog, self.f = z3, prog, f
        self.scope = prog.fsm_scope(f)
        self.vars = {}
        self.ctx = z3.Context()  # its own context: the same questions get the same witnesses
        self.solver = z3.Solver(ctx=self.ctx)
        for i, info in enumerate(prog.slots):
            if info.kind in ("flag", "memory"):
                continue
            v = z3.Int(info.name, self.ctx)
            self.vars[i] = v
            self.solver.add(v >= info.lo, v <= info.lo + info.size - 1)
        self.names = {name: self.vars[slot.index] for name, slot in self.scope.items() if slot.index in self.vars}
        self.cache: dict = {}
        self.checks = 0

    def term(self, expr):
        """The z3 term of a guard, built once per guard object (keyed by identity: hashing
        an expression tree costs as much as a lookup should)."""
        t = self.cache.get(id(expr))
        if t is None:
            t = self.z3.BoolVal(True, self.ctx) if expr is None else to_z3(expr, self.scope, self.names)
            self.cache[id(expr)] = t
        return t

    def witness(self, exprs) -> dict:
        """Decoded values of the names the ``exprs`` read, from the last sat model."""
        model = self.solver.model()
        out = {}
        for e in exprs:
            for name in sorted(names_in(e)):
                slot = self.scope[name]
                val = model.eval(self.names[name], model_completion=True).as_long()
                out[name] = self.prog.decode_slot(slot.index, val)
        return out

    def sat(self, *constraints) -> bool:
        self.checks += 1
        s = self.solver
        s.push()
        s.add(*constraints)
        r = s.check() == self.z3.sat
        if not r:
            s.pop()
        return r  # when sat, the caller reads the model then pops

    def pop(self):
        self.solver.pop()


def _literals(expr, scope) -> dict:
    """name -> allowed stored values, from the top-level conjuncts of the forms
    ``x == c``, ``x != c``, ``x in (...)`` (an or of equalities), ``x``, ``not x``."""
    out: dict = {}
    parts = expr.args if isinstance(expr, BoolOp) and expr.op == "and" else (expr,)
    for p in parts:
        got = _literal(p, scope)
        if got is not None:
            name, vals = got
            out[name] = out[name] & vals if name in out else vals
    return out


def _literal(p, scope):
    if isinstance(p, Name) and p.id in scope and scope[p.id].type == BOOL:
        return p.id, frozenset({1})
    if isinstance(p, Unary) and p.op == "not" and isinstance(p.arg, Name) and p.arg.id in scope and scope[p.arg.id].type == BOOL:
        return p.arg.id, frozenset({0})
    if isinstance(p, Compare) and p.op in ("==", "!="):
        a, b = p.left, p.right
        if isinstance(b, Name) and isinstance(a, Const):
            a, b = b, a
        if isinstance(a, Name) and isinstance(b, Const) and a.id in scope:
            slot = scope[a.id]
            code = _code(slot, b.value)
            if code is None:
                return None
            dom = frozenset(range(slot.lo, slot.hi + 1))
            return a.id, (frozenset({code}) if p.op == "==" else dom - {code})
    if isinstance(p, BoolOp) and p.op == "or":
        name, vals = None, frozenset()
        for q in p.args:
            got = _literal(q, scope)
            if got is None or (name is not None and got[0] != name):
                return None
            name, vals = got[0], vals | got[1]
        return name, vals
    return None


def _code(slot, value):
    if isinstance(value, bool):
        return int(value) if slot.type == BOOL else None
    if isinstance(value, str):
        return slot.type.values.index(value) if slot.type.kind == "enum" and value in slot.type.values else None
    if isinstance(value, int):
        return value
    return None


def _cached_literals(cache: dict, element, scope) -> dict:
    got = cache.get(id(element))
    if got is None:
        got = cache[id(element)] = _literals(element.guard, scope) if element.guard is not None else {}
    return got


def _disjoint(la: dict, lb: dict) -> bool:
    return any(not (la[n] & lb[n]) for n in la.keys() & lb.keys())


def overlap_pairs(items):
    """Pairs ``(a, b)`` of a firing point's elements, a declared before b."""
    return [(items[i], items[j]) for i in range(len(items)) for j in range(i + 1, len(items))]


def analyse(model, *, gaps: bool = True) -> tuple:
    """``(overlaps, gaps)``: lists of dicts (see the module docstring). Each overlap names
    the FSM, the state, the goals, the firing point, the element kind, the two element ids,
    their guards and z3's witness values (decoded: enum names, bools)."""
    prog = model.program
    overlaps, holes = [], []
    for f in model.fsms:
        solver = _Solver(prog, f)
        fi = prog.fsm_index[f.name]
        tok_var = solver.vars[prog.fsm_info[fi][2]]
        lits: dict = {}  # id(element) -> literal constraints of its guard
        done: dict = {}
        by_edge: dict
        by_marker: dict
        by_edge, by_marker = {}, {}  # (state, goal) -> elements, in declaration order
        for e in f.edges:
            for g in e.goals:
                by_edge.setdefault((e.source, g), []).append(e)
        for x in f.markers:
            for g in x.goals:
                by_marker.setdefault((x.state, g), []).append(x)
        for si, st in enumerate(f.states):
            solver.solver.push()  # the token is on this state for every query of the state
            solver.solver.add(tok_var == si)
            statuses = statuses_of_state(prog, st)
            for g in f.goals:
                edges = by_edge.get((st.id, g), [])
                markers = by_marker.get((st.id, g), [])
                if not edges and not markers:
                    continue  # not applicable: nothing fires
                groups = [("direct", "edge", [e for e in edges if e.direct]),
                          ("direct", "marker", [m for m in markers if m.direct])]
                for s in statuses:
                    groups.append((f"on {s.name.lower()}", "edge", [e for e in edges if not e.direct and e.on == s]))
                    groups.append((f"on {s.name.lower()}", "marker", [m for m in markers if not m.direct and m.on == s]))
                for point, kind, items in groups:
                    for a, b in overlap_pairs(items):
                        key = (st.id, kind, a.id, b.id)
                        if key in done:
                            if done[key] is not None:
                                done[key]["goals"].append(g)
                            continue
                        done[key] = None
                        la, lb = _cached_literals(lits, a, solver.scope), _cached_literals(lits, b, solver.scope)
                        if _disjoint(la, lb):
                            continue
                        if solver.sat(solver.term(a.guard), solver.term(b.guard)):
                            values = solver.witness([e for e in (a.guard, b.guard) if e is not None])
                            solver.pop()
                            item = {"fsm": f.name, "state": st.id, "goals": [g], "point": point, "kind": kind,
                                    "a": a.id, "b": b.id,
                                    "guards": [to_text(a.guard) if a.guard is not None else "true",
                                               to_text(b.guard) if b.guard is not None else "true"],
                                    "values": values}
                            done[key] = item
                            overlaps.append(item)
                if gaps:
                    holes += _gaps(solver, f, st, g, edges, markers, statuses, done)
            solver.solver.pop()
    return overlaps, holes


def _gaps(solver, f, st, g, edges, markers, statuses, done) -> list:
    out: list = []
    if any(e.direct and e.guard is None for e in edges):
        return out  # an unguarded direct edge always fires first
    for s in statuses:
        on = [e for e in edges if not e.direct and e.on == s]
        replies = [m for m in markers if not m.direct and m.on == s]
        key = ("gap", st.id, s, tuple(e.id for e in on))
        if key in done:
            if done[key] is not None:
                done[key]["goals"].append(g)
            continue
        done[key] = None
        if not on:
            if s == Status.RUNNING or replies:
                continue  # polling, or a reply with the token staying: by design
            item = {"fsm": f.name, "state": st.id, "goals": [g], "status": s.name.lower(), "kind": "no-edge",
                    "marker": replies[0].id if replies else None, "values": {}}
        elif any(e.guard is None for e in on):
            continue
        else:
            z3 = solver.z3
            if not solver.sat(z3.Not(z3.Or(*[solver.term(e.guard) for e in on]))):
                continue
            values = solver.witness([e.guard for e in on])
            solver.pop()
            item = {"fsm": f.name, "state": st.id, "goals": [g], "status": s.name.lower(), "kind": "uncovered",
                    "marker": replies[0].id if replies else None, "values": values}
        done[key] = item
        out.append(item)
    return out


def describe_overlap(o: dict) -> str:
    vals = ", ".join(f"{k}={_v(v)}" for k, v in o["values"].items()) or "any input"
    hint = ""
    if o["guards"][1] == "true":
        hint = f" (if '{o['b']}' means 'otherwise', guard it with the negation of the guards before it)"
    return (f"FSM {o['fsm']}, state '{o['state']}', goal(s) {', '.join(o['goals'])}, {o['point']}: "
            f"{o['kind']}s '{o['a']}' [{o['guards'][0]}] and '{o['b']}' [{o['guards'][1]}] can both fire, "
            f"e.g. when {vals}; '{o['a']}' is declared first and wins{hint}")


def describe_gap(gp: dict) -> str:
    who = f"FSM {gp['fsm']}, state '{gp['state']}', goal(s) {', '.join(gp['goals'])}, on {gp['status']}"
    reply = f" (marker '{gp['marker']}' replies)" if gp["marker"] else " (the reply is RUNNING)"
    if gp["kind"] == "no-edge":
        return f"{who}: no edge; the token stays and the state runs again{reply}"
    vals = ", ".join(f"{k}={_v(v)}" for k, v in gp["values"].items())
    return f"{who}: no edge fires when {vals}; the token stays{reply}"


def _v(x) -> str:
    return str(x).lower() if isinstance(x, bool) else str(x)


def confirm_overlap(model, o: dict) -> tuple:
    """Evaluate both guards of an overlap at its witness values (all other slots initial,
    the FSM's token on the state): ``(ok, text)``."""
    prog = model.program
    f = model.fsm(o["fsm"])
    scope = prog.fsm_scope(f)
    s = list(prog.initial)
    fi = prog.fsm_index[f.name]
    s[prog.fsm_info[fi][2]] = prog.fsm_info[fi][1].index(o["state"])
    for name, value in o["values"].items():
        slot = scope[name]
        code = _code(slot, value)
        if code is None:
            return False, f"value {value!r} of {name} is not in its domain"
        s[slot.index] = code
    elements = {e.id: e for e in (f.edges if o["kind"] == "edge" else f.markers)}
    results = []
    for eid in (o["a"], o["b"]):
        guard = elements[eid].guard
        results.append(True if guard is None else bool(compile_fn(guard, scope, f"fsms.{f.name}.{eid}", BOOL)(s)))
    if all(results):
        return True, f"confirmed: both guards of '{o['a']}' and '{o['b']}' hold at the witness values"
    return False, f"not both guards hold at the witness ({results})"
