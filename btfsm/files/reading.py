"""Data to Model: the shape of expanded data checked element by element, and the Model built."""
from __future__ import annotations

import dataclasses
import difflib
import heapq
import math
import re
from typing import cast

from ..bt import NODE_TYPES, Action, Composite, Decorator, Leaf, file_fields, walk
from ..errors import ModelError, ModelErrors, collected
from ..expr import Expr, as_expr
from ..fsm import FSM, Edge, Marker, State
from ..model import EnvChoice, EnvEvent, Model
from ..primitives import Outcome, Primitive
from ..profiles import PROFILES, TICKS
from ..status import Status
from ..timing import Response, duration_of
from ..world import Bool, Enum, Int, Var

from .repair import hides, pass_action, repair
from .templates import check_fields, expand_templates
from .text import MAX_DEPTH, MAX_ERRORS, err, join_path, kind_of, loads_data, where_of


_VAR_KINDS = ("bool", "enum", "int")
_STATUS = ("success", "failure", "running")
#: node field kinds whose null stands for the default (the others refuse null)
_NULL_IS_DEFAULT = ("opt_int", "opt_bool", "names", "opt_expr", "outcomes", "args", "duration", "params")


def node_keys(cls) -> tuple:
    """The keys a model file's node of type ``cls`` may have besides its type key."""
    own = tuple(f.name for f in file_fields(cls))
    if issubclass(cls, Composite):
        return own + ("children",)
    return own + ("child",) if issubclass(cls, Decorator) else own


def node_required(cls) -> tuple:
    """The keys a model file's node of type ``cls`` must have: its required fields, the
    child of a decorator, the children when its type needs some (``btfsm.bt`` arity)."""
    own = tuple(f.name for f in file_fields(cls) if f.metadata["required"])
    if issubclass(cls, Decorator):
        return own + ("child",)
    return own + ("children",) if issubclass(cls, Composite) and cls.arity[0] > 0 else own


TRIGGER_KEYS = ("when", "on", True)  # "on" and True (YAML 1.1's reading of on:) are older spellings
TOP_FIELDS = ("name", "description", "semantics", "tick", "tick_rate", "variables", "primitives", "fsms", "tree",
              "environment", "invariants", "workable", "terminal", "resources", "responses")
FSM_FIELDS = ("goals", "states", "initial", "edges", "markers", "params", "retarget", "withdraw_goal", "terminal")


_FILE_FIELDS = {"source": "from", "target": "to"}  # Python field -> file field (edges)
_FILE_FIELD = re.compile(r"^\.(source|target)\b")


class _Skipped(Exception):
    """An element holds a problem already noted: it is not built (nor what holds it)."""


class _Full(Exception):
    """``MAX_ERRORS`` problems are noted: the reading stops."""


