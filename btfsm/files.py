"""Model files: YAML and JSON in and out, templates, and ``btfsm validate``.

One data model for both formats (docs/model-files.md is the reference; the JSON Schema is
``btfsm/schema/model.schema.json``). Loading never executes code: YAML is composed with a
safe loader (YAML 1.2 core scalars: ``yes``, ``no``, ``on``, ``off`` stay strings) and turned into
plain dicts, lists and scalars by this module; templates are text substitution of
declared ``${PARAM}`` placeholders; expressions are parsed by ``btfsm.expr.parse``. Every
problem raises one ``ModelError`` naming the file, the element path in the file (such as
``fsms.arm.edges[3].guard``) and, for YAML, the line.

>>> m = loads_model('''
... name: counter
... variables: {n: {int: [0, 3]}}
... tree:
...   ReactiveFallback: root
...   children:
...     - {Condition: full, expr: n == 3}
...     - {Action: add, outcomes: [{success: {n: n + 1}}]}
... ''')
>>> m.program.initial
(0,)
>>> loads_model(dumps_model(m)) == m
True
"""
from __future__ import annotations

import copy
import dataclasses
import difflib
import importlib
import json
import math
import os
import re
import stat
from pathlib import Path
from typing import Any, cast

import yaml

from .bt import (NODE_TYPES, Action, Composite, Condition, Decorator, Effects, Guard, Parallel, ParallelAll, Repeat, Retry,
                 RunOnce, SkillRequest, SubTree, walk, RecoveryNode, RoundRobin)
from .errors import ModelError
from .expr import Const, Expr, as_expr, to_text
from .fsm import FSM, Edge, Marker, State
from .model import EnvChoice, EnvEvent, Model
from .primitives import Outcome, Primitive
from .profiles import DEFAULT_SEMANTICS, DEFAULT_TICK, PROFILES, TICKS
from .status import Status
from .timing import Response, duration_of
from .world import Bool, Enum, Int, Var

__all__ = [
    "FORMATS", "load_model", "load_cli_model", "python_model_ref", "load_python_model", "loads_model", "load_data", "loads_data", "expand_templates",
    "model_from_data", "model_to_data", "dump_model", "dumps_model", "builtin_models",
    "format_of", "cli_validate", "read_model_bytes", "MAX_FILE_BYTES", "MAX_NODES", "load_xml_model",
]

FORMATS = {".yaml": "yaml", ".yml": "yaml", ".json": "json"}
MAX_FILE_BYTES = 8 * 1024 * 1024  # size of a model file
MAX_NODES = 200_000  # YAML/JSON values in one document, aliases expanded
MAX_DEPTH = 100  # nesting of YAML/JSON values
MAX_TEMPLATE_DEPTH = 16
MAX_INT = 2 ** 63  # integers in a model file lie within -MAX_INT..MAX_INT
MAX_EXPANDED = 100_000  # items produced by templates
MAX_TEXT = MAX_FILE_BYTES  # characters of text produced by template placeholders


_CONTROL = {c: f"\\x{c:02x}" for c in list(range(32)) + [127, 0x85]}
_CONTROL.update({10: "\\n", 13: "\\r", 9: "\\t", 0x2028: "\\u2028", 0x2029: "\\u2029"})
_CONTROL.update({c: f"\\u{c:04x}" for c in range(0xD800, 0xE000)})  # lone surrogates (from JSON)


def _printable(text: str) -> str:
    """``text`` on one printable line."""
    return text.translate(_CONTROL)


_LONG_QUOTE = re.compile(r"'([^'\n]{100,})'")
MAX_MESSAGE = 1000  # characters of an error's problem text


def _clip(text: str) -> str:
    """A message with long quoted values (a 20,000-character name) shortened."""
    text = _LONG_QUOTE.sub(lambda m: f"'{m.group(1)[:60]}...' ({len(m.group(1))} characters)", text)
    return text if len(text) <= MAX_MESSAGE else text[:MAX_MESSAGE - 3] + "..."


def _err(element, problem: str, file=None) -> ModelError:
    """A ModelError whose text is one line (control characters in names are escaped) and
    of reasonable length (long quoted values are shortened)."""
    clean = (lambda t: _clip(_printable(t)) if isinstance(t, str) else t)
    return ModelError(clean(element), clean(problem), clean(file))


# ============================================================================ reading text

_STR, _INT, _FLOAT = "tag:yaml.org,2002:str", "tag:yaml.org,2002:int", "tag:yaml.org,2002:float"
_BOOL, _NULL = "tag:yaml.org,2002:bool", "tag:yaml.org,2002:null"
_MAP, _SEQ = "tag:yaml.org,2002:map", "tag:yaml.org,2002:seq"


class _Loader(yaml.SafeLoader):
    """PyYAML's safe loader with YAML 1.2 core-schema scalars: only true/false are
    booleans (``on``, ``yes`` and ``no`` stay strings), ints are decimal, 0x or 0o, and
    there are no timestamps, sexagesimals or merge keys. Only its composer is used."""


_Loader.yaml_implicit_resolvers = {}
_RESOLVERS = (
    (_BOOL, re.compile(r"^(?:true|True|TRUE|false|False|FALSE)$"), list("tTfF")),
    (_INT, re.compile(r"^(?:[-+]?[0-9]+|0x[0-9a-fA-F]+|0o[0-7]+)$"), list("-+0123456789")),
    (_FLOAT, re.compile(r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?"
                        r"|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"), list("-+0123456789.")),
    (_NULL, re.compile(r"^(?:~|null|Null|NULL|)$"), ["~", "n", "N", ""]),
)
for _tag, _re, _first in _RESOLVERS:
    _Loader.add_implicit_resolver(_tag, _re, _first)


class _Dumper(yaml.SafeDumper):
    """Safe dumper that quotes every string that YAML 1.1 readers *or* our loader would
    read as something else, so dumps load back identically everywhere."""


for _tag, _re, _first in _RESOLVERS:
    _Dumper.add_implicit_resolver(_tag, _re, _first)


def _represent_str(dumper, text):
    # PyYAML writes NEL and the Unicode line/paragraph separators raw in plain and single-
    # quoted scalars, where YAML reads them as line breaks; double quotes escape them
    style = '"' if any(c in text for c in "\x85\u2028\u2029") else None
    return dumper.represent_scalar(_STR, text, style=style)


_Dumper.add_representer(str, _represent_str)


class _Map(dict):
    """A mapping read from a file. ``line``: where it starts; ``lines``: key -> line;
    ``origin``: the template instantiation it came from; ``chain``: templates it is in."""

    line = None
    lines: dict = {}
    origin = None
    chain: tuple = ()


class _Seq(list):
    """A list read from a file; same position attributes as ``_Map`` (``lines``: index -> line)."""

    line = None
    lines: dict = {}
    origin = None
    chain: tuple = ()


def format_of(path, fmt: "str | None" = None) -> str:
    """The format of ``path`` ("yaml" or "json") from its extension, or ``fmt`` if given."""
    if fmt is not None:
        if fmt not in ("yaml", "json"):
            raise _err("", f"unknown format '{fmt}' (expected yaml or json)")
        return fmt
    ext = Path(str(path)).suffix.lower()
    if ext not in FORMATS:
        raise _err("", f"unknown model file extension '{ext}' (expected .yaml, .yml or .json)", str(path))
    return FORMATS[ext]


