"""Reading btfsm's own JSON files strictly: traces and counterexamples.

The formats are written down as JSON Schemas in ``btfsm/schema/`` (``trace.schema.json``,
``counterexample.schema.json``) and checked with ``jsonschema``; every problem becomes a
``FormatError`` whose text is one line naming the file, where (a line, a JSON path) and
what is wrong:

>>> parse_json('{"tick": NaN}', "t.jsonl", line=3)
Traceback (most recent call last):
...
btfsm.formats.FormatError: t.jsonl: line 3: tick: NaN is not allowed (JSON has no NaN or Infinity)
>>> validate([5], "trace", "t.jsonl", "line 2", "record")  # doctest: +ELLIPSIS
Traceback (most recent call last):
...
btfsm.formats.FormatError: t.jsonl: line 2: expected a tick record {tick, time, ...}, got an array of 1 item(s)

Strict JSON here means: no ``NaN``/``Infinity``, no number that overflows a float, text
that is UTF-8. ``printable`` makes any text safe to print (lone surrogates escaped).
"""
from __future__ import annotations

import functools
import json
import math
from importlib import resources

__all__ = ["FormatError", "parse_json", "decode_utf8", "validate", "load_schema", "printable", "describe", "json_path",
           "jsonable"]


class FormatError(ValueError):
    """A file does not follow its format: ``file``, ``where`` (a line or JSON path) and
    ``problem``; ``str()`` is the one-line message."""

    def __init__(self, file: str, where: str, problem: str):
        self.file, self.where, self.problem = str(file), where, problem
        super().__init__(printable(": ".join(p for p in (self.file, where, problem) if p)))


# control characters and line separators, escaped so that a message stays one line
_CONTROLS = {c: f"\\x{c:02x}" if c < 0x100 else f"\\u{c:04x}"
             for c in [*range(0x20), *range(0x7f, 0xa0), 0x2028, 0x2029]}


def printable(text: object, limit: int = 0) -> str:
    """``text`` with lone surrogates, control characters and line separators escaped, so
    that printing it never raises and stays on one line; cut to ``limit`` characters when
    ``limit`` > 0.

    >>> printable("a\\udc80b")
    'a\\\\udc80b'
    """
    text = str(text)
    if limit and len(text) > limit:
        text = text[: limit - 3] + "..."
    return text.translate(_CONTROLS).encode("utf-8", "backslashreplace").decode("utf-8")


def describe(value) -> str:
    """A short account of a JSON value for messages: its type and, if small, the value."""
    kind = {dict: "an object", list: "an array", str: "a string", bool: "a boolean", int: "an integer",
            float: "a number", type(None): "null"}.get(type(value), type(value).__name__)
    if value is None:
        return kind
    if isinstance(value, (dict, list)):
        return f"{kind} of {len(value)} item(s)"
    shown = json.dumps(value, ensure_ascii=True) if not isinstance(value, str) or len(value) < 200 else None
    if shown is None or len(shown) > 40:
        return kind
    return f"{kind} ({shown})"


class _Bad:
    """Stands for a number JSON cannot hold (NaN, Infinity, an overflowing float) until
    its place is found."""

    def __init__(self, problem: str):
        self.problem = problem


def _constant(name):
    return _Bad(f"{name} is not allowed (JSON has no NaN or Infinity)")


def _finite(text):
    x = float(text)
    return x if math.isfinite(x) else _Bad(f"the number {text[:30]} is too large for a float")


def _find_bad(obj, path: list):
    """(path, _Bad) of the first bad number in ``obj``, or None (no recursion: deep input)."""
    stack = [(obj, path)]
    while stack:
        x, p = stack.pop()
        if isinstance(x, _Bad):
            return p, x
        if isinstance(x, dict):
            stack.extend(reversed([(v, p + [k]) for k, v in x.items()]))
        elif isinstance(x, list):
            stack.extend(reversed([(v, p + [i]) for i, v in enumerate(x)]))
    return None


def decode_utf8(data: bytes, file: str, line: "int | None" = None) -> str:
    """Bytes as UTF-8 text, or a FormatError naming the line (and column) of the first bad byte."""
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        before = data[: exc.start]
        ln = (line if line is not None else before.count(b"\n") + 1)
        col = exc.start - (before.rfind(b"\n") + 1) + 1
        raise FormatError(file, f"line {ln} column {col}", f"not UTF-8 text (byte 0x{data[exc.start]:02x})") from None