class _Reader:
    """Checks the shape of expanded data and builds the Model objects.

    Problems are collected, element by element (a variable, a primitive, an FSM's state,
    edge or marker, a tree node's fields, an event, an invariant, a resource, a
    requirement): an element with a problem is noted and skipped, and the reading goes on
    with the next one, so that one pass reports every independent problem (up to
    ``MAX_ERRORS``). What holds a skipped element is not built, and the Model is not
    built either when the shape has problems (its checks would report what follows from
    them). A shape without problems is built into a Model; the Model's checks stop at
    their first problem, so ``build`` takes the element it names out (an edge, a marker,
    an unknown name in an expression...: ``_without``), or repairs it (a duplicate name,
    a variable's declaration, a cycle of direct edges...: ``repair``), and builds again,
    to report the next one, as long as what it changes cannot cause a problem of its own."""

    def __init__(self, file, earlier=()):
        self.file = file
        self.earlier = list(earlier)  # problems found when the data was read (keys given twice)
        self.where: dict = {}  # element path used by the Model -> (path in the file, parent, key)
        self.errors: list = []  # the problems noted so far, in the order found
        self.sites: dict = {}  # element path used by the Model -> every (path in the file, parent, key), in order
        self.shifts: dict = {}  # repair's record of the duplicates and members it took out
        self.renamed: dict = {}  # a node's name of its own (a duplicate's, by repair) -> the name in the file

    def each(self, build, *args):
        """``build(*args)``; when it raises a ModelError: the problem noted and None returned
        (the caller skips the element). Raises ``_Full`` at ``MAX_ERRORS`` problems."""
        try:
            return build(*args)
        except _Skipped:
            return None
        except ModelError as exc:
            self.errors.extend(exc.errors if isinstance(exc, ModelErrors) else [exc])
            if len(self.errors) >= MAX_ERRORS:
                raise _Full() from None
            return None

    @staticmethod
    def raise_(exc):
        """Raise ``exc`` (``each(self.raise_, exc)`` notes a problem and goes on)."""
        raise exc

    def all_built(self, *items):
        """Raise ``_Skipped`` when one of ``items`` (an element or a list of them) was skipped."""
        for x in items:
            if x is None or (isinstance(x, (list, tuple)) and any(y is None for y in x)):
                raise _Skipped()

    def fail(self, path, problem, obj=None, key=None):
        return err(path, problem + where_of(obj, key), self.file)

    def alias(self, model_path, path, parent, key):
        self.where.setdefault(model_path, (path, parent, key))
        sites = self.sites.setdefault(model_path, [])
        if not sites or sites[-1][0] != path:
            sites.append((path, parent, key))

    def translate(self, exc: ModelError) -> ModelError:
        """A Model error with its element path rewritten to the path in the file (+ line)."""
        el = exc.element or ""
        cut = len(el)
        while cut > 0:
            head = el[:cut]
            if head in self.where:
                path, parent, key = self.where[head]
                rest = _FILE_FIELD.sub(lambda m: "." + _FILE_FIELDS[m.group(1)], el[cut:], count=1)
                field = re.match(r"\.([^.\[]+)", rest)
                try:
                    elem = parent[key]
                except (KeyError, IndexError, TypeError):
                    elem = None
                if field and isinstance(elem, dict) and field.group(1) in elem:
                    line = where_of(elem, field.group(1))
                else:
                    line = where_of(parent, key)
                return err(path + rest, exc.problem + line, self.file)
            cut = max(el.rfind(".", 0, cut), el.rfind("[", 0, cut))
        return err(el, exc.problem, self.file)

    # ---------------------------------------------------------------- scalars
    def fields(self, obj, path, allowed, required=(), what="a mapping"):
        check_fields(self, obj, path, allowed, required, what)
        return obj

    def string(self, obj, path, parent=None, key=None, what="a string"):
        if not isinstance(obj, str):
            raise self.fail(path, f"expected {what}, got {kind_of(obj)}", parent, key)
        return obj

    def integer(self, obj, path, parent=None, key=None):
        if isinstance(obj, bool) or not isinstance(obj, int):
            raise self.fail(path, f"expected an integer, got {kind_of(obj)}", parent, key)
        return obj

    def expr(self, obj, path, parent=None, key=None) -> Expr:
        if isinstance(obj, float) or obj is None or not isinstance(obj, (str, int, bool)):
            raise self.fail(path, f"expected an expression (a string such as \"queue > 0\"), got {kind_of(obj)}", parent, key)
        try:
            return as_expr(obj)
        except ModelError as exc:
            raise err(path, exc.problem + where_of(parent, key), self.file) from None

    def opt_expr(self, obj, key, path):
        return self.expr(obj[key], join_path(path, key), obj, key) if obj.get(key) is not None else None

    def effects(self, obj, path, parent=None, key=None) -> tuple:
        if obj is None:
            return ()
        if not isinstance(obj, dict):
            raise self.fail(path, f"expected effects as a mapping 'variable: expression', got {kind_of(obj)}", parent, key)
        out = []
        for var, e in obj.items():
            self.string(var, path, obj, var, "a variable name")
            out.append((var, self.expr(e, join_path(path, var), obj, var)))
        return tuple(out)

    def names(self, obj, path, parent, key, what, allow_all=False) -> tuple:
        if isinstance(obj, str):
            return (obj,)
        if not isinstance(obj, list):
            raise self.fail(path, f"expected a list of {what}, got {kind_of(obj)}", parent, key)
        for i, x in enumerate(obj):
            self.string(x, f"{path}[{i}]", obj, i, f"a {what[:-1]} name")
        if not allow_all and "*" in obj:
            raise self.fail(path, "'*' (all goals) is only allowed in edges and markers", parent, key)
        return tuple(obj)

    def constants(self, obj, path, parent, key) -> tuple:
        """``args``: a mapping of names to constants, kept in file order."""
        if not isinstance(obj, dict):
            raise self.fail(path, f"expected a mapping of argument names to constants, got {kind_of(obj)}", parent, key)
        out = []
        for k, v in obj.items():
            self.string(k, path, obj, k, "an argument name")
            out.append((k, self.constant(v, join_path(path, k), obj, k)))
        return tuple(out)

    def constant(self, v, path, parent, key, depth=0):
        if isinstance(v, float) and not math.isfinite(v):
            raise self.fail(path, "numbers must be finite", parent, key)
        if isinstance(v, str):
            try:
                v.encode("utf-8")
            except UnicodeEncodeError:
                raise self.fail(path, "holds a lone surrogate, which is not valid text", parent, key) from None
        if v is None or isinstance(v, (str, int, float, bool)):
            return v
        if isinstance(v, list) and depth < 8:
            return tuple(self.constant(x, f"{path}[{i}]", v, i, depth + 1) for i, x in enumerate(v))
        raise self.fail(path, f"an argument is a constant (string, number, boolean) or a list of them, got {kind_of(v)}", parent, key)

    # ---------------------------------------------------------------- declarations
    def variables(self, obj, path, element_prefix) -> tuple:
        if obj is None:
            return ()
        if not isinstance(obj, dict):
            raise self.fail(path, f"expected a mapping of names to types, got {kind_of(obj)}", obj)
        out = [self.each(self.one_var, name, spec, path, obj, element_prefix) for name, spec in obj.items()]
        self.all_built(out)
        return tuple(out)

    def one_var(self, name, spec, path, obj, element_prefix) -> Var:
        p = join_path(path, name)
        self.string(name, path, obj, name, "a variable name")
        self.alias(f"{element_prefix}.{name}", p, obj, name)
        return self.var(name, spec, p, obj)

    def var(self, name, spec, path, parent) -> Var:
        if spec == "bool":
            return Bool(name)
        if isinstance(spec, str):
            raise self.fail(path, f"unknown type '{spec}' (write bool, {{bool: true}}, {{enum: [a, b]}} or {{int: [lo, hi]}})", parent, name)
        kinds = [k for k in _VAR_KINDS if isinstance(spec, dict) and k in spec]
        if not isinstance(spec, dict) or len(kinds) != 1:
            raise self.fail(path, "a variable is bool, {bool: INIT}, {enum: [VALUES], init: V} or {int: [LO, HI], init: N}", parent, name)
        kind = kinds[0]
        self.fields(spec, path, (kind,) if kind == "bool" else (kind, "init"))
        if kind == "bool":
            init = spec["bool"]
            if init is None:
                return Bool(name)
            if not isinstance(init, bool):
                raise self.fail(f"{path}.bool", f"the initial value of a bool is true or false, got {kind_of(init)}", spec, "bool")
            return Bool(name, init)
        init = spec.get("init")
        if isinstance(init, float) or isinstance(init, (list, dict)):
            raise self.fail(f"{path}.init", f"expected {'a value name' if kind == 'enum' else 'an integer'}, got {kind_of(init)}", spec, "init")
        if kind == "enum":
            values = spec["enum"]
            if not isinstance(values, list) or not values:
                raise self.fail(f"{path}.enum", "expected a non-empty list of value names", spec, "enum")
            for i, v in enumerate(values):
                self.string(v, f"{path}.enum[{i}]", values, i, "a value name")
            return Enum(name, values, init)
        bounds = spec["int"]
        if not isinstance(bounds, list) or len(bounds) != 2:
            raise self.fail(f"{path}.int", "expected [lo, hi]", spec, "int")
        lo, hi = (self.integer(b, f"{path}.int[{i}]", bounds, i) for i, b in enumerate(bounds))
        if init is not None:
            self.integer(init, f"{path}.init", spec, "init")
        return Int(name, lo, hi, init)

    def outcomes(self, obj, path, parent, key, element) -> tuple:
        if not isinstance(obj, list):
            raise self.fail(path, f"expected a list of outcomes such as [running, {{success: {{done: true}}}}], got {kind_of(obj)}", parent, key)
        out = []
        for i, o in enumerate(obj):
            p = f"{path}[{i}]"
            if isinstance(o, str):
                if o not in _STATUS:
                    raise self.fail(p, f"unknown status '{o}' (expected success, failure or running)", obj, i)
                out.append(Outcome(Status.parse(o)))
                continue
            statuses = [k for k in _STATUS if isinstance(o, dict) and k in o]
            if not isinstance(o, dict) or len(statuses) != 1:
                raise self.fail(p, "an outcome is success, failure, running, or {STATUS: {effects}, name: NAME}", obj, i)
            st = statuses[0]
            self.fields(o, p, (st, "name"))
            name = self.string(o["name"], f"{p}.name", o, "name") if "name" in o else ""
            if "name" in o and not name:
                raise self.fail(f"{p}.name", "an outcome name cannot be empty", o, "name")
            oc = Outcome(Status.parse(st), self.effects(o[st], f"{p}.{st}", o, st), name)
            self.alias(f"{element}.outcomes.{oc.name}", f"{p}.{st}", o, st)
            out.append(oc)
        return tuple(out)

    def primitives(self, obj) -> tuple:
        if obj is None:
            return ()
        if not isinstance(obj, dict):
            raise self.fail("primitives", f"expected a mapping of primitive names to outcome lists, got {kind_of(obj)}", obj)
        out = [self.each(self.primitive, name, outs, obj) for name, outs in obj.items()]
        self.all_built(out)
        return tuple(out)

    def primitive(self, name, outs, obj) -> Primitive:
        p = join_path("primitives", name)
        self.string(name, "primitives", obj, name, "a primitive name")
        self.alias(p, p, obj, name)
        duration = None
        if isinstance(outs, dict) and ("outcomes" in outs or "duration" in outs):  # {outcomes: [...], duration: ...}
            self.fields(outs, p, ("outcomes", "duration"), ("outcomes",), "a list of outcomes, or {outcomes: [...], duration: [min, max]}")
            duration = self.duration(outs.get("duration"), f"{p}.duration", outs, "duration")
            outs = outs["outcomes"]
        return Primitive(name, self.outcomes(outs, p, obj, name, p), duration)

    def duration(self, value, path, parent, key):
        """``[min, max]`` seconds (max may be null), ``{min: , max: }`` or one number (btfsm.timing)."""
        try:
            return duration_of(value, path)
        except ModelError as exc:
            raise self.fail(path, exc.problem, parent, key) from None

    # ---------------------------------------------------------------- tree
    def node(self, obj, path, root, parent=None, key=None, depth=0):
        if depth > MAX_DEPTH:
            raise self.fail(path, f"the tree is nested more than {MAX_DEPTH} levels deep", parent, key)
        if not isinstance(obj, dict):
            raise self.fail(path, f"expected a tree node such as {{Condition: name, expr: ...}}, got {kind_of(obj)}", parent, key)
        types = [k for k in obj if k in NODE_TYPES]
        if len(types) != 1:
            if types:
                raise self.fail(path, f"a node has exactly one type, got {', '.join(types)}", obj)
            keys = [k for k in obj if isinstance(k, str)]
            close = [c for k in keys for c in difflib.get_close_matches(k, list(NODE_TYPES), 1)]
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise self.fail(path, f"a node needs a type key{hint}: one of {', '.join(NODE_TYPES)}", obj)
        t = types[0]
        self.fields(obj, path, (t,) + node_keys(NODE_TYPES[t]), node_required(NODE_TYPES[t]))
        name = obj[t]
        if not isinstance(name, str) or not name:
            raise self.fail(join_path(path, t), f"the node name (the value of '{t}') must be a non-empty string, got {kind_of(name)}", obj, t)
        for prefix in ("tree", root):
            self.alias(f"{prefix}.{name}", path, parent, key)
        cls, kw = NODE_TYPES[t], {}
        if "children" in obj:
            kids = obj["children"]
            if not isinstance(kids, list):
                raise self.fail(f"{path}.children", f"expected a list of nodes, got {kind_of(kids)}", obj, "children")
            kw["children"] = tuple(self.each(self.node, c, f"{path}.children[{i}]", root, kids, i, depth + 1)
                                   for i, c in enumerate(kids))
        if "child" in obj:
            kw["child"] = self.each(self.node, obj["child"], f"{path}.child", root, obj, "child", depth + 1)
        n = len(self.errors)
        for f in file_fields(cls):
            kind = f.metadata["file"]
            if f.name in obj and (obj[f.name] is not None or kind not in _NULL_IS_DEFAULT):
                kw[f.name] = self.each(self.node_field, kind, obj[f.name], f"{path}.{f.name}", obj, f.name, f.metadata, name)
        self.all_built(kw.get("children", ()), kw.get("child", True))
        if len(self.errors) > n:
            raise _Skipped()
        return cls(name, **kw)

    def node_field(self, kind, value, path, obj, key, meta, name):
        """One node field of file kind ``kind`` (``btfsm.bt.FILE_KINDS``)."""
        if kind in ("int", "opt_int"):
            return self.integer(value, path, obj, key)
        if kind in ("bool", "opt_bool"):
            if not isinstance(value, bool):
                raise self.fail(path, f"expected true or false, got {kind_of(value)}", obj, key)
            return value
        if kind == "string":
            return self.string(value, path, obj, key, meta["what"] or "a string")
        if kind == "names":
            return self.names(value, path, obj, key, meta["what"])
        if kind in ("expr", "opt_expr"):
            return self.expr(value, path, obj, key)
        if kind == "effects":
            return self.effects(value, path, obj, key)
        if kind == "outcomes":
            return self.outcomes(value, path, obj, key, f"tree.{name}")
        if kind == "args":
            return self.constants(value, path, obj, key)
        if kind == "duration":
            return self.duration(value, path, obj, key)
        assert kind == "params", kind
        if not isinstance(value, dict):
            raise self.fail(path, f"expected a mapping of parameter names to expressions, got {kind_of(value)}", obj, key)
        return tuple((self.string(k, path, value, k, "a parameter name"), self.expr(v, f"{path}.{k}", value, k))
                     for k, v in value.items())

    def alias_declared_outcomes(self, kw):
        """Effects of a declared primitive are checked where it is used; point there at
        the declaration instead."""
        declared = {p.name: p for p in kw.get("primitives", ())}
        uses = []
        for f in kw.get("fsms", ()):
            uses += [(f"fsms.{f.name}.states.{st.id}", st.primitive) for st in f.states if st.outcomes is None]
            uses += [(f"tree.{n.name}", n.primitive) for st in f.states if st.subtree is not None for n in walk(st.subtree)
                     if isinstance(n, Action) and n.outcomes is None]
        tree = kw.get("tree")
        uses += [(f"tree.{n.name}", n.primitive) for n in (walk(tree) if tree is not None else ())
                 if isinstance(n, Action) and n.outcomes is None]
        for element, prim in uses:
            for o in declared[prim].outcomes if prim in declared else ():
                target = self.where.get(f"primitives.{prim}.outcomes.{o.name}")
                if target is not None:
                    self.where[f"{element}.outcomes.{o.name}"] = target

    # ---------------------------------------------------------------- FSMs
    def fsm(self, name, spec, path, parent) -> FSM:
        self.fields(spec, path, FSM_FIELDS, ("goals", "states"), "an FSM (a mapping with goals and states)")
        self.alias(path, path, parent, name)
        n = len(self.errors)
        goals = self.each(self.names, spec["goals"], f"{path}.goals", spec, "goals", "goals")
        states_data = spec["states"]
        states: tuple = ()
        if not isinstance(states_data, list):
            self.each(self.raise_, self.fail(f"{path}.states", f"expected a list of states, got {kind_of(states_data)}",
                                             spec, "states"))
        else:
            states = tuple(self.each(self.state, name, s, f"{path}.states[{i}]", states_data, i)
                           for i, s in enumerate(states_data))
        kw = {}
        for k in ("initial", "retarget", "withdraw_goal"):
            if k in spec:
                kw[k] = self.each(self.string, spec[k], f"{path}.{k}", spec, k)
        if "terminal" in spec:
            kw["terminal"] = self.each(self.names, spec["terminal"], f"{path}.terminal", spec, "terminal", "states")
        kw["params"] = self.each(self.variables, spec.get("params"), f"{path}.params", f"fsms.{name}.params")
        edges: list
        markers: list
        edges, markers = [], []
        for key, build, out in (("edges", self.edge, edges), ("markers", self.marker, markers)):
            items = spec.get(key)
            if items is None:
                continue
            if not isinstance(items, list):
                self.each(self.raise_, self.fail(f"{path}.{key}", f"expected a list, got {kind_of(items)}", spec, key))
                continue
            for i, x in enumerate(items):
                built = self.each(build, x, f"{path}.{key}[{i}]", items, i)
                out.extend(built if isinstance(built, list) else [built])
        if len(self.errors) > n:
            raise _Skipped()
        f = FSM(name, states=states, goals=goals, edges=tuple(e for e, _ in edges),
                markers=tuple(m for m, _ in markers), **kw)
        for built, (_, where) in zip(f.edges, edges):
            self.alias(f"fsms.{name}.edges.{built.id}", *where)
        for built, (_, where) in zip(f.markers, markers):
            self.alias(f"fsms.{name}.markers.{built.id}", *where)
        return f

    def state(self, fsm, obj, path, parent, key) -> State:
        if isinstance(obj, str):
            self.alias(f"fsms.{fsm}.states.{obj}", path, parent, key)
            return State(obj)
        self.fields(obj, path, ("id", "primitive", "args", "outcomes", "subtree", "duration"), ("id",), "a state (an id, or a mapping with id)")
        sid = self.string(obj["id"], f"{path}.id", obj, "id", "a state id")
        element = f"fsms.{fsm}.states.{sid}"
        self.alias(element, path, parent, key)
        kw = {}
        if "primitive" in obj:
            kw["primitive"] = self.string(obj["primitive"], f"{path}.primitive", obj, "primitive", "a primitive name")
        if obj.get("args") is not None:
            kw["args"] = self.constants(obj["args"], f"{path}.args", obj, "args")
        if obj.get("outcomes") is not None:
            kw["outcomes"] = self.outcomes(obj["outcomes"], f"{path}.outcomes", obj, "outcomes", element)
        if obj.get("subtree") is not None:
            kw["subtree"] = self.node(obj["subtree"], f"{path}.subtree", f"{element}.subtree", obj, "subtree")
        if obj.get("duration") is not None:
            kw["duration"] = self.duration(obj["duration"], f"{path}.duration", obj, "duration")
        return State(sid, **kw)

    def trigger(self, obj, path):
        """The trigger of an edge or marker: ``when:`` (or the older ``on:``, also as the
        boolean key ``true`` that YAML 1.1 readers make of it)."""
        given = [k for k in obj if k is True or (isinstance(k, str) and k in TRIGGER_KEYS)]
        if len(given) > 1:
            raise self.fail(path, f"give the trigger once (as 'when'; got {', '.join(str(k) for k in given)})", obj)
        key = given[0] if given else None
        on = obj[key] if given else "success"
        if on not in _STATUS + ("direct",):
            shown = "on" if key is True else key
            raise self.fail(f"{path}.{shown}", f"expected success, failure, running or direct, got {on!r}", obj, key)
        return {"direct": True} if on == "direct" else {"on": Status.parse(on)}

    def trigger_fields(self, obj, path, allowed, required, what):
        """Check the fields of an edge or marker, accepting the trigger's old spellings."""
        if isinstance(obj, dict) and any(k is True for k in obj):
            obj = {("on" if k is True else k): v for k, v in obj.items() if not (k is True and "on" in obj)}
        self.fields(obj, path, allowed, required, what)

    def edge(self, obj, path, parent, key):
        self.trigger_fields(obj, path, ("from", "to", "goals", "when", "on", "guard", "effects", "id"), ("from", "to"), "an edge {from: A, to: B, ...}")
        kw = self.trigger(obj, path)
        if "goals" in obj:
            kw["goals"] = self.names(obj["goals"], f"{path}.goals", obj, "goals", "goals", allow_all=True)
        if "id" in obj:
            kw["id"] = self.string(obj["id"], f"{path}.id", obj, "id")
        target = self.string(obj["to"], f"{path}.to", obj, "to", "a state id")
        guard, effects = self.opt_expr(obj, "guard", path), self.effects(obj.get("effects"), f"{path}.effects", obj, "effects")
        sources = obj["from"]
        if not isinstance(sources, list):
            return Edge(self.string(sources, f"{path}.from", obj, "from", "a state id"), target, guard=guard,
                        effects=effects, **kw), (path, parent, key)
        # from: [a, b]: one edge per source, alike in everything else (ids: ID/SOURCE when given)
        if not sources:
            raise self.fail(f"{path}.from", "expected a state id or a non-empty list of state ids", obj, "from")
        out = []
        for k, src in enumerate(sources):
            sid = self.string(src, f"{path}.from[{k}]", sources, k, "a state id")
            if sid in sources[:k]:
                raise self.fail(f"{path}.from[{k}]", f"state '{sid}' is listed twice", sources, k)
            one = dict(kw, id=f"{kw['id']}/{sid}") if "id" in kw and len(sources) > 1 else kw
            out.append((Edge(sid, target, guard=guard, effects=effects, **one), (path, parent, key)))
        return out

    def marker(self, obj, path, parent, key):
        self.trigger_fields(obj, path, ("state", "goals", "when", "on", "outcome", "guard", "id"), ("state",), "a marker {state: S, ...}")
        kw = self.trigger(obj, path)
        if "goals" in obj:
            kw["goals"] = self.names(obj["goals"], f"{path}.goals", obj, "goals", "goals", allow_all=True)
        if "id" in obj:
            kw["id"] = self.string(obj["id"], f"{path}.id", obj, "id")
        if "outcome" in obj:
            if obj["outcome"] not in ("success", "failure"):
                raise self.fail(f"{path}.outcome", f"expected success or failure, got {obj['outcome']!r}", obj, "outcome")
            kw["outcome"] = Status.parse(obj["outcome"])
        m = Marker(self.string(obj["state"], f"{path}.state", obj, "state", "a state id"), guard=self.opt_expr(obj, "guard", path), **kw)
        return m, (path, parent, key)

    # ---------------------------------------------------------------- environment
    def event(self, obj, path, parent, key, element):
        self.fields(obj, path, ("event", "guard", "effects", "min_interval"), ("event",),
                    "an event {event: NAME, guard: ..., effects: {...}, min_interval: SECONDS}")
        name = self.string(obj["event"], f"{path}.event", obj, "event", "an event name")
        self.alias(f"{element}.{name}", path, parent, key)
        gap = obj.get("min_interval")
        if gap is not None and (isinstance(gap, bool) or not isinstance(gap, (int, float)) or not 0 <= gap < math.inf):
            raise self.fail(f"{path}.min_interval", f"expected a finite number of seconds >= 0, got {kind_of(gap)}", obj, "min_interval")
        return EnvEvent(name, self.opt_expr(obj, "guard", path), self.effects(obj.get("effects"), f"{path}.effects", obj, "effects"),
                        gap)

    def environment(self, obj) -> tuple:
        if obj is None:
            return ()
        if not isinstance(obj, list):
            raise self.fail("environment", f"expected a list of events and choices, got {kind_of(obj)}", obj)
        out = [self.each(self.env_entry, ev, i, obj) for i, ev in enumerate(obj)]
        self.all_built(out)
        return tuple(out)

    def env_entry(self, ev, i, obj):
        p = f"environment[{i}]"
        self.alias(p, p, obj, i)
        if isinstance(ev, dict) and "choice" in ev:
            self.fields(ev, p, ("choice", "options"), ("options",), "a choice {choice: NAME, options: [...]}")
            name = self.string(ev["choice"], f"{p}.choice", ev, "choice", "a choice name")
            self.alias(f"environment.{name}", p, obj, i)
            opts = ev["options"]
            if not isinstance(opts, list):
                raise self.fail(f"{p}.options", f"expected a list of events, got {kind_of(opts)}", ev, "options")
            for k in range(len(opts)):
                self.alias(f"environment.{name}.options[{k}]", f"{p}.options[{k}]", opts, k)
            options = [self.each(self.event, o, f"{p}.options[{k}]", opts, k, f"environment.{name}.options")
                       for k, o in enumerate(opts)]
            self.all_built(options)
            return EnvChoice(name, tuple(options))
        return self.event(ev, p, obj, i, "environment")

    def resources(self, obj, data) -> tuple:
        """``resources: {arm: [pick_a, pick_b]}``: resource name -> node names."""
        if not isinstance(obj, dict):
            raise self.fail("resources", f"expected a mapping of resource names to lists of node names, got {kind_of(obj)}",
                            data, "resources")
        out = [self.each(self.resource, name, members, obj) for name, members in obj.items()]
        self.all_built(out)
        return tuple(out)

    def resource(self, name, members, obj) -> tuple:
        self.string(name, "resources", obj, name, "a resource name")
        path = join_path("resources", name)
        self.alias(path, path, obj, name)
        if isinstance(members, str):
            members = [members]
        if not isinstance(members, list):
            raise self.fail(path, f"expected a list of node names, got {kind_of(members)}", obj, name)
        for i, m in enumerate(members):
            self.string(m, f"{path}[{i}]", members, i, "a node name")
        return (name, tuple(members))

    def responses(self, obj, data) -> tuple:
        """``responses: {NAME: {trigger: EXPR | event:NAME, response: EXPR, within: SECONDS}}``."""
        if not isinstance(obj, dict):
            raise self.fail("responses", f"expected a mapping of names to {{trigger, response, within}}, got {kind_of(obj)}",
                            data, "responses")
        out = [self.each(self.response, name, spec, obj) for name, spec in obj.items()]
        self.all_built(out)
        return tuple(out)

    def response(self, name, spec, obj) -> Response:
        self.string(name, "responses", obj, name, "a requirement name")
        path = join_path("responses", name)
        self.alias(path, path, obj, name)
        if not isinstance(spec, dict):
            raise self.fail(path, f"expected {{trigger: ..., response: ..., within: SECONDS}}, got {kind_of(spec)}", obj, name)
        self.fields(spec, path, ("trigger", "response", "within"), ("trigger", "response"),
                    "{trigger: EXPR or event:NAME, response: EXPR, within: SECONDS}")
        trig = spec["trigger"]
        if isinstance(trig, str) and trig.strip().startswith("event:"):
            trig = trig.strip()
        else:
            trig = self.expr(trig, f"{path}.trigger", spec, "trigger")
        resp = self.expr(spec["response"], f"{path}.response", spec, "response")
        within = spec.get("within")
        if within is not None and (isinstance(within, bool) or not isinstance(within, (int, float))
                                   or not 0 <= within < math.inf):
            raise self.fail(f"{path}.within", f"expected a finite number of seconds >= 0, got {kind_of(within)}", spec, "within")
        return Response(name, trig, resp, within)

    # ---------------------------------------------------------------- the model
    def model(self, data) -> Model:
        """The Model of ``data``, or every independent problem found (``ModelErrors``)."""
        if not isinstance(data, dict):
            self.fields(data, "", TOP_FIELDS, ("name",), "a mapping with the model")
        try:
            kw = self.read(data)
        except _Full:
            kw = {}
        if self.errors or self.earlier:
            raise collected_at_most(_merged(self.earlier, self.errors))
        return self.build(kw)

    def read(self, data) -> dict:
        """The Model's arguments, each top-level element read on its own (problems noted)."""
        each = self.each
        each(self.fields, data, "", TOP_FIELDS, ("name",), "a mapping with the model")
        kw: dict = {}
        if "name" in data:
            kw["name"] = each(self.string, data["name"], "name", data, "name", "a model name")
        if "description" in data:
            kw["description"] = each(self.string, data["description"], "description", data, "description")
        if "semantics" in data:
            sem = data["semantics"]
            if not isinstance(sem, str) or sem not in PROFILES:
                each(self.raise_, self.fail("semantics", f"expected one of {', '.join(PROFILES)}, got {sem!r}", data, "semantics"))
            kw["semantics"] = sem
        if "tick" in data:
            tick = data["tick"]
            if not isinstance(tick, str) or tick not in TICKS:
                each(self.raise_, self.fail("tick", f"expected one of {', '.join(TICKS)}, got {tick!r}", data, "tick"))
            kw["tick"] = tick
        if "tick_rate" in data:
            r = data["tick_rate"]
            if isinstance(r, bool) or not isinstance(r, (int, float)) or not math.isfinite(r):
                each(self.raise_, self.fail("tick_rate", f"expected a finite number of ticks per second, got {kind_of(r)}",
                                            data, "tick_rate"))
            kw["tick_rate"] = r
        for key in TOP_FIELDS:
            self.alias(key, key, data, key)
        kw["variables"] = each(self.variables, data.get("variables"), "variables", "variables")
        kw["primitives"] = each(self.primitives, data.get("primitives"))
        fsms = data.get("fsms")
        if fsms is not None:
            if not isinstance(fsms, dict):
                each(self.raise_, self.fail("fsms", f"expected a mapping of FSM names to FSMs, got {kind_of(fsms)}", data, "fsms"))
            else:
                kw["fsms"] = tuple(each(self.named_fsm, n, spec, fsms) for n, spec in fsms.items())
        if data.get("tree") is not None:
            kw["tree"] = each(self.node, data["tree"], "tree", "tree", data, "tree")
        kw["environment"] = each(self.environment, data.get("environment"))
        inv = data.get("invariants")
        if inv is not None:
            if not isinstance(inv, dict):
                each(self.raise_, self.fail("invariants", f"expected a mapping of names to expressions, got {kind_of(inv)}",
                                            data, "invariants"))
            else:
                kw["invariants"] = tuple(each(self.invariant, k, v, inv) for k, v in inv.items())
        for key in ("workable", "terminal"):
            if data.get(key) is not None:
                kw[key] = each(self.expr, data[key], key, data, key)
        if data.get("resources") is not None:
            kw["resources"] = each(self.resources, data["resources"], data)
        if data.get("responses") is not None:
            kw["responses"] = each(self.responses, data["responses"], data)
        return kw

    def named_fsm(self, name, spec, fsms) -> FSM:
        return self.fsm(self.string(name, "fsms", fsms, name, "an FSM name"), spec, join_path("fsms", name), fsms)

    def invariant(self, name, expr, inv) -> tuple:
        return (self.string(name, "invariants", inv, name, "an invariant name"), self.expr(expr, join_path("invariants", name), inv, name))

    def build(self, kw) -> Model:
        """``Model(**kw)``; when its checks find a problem, the element it names is taken out
        (``_without``), or the problem repaired (``repair``: a duplicate name, a variable's
        declaration, a cycle of direct edges...), and the Model built again, for the next
        problem, until it builds, a problem can be neither, or ``MAX_ERRORS``. A problem
        about an element taken out (or made neutral), or about a name whose declaration
        was taken out, follows from it and is not reported."""
        self.alias_declared_outcomes(kw)
        errors: list = []
        taken: list = []
        hidden: set = set()
        for _ in range(_MAX_BUILDS):
            try:
                model = Model(**kw)
            except ModelError as exc:
                el = exc.element or ""
                if any(el == t or el.startswith((t + ".", t + "[")) for t in taken):
                    break  # it follows from what was taken out
                follows = hides(exc, hidden)
                fixed = None if follows else repair(self, kw, exc)
                if fixed is not None:
                    if any(str(e) == str(fixed.error) for e in errors):
                        break  # the repair did not take the problem away
                    errors += [fixed.error, *fixed.also]
                    kw, hidden = fixed.kw, hidden | fixed.hidden
                    if len(errors) >= MAX_ERRORS:
                        break
                    continue
                if not follows:
                    errors.append(self.translate(exc))
                fewer = _without(kw, el) if len(errors) < MAX_ERRORS else None
                if fewer is None:
                    break
                kw, gone = fewer
                taken.append(gone)
                continue
            if not errors:
                return model
            break
        else:  # the builds ran out: there may be more
            errors.sort(key=_line)
            raise ModelErrors(_once_per_name(errors), stopped=True)
        errors.sort(key=_line)  # in the file's order
        raise collected_at_most(_once_per_name(errors))