def loads_data(text, fmt: str = "yaml", file_name: str = "<string>"):
    """Parse model-file text into plain data (dicts, lists, scalars); no templates expanded.

    >>> loads_data("edges: [{from: a, to: b, when: failure, on: off}]")
    {'edges': [{'from': 'a', 'to': 'b', 'when': 'failure', 'on': 'off'}]}
    """
    fmt = format_of(file_name, fmt)
    if isinstance(text, bytes):
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise _err("", f"not UTF-8 text (byte {exc.start})", file_name) from None
    if not isinstance(text, str):
        raise _err("", f"expected text, got {type(text).__name__}", file_name)
    data = _parse_json(text, file_name) if fmt == "json" else _parse_yaml(text, file_name)
    if data is None:
        raise _err("", "the file is empty (expected a mapping with the model)", file_name)
    return data


def load_data(path, fmt: "str | None" = None, file_name: "str | None" = None):
    """Read a model file into plain data; ``fmt`` defaults to the extension's."""
    name = file_name or str(path)
    fmt = format_of(path, fmt)
    return loads_data(read_model_bytes(path, name), fmt, name)


def read_model_bytes(path, name: "str | None" = None, limit: int = MAX_FILE_BYTES, what: str = "model file") -> bytes:
    """The bytes of a model file (or another input, ``what``): only a regular file, at most
    ``limit`` bytes (default ``MAX_FILE_BYTES``).

    The file is opened without blocking and checked with ``fstat`` before anything is
    read, so a FIFO, a device or a folder is refused at once instead of hanging the loader.
    """
    name = name or str(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the path
        raise _err("", f"cannot read: {getattr(exc, 'strerror', None) or exc}", name) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            kind = "a folder" if stat.S_ISDIR(st.st_mode) else "a FIFO" if stat.S_ISFIFO(st.st_mode) else \
                "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode) else "a socket" if stat.S_ISSOCK(st.st_mode) else "not a file"
            raise _err("", f"is {kind}, not a regular {what}", name)
        if st.st_size > limit:
            raise _err("", f"is {st.st_size} bytes; {what}s are at most {limit} bytes", name)
        chunks, total = [], 0
        while True:
            chunk = os.read(fd, 1 << 20)
            if not chunk:
                break
            total += len(chunk)
            if total > limit:  # grew while being read
                raise _err("", f"is more than {limit} bytes; {what}s are at most {limit} bytes", name)
            chunks.append(chunk)
        return b"".join(chunks)
    except OSError as exc:
        raise _err("", f"cannot read: {exc.strerror or exc}", name) from None
    finally:
        os.close(fd)


def _parse_json(text: str, file: str):
    def pairs(items):
        out = {}
        for k, v in items:
            if k in out:
                raise _err("", f"duplicate key '{k}' in a JSON object", file)
            out[k] = v
        return out

    def constant(name):
        raise _err("", f"{name} is not allowed (numbers must be finite)", file)

    try:
        data = json.loads(text, object_pairs_hook=pairs, parse_constant=constant)
    except json.JSONDecodeError as exc:
        raise _err("", f"JSON syntax error at line {exc.lineno}, column {exc.colno}: {exc.msg}", file) from None
    except RecursionError:
        raise _err("", "JSON nested too deeply", file) from None
    except ModelError:  # from the hooks above (a ValueError too)
        raise
    except ValueError as exc:  # e.g. an integer with too many digits
        raise _err("", f"JSON: {_one_line(exc)}", file) from None
    _check_size(data, file)
    return data


def _check_size(data, file):
    """Refuse data with more than ``MAX_NODES`` values (shared values counted each time
    they appear), nested deeper than ``MAX_DEPTH`` or holding an integer beyond ``MAX_INT``."""
    count, stack = 0, [(data, 0, "")]
    while stack:
        x, depth, path = stack.pop()
        count += 1
        if depth > MAX_DEPTH:
            raise _err(path, f"values nested more than {MAX_DEPTH} levels deep", file)
        if count > MAX_NODES:
            raise _err(path, f"more than {MAX_NODES} values in one file", file)
        if isinstance(x, int) and not isinstance(x, bool) and not -MAX_INT <= x <= MAX_INT:
            raise _err(path, f"an integer of about {int(x.bit_length() * 0.30103) + 1} digits is too large "
                             "(integers lie within -2**63..2**63)", file)
        if isinstance(x, dict):
            stack.extend((v, depth + 1, _join(path, k)) for k, v in x.items())
        elif isinstance(x, list):
            stack.extend((v, depth + 1, f"{path}[{i}]") for i, v in enumerate(x))


def _parse_yaml(text: str, file: str):
    try:
        node = yaml.compose(text, Loader=_Loader)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        what = exc.problem or exc.context or "invalid YAML"
        raise _err("", f"YAML syntax error{where}: {_one_line(what)}", file) from None
    except yaml.YAMLError as exc:
        raise _err("", f"YAML error: {_one_line(exc)}", file) from None
    except RecursionError:
        raise _err("", "YAML nested too deeply", file) from None
    if node is None:
        return None
    return _Builder(file).build(node)


def _one_line(x) -> str:
    return " ".join(str(x).split())


class _Builder:
    """Turns composed YAML nodes into ``_Map`` / ``_Seq`` / scalars, with positions."""

    def __init__(self, file):
        self.file, self.count, self.active = file, 0, set()

    def fail(self, node, problem, path=""):
        return _err(path, f"{problem} (line {node.start_mark.line + 1})", self.file)

    def build(self, node, depth=0, path=""):
        self.count += 1
        if self.count > MAX_NODES:
            raise self.fail(node, f"more than {MAX_NODES} values (aliases expanded)", path)
        if depth > MAX_DEPTH:
            raise self.fail(node, f"values nested more than {MAX_DEPTH} levels deep", path)
        if isinstance(node, yaml.ScalarNode):
            return self.scalar(node, path)
        if id(node) in self.active:
            raise self.fail(node, "an alias refers to a value that contains it", path)
        self.active.add(id(node))
        try:
            if isinstance(node, yaml.SequenceNode):
                if node.tag != _SEQ:
                    raise self.fail(node, f"unsupported YAML tag {node.tag}", path)
                out = _Seq()
                out.line, out.lines = node.start_mark.line + 1, {}
                for i, item in enumerate(node.value):
                    out.lines[i] = item.start_mark.line + 1
                    out.append(self.build(item, depth + 1, f"{path}[{i}]"))
                return out
            if node.tag != _MAP:
                raise self.fail(node, f"unsupported YAML tag {node.tag}", path)
            out = _Map()
            out.line, out.lines = node.start_mark.line + 1, {}
            for knode, vnode in node.value:
                if not isinstance(knode, yaml.ScalarNode):
                    raise self.fail(knode, "a mapping key must be a plain value, not a list or mapping", path)
                key = self.scalar(knode, path)
                if key in out:
                    raise self.fail(knode, f"duplicate key '{key}'", path)
                out.lines[key] = knode.start_mark.line + 1
                out[key] = self.build(vnode, depth + 1, _join(path, key))
            return out
        finally:
            self.active.discard(id(node))

    def scalar(self, node, path=""):
        tag, text = node.tag, node.value
        if tag == _STR:
            return text
        if tag == _NULL:
            return None
        if tag == _BOOL:
            if text.lower() in ("true", "false"):
                return text.lower() == "true"
            raise self.fail(node, f"'{text}' is not true or false", path)
        if tag == _INT:
            try:
                t = text.lower()
                value = int(t, 16) if t.startswith("0x") else int(t, 8) if t.startswith("0o") else int(t, 10)
            except ValueError:
                raise self.fail(node, f"'{text[:40]}' is not an integer (or has too many digits)", path) from None
            if not -MAX_INT <= value <= MAX_INT:
                raise self.fail(node, f"'{text[:40]}...' is too large (integers lie within -2**63..2**63)", path)
            return value
        if tag == _FLOAT:
            t = text.lower()
            if t.lstrip("+-") == ".inf":
                return -math.inf if t.startswith("-") else math.inf
            if t == ".nan":
                return math.nan
            try:
                return float(text)
            except ValueError:
                raise self.fail(node, f"'{text[:40]}' is not a number", path) from None
        raise self.fail(node, f"unsupported YAML tag {tag}", path)


# ============================================================================ templates

_PLACEHOLDER = re.compile(r"\$\{([A-Za-z_][A-Za-z0-9_]*)\}")
LIST_SECTIONS = ("goals", "states", "edges", "markers", "terminal", "children", "environment", "options")
VALUE_SECTIONS = ("fsm", "node")
_USE_KEYS = ("use", "with", "for_each")


def _is_use(x) -> bool:
    return isinstance(x, dict) and "use" in x


def _kind(x) -> str:
    if x is None:
        return "null"
    if isinstance(x, bool):
        return "a boolean"
    if isinstance(x, int):
        return "an integer"
    if isinstance(x, float):
        return "a number"
    if isinstance(x, str):
        return "a string"
    if isinstance(x, dict):
        return "a mapping"
    if isinstance(x, list):
        return "a list"
    return type(x).__name__


def _where(obj, key=None) -> str:
    """`` (line N[, template ...])`` for an element read from YAML, else ``""``."""
    line = None
    lines = getattr(obj, "lines", None)
    if key is not None and lines:
        line = lines.get(key)
    if line is None:
        line = getattr(obj, "line", None)
    origin = getattr(obj, "origin", None)
    if line is None and origin is None:
        return ""
    parts = [f"line {line}"] if line is not None else []
    if origin:
        parts.append(origin)
    return " (" + ", ".join(parts) + ")"


def _join(path: str, key) -> str:
    return f"{path}.{key}" if path else str(key)


class _Expander:
    """Expands ``use`` entries (see docs/model-files.md, "Templates")."""

    def __init__(self, file):
        self.file, self.templates, self.produced, self.copied, self.chars = file, {}, 0, 0, 0

    def fail(self, path, problem, obj=None, key=None):
        return _err(path, problem + _where(obj, key), self.file)

    # ---------------------------------------------------------------- definitions
    def define(self, templates):
        if templates is None:
            return
        if not isinstance(templates, dict):
            raise self.fail("templates", f"expected a mapping of template names to definitions, got {_kind(templates)}", templates)
        for name, spec in templates.items():
            path = _join("templates", name)
            if not isinstance(name, str) or not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name):
                raise self.fail("templates", f"template name {name!r} is not an identifier", templates, name)
            _check_fields(self, spec, path, ("params", "description") + LIST_SECTIONS + VALUE_SECTIONS, (), "a template")
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
                    raise self.fail(f"{path}.{sec}", f"expected a list, got {_kind(body)}", spec, sec)
                if sec in VALUE_SECTIONS and not isinstance(body, dict):
                    raise self.fail(f"{path}.{sec}", f"expected a mapping, got {_kind(body)}", spec, sec)
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
                self._check_placeholders(k, _join(path, k), params, obj, k)
                self._check_placeholders(v, _join(path, k), params, obj, k)
        elif isinstance(obj, list):
            for i, v in enumerate(obj):
                self._check_placeholders(v, f"{path}[{i}]", params, obj, i)

    # ---------------------------------------------------------------- walking the model
    def model(self, data):
        fsms = data.get("fsms")
        if isinstance(fsms, dict):
            for name in list(fsms):
                path = _join("fsms", name)
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
        out = _Seq()
        out.line, out.origin, out.chain = getattr(items, "line", None), getattr(items, "origin", None), getattr(items, "chain", ())
        out.lines = {}
        src_lines = getattr(items, "lines", None) or {}
        for i, item in enumerate(items):
            if _is_use(item):
                for x, line in self.use(item, section, f"{path}[{i}]", in_list=True):
                    out.lines[len(out)] = line
                    out.append(x)
            else:
                if i in src_lines:
                    out.lines[len(out)] = src_lines[i]
                out.append(item)
        parent[key] = out

    def value(self, v, section, path, parent, key):
        depth = 0
        while _is_use(v):
            depth += 1
            if depth > MAX_TEMPLATE_DEPTH:
                raise self.fail(path, "templates nested too deeply", v)
            (v, _), = self.use(v, section, path, in_list=False)
        return v

    def use(self, entry, section, path, in_list):
        """Instantiate one ``use`` entry: a list of ``(item, line)`` (one item when not in a list)."""
        _check_fields(self, entry, path, _USE_KEYS, ("use",), "a template use")
        name = entry["use"]
        if not isinstance(name, str) or name not in self.templates:
            known = ", ".join(self.templates) or "none defined"
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
                raise self.fail(path, f"templates produce more than {MAX_EXPANDED} items", entry)
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
            raise self.fail(f"{path}.with", f"expected a mapping of parameter values, got {_kind(shared)}", entry, "with")
        rows = entry.get("for_each")
        if rows is None:
            rows = [{}]
        elif not isinstance(rows, list):
            raise self.fail(f"{path}.for_each", f"expected a list of parameter mappings, got {_kind(rows)}", entry, "for_each")
        out = []
        for i, row in enumerate(rows):
            where = f"{path}.for_each[{i}]" if "for_each" in entry else f"{path}.with"
            if not isinstance(row, dict):
                raise self.fail(where, f"expected a mapping of parameter values, got {_kind(row)}", rows, i)
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
            raise self.fail(path, f"templates produce more than {MAX_NODES} values")

    def _subst(self, obj, binding, origin, chain, path):
        self._count(path)
        if isinstance(obj, str):
            return self._text(obj, binding, path)
        if isinstance(obj, dict):
            out = _Map()
            out.line, out.lines, out.origin, out.chain = getattr(obj, "line", None), {}, origin, chain
            lines = getattr(obj, "lines", None) or {}
            for k, v in obj.items():
                nk = self._text(k, binding, path) if isinstance(k, str) else k
                if not isinstance(nk, (str, int, float, bool, type(None))):
                    raise self.fail(path, f"a key placeholder must be replaced by a plain value, got {_kind(nk)}", obj, k)
                if nk in out:
                    raise self.fail(path, f"duplicate key '{nk}' after substitution", obj, k)
                if k in lines:
                    out.lines[nk] = lines[k]
                out[nk] = self._subst(v, binding, origin, chain, path)
            return out
        if isinstance(obj, list):
            out = _Seq()
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
            raise self.fail(path, f"templates produce more than {MAX_TEXT} characters of text")

        def rep(m):
            val = binding[m.group(1)]
            if isinstance(val, bool):
                return "true" if val else "false"
            if isinstance(val, (str, int, float)):
                return str(val)
            raise self.fail(path, f"parameter {m.group(1)} is {_kind(val)}; only a lone '${{{m.group(1)}}}' can stand for it")
        return _PLACEHOLDER.sub(rep, s)

    def _copy(self, x, path, depth=0):
        """A fresh copy of a parameter value (counted like every produced value)."""
        self._count(path)
        if depth > MAX_DEPTH:
            raise self.fail(path, f"a parameter value is nested more than {MAX_DEPTH} levels deep")
        if isinstance(x, dict):
            out = _Map((k, self._copy(v, path, depth + 1)) for k, v in x.items())
            out.line, out.lines = getattr(x, "line", None), dict(getattr(x, "lines", None) or {})
            return out
        if isinstance(x, list):
            out = _Seq(self._copy(v, path, depth + 1) for v in x)
            out.line, out.lines = getattr(x, "line", None), dict(getattr(x, "lines", None) or {})
            return out
        return x


