"""The step description shared by the exporters (Promela, SMV) and the vectorised engine.

``step_spec(model, fsm=None, goals=None) -> StepSpec`` says which slots a state stores,
what is chosen each step, and the FSM's per-(state, goal) tables in the order of
docs/semantics.md section 5, with the expressions as ASTs; ``int_bounds`` gives the static
range of an int expression.

>>> from btfsm.models.pickplace import pickplace
>>> spec = step_spec(pickplace(3))
>>> spec.kind, spec.fsm, [r.applicable for r in spec.rows[0]]
('model', 'skill', [True])
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from btfsm.bt import SkillRequest
from btfsm.errors import ModelError
from btfsm.expr import INT, BinOp, Call, Const, IfElse, Name, Unary

__all__ = ["Row", "StepSpec", "step_spec", "terminal_expr", "int_bounds"]


@dataclass(frozen=True)
class Row:
    """What FSM state ``s`` does for goal ``g`` (docs/semantics.md section 5).

    ``dedges``: direct edges ``(guard, target, effects, id)``; ``dmarkers``: direct markers
    ``(guard, outcome, id)``; ``applicable``: any edge or marker for the goal here;
    ``edges[status]`` / ``markers[status]``: the status edges and markers;
    ``outcomes``: the state's primitive outcomes ``(status, effects, name)``; ``site``: its
    label (``fsm/state``). Guards are ASTs (None: always), effects ``((var, AST), ...)``."""

    dedges: tuple
    dmarkers: tuple
    applicable: bool
    edges: tuple
    markers: tuple
    outcomes: tuple
    site: str


@dataclass(frozen=True, eq=False)
class StepSpec:
    """One transition of an exported system.

    ``kind`` ``"fsm"``: the open system of ``btfsm.verify.explore.open_fsm`` (``inputs`` chosen
    first and reset after the step; then the ``env`` entries; then a goal of ``goals``,
    requestable when one of ``pres[goal]`` holds (no entry: always); then every
    ``params`` value; then the FSM tick). ``kind`` ``"model"``: the environment, then the
    tree's single ``request`` (its ``flag`` slot, goal ``goals[0]``, parameter
    expressions ``params`` as ``((slot, AST), ...)``). ``stored``: the program slots a
    state holds."""

    model: Any  # btfsm.model.Model
    program: Any  # btfsm.semantics.Program
    kind: str
    fsm: str
    index: int
    stored: tuple
    inputs: tuple
    env: tuple
    goals: tuple
    pres: dict
    params: tuple
    request: "SkillRequest | None"
    flag: "int | None"
    rows: tuple

    @property
    def fsm_obj(self):
        return self.program.fsm_info[self.index][0]

    @property
    def token(self) -> int:
        return self.program.fsm_info[self.index][2]

    @property
    def goal_slot(self) -> int:
        return self.program.fsm_info[self.index][3]

    @property
    def param_slots(self) -> tuple:
        return self.program.fsm_info[self.index][4]

    @property
    def withdraw(self) -> "int | None":
        f = self.fsm_obj
        return f.goals.index(f.withdraw_goal) if f.retarget == "withdraw" else None

    def fixed(self) -> dict:
        """Slot -> value for every slot that is not stored (sliced away or a free input
        outside its step): they hold their initial value."""
        init = self.program.initial
        stored = set(self.stored)
        return {k: init[k] for k in range(len(init)) if k not in stored}


def step_spec(model, fsm: "str | None" = None, goals=None) -> StepSpec:
    """The step description of FSM ``fsm`` as an open system, or (``fsm`` None) of the
    whole model, whose tree must then be a single SkillRequest."""
    prog = model.program
    timed = next((info.name for info in prog.slots if info.kind == "timer"), None)
    if timed is not None:  # the environment phases and steps of these routes keep no timer (docs/semantics.md 6.1)
        ev = next(iter(prog.since_slots), None)
        what = f"since({ev}) is read" if ev is not None else \
            f"the model declares time (the counter '{timed}': a duration or an event's min_interval)"
        raise ModelError("environment" if ev is not None or timed.endswith(":since") else "durations",
                         f"{what}: whole-model and FSM exports and vectorised exploration do not model rules 'Durations' "
                         "and 'Event spacing' (docs/semantics.md 6.1); explore with the scalar or traced engine")
    if fsm is None:
        tree = model.tree
        if not isinstance(tree, SkillRequest):
            what = "no tree" if tree is None else f"a {type(tree).__name__}"
            raise ModelError("tree", f"whole-model export and vectorised exploration support a tree that is a single "
                                     f"SkillRequest (this model has {what}); export one FSM's open system instead (fsm=NAME, --fsm NAME)")
        fi = prog.fsm_index[tree.fsm]
        f = prog.fsm_info[fi][0]
        rows = _rows(prog, fi)
        pexprs = dict(tree.params)
        params = tuple((slot, pexprs[p.name]) for slot, p in zip(prog.fsm_info[fi][4], f.params))
        flag = prog.nodes[tree.name].flag
        return StepSpec(model, prog, "model", f.name, fi, tuple(range(len(prog.slots))), (), tuple(range(len(model.environment))),
                        (f.goals.index(tree.goal),), {}, params, tree, flag, rows)
    from .explore import open_fsm, requests_of

    if fsm not in prog.fsm_index:
        raise ModelError(f"fsms.{fsm}", f"no FSM named '{fsm}' (have: {', '.join(f.name for f in model.fsms) or 'none'})")
    try:
        op = open_fsm(model, fsm, goals)
    except KeyError as exc:
        raise ModelError(f"fsms.{fsm}.goals", str(exc.args[0])) from None
    fi = op.index
    f = prog.fsm_info[fi][0]
    rows = _rows(prog, fi)
    pres: dict = {}
    if op.pres:  # mirror open_fsm: per goal the requests' pre conditions (any may hold)
        for n in requests_of(model, fsm):
            pres.setdefault(f.goals.index(n.goal), []).append(n.pre)
        pres = {g: tuple(ps) for g, ps in pres.items() if all(p is not None for p in ps)}
    return StepSpec(model, prog, "fsm", fsm, fi, op.kept, op.inputs, op.env, op.goals, pres, op.params, None, None, rows)


def _rows(prog, fi) -> tuple:
    """rows[state][goal], mirroring ``Program._compile_fsm``."""
    f, ids, _, _, _ = prog.fsm_info[fi]
    index = {sid: k for k, sid in enumerate(ids)}
    out = []
    for st in f.states:
        if st.subtree is not None:
            raise ModelError(f"fsms.{f.name}.states.{st.id}.subtree",
                             "states that run a BT subtree are not supported by the Promela/SMV export and the vectorised engine "
                             "(primitive states only); use btfsm.verify.explore")
        prim = prog.prims[st.primitive or (st.id if st.outcomes is not None else "pass")]
        outcomes = tuple((int(o.status), o.effects, o.name) for o in prim.outcomes)
        per_goal = []
        for g in f.goals:
            dedges: list
            dmarkers: list
            edges: Any
            markers: Any
            item: tuple
            dedges, dmarkers, edges, markers, applicable = [], [], ([], [], []), ([], [], []), False
            for e in f.edges:
                if e.source != st.id or g not in e.goals:
                    continue
                applicable = True
                item = (e.guard, index[e.target], e.effects, e.id)
                (dedges if e.direct else edges[int(e.on)]).append(item)
            for m in f.markers:
                if m.state != st.id or g not in m.goals:
                    continue
                applicable = True
                item = (m.guard, int(m.outcome), m.id)
                (dmarkers if m.direct else markers[int(m.on)]).append(item)
            per_goal.append(Row(tuple(dedges), tuple(dmarkers), applicable, tuple(map(tuple, edges)),
                                tuple(map(tuple, markers)), outcomes, f"{f.name}/{st.id}"))
        out.append(tuple(per_goal))
    return tuple(out)


def terminal_expr(spec: StepSpec):
    """The AST of "stopping here is intended": the model's ``terminal`` or, for each FSM
    the system steps, its token on one of its ``terminal`` states (None: no such state)."""
    from btfsm.expr import BoolOp, Compare, Const, Name

    parts = [spec.model.terminal] if spec.model.terminal is not None else []
    f = spec.fsm_obj
    parts += [Compare("==", Name(f"{f.name}.state"), Const(t)) for t in f.terminal]
    if not parts:
        return None
    return parts[0] if len(parts) == 1 else BoolOp("or", tuple(parts))



def int_bounds(e, scope):
    """A conservative (lo, hi) of an int expression, or None when unknown."""
    if isinstance(e, Const):
        return (int(e.value), int(e.value)) if isinstance(e.value, int) and not isinstance(e.value, bool) else None
    if isinstance(e, Name):
        slot = scope[e.id]
        return (slot.lo, slot.hi) if slot.type == INT else None
    if isinstance(e, Unary) and e.op == "-":
        b = int_bounds(e.arg, scope)
        return None if b is None else (-b[1], -b[0])
    if isinstance(e, BinOp):
        a, b = int_bounds(e.left, scope), int_bounds(e.right, scope)
        if a is None or b is None:
            return None
        if e.op == "+":
            return a[0] + b[0], a[1] + b[1]
        if e.op == "-":
            return a[0] - b[1], a[1] - b[0]
        if e.op == "*":
            p = [a[0] * b[0], a[0] * b[1], a[1] * b[0], a[1] * b[1]]
            return min(p), max(p)
        if e.op == "%":
            return 0, b[1] - 1
        if e.op == "//":
            return a[0] // b[1] if a[0] >= 0 else a[0] // b[0], a[1] // b[0] if a[1] >= 0 else a[1] // b[1]
    if isinstance(e, Call):
        bs = [int_bounds(a, scope) for a in e.args]
        if any(b is None for b in bs):
            return None
        if e.fn == "abs":
            lo, hi = bs[0]
            return (0 if lo <= 0 <= hi else min(abs(lo), abs(hi))), max(abs(lo), abs(hi))
        (a0, a1), (b0, b1) = bs
        return (min(a0, b0), min(a1, b1)) if e.fn == "min" else (max(a0, b0), max(a1, b1))
    if isinstance(e, IfElse):
        a, b = int_bounds(e.then, scope), int_bounds(e.other, scope)
        return None if a is None or b is None else (min(a[0], b[0]), max(a[1], b[1]))
    return None