#: the most times ``build`` builds a Model to find the problems of one file
_MAX_BUILDS = 4 * MAX_ERRORS


_UNKNOWN = re.compile(r"unknown (name|variable|state|goal|FSM|primitive) '([^']*)'|'([^']*)' is not a goal of (\S+)")


def _once_per_name(errors: list) -> list:
    """``errors`` with each unknown name reported once (a name used but never declared, or
    misspelt in its declaration, is one problem however often it is used): its first
    report says where else it is used."""
    first: dict = {}
    also: dict = {}
    for e in errors:
        m = _UNKNOWN.search(str(e.problem))
        if m is None:
            continue
        kind = {"name": "variable"}.get(m.group(1) or "", m.group(1) or "goal")
        key = (e.file, kind, m.group(2) if m.group(1) else m.group(3))
        if key in first:
            also[id(first[key])].append(e)
        else:
            first[key] = e
            also[id(e)] = []
    out = []
    for e in errors:
        if id(e) not in also:
            if _UNKNOWN.search(str(e.problem)) is None:
                out.append(e)
            continue
        more = also[id(e)]
        if more:
            lines = ", ".join(str(_line(x)) for x in more if _line(x))
            e = ModelError(e.element, f"{e.problem}; also used at {len(more)} more place(s)"
                                      + (f" (line {lines})" if lines else ""), e.file)
        out.append(e)
    return out


