"""Export a model to Promela (SPIN), SMV (nuXmv/NuSMV), dot or BehaviorTree.CPP XML.

``export(model, fmt, fsm=None, output=None) -> str``:

* ``promela`` / ``smv``: with ``fsm`` given, that FSM as an open system (exactly the
  system ``btfsm.verify.explore.explore_fsm`` explores: the same stored slots, free inputs,
  environment entries, goals and parameters); without it, the whole model when its tree
  is a single ``SkillRequest`` (one transition = one BT tick), or the first FSM when the
  model has no tree. Anything else raises ``ModelError`` naming what is not supported.
* ``dot``: the explored transition system (``explore`` / ``explore_fsm``), refused above
  ``DOT_MAX_STATES`` states.
* ``btcpp``: the tree as BehaviorTree.CPP XML v4 (``btfsm.interop.btcpp_export``); no
  ``fsm``.

The step description the exporters share with the vectorised engine is
``btfsm.verify.stepspec``.
"""
from __future__ import annotations

from btfsm.errors import ModelError
from btfsm.escape import dot_string

from .stepspec import Row, StepSpec, step_spec, terminal_expr

__all__ = ["export", "step_spec", "StepSpec", "Row", "to_dot", "FORMATS", "DOT_MAX_STATES", "DOT_MAX_TRANSITIONS", "terminal_expr"]

FORMATS = ("promela", "smv", "dot", "btcpp")
DOT_MAX_STATES = 2000
DOT_MAX_TRANSITIONS = 100_000


# ---------------------------------------------------------------------- export


def export(model, fmt: str, fsm: "str | None" = None, output: "str | None" = None, *, source: "str | None" = None,
           max_states=None, max_transitions=None, max_seconds=None) -> str:
    """The model in format ``fmt`` (promela, smv, dot or btcpp); also written to ``output``
    (atomically, ``btfsm.outputs``).

    Every error is a ModelError naming ``source`` (default: the file or built-in name
    ``btfsm.files.load_model`` read the model from, else the model's name) and the element.
    The budgets bound the exploration behind ``dot`` (``btfsm.verify.search.Budget``);
    hitting one raises ``BudgetExceeded``."""
    try:
        return _export(model, fmt, fsm, output, max_states, max_transitions, max_seconds)
    except ModelError as exc:
        if exc.file:
            raise
        shown = source if source is not None else getattr(model, "source", None) or getattr(model, "name", None)
        raise exc.at("", shown) from None


def _export(model, fmt, fsm, output, max_states, max_transitions, max_seconds) -> str:
    if fmt not in FORMATS:
        raise ModelError("format", f"unknown export format '{fmt}' (expected one of {', '.join(FORMATS)})")
    if fmt == "btcpp":
        if fsm is not None:
            raise ModelError("format", "btcpp export writes the tree; --fsm does not apply")
        from btfsm.interop.btcpp_export import to_btcpp_xml

        text = to_btcpp_xml(model)
    elif fmt == "dot":
        text = to_dot(_explore_small(model, fsm, max_states, max_transitions, max_seconds))
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
        from btfsm.outputs import atomic_write_text

        atomic_write_text(output, text)
    return text


def _explore_small(model, fsm, max_states=None, max_transitions=None, max_seconds=None):
    from .explore import explore, explore_fsm
    from .search import BudgetExceeded, describe_hit

    if fsm is not None and fsm not in model.program.fsm_index:
        raise ModelError(f"fsms.{fsm}", f"no FSM named '{fsm}'")
    states = DOT_MAX_STATES + 1 if max_states is None else min(max_states, DOT_MAX_STATES + 1)
    trans = DOT_MAX_TRANSITIONS + 1 if max_transitions is None else min(max_transitions, DOT_MAX_TRANSITIONS + 1)
    kw = dict(max_states=states, max_transitions=trans, max_seconds=max_seconds)
    ts = explore(model, **kw) if fsm is None else explore_fsm(model, fsm, **kw)
    own = {"states": max_states is None or max_states > DOT_MAX_STATES,
           "transitions": max_transitions is None or max_transitions > DOT_MAX_TRANSITIONS}
    if not ts.complete and not own.get(ts.stopped, False):
        raise BudgetExceeded(ts.stopped, f"{describe_hit(ts.stopped, max_states, max_transitions, max_seconds)} hit "
                                         f"after {ts.n_states:,} states, {ts.n_transitions:,} transitions, "
                                         f"{ts.seconds:.2f} s; nothing written")
    if ts.stopped == "transitions" or ts.n_transitions > DOT_MAX_TRANSITIONS:
        what = "the model" if fsm is None else f"FSM {fsm}"
        raise ModelError("format", f"dot export draws at most {DOT_MAX_TRANSITIONS} transitions; {what} has more "
                                   f"(use promela or smv, or `btfsm show` for the FSM's structure)")
    if not ts.complete or ts.n_states > DOT_MAX_STATES:
        what = "the model" if fsm is None else f"FSM {fsm}"
        raise ModelError("format", f"dot export draws at most {DOT_MAX_STATES} states; {what} has more "
                                   f"(use promela or smv, or `btfsm show` for the FSM's structure)")
    return ts


def to_dot(ts, max_states: int = DOT_MAX_STATES) -> str:
    """Graphviz dot of an explored ``TransitionSystem``: one node per state (its variables,
    FSM states and goals, non-zero node memories and the running nodes), one edge per
    pair of states (the readable choices of its transitions).

    Dead states are drawn as double octagons, the initial state bold."""
    if ts.n_states > max_states:
        raise ModelError("format", f"dot export draws at most {max_states} states; this system has {ts.n_states}")
    title = ts.model.name if ts.kind == "model" else f"{ts.model.name}: FSM {ts.fsm}"
    lines = [f"digraph {dot_string(title)} {{", "  rankdir=LR;", '  node [shape=box, fontname="Helvetica", fontsize=10];',
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
        lines.append(f"  s{i} [label={dot_string(text)}{style}{shape}];")
    merged: dict = {}
    for t in range(ts.n_transitions):
        key = (int(ts.src[t]), int(ts.dst[t]))
        merged.setdefault(key, []).append(_label_text(ts.labels[int(ts.label[t])]))
    for (a, b), texts in merged.items():
        shown = texts if len(texts) <= 3 else texts[:3] + [f"... {len(texts) - 3} more"]
        lines.append(f"  s{a} -> s{b} [label={dot_string(chr(10).join(shown))}];")
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