def parse_json(text: str, file: str, line: "int | None" = None):
    """One JSON document, strictly (see the module doc). ``line``: the line number of a
    JSON Lines record (else lines are counted inside ``text``)."""
    try:
        obj = json.loads(text, parse_constant=_constant, parse_float=_finite)
    except json.JSONDecodeError as exc:
        where = f"line {line}" if line is not None else f"line {exc.lineno} column {exc.colno}"
        ended = exc.pos >= len(text.rstrip()) or exc.msg.startswith("Unterminated string")
        problem = "the JSON ends too early (truncated?)" if ended and text.strip() else f"not valid JSON ({exc.msg})"
        if not text.strip():
            problem = "empty, not JSON"
        raise FormatError(file, where, problem) from None
    except RecursionError:
        raise FormatError(file, f"line {line}" if line is not None else "", "JSON nested too deeply") from None
    except ValueError as exc:  # an integer of more than 4300 digits
        raise FormatError(file, f"line {line}" if line is not None else "",
                          f"a number is too long ({printable(exc, 60)})") from None
    bad = _find_bad(obj, [])
    if bad is not None:
        path, b = bad
        raise FormatError(file, ": ".join(p for p in (f"line {line}" if line is not None else "", json_path(path)) if p),
                          b.problem)
    return obj


@functools.lru_cache(maxsize=None)
def load_schema(name: str) -> dict:
    """The JSON Schema ``btfsm/schema/NAME.schema.json``."""
    return json.loads(resources.files("btfsm").joinpath("schema", f"{name}.schema.json").read_text("utf-8"))


@functools.lru_cache(maxsize=None)
def _validator(name: str, definition: "str | None"):
    from jsonschema import Draft202012Validator

    schema = load_schema(name)
    if definition is not None:
        schema = {"$defs": schema["$defs"], "$ref": f"#/$defs/{definition}"}
    return Draft202012Validator(schema)


def json_path(parts) -> str:
    """``steps[1].outcomes[0]`` from ``["steps", 1, "outcomes", 0]``."""
    out = ""
    for p in parts:
        out += f"[{p}]" if isinstance(p, int) else (f".{printable(p, 40)}" if out else printable(p, 40))
    return out


def _message(err) -> tuple:
    """(JSON path parts, problem) of one jsonschema error, in our words."""
    path = list(err.absolute_path)
    schema = err.schema if isinstance(err.schema, dict) else {}
    what = schema.get("description")
    kw, inst = err.validator, err.instance
    if kw == "required":
        missing = [k for k in err.validator_value if isinstance(inst, dict) and k not in inst]
        return path, f"missing field '{missing[0] if missing else err.validator_value[0]}'"
    if kw in ("additionalProperties", "unevaluatedProperties") and isinstance(inst, dict):
        allowed = set(schema.get("properties", {}))
        extra = sorted(k for k in inst if k not in allowed)
        return path, f"unknown field '{printable(extra[0], 40)}'" if extra else "unknown field"
    if kw == "const":
        return path, f"must be {json.dumps(err.validator_value)}, not {describe(inst)}"
    if kw == "enum":
        return path, f"must be one of {', '.join(json.dumps(v) for v in err.validator_value)}, not {describe(inst)}"
    if kw in ("minItems", "maxItems"):
        return path, f"expected {what or 'an array'}, got {len(inst)} item(s)"
    if kw in ("minimum", "exclusiveMinimum"):
        op = ">=" if kw == "minimum" else ">"
        return path, f"must be {op} {err.validator_value}, not {describe(inst)}"
    if kw == "type":
        return path, f"expected {what or err.validator_value}, got {describe(inst)}"
    return path, f"{what + ': ' if what else ''}{printable(err.message, 120)}"


def _rank(err):
    # deepest first, then the order of the path, so the message names the innermost element
    return (-len(err.absolute_path), [str(p) for p in err.absolute_path])


def validate(obj, name: str, file: str, where: str = "", definition: "str | None" = None) -> None:
    """Check ``obj`` against schema ``name`` (its ``$defs/definition`` if given); raise a
    FormatError naming ``where`` plus the JSON path of the first problem."""
    try:
        errors = list(_validator(name, definition).iter_errors(obj))
    except RecursionError:
        raise FormatError(file, where, "JSON nested too deeply") from None
    if not errors:
        return
    from jsonschema.exceptions import best_match

    err = best_match(errors)
    while err.context:  # a failed oneOf/anyOf/if: name the innermost reason
        err = best_match(err.context)
    path, problem = _message(err)
    raise FormatError(file, ": ".join(p for p in (where, json_path(path)) if p), problem)


def jsonable(x):
    """``x`` with tuples as lists, keys as strings and numpy scalars as Python numbers.

    >>> import numpy as np
    >>> jsonable({1: (np.int64(2), [3])})
    {'1': [2, [3]]}
    """
    if isinstance(x, (list, tuple)):
        return [jsonable(y) for y in x]
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if hasattr(x, "item"):
        return x.item()
    return x