def _short(x) -> str:
    text = x if isinstance(x, str) else json.dumps(x, default=str)
    return text if len(text) <= 30 else text[:27] + "..."


def _check_fields(ctx, obj, path, allowed, required=(), what="a mapping"):
    """Raise ``ctx.fail`` unless ``obj`` is a mapping with only ``allowed`` string keys
    and every ``required`` one."""
    if not isinstance(obj, dict):
        raise ctx.fail(path, f"expected {what}, got {_kind(obj)}", obj)
    for k in obj:
        if not isinstance(k, str):
            raise ctx.fail(path, f"field names are strings, got {_kind(k)} {k!r}", obj, k)
        if k not in allowed:
            close = difflib.get_close_matches(k, allowed, 1)
            hint = f" (did you mean '{close[0]}'?)" if close else f" (expected: {', '.join(allowed)})"
            raise ctx.fail(_join(path, k), f"unknown field '{k}'{hint}", obj, k)
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
                    return _join(p, k), k
                if k != "description":
                    stack.append((v, _join(p, k)))
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
        raise _err("", f"expected a mapping with the model, got {_kind(data)}", file)
    _check_size(data, file)  # data built in Python may share sub-values (an alias bomb)
    data = copy.deepcopy(data)
    ex = _Expander(file)
    ex.define(data.pop("templates", None))
    ex.model(data)
    left = _find_placeholder(data, "")
    if left is not None:
        raise _err(left[0], f"unresolved placeholder in {left[1]!r} (placeholders are replaced only inside templates)", file)
    return data


