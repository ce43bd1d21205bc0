"""Model to data: the model written out in the file format (``model_from_data`` inverts it)."""
from __future__ import annotations

import json
from typing import Any, cast

import yaml

from ..bt import Composite, Decorator, file_fields
from ..expr import Const, Expr, to_text
from ..fsm import FSM, State
from ..model import EnvChoice, EnvEvent, Model
from ..primitives import Outcome
from ..profiles import DEFAULT_SEMANTICS, DEFAULT_TICK
from ..status import Status
from ..timing import Response
from ..world import Var

from .text import Dumper, format_of


def _expr_data(e: Any):  # an Expr (the model's expressions are Exprs once built)
    """Bool and int constants as YAML scalars, anything else as expression text."""
    if isinstance(e, Const) and isinstance(e.value, (bool, int)):
        return e.value
    return to_text(e)


def _effects_data(effects) -> dict:
    return {name: _expr_data(e) for name, e in effects}


def _var_data(var: Var):
    if var.kind == "bool":
        return {"bool": True} if var.init else "bool"
    out: dict
    if var.kind == "enum":
        out = {"enum": list(var.values)}
        if var.init != var.values[0]:
            out["init"] = var.init
        return out
    out = {"int": [var.lo, var.hi]}
    if var.init != var.lo:
        out["init"] = var.init
    return out


def _outcome_data(o: Outcome):
    key = cast(Status, o.status).name.lower()
    if not o.effects and o.name == key:
        return key
    out: dict = {key: _effects_data(o.effects)}
    if o.name != key:
        out["name"] = o.name
    return out


def _args_data(args) -> dict:
    return {k: _constant_data(v) for k, v in args}


def _constant_data(v):
    return [_constant_data(x) for x in v] if isinstance(v, (tuple, list)) else v


def _node_data(n) -> dict:
    t = type(n).__name__
    out = {t: n.name}
    for f in file_fields(type(n)):
        value, write = getattr(n, f.name), f.metadata["write"]
        if write == "always" or (value != n.name if write == "not_name" else value != f.default):
            out[f.name] = _FIELD_DATA[f.metadata["file"]](value)
    if isinstance(n, Composite) and n.children:
        out["children"] = [_node_data(c) for c in n.children]
    if isinstance(n, Decorator) and n.child is not None:
        out["child"] = _node_data(n.child)
    return out


#: node field kind (``btfsm.bt.FILE_KINDS``) -> its value as file data
_FIELD_DATA = {
    "int": lambda v: v, "opt_int": lambda v: v, "bool": lambda v: v, "opt_bool": lambda v: v, "string": lambda v: v,
    "names": list, "expr": _expr_data, "opt_expr": _expr_data, "effects": _effects_data,
    "outcomes": lambda v: [_outcome_data(o) for o in v], "args": _args_data, "duration": list,
    "params": lambda v: {k: _expr_data(e) for k, e in v},
}


def _state_data(st: State):
    if not st.primitive and not st.args and st.outcomes is None and st.subtree is None and st.duration is None:
        return st.id
    out: dict = {"id": st.id}
    if st.primitive:
        out["primitive"] = st.primitive
    if st.args:
        out["args"] = _args_data(st.args)
    if st.outcomes is not None:
        out["outcomes"] = [_outcome_data(o) for o in st.outcomes]
    if st.subtree is not None:
        out["subtree"] = _node_data(st.subtree)
    if st.duration is not None:
        out["duration"] = list(st.duration)
    return out


def _ids_to_write(elements, default_id) -> list:
    """Per element, whether its id must be written (it differs from the one the FSM
    would give it when loaded without an id; mirrors ``btfsm.fsm._with_ids``)."""
    used: dict
    used, out = {}, []
    for el in elements:
        base = default_id(el)
        n = used.get(base, 0)
        if el.id == (base if n == 0 else f"{base}#{n}"):
            used[base] = n + 1
            out.append(False)
        else:
            out.append(True)
    return out


def _trigger(el) -> "str | None":
    return "direct" if el.direct else el.on.name.lower()


