"""Templates: ``use`` entries expanded by text substitution of declared ``${PARAM}``
placeholders (docs/model-files.md, "Templates"); nothing is evaluated."""
from __future__ import annotations

import copy
import difflib
import json
import re
from typing import cast

from ..errors import ModelError, ModelErrors, collected
from .text import (MAX_DEPTH, MAX_ERRORS, MAX_EXPANDED, MAX_NODES, MAX_TEMPLATE_DEPTH, MAX_TEXT, FileList, FileMap,
                   check_size, err, join_path, kind_of, where_of)


_PLACEHOLDER = re.compile(r"\$\{([A-Za-z_][A-Za-z0-9_]*)\}")
LIST_SECTIONS = ("goals", "states", "edges", "markers", "terminal", "children", "environment", "options")
VALUE_SECTIONS = ("fsm", "node")
_USE_KEYS = ("use", "with", "for_each")


def _is_use(x) -> bool:
    return isinstance(x, dict) and "use" in x


class _FollowOn(Exception):
    """A use of a template whose definition has a problem (already noted)."""


_FAILED = object()  # what ``note`` returns for a definition or use with a problem


class _Expander:
    """Expands ``use`` entries (see docs/model-files.md, "Templates").

    Problems are collected definition by definition and use by use (``note``): a
    definition with a problem is left out, and its uses are not reported; a use with a
    problem is left out. A limit reached (``budget``) stops at once."""

    def __init__(self, file):
        self.file, self.templates, self.produced, self.copied, self.chars = file, {}, 0, 0, 0
        self.errors: list = []  # the problems noted, in the order found
        self.bad: set = set()  # names of the templates whose definitions have a problem
        self.defined: list = []  # every template's name, as defined (with a problem or not)
        self.over = False  # a limit was reached, or MAX_ERRORS problems noted: stop

    def fail(self, path, problem, obj=None, key=None):
        return err(path, problem + where_of(obj, key), self.file)

    def budget(self, path, problem, obj=None):
        """The problem of a limit reached: it ends the expansion."""
        self.over = True
        return self.fail(path, problem, obj)

    def note(self, build, *args):
        """``build(*args)``, or ``_FAILED`` when it raises a ModelError (noted) or meets a
        use of a template with a problem; a limit reached is raised on."""
        try:
            return build(*args)
        except _FollowOn:
            return _FAILED
        except ModelError as exc:
            if self.over:
                raise
            self.errors.extend(exc.errors if isinstance(exc, ModelErrors) else [exc])
            if len(self.errors) >= MAX_ERRORS:
                self.over = True
                raise ModelErrors(self.errors[:MAX_ERRORS], stopped=True) from None
            return _FAILED

    # ---------------------------------------------------------------- definitions
    def define(self, templates):
        if templates is None:
            return
        if not isinstance(templates, dict):
            raise self.fail("templates", f"expected a mapping of template names to definitions, got {kind_of(templates)}", templates)
        for name, spec in templates.items():
            self.defined.append(name)
            if self.note(self.define_one, templates, name, spec) is _FAILED:
                self.bad.add(name)

    def define_one(self, templates, name, spec):
        """Check and keep one template's definition."""
        path = join_path("templates", name)
        if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
            raise self.fail("templates", f"template name {name!r} is not an identifier", templates, name)
        check_fields(self, spec, path, ("params", "description") + LIST_SECTIONS + VALUE_SECTIONS, (), "a template")
        params = spec.get("params", [])
        if not isinstance(params, list) or not all(isinstance(p, str) and re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", p) for p in params):
            raise self.fail(f"{path}.params", "expected a list of parameter names (identifiers)", spec, "params")
        if len(set(params)) != len(params):
            raise self.fail(f"{path}.params", "a parameter is listed twice", spec, "params")
        if "description" in spec and not isinstance(spec["description"], str):
            raise self.fail(f"{path}.description", "expected a string", spec, "description")
        sections = {k: v for k, v in spec.items() if k in LIST_SECTIONS + VALUE_SECTIONS}
        if not sections:
            raise self.fail(path, f"defines no section (one or more of: {', '.join(LIST_SECTIONS + VALUE_SECTIONS)})", spec)
        for sec, body in sections.items():
            if sec in LIST_SECTIONS and not isinstance(body, list):
                raise self.fail(f"{path}.{sec}", f"expected a list, got {kind_of(body)}", spec, sec)
            if sec in VALUE_SECTIONS and not isinstance(body, dict):
                raise self.fail(f"{path}.{sec}", f"expected a mapping, got {kind_of(body)}", spec, sec)
            self._check_placeholders(body, f"{path}.{sec}", set(params), spec, sec)
        self.templates[name] = (tuple(params), sections)

    def _check_placeholders(self, obj, path, params, parent, key):
        if isinstance(obj, str):
            for name in _PLACEHOLDER.findall(obj):
                if name not in params:
                    raise self.fail(path, f"placeholder '${{{name}}}' is not a parameter of this template", parent, key)
            if "${" in _PLACEHOLDER.sub("", obj):
                raise self.fail(path, f"malformed placeholder in {obj!r} (write ${{NAME}})", parent, key)
        elif isinstance(obj, dict):
            for k, v in obj.items():
                self._check_placeholders(k, join_path(path, k), params, obj, k)
                self._check_placeholders(v, join_path(path, k), params, obj, k)
        elif isinstance(obj, list):
            for i, v in enumerate(obj):
                self._check_placeholders(v, f"{path}[{i}]", params, obj, i)

    # ---------------------------------------------------------------- walking the model
    def model(self, data):
        fsms = data.get("fsms")
        if isinstance(fsms, dict):
            for name in list(fsms):
                path = join_path("fsms", name)
                fsms[name] = self.value(fsms[name], "fsm", path, fsms, name)
                self.fsm(fsms[name], path)
        if "tree" in data:
            data["tree"] = self.value(data["tree"], "node", "tree", data, "tree")
            self.node(data["tree"], "tree")
        self.list(data, "environment", "environment", "environment")
        events = data.get("environment")
        for i, ev in enumerate(events if isinstance(events, list) else ()):
            if isinstance(ev, dict):
                self.list(ev, "options", "options", f"environment[{i}].options")

    def fsm(self, spec, path):
        if not isinstance(spec, dict):
            return
        for sec in ("goals", "states", "edges", "markers", "terminal"):
            self.list(spec, sec, sec, f"{path}.{sec}")
        states = spec.get("states")
        if isinstance(states, list):
            for i, st in enumerate(states):
                if isinstance(st, dict) and "subtree" in st:
                    p = f"{path}.states[{i}].subtree"
                    st["subtree"] = self.value(st["subtree"], "node", p, st, "subtree")
                    self.node(st["subtree"], p)

    def node(self, n, path, depth=0):
        if not isinstance(n, dict) or depth > MAX_DEPTH:
            return
        if "child" in n:
            n["child"] = self.value(n["child"], "node", f"{path}.child", n, "child")
            self.node(n["child"], f"{path}.child", depth + 1)
        if "children" in n:
            self.list(n, "children", "children", f"{path}.children")
            if isinstance(n["children"], list):
                for i, c in enumerate(n["children"]):
                    self.node(c, f"{path}.children[{i}]", depth + 1)

    # ---------------------------------------------------------------- expansion
    def list(self, parent, key, section, path):
        items = parent.get(key)
        if not isinstance(items, list) or not any(_is_use(x) for x in items):
            return
        out = FileList()
        out.line, out.origin, out.chain = getattr(items, "line", None), getattr(items, "origin", None), getattr(items, "chain", ())
        out.lines = {}
        src_lines = getattr(items, "lines", None) or {}
        for i, item in enumerate(items):
            if _is_use(item):
                made = self.note(self.use, item, section, f"{path}[{i}]", True)
                for x, line in () if made is _FAILED else made:
                    out.lines[len(out)] = line
                    out.append(x)
            else:
                if i in src_lines:
                    out.lines[len(out)] = src_lines[i]
                out.append(item)
        parent[key] = out

    def value(self, v, section, path, parent, key):
        made = self.note(self.one_value, v, section, path)
        return v if made is _FAILED else made

    def one_value(self, v, section, path):
        depth = 0
        while _is_use(v):
            depth += 1
            if depth > MAX_TEMPLATE_DEPTH:
                raise self.fail(path, "templates nested too deeply", v)
            (v, _), = self.use(v, section, path, in_list=False)
        return v

    def use(self, entry, section, path, in_list):
        """Instantiate one ``use`` entry: a list of ``(item, line)`` (one item when not in a list)."""
        check_fields(self, entry, path, _USE_KEYS, ("use",), "a template use")
        name = entry["use"]
        if not isinstance(name, (list, dict)) and name in self.bad:  # (a list or mapping cannot be a name)
            raise _FollowOn()
        if not isinstance(name, str) or name not in self.templates:
            known = ", ".join(str(t) for t in self.defined) or "none defined"
            raise self.fail(f"{path}.use", f"unknown template {name!r} (templates: {known})", entry, "use")
        chain = tuple(getattr(entry, "chain", ()))
        if name in chain:
            raise self.fail(f"{path}.use", f"template '{name}' uses itself ({' -> '.join(chain + (name,))})", entry, "use")
        if len(chain) >= MAX_TEMPLATE_DEPTH:
            raise self.fail(f"{path}.use", f"templates nested more than {MAX_TEMPLATE_DEPTH} deep", entry, "use")
        params, sections = self.templates[name]
        if section not in sections:
            raise self.fail(f"{path}.use", f"template '{name}' has no '{section}' section (it has: {', '.join(sections)})", entry, "use")
        if "for_each" in entry and not in_list:
            raise self.fail(f"{path}.for_each", "for_each can only be used inside a list", entry, "for_each")
        body = sections[section]
        out = []
        use_line = getattr(entry, "line", None)
        for binding in self._bindings(entry, path, name, params):
            shown = ", ".join(f"{k}={_short(v)}" for k, v in binding.items())
            origin = f"in template '{name}'" + (f" used at line {use_line}" if use_line else f" used at {path}") + (f" with {shown}" if shown else "")
            inst = self._subst(body, binding, origin, chain + (name,), path)
            self.produced += len(inst) if isinstance(inst, list) else 1
            if self.produced > MAX_EXPANDED:
                raise self.budget(path, f"templates produce more than {MAX_EXPANDED} items", entry)
            if isinstance(inst, list):  # nested uses in the fragment itself
                holder = {"x": inst}
                self.list(holder, "x", section, path)
                inst = holder["x"]
                lines = getattr(inst, "lines", {}) or {}
                out.extend((x, lines.get(k, use_line)) for k, x in enumerate(inst))
            else:
                out.append((inst, getattr(inst, "line", use_line)))
        return out

    def _bindings(self, entry, path, name, params):
        shared = entry.get("with", {})
        if shared is None:
            shared = {}
        if not isinstance(shared, dict):
            raise self.fail(f"{path}.with", f"expected a mapping of parameter values, got {kind_of(shared)}", entry, "with")
        rows = entry.get("for_each")
        if rows is None:
            rows = [{}]
        elif not isinstance(rows, list):
            raise self.fail(f"{path}.for_each", f"expected a list of parameter mappings, got {kind_of(rows)}", entry, "for_each")
        out = []
        for i, row in enumerate(rows):
            where = f"{path}.for_each[{i}]" if "for_each" in entry else f"{path}.with"
            if not isinstance(row, dict):
                raise self.fail(where, f"expected a mapping of parameter values, got {kind_of(row)}", rows, i)
            both = set(row) & set(shared)
            if both:
                raise self.fail(where, f"parameter(s) {', '.join(map(str, sorted(both, key=str)))} given in both with and for_each", entry)
            binding = {**shared, **row}
            missing = [p for p in params if p not in binding]
            extra = [str(k) for k in binding if k not in params]
            takes = f"template '{name}' takes {', '.join(params) or 'no parameters'}"
            if missing:
                raise self.fail(where, f"missing parameter(s) {', '.join(missing)}: {takes}", entry)
            if extra:
                raise self.fail(where, f"unknown parameter(s) {', '.join(extra)}: {takes}", entry)
            out.append(binding)
        return out

    def _count(self, path):
        """Count one value produced by a template; refuse past ``MAX_NODES`` (structure bombs)."""
        self.copied += 1
        if self.copied > MAX_NODES:
            raise self.budget(path, f"templates produce more than {MAX_NODES} values")

    def _subst(self, obj, binding, origin, chain, path):
        self._count(path)
        if isinstance(obj, str):
            return self._text(obj, binding, path)
        if isinstance(obj, dict):
            out = FileMap()
            out.line, out.lines, out.origin, out.chain = getattr(obj, "line", None), {}, origin, chain
            lines = getattr(obj, "lines", None) or {}
            for k, v in obj.items():
                nk = self._text(k, binding, path) if isinstance(k, str) else k
                if not isinstance(nk, (str, int, float, bool, type(None))):
                    raise self.fail(path, f"a key placeholder must be replaced by a plain value, got {kind_of(nk)}", obj, k)
                if nk in out:
                    raise self.fail(path, f"duplicate key '{nk}' after substitution", obj, k)
                if k in lines:
                    out.lines[nk] = lines[k]
                out[nk] = self._subst(v, binding, origin, chain, path)
            return out
        if isinstance(obj, list):
            out = FileList()
            out.line, out.lines, out.origin, out.chain = getattr(obj, "line", None), dict(getattr(obj, "lines", None) or {}), origin, chain
            out.extend(self._subst(v, binding, origin, chain, path) for v in obj)
            return out
        return obj

    def _text(self, s, binding, path):
        whole = _PLACEHOLDER.fullmatch(s)
        if whole:  # a lone placeholder takes the value itself (a list, a number...)
            return self._copy(binding[whole.group(1)], path)

        size = len(s)  # the text's length once replaced, known before it is built (string bombs)
        for m in _PLACEHOLDER.finditer(s):
            val = binding[m.group(1)]
            size += (len(val) if isinstance(val, str) else len(str(val)) + 1) - len(m.group(0))
        self.chars += size
        if size > MAX_TEXT or self.chars > MAX_TEXT:
            raise self.budget(path, f"templates produce more than {MAX_TEXT} characters of text")

        def rep(m):
            val = binding[m.group(1)]
            if isinstance(val, bool):
                return "true" if val else "false"
            if isinstance(val, (str, int, float)):
                return str(val)
            raise self.fail(path, f"parameter {m.group(1)} is {kind_of(val)}; only a lone '${{{m.group(1)}}}' can stand for it")
        return _PLACEHOLDER.sub(rep, s)

    def _copy(self, x, path, depth=0):
        """A fresh copy of a parameter value (counted like every produced value)."""
        self._count(path)
        if depth > MAX_DEPTH:
            raise self.fail(path, f"a parameter value is nested more than {MAX_DEPTH} levels deep")
        if isinstance(x, dict):
            out = FileMap((k, self._copy(v, path, depth + 1)) for k, v in x.items())
            out.line, out.lines = getattr(x, "line", None), dict(getattr(x, "lines", None) or {})
            return out
        if isinstance(x, list):
            out = FileList(self._copy(v, path, depth + 1) for v in x)
            out.line, out.lines = getattr(x, "line", None), dict(getattr(x, "lines", None) or {})
            return out
        return x


def _short(x) -> str:
    text = x if isinstance(x, str) else json.dumps(x, default=str)
    return text if len(text) <= 30 else text[:27] + "..."


def check_fields(ctx, obj, path, allowed, required=(), what="a mapping"):
    """Raise ``ctx.fail`` unless ``obj`` is a mapping with only ``allowed`` string keys
    and every ``required`` one."""
    if not isinstance(obj, dict):
        raise ctx.fail(path, f"expected {what}, got {kind_of(obj)}", obj)
    unknown = []  # every unknown field of the mapping at once
    for k in obj:
        if not isinstance(k, str):
            unknown.append(ctx.fail(path, f"field names are strings, got {kind_of(k)} {k!r}", obj, k))
        elif k not in allowed:
            close = difflib.get_close_matches(k, allowed, 1)
            hint = f" (did you mean '{close[0]}'?)" if close else f" (expected: {', '.join(allowed)})"
            unknown.append(ctx.fail(join_path(path, k), f"unknown field '{k}'{hint}", obj, k))
    if unknown:  # a missing field may be one of them, misspelt: not reported
        raise cast(ModelError, collected(unknown))
    for r in required:
        if r not in obj:
            raise ctx.fail(path, f"missing field '{r}'", obj)


def _find_placeholder(obj, path):
    """(path, text) of the first string still holding a placeholder ``${NAME}``, or None.
    Descriptions are free text and are not searched."""
    stack = [(obj, path)]
    while stack:
        x, p = stack.pop()
        if isinstance(x, str) and _PLACEHOLDER.search(x):
            return p, x
        if isinstance(x, dict):
            for k, v in reversed(list(x.items())):
                if isinstance(k, str) and _PLACEHOLDER.search(k):
                    return join_path(p, k), k
                if k != "description":
                    stack.append((v, join_path(p, k)))
        elif isinstance(x, list):
            stack.extend((v, f"{p}[{i}]") for i, v in reversed(list(enumerate(x))))
    return None


def expand_templates(data, file: "str | None" = None):
    """The data with every template ``use`` expanded and the ``templates`` section removed.

    Pure data in, data out: placeholders ``${P}`` of declared parameters are replaced by
    text; nothing is evaluated. The input is not modified.

    >>> d = {"templates": {"t": {"params": ["X"], "states": ["at_${X}"]}},
    ...      "fsms": {"f": {"states": [{"use": "t", "for_each": [{"X": "a"}, {"X": "b"}]}]}}}
    >>> expand_templates(d)["fsms"]["f"]["states"]
    ['at_a', 'at_b']
    """
    if not isinstance(data, dict):
        raise err("", f"expected a mapping with the model, got {kind_of(data)}", file)
    check_size(data, file)  # data built in Python may share sub-values (an alias bomb)
    data = copy.deepcopy(data)
    ex = _Expander(file)
    ex.define(data.pop("templates", None))
    ex.model(data)
    if ex.errors:
        raise cast(ModelError, collected(ex.errors))
    left = _find_placeholder(data, "")
    if left is not None:
        raise err(left[0], f"unresolved placeholder in {left[1]!r} (placeholders are replaced only inside templates)", file)
    return data
