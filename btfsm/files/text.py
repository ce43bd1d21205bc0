"""Reading model-file text with limits: YAML (a safe loader, YAML 1.2 core scalars) and JSON into
plain data with the positions of its elements, and the one-line ``ModelError``s of ``btfsm.files``."""
from __future__ import annotations

import json
import math
import os
import re
import stat
from pathlib import Path
from typing import Any, cast

import yaml

from ..errors import ModelError


FORMATS = {".yaml": "yaml", ".yml": "yaml", ".json": "json"}
MAX_FILE_BYTES = 8 * 1024 * 1024  # size of a model file
MAX_NODES = 200_000  # YAML/JSON values in one document, aliases expanded
MAX_DEPTH = 100  # nesting of YAML/JSON values
MAX_TEMPLATE_DEPTH = 16
MAX_INT = 2 ** 63  # integers in a model file lie within -MAX_INT..MAX_INT
MAX_EXPANDED = 100_000  # items produced by templates
MAX_TEXT = MAX_FILE_BYTES  # characters of text produced by template placeholders
MAX_ERRORS = 20  # problems of one model file reported together (``ModelErrors``); the search stops there


_CONTROL = {c: f"\\x{c:02x}" for c in list(range(32)) + [127, 0x85]}
_CONTROL.update({10: "\\n", 13: "\\r", 9: "\\t", 0x2028: "\\u2028", 0x2029: "\\u2029"})
_CONTROL.update({c: f"\\u{c:04x}" for c in range(0xD800, 0xE000)})  # lone surrogates (from JSON)


def printable(text: str) -> str:
    """``text`` on one printable line."""
    return text.translate(_CONTROL)


_LONG_QUOTE = re.compile(r"'([^'\n]{100,})'")
MAX_MESSAGE = 1000  # characters of an error's problem text


def _clip(text: str) -> str:
    """A message with long quoted values (a 20,000-character name) shortened."""
    text = _LONG_QUOTE.sub(lambda m: f"'{m.group(1)[:60]}...' ({len(m.group(1))} characters)", text)
    return text if len(text) <= MAX_MESSAGE else text[:MAX_MESSAGE - 3] + "..."


def err(element, problem: str, file=None) -> ModelError:
    """A ModelError whose text is one line (control characters in names are escaped) and
    of reasonable length (long quoted values are shortened)."""
    clean = (lambda t: _clip(printable(t)) if isinstance(t, str) else t)
    return ModelError(clean(element), clean(problem), clean(file))


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


class Dumper(yaml.SafeDumper):
    """Safe dumper that quotes every string that YAML 1.1 readers *or* our loader would
    read as something else, so dumps load back identically everywhere."""


for _tag, _re, _first in _RESOLVERS:
    Dumper.add_implicit_resolver(_tag, _re, _first)


def _represent_str(dumper, text):
    # PyYAML writes NEL and the Unicode line/paragraph separators raw in plain and single-
    # quoted scalars, where YAML reads them as line breaks; double quotes escape them
    style = '"' if any(c in text for c in "\x85\u2028\u2029") else None
    return dumper.represent_scalar(_STR, text, style=style)


Dumper.add_representer(str, _represent_str)


class FileMap(dict):
    """A mapping read from a file. ``line``: where it starts; ``lines``: key -> line;
    ``origin``: the template instantiation it came from; ``chain``: templates it is in."""

    line = None
    lines: dict = {}
    origin = None
    chain: tuple = ()


class FileList(list):
    """A list read from a file; same position attributes as ``FileMap`` (``lines``: index -> line)."""

    line = None
    lines: dict = {}
    origin = None
    chain: tuple = ()


def format_of(path, fmt: "str | None" = None) -> str:
    """The format of ``path`` ("yaml" or "json") from its extension, or ``fmt`` if given."""
    if fmt is not None:
        if fmt not in ("yaml", "json"):
            raise err("", f"unknown format '{fmt}' (expected yaml or json)")
        return fmt
    ext = Path(str(path)).suffix.lower()
    if ext not in FORMATS:
        raise err("", f"unknown model file extension '{ext}' (expected .yaml, .yml or .json)", str(path))
    return FORMATS[ext]