# ============================================================================ data -> Model

_VAR_KINDS = ("bool", "enum", "int")
_STATUS = ("success", "failure", "running")
_NODE_FIELDS = {
    "ReactiveSequence": ("children",), "MemorySequence": ("children",),
    "ReactiveFallback": ("children",), "MemoryFallback": ("children",),
    "Parallel": ("success_threshold", "failure_threshold", "synchronise", "selected", "children"),
    "SequenceWithMemory": ("children",), "ParallelAll": ("max_failures", "children"),
    "IfThenElse": ("children",), "WhileDoElse": ("children",),
    "PipelineSequence": ("children",), "RecoveryNode": ("retries", "children"),
    "RoundRobin": ("wrap_around", "children"),
    "KeepRunningUntilFailure": ("child",), "RunOnce": ("then_skip", "child"), "SubTree": ("tree_id", "child"),
    "FailureIsRunning": ("child",), "RunningIsFailure": ("child",), "RunningIsSuccess": ("child",),
    "Inverter": ("child",), "ForceSuccess": ("child",), "ForceFailure": ("child",),
    "Retry": ("attempts", "child"), "Repeat": ("times", "child"), "Guard": ("condition", "child"),
    "Effects": ("on_start", "on_success", "on_failure", "on_halt", "child"),
    "Condition": ("expr",), "Action": ("primitive", "args", "outcomes", "duration"),
    "SkillRequest": ("fsm", "goal", "params", "pre", "post"),
}
_NODE_REQUIRED = {"Guard": ("condition", "child"), "Condition": ("expr",), "SkillRequest": ("fsm", "goal"),
                  "Inverter": ("child",), "ForceSuccess": ("child",), "ForceFailure": ("child",),
                  "Retry": ("child",), "Repeat": ("child",), "Effects": ("child",),
                  "KeepRunningUntilFailure": ("child",), "RunOnce": ("child",), "SubTree": ("child",),
                  "FailureIsRunning": ("child",), "RunningIsFailure": ("child",), "RunningIsSuccess": ("child",),
                  "IfThenElse": ("children",), "WhileDoElse": ("children",)}
TRIGGER_KEYS = ("when", "on", True)  # "on" and True (YAML 1.1's reading of on:) are older spellings
TOP_FIELDS = ("name", "description", "semantics", "tick", "tick_rate", "variables", "primitives", "fsms", "tree",
              "environment", "invariants", "workable", "terminal", "resources", "responses")
FSM_FIELDS = ("goals", "states", "initial", "edges", "markers", "params", "retarget", "withdraw_goal", "terminal")


_FILE_FIELDS = {"source": "from", "target": "to"}  # Python field -> file field (edges)
_FILE_FIELD = re.compile(r"^\.(source|target)\b")