def _line(e: ModelError) -> int:
    """The line a problem's text ends with (0 when none)."""
    m = re.search(r"\(line (\d+)[,)]", str(e.problem))
    return int(m.group(1)) if m else 0


def _merged(first: list, then: list) -> list:
    """Two lists of problems, each in the file's order, merged by line."""
    return list(heapq.merge(first, then, key=_line))


def collected_at_most(errors: list) -> ModelError:
    """One error for the problems found: the problem itself, or a ``ModelErrors`` (which
    says when the reading stopped at ``MAX_ERRORS``)."""
    if len(errors) >= MAX_ERRORS:
        return ModelErrors(errors[:MAX_ERRORS], stopped=True)
    return cast(ModelError, collected(errors))


# ------------------------------------------------------ taking a problem's element out
def _rest(element: str, head: str) -> "str | None":
    """What follows ``head`` in ``element`` ('' for ``head`` itself), None when it is not there."""
    if element == head:
        return ""
    if element.startswith(head + "."):
        return element[len(head) + 1:]
    return None


def _find(items, element: str, head: str, key) -> "tuple | None":
    """(item, what follows it) for the item of ``items`` whose path ``head.KEY`` starts
    ``element`` (the longest such key: names may hold dots)."""
    best = None
    for x in items:
        rest = _rest(element, f"{head}.{key(x)}")
        if rest is not None and (best is None or len(key(x)) > len(key(best[0]))):
            best = (x, rest)
    return best