def _fsm_data(f: FSM) -> dict:
    out: dict = {"goals": list(f.goals), "initial": f.initial}
    if f.params:
        out["params"] = {p.name: _var_data(p) for p in f.params}
    if f.retarget != "immediate":
        out["retarget"] = f.retarget
    if f.withdraw_goal:
        out["withdraw_goal"] = f.withdraw_goal
    out["states"] = [_state_data(s) for s in f.states]
    edges = []
    for e, write_id in zip(f.edges, _ids_to_write(f.edges, lambda e: f"{e.source}->{e.target}")):
        d: dict = {"from": e.source, "to": e.target, "goals": list(e.goals)}
        if _trigger(e) != "success":
            d["when"] = _trigger(e)
        if e.guard is not None:
            d["guard"] = _expr_data(e.guard)
        if e.effects:
            d["effects"] = _effects_data(e.effects)
        if write_id:
            d["id"] = e.id
        edges.append(d)
    if edges:
        out["edges"] = edges
    markers = []
    for m, write_id in zip(f.markers, _ids_to_write(f.markers, lambda m: f"{m.state}:{'direct' if m.direct else m.on.name.lower()}")):
        d = {"state": m.state, "goals": list(m.goals)}
        if _trigger(m) != "success":
            d["when"] = _trigger(m)
        if m.outcome != Status.SUCCESS:
            d["outcome"] = cast(Status, m.outcome).name.lower()
        if m.guard is not None:
            d["guard"] = _expr_data(m.guard)
        if write_id:
            d["id"] = m.id
        markers.append(d)
    if markers:
        out["markers"] = markers
    if f.terminal:
        out["terminal"] = list(f.terminal)
    return out


def _event_data(ev: EnvEvent) -> dict:
    out: dict = {"event": ev.name}
    if ev.guard is not None:
        out["guard"] = _expr_data(ev.guard)
    if ev.effects:
        out["effects"] = _effects_data(ev.effects)
    if ev.min_interval is not None:
        out["min_interval"] = ev.min_interval
    return out


def model_to_data(model: Model) -> dict:
    """The model as plain data in the file format: no templates, every element written
    out, fields at their default values left out. ``model_from_data`` inverts it."""
    out: dict = {"name": model.name}
    if model.description:
        out["description"] = model.description
    if model.semantics != DEFAULT_SEMANTICS:
        out["semantics"] = model.semantics
    if model.tick != DEFAULT_TICK:
        out["tick"] = model.tick
    if model.tick_rate != 10.0:
        out["tick_rate"] = model.tick_rate
    if model.variables:
        out["variables"] = {v.name: _var_data(v) for v in model.variables}
    if model.primitives:
        out["primitives"] = {p.name: ([_outcome_data(o) for o in p.outcomes] if p.duration is None else
                                      {"outcomes": [_outcome_data(o) for o in p.outcomes], "duration": list(p.duration)})
                             for p in model.primitives}
    if model.fsms:
        out["fsms"] = {f.name: _fsm_data(f) for f in model.fsms}
    if model.tree is not None:
        out["tree"] = _node_data(model.tree)
    if model.environment:
        out["environment"] = [
            {"choice": ev.name, "options": [_event_data(o) for o in ev.options]} if isinstance(ev, EnvChoice) else _event_data(ev)
            for ev in model.environment]
    if model.invariants:
        out["invariants"] = {k: _expr_data(e) for k, e in cast("tuple[tuple[str, Expr], ...]", model.invariants)}
    for key in ("workable", "terminal"):
        if getattr(model, key) is not None:
            out[key] = _expr_data(getattr(model, key))
    if model.resources:
        out["resources"] = {name: list(members) for name, members in cast("tuple[tuple[str, tuple[str, ...]], ...]", model.resources)}
    if model.responses:
        out["responses"] = {r.name: {"trigger": r.trigger if isinstance(r.trigger, str) else _expr_data(r.trigger),
                                     "response": _expr_data(r.response),
                                     **({} if r.within is None else {"within": r.within})}
                            for r in cast("tuple[Response, ...]", model.responses)}
    return out


def dumps_model(model: Model, fmt: str = "yaml") -> str:
    """The model as YAML or JSON text (see ``model_to_data``)."""
    data = model_to_data(model)
    if format_of("", fmt) == "json":
        return json.dumps(data, indent=2, ensure_ascii=False) + "\n"
    return yaml.dump(data, Dumper=Dumper, sort_keys=False, allow_unicode=True, default_flow_style=None, width=100)


def dump_model(model: Model, path_or_stream, fmt: "str | None" = None) -> None:
    """Write the model to a path (format from its extension unless ``fmt``) or a text stream."""
    if hasattr(path_or_stream, "write"):
        path_or_stream.write(dumps_model(model, fmt or "yaml"))
        return
    text = dumps_model(model, format_of(path_or_stream, fmt))
    with open(path_or_stream, "w", encoding="utf-8") as fh:
        fh.write(text)