class _Reader:
    """Checks the shape of expanded data and builds the Model objects."""

    def __init__(self, file):
        self.file = file
        self.where: dict = {}  # element path used by the Model -> (path in the file, parent, key)

    def fail(self, path, problem, obj=None, key=None):
        return _err(path, problem + _where(obj, key), self.file)

    def alias(self, model_path, path, parent, key):
        self.where.setdefault(model_path, (path, parent, key))

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
                    line = _where(elem, field.group(1))
                else:
                    line = _where(parent, key)
                return _err(path + rest, exc.problem + line, self.file)
            cut = max(el.rfind(".", 0, cut), el.rfind("[", 0, cut))
        return _err(el, exc.problem, self.file)

    # ---------------------------------------------------------------- scalars
    def fields(self, obj, path, allowed, required=(), what="a mapping"):
        _check_fields(self, obj, path, allowed, required, what)
        return obj

    def string(self, obj, path, parent=None, key=None, what="a string"):
        if not isinstance(obj, str):
            raise self.fail(path, f"expected {what}, got {_kind(obj)}", parent, key)
        return obj

    def integer(self, obj, path, parent=None, key=None):
        if isinstance(obj, bool) or not isinstance(obj, int):
            raise self.fail(path, f"expected an integer, got {_kind(obj)}", parent, key)
        return obj

    def expr(self, obj, path, parent=None, key=None) -> Expr:
        if isinstance(obj, float) or obj is None or not isinstance(obj, (str, int, bool)):
            raise self.fail(path, f"expected an expression (a string such as \"queue > 0\"), got {_kind(obj)}", parent, key)
        try:
            return as_expr(obj)
        except ModelError as exc:
            raise _err(path, exc.problem + _where(parent, key), self.file) from None

    def opt_expr(self, obj, key, path):
        return self.expr(obj[key], _join(path, key), obj, key) if obj.get(key) is not None else None

    def effects(self, obj, path, parent=None, key=None) -> tuple:
        if obj is None:
            return ()
        if not isinstance(obj, dict):
            raise self.fail(path, f"expected effects as a mapping 'variable: expression', got {_kind(obj)}", parent, key)
        out = []
        for var, e in obj.items():
            self.string(var, path, obj, var, "a variable name")
            out.append((var, self.expr(e, _join(path, var), obj, var)))
        return tuple(out)

    def names(self, obj, path, parent, key, what, allow_all=False) -> tuple:
        if isinstance(obj, str):
            return (obj,)
        if not isinstance(obj, list):
            raise self.fail(path, f"expected a list of {what}, got {_kind(obj)}", parent, key)
        for i, x in enumerate(obj):
            self.string(x, f"{path}[{i}]", obj, i, f"a {what[:-1]} name")
        if not allow_all and "*" in obj:
            raise self.fail(path, "'*' (all goals) is only allowed in edges and markers", parent, key)
        return tuple(obj)

    def constants(self, obj, path, parent, key) -> tuple:
        """``args``: a mapping of names to constants, kept in file order."""
        if not isinstance(obj, dict):
            raise self.fail(path, f"expected a mapping of argument names to constants, got {_kind(obj)}", parent, key)
        out = []
        for k, v in obj.items():
            self.string(k, path, obj, k, "an argument name")
            out.append((k, self.constant(v, _join(path, k), obj, k)))
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
        raise self.fail(path, f"an argument is a constant (string, number, boolean) or a list of them, got {_kind(v)}", parent, key)

    # ---------------------------------------------------------------- declarations
    def variables(self, obj, path, element_prefix) -> tuple:
        if obj is None:
            return ()
        if not isinstance(obj, dict):
            raise self.fail(path, f"expected a mapping of names to types, got {_kind(obj)}", obj)
        out = []
        for name, spec in obj.items():
            p = _join(path, name)
            self.string(name, path, obj, name, "a variable name")
            self.alias(f"{element_prefix}.{name}", p, obj, name)
            out.append(self.var(name, spec, p, obj))
        return tuple(out)

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
                raise self.fail(f"{path}.bool", f"the initial value of a bool is true or false, got {_kind(init)}", spec, "bool")
            return Bool(name, init)
        init = spec.get("init")
        if isinstance(init, float) or isinstance(init, (list, dict)):
            raise self.fail(f"{path}.init", f"expected {'a value name' if kind == 'enum' else 'an integer'}, got {_kind(init)}", spec, "init")
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
            raise self.fail(path, f"expected a list of outcomes such as [running, {{success: {{done: true}}}}], got {_kind(obj)}", parent, key)
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
            raise self.fail("primitives", f"expected a mapping of primitive names to outcome lists, got {_kind(obj)}", obj)
        out = []
        for name, outs in obj.items():
            p = _join("primitives", name)
            self.string(name, "primitives", obj, name, "a primitive name")
            self.alias(p, p, obj, name)
            duration = None
            if isinstance(outs, dict) and ("outcomes" in outs or "duration" in outs):  # {outcomes: [...], duration: ...}
                self.fields(outs, p, ("outcomes", "duration"), ("outcomes",), "a list of outcomes, or {outcomes: [...], duration: [min, max]}")
                duration = self.duration(outs.get("duration"), f"{p}.duration", outs, "duration")
                outs = outs["outcomes"]
            out.append(Primitive(name, self.outcomes(outs, p, obj, name, p), duration))
        return tuple(out)

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
            raise self.fail(path, f"expected a tree node such as {{Condition: name, expr: ...}}, got {_kind(obj)}", parent, key)
        types = [k for k in obj if k in NODE_TYPES]
        if len(types) != 1:
            if types:
                raise self.fail(path, f"a node has exactly one type, got {', '.join(types)}", obj)
            keys = [k for k in obj if isinstance(k, str)]
            close = [c for k in keys for c in difflib.get_close_matches(k, list(NODE_TYPES), 1)]
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise self.fail(path, f"a node needs a type key{hint}: one of {', '.join(NODE_TYPES)}", obj)
        t = types[0]
        self.fields(obj, path, (t,) + _NODE_FIELDS[t], _NODE_REQUIRED.get(t, ()))
        name = obj[t]
        if not isinstance(name, str) or not name:
            raise self.fail(_join(path, t), f"the node name (the value of '{t}') must be a non-empty string, got {_kind(name)}", obj, t)
        for prefix in ("tree", root):
            self.alias(f"{prefix}.{name}", path, parent, key)
        cls, kw = NODE_TYPES[t], {}
        if "children" in obj:
            kids = obj["children"]
            if not isinstance(kids, list):
                raise self.fail(f"{path}.children", f"expected a list of nodes, got {_kind(kids)}", obj, "children")
            kw["children"] = tuple(self.node(c, f"{path}.children[{i}]", root, kids, i, depth + 1) for i, c in enumerate(kids))
        if "child" in obj:
            kw["child"] = self.node(obj["child"], f"{path}.child", root, obj, "child", depth + 1)
        for f in ("attempts", "times", "failure_threshold", "max_failures", "retries"):
            if f in obj:
                kw[f] = self.integer(obj[f], f"{path}.{f}", obj, f)
        for f in ("then_skip", "wrap_around"):
            if f in obj:
                if not isinstance(obj[f], bool):
                    raise self.fail(f"{path}.{f}", f"expected true or false, got {_kind(obj[f])}", obj, f)
                kw[f] = obj[f]
        if obj.get("tree_id") is not None:
            kw["tree_id"] = self.string(obj["tree_id"], f"{path}.tree_id", obj, "tree_id", "a BehaviorTree ID")
        if obj.get("synchronise") is not None:
            if not isinstance(obj["synchronise"], bool):
                raise self.fail(f"{path}.synchronise", f"expected true or false, got {_kind(obj['synchronise'])}", obj, "synchronise")
            kw["synchronise"] = obj["synchronise"]
        if obj.get("selected") is not None:
            kw["selected"] = self.names(obj["selected"], f"{path}.selected", obj, "selected", "children")
        if obj.get("success_threshold") is not None:
            kw["success_threshold"] = self.integer(obj["success_threshold"], f"{path}.success_threshold", obj, "success_threshold")
        for f in ("condition", "expr", "pre", "post"):
            if f in obj and (obj[f] is not None or f in ("condition", "expr")):
                kw[f] = self.expr(obj[f], f"{path}.{f}", obj, f)
        for f in ("on_start", "on_success", "on_failure", "on_halt"):
            if f in obj:
                kw[f] = self.effects(obj[f], f"{path}.{f}", obj, f)
        if "primitive" in obj:
            kw["primitive"] = self.string(obj["primitive"], f"{path}.primitive", obj, "primitive", "a primitive name")
        if obj.get("outcomes") is not None:
            kw["outcomes"] = self.outcomes(obj["outcomes"], f"{path}.outcomes", obj, "outcomes", f"tree.{name}")
        if obj.get("args") is not None:
            kw["args"] = self.constants(obj["args"], f"{path}.args", obj, "args")
        if obj.get("duration") is not None:
            kw["duration"] = self.duration(obj["duration"], f"{path}.duration", obj, "duration")
        for f in ("fsm", "goal"):
            if f in obj:
                kw[f] = self.string(obj[f], f"{path}.{f}", obj, f, f"a{'n FSM' if f == 'fsm' else ' goal'} name")
        if obj.get("params") is not None:
            ps = obj["params"]
            if not isinstance(ps, dict):
                raise self.fail(f"{path}.params", f"expected a mapping of parameter names to expressions, got {_kind(ps)}", obj, "params")
            kw["params"] = tuple((self.string(k, f"{path}.params", ps, k, "a parameter name"), self.expr(v, f"{path}.params.{k}", ps, k))
                                 for k, v in ps.items())
        return cls(name, **kw)

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
        goals = self.names(spec["goals"], f"{path}.goals", spec, "goals", "goals")
        states_data = spec["states"]
        if not isinstance(states_data, list):
            raise self.fail(f"{path}.states", f"expected a list of states, got {_kind(states_data)}", spec, "states")
        states = tuple(self.state(name, s, f"{path}.states[{i}]", states_data, i) for i, s in enumerate(states_data))
        kw = {}
        for k in ("initial", "retarget", "withdraw_goal"):
            if k in spec:
                kw[k] = self.string(spec[k], f"{path}.{k}", spec, k)
        if "terminal" in spec:
            kw["terminal"] = self.names(spec["terminal"], f"{path}.terminal", spec, "terminal", "states")
        kw["params"] = self.variables(spec.get("params"), f"{path}.params", f"fsms.{name}.params")
        edges: list
        markers: list
        edges, markers = [], []
        for key, build, out in (("edges", self.edge, edges), ("markers", self.marker, markers)):
            items = spec.get(key)
            if items is None:
                continue
            if not isinstance(items, list):
                raise self.fail(f"{path}.{key}", f"expected a list, got {_kind(items)}", spec, key)
            for i, x in enumerate(items):
                built = build(x, f"{path}.{key}[{i}]", items, i)
                out.extend(built if isinstance(built, list) else [built])
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
            raise self.fail(f"{path}.min_interval", f"expected a finite number of seconds >= 0, got {_kind(gap)}", obj, "min_interval")
        return EnvEvent(name, self.opt_expr(obj, "guard", path), self.effects(obj.get("effects"), f"{path}.effects", obj, "effects"),
                        gap)

    def environment(self, obj) -> tuple:
        if obj is None:
            return ()
        if not isinstance(obj, list):
            raise self.fail("environment", f"expected a list of events and choices, got {_kind(obj)}", obj)
        out = []
        for i, ev in enumerate(obj):
            p = f"environment[{i}]"
            self.alias(p, p, obj, i)
            if isinstance(ev, dict) and "choice" in ev:
                self.fields(ev, p, ("choice", "options"), ("options",), "a choice {choice: NAME, options: [...]}")
                name = self.string(ev["choice"], f"{p}.choice", ev, "choice", "a choice name")
                self.alias(f"environment.{name}", p, obj, i)
                opts = ev["options"]
                if not isinstance(opts, list):
                    raise self.fail(f"{p}.options", f"expected a list of events, got {_kind(opts)}", ev, "options")
                for k in range(len(opts)):
                    self.alias(f"environment.{name}.options[{k}]", f"{p}.options[{k}]", opts, k)
                out.append(EnvChoice(name, tuple(self.event(o, f"{p}.options[{k}]", opts, k, f"environment.{name}.options")
                                                 for k, o in enumerate(opts))))
            else:
                out.append(self.event(ev, p, obj, i, "environment"))
        return tuple(out)

    def resources(self, obj, data) -> tuple:
        """``resources: {arm: [pick_a, pick_b]}``: resource name -> node names."""
        if not isinstance(obj, dict):
            raise self.fail("resources", f"expected a mapping of resource names to lists of node names, got {_kind(obj)}",
                            data, "resources")
        out = []
        for name, members in obj.items():
            self.string(name, "resources", obj, name, "a resource name")
            path = _join("resources", name)
            self.alias(path, path, obj, name)
            if isinstance(members, str):
                members = [members]
            if not isinstance(members, list):
                raise self.fail(path, f"expected a list of node names, got {_kind(members)}", obj, name)
            for i, m in enumerate(members):
                self.string(m, f"{path}[{i}]", members, i, "a node name")
            out.append((name, tuple(members)))
        return tuple(out)

    def responses(self, obj, data) -> tuple:
        """``responses: {NAME: {trigger: EXPR | event:NAME, response: EXPR, within: SECONDS}}``."""
        if not isinstance(obj, dict):
            raise self.fail("responses", f"expected a mapping of names to {{trigger, response, within}}, got {_kind(obj)}",
                            data, "responses")
        out = []
        for name, spec in obj.items():
            self.string(name, "responses", obj, name, "a requirement name")
            path = _join("responses", name)
            self.alias(path, path, obj, name)
            if not isinstance(spec, dict):
                raise self.fail(path, f"expected {{trigger: ..., response: ..., within: SECONDS}}, got {_kind(spec)}", obj, name)
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
                raise self.fail(f"{path}.within", f"expected a finite number of seconds >= 0, got {_kind(within)}", spec, "within")
            out.append(Response(name, trig, resp, within))
        return tuple(out)

    # ---------------------------------------------------------------- the model
    def model(self, data) -> Model:
        self.fields(data, "", TOP_FIELDS, ("name",), "a mapping with the model")
        kw = {"name": self.string(data["name"], "name", data, "name", "a model name")}
        if "description" in data:
            kw["description"] = self.string(data["description"], "description", data, "description")
        if "semantics" in data:
            sem = data["semantics"]
            if not isinstance(sem, str) or sem not in PROFILES:
                raise self.fail("semantics", f"expected one of {', '.join(PROFILES)}, got {sem!r}", data, "semantics")
            kw["semantics"] = sem
        if "tick" in data:
            tick = data["tick"]
            if not isinstance(tick, str) or tick not in TICKS:
                raise self.fail("tick", f"expected one of {', '.join(TICKS)}, got {tick!r}", data, "tick")
            kw["tick"] = tick
        if "tick_rate" in data:
            r = data["tick_rate"]
            if isinstance(r, bool) or not isinstance(r, (int, float)) or not math.isfinite(r):
                raise self.fail("tick_rate", f"expected a finite number of ticks per second, got {_kind(r)}", data, "tick_rate")
            kw["tick_rate"] = r
        for key in TOP_FIELDS:
            self.alias(key, key, data, key)
        kw["variables"] = self.variables(data.get("variables"), "variables", "variables")
        kw["primitives"] = self.primitives(data.get("primitives"))
        fsms = data.get("fsms")
        if fsms is not None:
            if not isinstance(fsms, dict):
                raise self.fail("fsms", f"expected a mapping of FSM names to FSMs, got {_kind(fsms)}", data, "fsms")
            kw["fsms"] = tuple(self.fsm(self.string(n, "fsms", fsms, n, "an FSM name"), spec, _join("fsms", n), fsms) for n, spec in fsms.items())
        if data.get("tree") is not None:
            kw["tree"] = self.node(data["tree"], "tree", "tree", data, "tree")
        kw["environment"] = self.environment(data.get("environment"))
        inv = data.get("invariants")
        if inv is not None:
            if not isinstance(inv, dict):
                raise self.fail("invariants", f"expected a mapping of names to expressions, got {_kind(inv)}", data, "invariants")
            kw["invariants"] = tuple((self.string(k, "invariants", inv, k, "an invariant name"), self.expr(v, _join("invariants", k), inv, k))
                                     for k, v in inv.items())
        for key in ("workable", "terminal"):
            if data.get(key) is not None:
                kw[key] = self.expr(data[key], key, data, key)
        if data.get("resources") is not None:
            kw["resources"] = self.resources(data["resources"], data)
        if data.get("responses") is not None:
            kw["responses"] = self.responses(data["responses"], data)
        self.alias_declared_outcomes(kw)
        try:
            return Model(**kw)
        except ModelError as exc:
            raise self.translate(exc) from None