def _without_effect(outcomes, rest: str):
    """``outcomes`` without the effect that ``rest`` (``OUTCOME.VARIABLE``) names, or None."""
    for oc in outcomes or ():
        var = _rest(rest, oc.name)
        if var and var in {v for v, _ in oc.effects}:
            new = dataclasses.replace(oc, effects=tuple((v, e) for v, e in oc.effects if v != var))
            return tuple(new if o is oc else o for o in outcomes)
    return None


def _neutral_node(node, rest: str) -> tuple:
    """``(node, part)``: ``node`` with what a problem names (``rest``: the node, or one of
    its fields) made neutral, and the part of it changed ('' for the whole node); a leaf
    becomes an Action that succeeds at once. ``(None, '')`` when it cannot be."""
    if isinstance(node, Leaf):
        return pass_action(node), ""
    field, _, sub = rest.partition(".")
    fields = {f.name: f for f in dataclasses.fields(node)}
    if field in fields and fields[field].default is None and not sub:
        return dataclasses.replace(node, **{field: None}), rest
    return None, ""


def _with_node(root, name: str, new):
    """``root`` with its node named ``name`` replaced by ``new``."""
    if root.name == name:
        return new
    changes: dict = {}
    if isinstance(root, Composite):
        kids = tuple(_with_node(c, name, new) for c in root.children)
        if any(a is not b for a, b in zip(kids, root.children)):
            changes["children"] = kids
    elif isinstance(root, Decorator):
        kid = _with_node(root.child, name, new)
        if kid is not root.child:
            changes["child"] = kid
    return dataclasses.replace(root, **changes) if changes else root