def loads_data(text, fmt: str = "yaml", file_name: str = "<string>", *, duplicates: "list | None" = None):
    """Parse model-file text into plain data (dicts, lists, scalars); no templates expanded.

    A key given twice in one mapping is an error; with a ``duplicates`` list, each is
    appended to it instead (a ``ModelError``) and the later value left out.

    >>> loads_data("edges: [{from: a, to: b, when: failure, on: off}]")
    {'edges': [{'from': 'a', 'to': 'b', 'when': 'failure', 'on': 'off'}]}
    """
    fmt = format_of(file_name, fmt)
    if isinstance(text, bytes):
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise err("", f"not UTF-8 text (byte {exc.start})", file_name) from None
    if not isinstance(text, str):
        raise err("", f"expected text, got {type(text).__name__}", file_name)
    data = _parse_json(text, file_name, duplicates) if fmt == "json" else _parse_yaml(text, file_name, duplicates)
    if data is None:
        raise err("", "the file is empty (expected a mapping with the model)", file_name)
    return data


def load_data(path, fmt: "str | None" = None, file_name: "str | None" = None, *, duplicates: "list | None" = None):
    """Read a model file into plain data; ``fmt`` defaults to the extension's
    (``duplicates``: as for ``loads_data``)."""
    name = file_name or str(path)
    fmt = format_of(path, fmt)
    return loads_data(read_model_bytes(path, name), fmt, name, duplicates=duplicates)


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
        raise err("", f"cannot read: {getattr(exc, 'strerror', None) or exc}", name) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            kind = "a folder" if stat.S_ISDIR(st.st_mode) else "a FIFO" if stat.S_ISFIFO(st.st_mode) else \
                "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode) else "a socket" if stat.S_ISSOCK(st.st_mode) else "not a file"
            raise err("", f"is {kind}, not a regular {what}", name)
        if st.st_size > limit:
            raise err("", f"is {st.st_size} bytes; {what}s are at most {limit} bytes", name)
        chunks, total = [], 0
        while True:
            chunk = os.read(fd, 1 << 20)
            if not chunk:
                break
            total += len(chunk)
            if total > limit:  # grew while being read
                raise err("", f"is more than {limit} bytes; {what}s are at most {limit} bytes", name)
            chunks.append(chunk)
        return b"".join(chunks)
    except OSError as exc:
        raise err("", f"cannot read: {exc.strerror or exc}", name) from None
    finally:
        os.close(fd)


def _parse_json(text: str, file: str, duplicates: "list | None" = None):
    seen: list = []  # (the object, the key given again in it)

    def pairs(items):
        out: dict = {}
        for k, v in items:
            if k in out:
                seen.append((out, k))  # the later value is left out
                continue
            out[k] = v
        return out

    def constant(name):
        raise err("", f"{name} is not allowed (numbers must be finite)", file)

    try:
        data = json.loads(text, object_pairs_hook=pairs, parse_constant=constant)
    except json.JSONDecodeError as exc:
        raise err("", f"JSON syntax error at line {exc.lineno}, column {exc.colno}: {exc.msg}", file) from None
    except RecursionError:
        raise err("", "JSON nested too deeply", file) from None
    except ModelError:  # from the hooks above (a ValueError too)
        raise
    except ValueError as exc:  # e.g. an integer with too many digits
        raise err("", f"JSON: {_one_line(exc)}", file) from None
    check_size(data, file)
    if seen:
        where = _paths_of_objects(data)  # in the file's order: an object's own keys before the objects inside it
        order = {i: n for n, i in enumerate(where)}
        seen.sort(key=lambda dup: order[id(dup[0])])  # stable: one object's keys as given
        again = [err(where[id(obj)], f"duplicate key '{k}'", file) for obj, k in seen]
        if duplicates is None:
            raise again[0]
        duplicates.extend(again)
    return data


def _paths_of_objects(data) -> dict:
    """id of every dict in ``data`` -> its path (``fsms.f.edges[0]``; the top: ''), in the
    order the objects begin in the text."""
    out, stack = {}, [(data, "")]
    while stack:
        x, path = stack.pop()
        if isinstance(x, dict):
            out[id(x)] = path
            stack.extend(reversed([(v, join_path(path, k)) for k, v in x.items()]))
        elif isinstance(x, list):
            stack.extend(reversed([(v, f"{path}[{i}]") for i, v in enumerate(x)]))
    return out