def model_from_data(data, file: "str | None" = None) -> Model:
    """Build a Model from loaded data (templates are expanded first)."""
    data = expand_templates(data, file)
    return _Reader(file).model(data)


def loads_model(text, fmt: str = "yaml", file_name: str = "<string>") -> Model:
    """A Model from YAML or JSON text."""
    return model_from_data(loads_data(text, fmt, file_name), file_name)


# ============================================================================ built-in models and load_model


def builtin_models() -> dict:
    """The registry of built-in models (``btfsm.models.registry.BUILTIN``); empty when absent."""
    try:
        from btfsm.models.registry import BUILTIN
    except ImportError as exc:
        if getattr(exc, "name", None) in ("btfsm.models", "btfsm.models.registry"):
            return {}
        raise
    return dict(BUILTIN)


def load_model(ref, *, file_name: "str | None" = None, semantics: "str | None" = None,
               tick: "str | None" = None, **xml) -> Model:
    """A Model from a file (.yaml/.yml/.json) or a built-in name (``builtin_models()``).

    ``semantics`` (a ``btfsm.profiles`` name) overrides the profile the model names,
    ``tick`` (``once``, ``exactly-once``) the way a BehaviorTree.CPP main loop ticks it.

    Built-in entries are ``module:function`` (a shipped function returning a Model) or a
    file path relative to the ``models`` package; user input never names a module.

    ``xml``: ``node_library``, ``nodes``, ``main_tree`` for a BehaviorTree.CPP XML file
    (``load_xml_model``); an error for any other model."""
    xml = {k: v for k, v in xml.items() if v}
    model = _load_model(ref, file_name, xml)
    semantics = model.semantics if semantics is None else semantics
    tick = model.tick if tick is None else tick
    if semantics == model.semantics and tick == model.tick:
        return model
    source = getattr(model, "source")  # set by _with_source
    if semantics not in PROFILES:
        raise _err("semantics", f"unknown semantics {semantics!r} (one of: {', '.join(PROFILES)})", source)
    if tick not in TICKS:
        raise _err("tick", f"unknown tick {tick!r} (one of: {', '.join(TICKS)})", source)
    try:
        new = dataclasses.replace(model, semantics=semantics, tick=tick)
        object.__setattr__(new, "warnings", new.warnings + tuple(w for w in model.warnings if w not in new.warnings))
        return _with_source(new, source)
    except ModelError as exc:
        raise (exc if exc.file else exc.at(file=source)) from None