def _without_event_part(ev, rest):
    """``ev`` without the guard or the effect that ``rest`` names, or None."""
    if rest == "guard":
        return dataclasses.replace(ev, guard=None)
    var = rest[len("effects."):] if rest.startswith("effects.") else None
    if var is not None and var in {v for v, _ in ev.effects}:
        return dataclasses.replace(ev, effects=tuple((v, e) for v, e in ev.effects if v != var))
    return None


def _without(kw: dict, element: str) -> "tuple[dict, str] | None":
    """``(kw, taken)``: the Model's arguments ``kw`` with the element a problem names
    (``element``, a Model's element path) taken out, or made neutral where it cannot be
    left out (an unknown name in a condition: true; a request of an unknown FSM or goal:
    an Action that succeeds), and the path of what was taken; None when the problem's
    element is not one that can go without others depending on it (a variable, a state,
    a primitive, an event's name...)."""
    fsms = kw.get("fsms") or ()
    found = _find(fsms, element, "fsms", lambda f: f.name)
    if found is not None:
        f, rest = found
        head = f"fsms.{f.name}"
        new, taken = None, None
        if rest == "initial" and f.states:
            new, taken = dataclasses.replace(f, initial=f.states[0].id), f"{head}.initial"
        elif rest == "terminal":
            new, taken = dataclasses.replace(f, terminal=()), f"{head}.terminal"
        for kind in ("edges", "markers"):
            hit = _find(getattr(f, kind), rest, kind, lambda e: e.id) if rest.startswith(kind + ".") else None
            if hit is not None:
                new = dataclasses.replace(f, **{kind: tuple(e for e in getattr(f, kind) if e is not hit[0])})
                taken = f"{head}.{kind}.{hit[0].id}"
        hit = _find(f.states, rest, "states", lambda st: st.id) if rest.startswith("states.") else None
        if hit is not None:
            st, sub = hit
            field, _, more = sub.partition(".")
            state = None
            if sub == "primitive" and st.outcomes is None:
                state = dataclasses.replace(st, primitive="")
            elif field == "outcomes":
                outs = _without_effect(st.outcomes, more)
                state = None if outs is None else dataclasses.replace(st, outcomes=outs)
            if state is not None:
                new = dataclasses.replace(f, states=tuple(state if x is st else x for x in f.states))
                taken = f"{head}.states.{st.id}.{sub}"
        if new is None:
            return None
        return dict(kw, fsms=tuple(new if g is f else g for g in fsms)), cast(str, taken)
    roots = [r for r in [kw.get("tree")] + [st.subtree for f in fsms for st in f.states] if r is not None]
    found = _find([n for r in roots for n in walk(r)], element, "tree", lambda n: n.name)
    if found is not None:
        node, rest = found
        new_node, part = _neutral_node(node, rest)
        if new_node is None:
            return None
        tree = kw.get("tree")
        out = dict(kw, tree=None if tree is None else _with_node(tree, node.name, new_node))
        if fsms:
            out["fsms"] = tuple(dataclasses.replace(f, states=tuple(
                st if st.subtree is None else dataclasses.replace(st, subtree=_with_node(st.subtree, node.name, new_node))
                for st in f.states)) for f in fsms)
        return out, f"tree.{node.name}" + (f".{part}" if part else "")
    env = kw.get("environment") or ()
    found = _find(env, element, "environment", lambda e: e.name)
    if found is not None and isinstance(found[0], EnvChoice):  # an option of a choice: environment.CHOICE.options.NAME
        choice, rest = found
        option = _find(choice.options, rest, "options", lambda o: o.name)
        new_opt = None if option is None else _without_event_part(*option)
        if option is None or new_opt is None:
            return None
        opt = option[0]
        new_choice = dataclasses.replace(choice, options=tuple(new_opt if o is opt else o for o in choice.options))
        return dict(kw, environment=tuple(new_choice if e is choice else e for e in env)), element
    if found is not None:
        event = _without_event_part(*found)
        if event is None:
            return None
        return dict(kw, environment=tuple(event if e is found[0] else e for e in env)), element
    found = _find(kw.get("primitives") or (), element, "primitives", lambda p: p.name)
    if found is not None:
        prim, rest = found
        outs = _without_effect(prim.outcomes, rest[len("outcomes."):]) if rest.startswith("outcomes.") else None
        if outs is None:
            return None
        new_prim = dataclasses.replace(prim, outcomes=outs)
        return dict(kw, primitives=tuple(new_prim if p is prim else p for p in kw["primitives"])), element
    for key in ("workable", "terminal"):
        if element == key:
            return dict(kw, **{key: None}), key
    for key in ("invariants", "responses"):
        items = kw.get(key) or ()
        found = _find(items, element, key, (lambda x: x[0]) if key == "invariants" else (lambda x: x.name))
        if found is not None:
            return dict(kw, **{key: tuple(x for x in items if x is not found[0])}), element
    return None


def model_from_data(data, file: "str | None" = None, *, earlier=()) -> Model:
    """Build a Model from loaded data (templates are expanded first).

    ``earlier``: problems found when the data was read (keys given twice, whose later
    values are left out: ``loads_data(duplicates=...)``), reported with those of the
    templates or of the shape; the model's checks wait until there are none (what a
    later value declared would be reported unknown)."""
    earlier = list(earlier)
    try:
        data = expand_templates(data, file)
    except ModelError as exc:
        if not earlier:
            raise
        raise collected_at_most(_merged(earlier, exc.errors if isinstance(exc, ModelErrors) else [exc])) from None
    return _Reader(file, earlier).model(data)


def loads_model(text, fmt: str = "yaml", file_name: str = "<string>") -> Model:
    """A Model from YAML or JSON text."""
    duplicates: list = []
    data = loads_data(text, fmt, file_name, duplicates=duplicates)
    return model_from_data(data, file_name, earlier=duplicates)
