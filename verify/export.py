"""Export a model to Promela (SPIN), SMV (nuXmv/NuSMV) or dot, and the step description
the exporters and the vectorised engine (``verify.vector``) share.

``export(model, fmt, fsm=None, output=None) -> str``:

* ``promela`` / ``smv``: with ``fsm`` given, that FSM as an open system (exactly the
  system ``verify.explore.explore_fsm`` explores: the same stored slots, free inputs,
  environment entries, goals and parameters); without it, the whole model when its tree
  is a single ``SkillRequest`` (one transition = one BT tick), or the first FSM when the
  model has no tree. Anything else raises ``ModelError`` naming what is not supported.
* ``dot``: the explored transition system (``explore`` / ``explore_fsm``), refused above
  ``DOT_MAX_STATES`` states.

``step_spec(model, fsm=None, goals=None) -> StepSpec`` is the shared description: which
slots a state stores, what is chosen each step, and the FSM's per-(state, goal) tables in
the order of docs/semantics.md section 5, with the expressions as ASTs.

>>> from models.pickplace import pickplace
>>> spec = step_spec(pickplace(3))
>>> spec.kind, spec.fsm, [r.applicable for r in spec.rows[0]]
('model', 'skill', [True])
"""
from __future__ import annotations

from dataclasses import dataclass

from btfsm.bt import SkillRequest
from btfsm.errors import ModelError

__all__ = ["export", "step_spec", "StepSpec", "Row", "to_dot", "FORMATS", "DOT_MAX_STATES", "terminal_expr"]

FORMATS = ("promela", "smv", "dot")
DOT_MAX_STATES = 2000
_STATUS = ("RUNNING", "SUCCESS", "FAILURE")


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

    ``kind`` ``"fsm"``: the open system of ``verify.explore.open_fsm`` (``inputs`` chosen
    first and reset after the step; then the ``env`` entries; then a goal of ``goals``,
    requestable when one of ``pres[goal]`` holds (no entry: always); then every
    ``params`` value; then the FSM tick). ``kind`` ``"model"``: the environment, then the
    tree's single ``request`` (its ``flag`` slot, goal ``goals[0]``, parameter
    expressions ``params`` as ``((slot, AST), ...)``). ``stored``: the program slots a
    state holds."""

    model: object
    program: object
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
                             "(primitive states only); use verify.explore")
        prim = prog.prims[st.primitive or (st.id if st.outcomes is not None else "pass")]
        outcomes = tuple((int(o.status), o.effects, o.name) for o in prim.outcomes)
        per_goal = []
        for g in f.goals:
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


# ---------------------------------------------------------------------- export


def export(model, fmt: str, fsm: "str | None" = None, output: "str | None" = None) -> str:
    """The model in format ``fmt`` (promela, smv or dot); also written to ``output``."""
    if fmt not in FORMATS:
        raise ModelError("format", f"unknown export format '{fmt}' (expected one of {', '.join(FORMATS)})")
    if fmt == "dot":
        text = to_dot(_explore_small(model, fsm))
    else:
        if fsm is None and model.tree is None:
            if not model.fsms:
                raise ModelError("fsms", f"{fmt} export needs a tree that is a single SkillRequest or an FSM; the model has neither")
            fsm = model.fsms[0].name
        spec = step_spec(model, fsm)
        if fmt == "promela":
            from .promela import to_promela

            text = to_promela(spec)
        else:
            from .smv import to_smv

            text = to_smv(spec)
    if output:
        try:
            with open(output, "w", encoding="utf-8") as fh:
                fh.write(text)
        except OSError as exc:
            raise ModelError("output", f"cannot write {output}: {exc.strerror or exc}") from None
    return text


def _explore_small(model, fsm):
    from .explore import explore, explore_fsm

    if fsm is not None and fsm not in model.program.fsm_index:
        raise ModelError(f"fsms.{fsm}", f"no FSM named '{fsm}'")
    budget = DOT_MAX_STATES + 1
    ts = explore(model, max_states=budget) if fsm is None else explore_fsm(model, fsm, max_states=budget)
    if not ts.complete or ts.n_states > DOT_MAX_STATES:
        what = "the model" if fsm is None else f"FSM {fsm}"
        raise ModelError("format", f"dot export draws at most {DOT_MAX_STATES} states; {what} has more "
                                   f"(use promela or smv, or `btfsm show` for the FSM's structure)")
    return ts


def _dot_id(text: str) -> str:
    return '"' + str(text).replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def to_dot(ts, max_states: int = DOT_MAX_STATES) -> str:
    """Graphviz dot of an explored ``TransitionSystem``: one node per state (its variables,
    FSM states and goals, non-zero node memories and the running nodes), one edge per
    pair of states (the readable choices of its transitions).

    Dead states are drawn as double octagons, the initial state bold."""
    if ts.n_states > max_states:
        raise ModelError("format", f"dot export draws at most {max_states} states; this system has {ts.n_states}")
    title = ts.model.name if ts.kind == "model" else f"{ts.model.name}: FSM {ts.fsm}"
    lines = [f"digraph {_dot_id(title)} {{", "  rankdir=LR;", '  node [shape=box, fontname="Helvetica", fontsize=10];',
             '  edge [fontname="Helvetica", fontsize=9];']
    dead = set(int(x) for x in ts.dead)
    prog = ts.model.program
    kinds = [prog.slots[k].kind for k in ts.slots]
    for i in range(ts.n_states):
        label, running = [f"s{i}"], []
        for kind, (k, v) in zip(kinds, ts.decode(i).items()):
            if kind == "flag":  # node flags and memories: only the set ones
                if v:
                    running.append(k.split(":")[0])
            elif kind != "memory" or v:
                label.append(f"{k} = {_value(v)}")
        if running:
            label.append("running: " + ", ".join(running))
        text = "\n".join(label)
        style = ", style=bold" if i == 0 else ""
        shape = ", shape=doubleoctagon" if i in dead else ""
        lines.append(f"  s{i} [label={_dot_id(text)}{style}{shape}];")
    merged: dict = {}
    for t in range(ts.n_transitions):
        key = (int(ts.src[t]), int(ts.dst[t]))
        merged.setdefault(key, []).append(_label_text(ts.labels[int(ts.label[t])]))
    for (a, b), texts in merged.items():
        shown = texts if len(texts) <= 3 else texts[:3] + [f"... {len(texts) - 3} more"]
        lines.append(f"  s{a} -> s{b} [label={_dot_id(chr(10).join(shown))}];")
    lines.append("}")
    return "\n".join(lines) + "\n"


def _value(v) -> str:
    return str(v).lower() if isinstance(v, bool) else str(v)


def _label_text(label) -> str:
    parts = []
    for item in label:
        if item[0] == "env":
            parts.append(item[1])
        elif item[0] == "choice":
            parts.append(f"{item[1]}={item[2]}")
        elif item[0] == "goal":
            parts.append(f"goal {item[1]}")
        elif item[0] in ("input", "param"):
            parts.append(f"{item[1]}={_value(item[2])}")
        elif item[0] == "outcome":
            parts.append(f"{item[1]}:{item[2]}")
    return ", ".join(parts) or "tick"