def load_cli_model(args) -> Model:
    """The model a command's arguments name: ``args.model``, under ``args.semantics`` and
    ``args.tick`` when given (and ``--node-library``, ``--nodes``, ``--main-tree`` for an XML tree)."""
    return load_model(args.model, semantics=getattr(args, "semantics", None), tick=getattr(args, "tick", None),
                      node_library=getattr(args, "node_library", None), nodes=getattr(args, "nodes", None) or (),
                      main_tree=getattr(args, "main_tree", None))


def _load_model(ref, file_name, xml=None) -> Model:
    text = os.fspath(ref) if isinstance(ref, os.PathLike) else ref
    if not isinstance(text, str) or not text:
        raise _err("", f"expected a model file or a built-in model name, got {text!r}")
    python = python_model_ref(text)
    if python is not None:
        return _with_source(load_python_model(*python, shown=file_name or text), file_name or text)
    suffix = Path(text).suffix.lower()
    if suffix == ".py" and not os.path.isdir(text):
        raise _err("", "a model written in Python is named FILE.py:FUNCTION (the function returns a Model)", file_name or text)
    registry = {} if suffix in FORMATS or os.sep in text or "/" in text else builtin_models()
    if text in registry:
        return _with_source(_load_builtin(text, registry[text], file_name), file_name or text)
    if suffix == ".xml":
        return _with_source(load_xml_model(text, file_name=file_name, **(xml or {})), file_name or text)
    if xml:
        opts = ", ".join("--" + k.replace("_", "-") for k in xml)
        raise _err("", f"{opts}: only for a BehaviorTree.CPP XML tree (.xml); {text} is not one", file_name or text)
    if suffix in FORMATS or os.path.exists(text):
        if os.path.isdir(text):
            raise _err("", "is a folder, not a model file", file_name or text)
        return _with_source(model_from_data(load_data(text, file_name=file_name), file_name or text), file_name or text)
    names = ", ".join(sorted(builtin_models())) or "none installed"
    raise _err("", f"no such file or built-in model '{text}' (model files end in .yaml, .yml, .json or .xml; built-in models: {names})")


def load_xml_model(path, *, leaves=None, file_name: "str | None" = None, node_library: "str | None" = None,
                   nodes=(), main_tree: "str | None" = None) -> Model:
    """A Model from a BehaviorTree.CPP XML v4 file and its side file (``leaves``, or
    ``STEM.btfsm.yaml`` beside the XML when found): ``btfsm.interop.btcpp_import``.

    ``node_library`` names a node library (``btfsm.interop.libraries``; else the side
    file's ``node_library``), ``nodes`` are Groot2 node model files (``TreeNodesModel``;
    the side file's ``node_models`` add to them, relative to the side file), ``main_tree``
    the BehaviorTree to check. ``<include path=...>`` is read relative to the including
    file, within the folder of ``path``."""
    from .interop.btcpp_import import parse_xml, side_file_for, xml_to_data
    from .interop.groot import models_of_document
    from .interop.libraries import load_library

    shown = file_name or os.fspath(path)
    xml = read_model_bytes(path, shown)
    side_path = leaves if leaves is not None else side_file_for(path)
    side_name = None if side_path is None else os.fspath(side_path)
    side = {} if side_path is None else load_data(side_path)
    lib_name = node_library if node_library is not None else (side.get("node_library") if isinstance(side, dict) else None)
    if lib_name is not None and not isinstance(lib_name, str):
        raise _err("node_library", "expected the name of a node library", side_name)
    try:
        library = load_library(lib_name) if lib_name is not None else None
    except ModelError as exc:
        raise (exc if node_library is not None else exc.at(file=side_name)) from None
    files = [(os.fspath(f), os.fspath(f)) for f in nodes]
    side_models = side.get("node_models") if isinstance(side, dict) else None
    if side_models is not None:
        if isinstance(side_models, str):
            side_models = [side_models]
        if not isinstance(side_models, list) or not all(isinstance(x, str) for x in side_models):
            raise _err("node_models", "expected a node model file (or a list of them), relative to the side file", side_name)
        base = Path(cast(str, side_name)).parent
        files += [(os.fspath(base / x), x) for x in side_models]
    models: dict = {}
    for f, _text in files:
        models.update({k: v for k, v in models_of_document(parse_xml(read_model_bytes(f, f), f), f).items()
                       if k not in models})
    top = Path(path).resolve().parent

    def include(text, including):
        here = Path(including).parent if including != shown else Path(path).parent
        target = (here / text)
        real = target.resolve()
        if top not in real.parents:
            raise _err("", f"<include path=\"{text}\"> leads outside the folder of {shown} ({top}): refused")
        name = os.path.normpath(target)  # one name per file, so that a cycle of includes is seen
        return parse_xml(read_model_bytes(real, name), name), name

    result = xml_to_data(xml, shown, side, side_name, library=library, models=models, main_tree=main_tree,
                         include=include)
    try:
        model = model_from_data(result.data, side_name or shown)
    except ModelError as exc:
        raise result.locate(exc, shown) from None
    object.__setattr__(model, "warnings", model.warnings + tuple(result.warnings))
    return model


_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_MODULE = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*\Z")


def python_model_ref(text: str) -> "tuple | None":
    """``(file or module, function)`` when ``text`` names a model written in Python:
    ``path/to/file.py:function`` or ``package.module:function``; None otherwise (an existing
    file of that exact name stays a file).

    >>> python_model_ref("models/examples/two_area.py:two_area")
    ('models/examples/two_area.py', 'two_area')
    >>> python_model_ref("btfsm.models.pickplace:pickplace")
    ('btfsm.models.pickplace', 'pickplace')
    >>> python_model_ref("model.yaml") is None, python_model_ref("a:b:c") is None
    (True, True)
    """
    where, colon, func = text.rpartition(":")
    if not colon or not _IDENT.match(func) or os.path.exists(text):
        return None
    if where.lower().endswith(".py") or _MODULE.match(where):
        return where, func
    return None