def check_size(data, file):
    """Refuse data with more than ``MAX_NODES`` values (shared values counted each time
    they appear), nested deeper than ``MAX_DEPTH`` or holding an integer beyond ``MAX_INT``."""
    count, stack = 0, [(data, 0, "")]
    while stack:
        x, depth, path = stack.pop()
        count += 1
        if depth > MAX_DEPTH:
            raise err(path, f"values nested more than {MAX_DEPTH} levels deep", file)
        if count > MAX_NODES:
            raise err(path, f"more than {MAX_NODES} values in one file", file)
        if isinstance(x, int) and not isinstance(x, bool) and not -MAX_INT <= x <= MAX_INT:
            raise err(path, f"an integer of about {int(x.bit_length() * 0.30103) + 1} digits is too large "
                             "(integers lie within -2**63..2**63)", file)
        if isinstance(x, dict):
            stack.extend((v, depth + 1, join_path(path, k)) for k, v in x.items())
        elif isinstance(x, list):
            stack.extend((v, depth + 1, f"{path}[{i}]") for i, v in enumerate(x))


def _parse_yaml(text: str, file: str, duplicates: "list | None" = None):
    try:
        node = yaml.compose(text, Loader=_Loader)
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        what = exc.problem or exc.context or "invalid YAML"
        raise err("", f"YAML syntax error{where}: {_one_line(what)}", file) from None
    except yaml.YAMLError as exc:
        raise err("", f"YAML error: {_one_line(exc)}", file) from None
    except RecursionError:
        raise err("", "YAML nested too deeply", file) from None
    if node is None:
        return None
    return _Builder(file, duplicates).build(node)


def _one_line(x) -> str:
    return " ".join(str(x).split())


class _Builder:
    """Turns composed YAML nodes into ``FileMap`` / ``FileList`` / scalars, with positions."""

    def __init__(self, file, duplicates: "list | None" = None):
        self.file, self.count = file, 0
        self.active: set = set()
        self.duplicates = duplicates  # where a key given twice is noted (else it is raised)

    def fail(self, node, problem, path=""):
        return err(path, f"{problem} (line {node.start_mark.line + 1})", self.file)

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
                out = FileList()
                out.line, out.lines = node.start_mark.line + 1, {}
                for i, item in enumerate(node.value):
                    out.lines[i] = item.start_mark.line + 1
                    out.append(self.build(item, depth + 1, f"{path}[{i}]"))
                return out
            if node.tag != _MAP:
                raise self.fail(node, f"unsupported YAML tag {node.tag}", path)
            out = FileMap()
            out.line, out.lines = node.start_mark.line + 1, {}
            for knode, vnode in node.value:
                if not isinstance(knode, yaml.ScalarNode):
                    raise self.fail(knode, "a mapping key must be a plain value, not a list or mapping", path)
                key = self.scalar(knode, path)
                if key in out:
                    if self.duplicates is None:
                        raise self.fail(knode, f"duplicate key '{key}'", path)
                    self.duplicates.append(self.fail(knode, f"duplicate key '{key}'", path))
                    continue  # the later value is left out
                out.lines[key] = knode.start_mark.line + 1
                out[key] = self.build(vnode, depth + 1, join_path(path, key))
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


_KINDS = ((bool, "a boolean"), (int, "an integer"), (float, "a number"), (str, "a string"),
          (dict, "a mapping"), (list, "a list"))  # bool before int: a bool is an int


def kind_of(x) -> str:
    """What ``x`` is, for messages: "a mapping", "an integer", "null"...

    >>> kind_of(None), kind_of(True), kind_of(3), kind_of([]), kind_of(b"")
    ('null', 'a boolean', 'an integer', 'a list', 'bytes')
    """
    if x is None:
        return "null"
    return next((name for t, name in _KINDS if isinstance(x, t)), type(x).__name__)


def where_of(obj, key=None) -> str:
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


def join_path(path: str, key) -> str:
    """The element path of ``key`` inside ``path`` (``fsms.arm``)."""
    return f"{path}.{key}" if path else str(key)