#: modules of btfsm's command line: calling their functions as a model would run btfsm again
_COMMAND_LINES = frozenset({"btfsm.cli", "btfsm.__main__", "btfsm.sim.cli", "btfsm.pytest_plugin"})


def load_python_model(where: str, func: str, *, shown: "str | None" = None) -> Model:
    """Call ``func`` of the Python file or module ``where`` (the user's explicit choice to
    run their code) and return the Model it builds; anything else is a one-line ModelError."""
    import importlib.util
    import sys

    shown = shown or f"{where}:{func}"
    try:
        if where.lower().endswith(".py"):
            if not os.path.isfile(where):
                raise _err("", f"no such Python file '{where}'", shown)
            name = "_btfsm_user_model_" + re.sub(r"\W", "_", os.path.abspath(where))
            spec = importlib.util.spec_from_file_location(name, where)
            if spec is None or spec.loader is None:
                raise _err("", f"cannot load '{where}' as a Python module", shown)
            module = importlib.util.module_from_spec(spec)
            folder = os.path.dirname(os.path.abspath(where))
            sys.path.insert(0, folder)  # its sibling modules import as they would when run as a script
            try:
                spec.loader.exec_module(module)
            finally:
                if sys.path and sys.path[0] == folder:
                    del sys.path[0]
        else:
            module = importlib.import_module(where)
    except ModelError:
        raise
    except ModuleNotFoundError as exc:
        raise _err("", f"cannot import '{where}': no module named '{exc.name}'", shown) from None
    except SyntaxError as exc:
        raise _err("", f"{exc.filename or where}: line {exc.lineno}: syntax error: {exc.msg}", shown) from None
    except MemoryError:
        raise
    except (Exception, SystemExit) as exc:  # the user's module raised while it was imported
        raise _err("", f"importing '{where}' raised {type(exc).__name__}: {exc}", shown) from None
    fn = getattr(module, func, None)
    if not callable(fn):
        raise _err("", f"'{where}' has no function '{func}'", shown)
    if getattr(fn, "__module__", None) in _COMMAND_LINES:
        raise _err("", f"{func}() is btfsm's own command line, not a function that returns a Model", shown)
    try:
        model = fn()
    except ModelError as exc:
        raise (exc if exc.file else exc.at(file=shown)) from None
    except MemoryError:
        raise
    except (Exception, SystemExit) as exc:
        raise _err("", f"{func}() raised {type(exc).__name__}: {exc}", shown) from None
    if not isinstance(model, Model):
        raise _err("", f"{func}() returned {type(model).__name__}, not a btfsm Model", shown)
    return model


def _with_source(model: Model, shown: str) -> Model:
    """Record where the model came from (``model.source``: the file or built-in name that
    messages show; not part of the model's value), so that later errors can name it."""
    object.__setattr__(model, "source", shown)
    return model


def _load_builtin(name, entry, file_name):
    shown = file_name or name
    if not isinstance(entry, str):
        raise _err("", f"registry entry for '{name}' is not a string", shown)
    if Path(entry).suffix.lower() in FORMATS:
        import btfsm.models as shipped  # the package the registry lives in

        path = Path(shipped.__file__).parent / entry
        return model_from_data(load_data(path, file_name=shown), shown)
    module, _, func = entry.partition(":")
    if not module or not func:
        raise _err("", f"registry entry '{entry}' for '{name}' is neither module:function nor a model file", shown)
    try:
        model = getattr(importlib.import_module(module), func)()
    except ModelError as exc:
        raise exc.at("", shown) from None
    if not isinstance(model, Model):
        raise _err("", f"built-in '{name}' ({entry}) returned {type(model).__name__}, not a Model", shown)
    return model


# ============================================================================ Model -> data


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
    if isinstance(n, Parallel):
        if n.success_threshold is not None:
            out["success_threshold"] = n.success_threshold
        if n.failure_threshold != 1:
            out["failure_threshold"] = n.failure_threshold
        if n.synchronise:
            out["synchronise"] = True
        if n.selected:
            out["selected"] = list(n.selected)
    if isinstance(n, ParallelAll) and n.max_failures != 1:
        out["max_failures"] = n.max_failures
    if isinstance(n, RunOnce):
        out["then_skip"] = n.then_skip
    if isinstance(n, RecoveryNode) and n.retries != 1:
        out["retries"] = n.retries
    if isinstance(n, RoundRobin) and n.wrap_around:
        out["wrap_around"] = True
    if isinstance(n, SubTree) and n.tree_id != n.name:
        out["tree_id"] = n.tree_id
    if isinstance(n, Retry) and n.attempts != 1:
        out["attempts"] = n.attempts
    if isinstance(n, Repeat) and n.times != 1:
        out["times"] = n.times
    if isinstance(n, Guard):
        out["condition"] = _expr_data(n.condition)
    if isinstance(n, Effects):
        for f in ("on_start", "on_success", "on_failure", "on_halt"):
            if getattr(n, f):
                out[f] = _effects_data(getattr(n, f))
    if isinstance(n, Condition):
        out["expr"] = _expr_data(n.expr)
    if isinstance(n, Action):
        if n.primitive != n.name:
            out["primitive"] = n.primitive
        if n.args:
            out["args"] = _args_data(n.args)
        if n.outcomes is not None:
            out["outcomes"] = [_outcome_data(o) for o in n.outcomes]
        if n.duration is not None:
            out["duration"] = list(n.duration)
    if isinstance(n, SkillRequest):
        out["fsm"], out["goal"] = n.fsm, n.goal
        if n.params:
            out["params"] = {k: _expr_data(e) for k, e in cast("tuple[tuple[str, Expr], ...]", n.params)}
        for f in ("pre", "post"):
            if getattr(n, f) is not None:
                out[f] = _expr_data(getattr(n, f))
    if isinstance(n, Composite) and n.children:
        out["children"] = [_node_data(c) for c in n.children]
    if isinstance(n, Decorator) and n.child is not None:
        out["child"] = _node_data(n.child)
    return out


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
    return yaml.dump(data, Dumper=_Dumper, sort_keys=False, allow_unicode=True, default_flow_style=None, width=100)


def dump_model(model: Model, path_or_stream, fmt: "str | None" = None) -> None:
    """Write the model to a path (format from its extension unless ``fmt``) or a text stream."""
    if hasattr(path_or_stream, "write"):
        path_or_stream.write(dumps_model(model, fmt or "yaml"))
        return
    text = dumps_model(model, format_of(path_or_stream, fmt))
    with open(path_or_stream, "w", encoding="utf-8") as fh:
        fh.write(text)


# ============================================================================ btfsm validate


def cli_validate(args) -> int:
    """``btfsm validate FILE [--strict]``: load, summarise, list warnings and lints."""
    model = load_cli_model(args)
    states = sum(len(f.states) for f in model.fsms)
    nodes = len(model.nodes())
    print(f"{args.model}: ok ({_count(len(model.variables), 'variable')}, {_count(len(model.fsms), 'FSM')} "
          f"with {_count(states, 'state')}, {_count(nodes, 'tree node')})")
    warnings = list(model.warnings) + list(model.program.lints)
    for element, text in warnings:
        print(_printable(f"warning: {element}: {text}"))
    return 1 if warnings and getattr(args, "strict", False) else 0


def _count(n: int, word: str) -> str:
    return f"{n} {word}{'' if n == 1 else 's'}"
