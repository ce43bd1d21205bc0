"""World model: declared finite-domain variables with initial values.

A model's variables live in the model instance (there is no global blackboard). Every
value is stored as a small int: a bool as 0/1, an enum as the index of its value, an int
as itself. ``Var.encode`` / ``Var.decode`` convert between user values and stored ints.

>>> q = Int("queue", 0, 3)
>>> q.encode(2), q.domain_size
(2, 4)
>>> Enum("mode", ("idle", "busy")).decode(1)
'busy'
"""
from __future__ import annotations

import keyword
import re
from dataclasses import dataclass, field

from .errors import ModelError
from .expr import INT_LIMIT, int_text

__all__ = ["Var", "Bool", "Enum", "Int", "check_name", "check_label", "check_text", "RESERVED_NAMES", "MAX_LABEL"]

_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
RESERVED_NAMES = frozenset({"true", "false", "none", "min", "max", "abs", "and", "or", "not", "in"})


def check_name(name: object, element: str, what: str = "name") -> str:
    """Return ``name`` if it is a usable identifier, else raise ModelError at ``element``."""
    if not isinstance(name, str) or not _NAME.match(name) or keyword.iskeyword(name):
        raise ModelError(element, f"{what} {name!r} is not an identifier (letters, digits, _)")
    if name in RESERVED_NAMES:
        raise ModelError(element, f"{what} {name!r} is reserved")
    return name


MAX_LABEL = 256  # characters of a label


_PLACEHOLDER = re.compile(r"\$\{[A-Za-z_][A-Za-z0-9_]*\}")


def check_label(text: object, element: str, what: str = "name", limit: "int | None" = MAX_LABEL) -> str:
    """Return ``text`` if it is a usable label, else raise ModelError at ``element``.

    Labels (the model's name, node names, state ids, goals, primitive and outcome names,
    edge and marker ids, invariant names, enum values) are one line of printable text:
    non-empty, at most ``MAX_LABEL`` characters, every character printable in the sense of
    ``str.isprintable`` (no control characters, line breaks, format characters or lone
    surrogates). They are shown by every command and written into exported files.

    >>> check_label("pick up", "x")
    'pick up'
    >>> check_label("a\\ud800", "tree.n", "node name")
    Traceback (most recent call last):
    ...
    btfsm.errors.ModelError: tree.n: node name 'a\\ud800' holds the non-printable character U+D800 (a name is one line of printable text)
    """
    if not isinstance(text, str) or not text:
        raise ModelError(element, f"{what} must be a non-empty string, got {text!r}")
    if limit is not None and len(text) > limit:
        raise ModelError(element, f"{what} {text[:40]!r}... is {len(text)} characters long (limit {limit})")
    if not text.isprintable():
        bad = next(c for c in text if not c.isprintable())
        raise ModelError(element, f"{what} {text!r} holds the non-printable character U+{ord(bad):04X} "
                                  "(a name is one line of printable text)")
    if _PLACEHOLDER.search(text):
        raise ModelError(element, f"{what} {text!r} holds a template placeholder ${{...}} "
                                  "(model files replace those; a name cannot keep one)")
    return text


def check_text(text: object, element: str, what: str = "text") -> str:
    """Return ``text`` if it is valid Unicode text (no lone surrogate), else raise ModelError."""
    if not isinstance(text, str):
        raise ModelError(element, f"{what} must be a string, got {type(text).__name__}")
    try:
        text.encode("utf-8")
    except UnicodeEncodeError as exc:
        raise ModelError(element, f"{what} holds a lone surrogate U+{ord(text[exc.start]):04X}, which is not valid text") from None
    return text


@dataclass(frozen=True)
class Var:
    """A declared variable. Use the constructors ``Bool``, ``Enum`` and ``Int``."""

    name: str
    kind: str  # "bool" | "enum" | "int"
    init: object = None
    lo: int = 0
    hi: int = 1
    values: tuple = field(default=())

    @property
    def domain_size(self) -> int:
        return self.hi - self.lo + 1

    def encode(self, value: object) -> int:
        """The stored int of a user value; ValueError when it is not in the domain."""
        if self.kind == "bool":
            if isinstance(value, bool) or value in (0, 1):
                return int(value)
        elif self.kind == "enum":
            if value in self.values:
                return self.values.index(value)
        elif isinstance(value, int) and not isinstance(value, bool) and self.lo <= value <= self.hi:
            return value
        raise ValueError(f"{value!r} is not in the domain of {self.name} ({self.describe_domain()})")

    def decode(self, stored: int) -> object:
        """The user value of a stored int."""
        if self.kind == "bool":
            return bool(stored)
        if self.kind == "enum":
            return self.values[stored]
        return int(stored)

    def describe_domain(self) -> str:
        if self.kind == "bool":
            return "bool"
        if self.kind == "enum":
            return "one of " + ", ".join(self.values)
        return f"{self.lo}..{self.hi}"

    @property
    def init_code(self) -> int:
        return self.encode(self.init)

    def validated(self, element: str) -> "Var":
        """Check the declaration; raise ModelError naming ``element``."""
        check_name(self.name, element, "variable name")
        if self.kind == "enum":
            if not self.values:
                raise ModelError(element, f"enum {self.name} has no values")
            if len(set(self.values)) != len(self.values):
                raise ModelError(element, f"enum {self.name} repeats a value")
            for v in self.values:
                if not isinstance(v, str) or not v:
                    raise ModelError(element, f"enum {self.name} value {v!r} is not a non-empty string")
                check_label(v, element, f"enum {self.name} value")
        if self.kind == "int" and not (isinstance(self.lo, int) and isinstance(self.hi, int) and self.lo <= self.hi):
            raise ModelError(element, f"int {self.name} needs integer bounds lo <= hi, got {_bound(self.lo)}..{_bound(self.hi)}")
        if self.kind == "int" and not (-INT_LIMIT <= self.lo and self.hi <= INT_LIMIT):
            raise ModelError(element, f"int {self.name} has bounds {int_text(self.lo)}..{int_text(self.hi)}: int values must stay within -2**53..2**53")
        try:
            self.encode(self.init)
        except ValueError as exc:
            raise ModelError(element, f"initial value: {exc}") from None
        return self


def _bound(x) -> str:
    return int_text(x) if isinstance(x, int) else repr(x)[:40]


def Bool(name: str, init: bool = False) -> Var:
    """A boolean variable (stored 0/1)."""
    return Var(name, "bool", bool(init) if isinstance(init, bool) else init, 0, 1)


def Enum(name: str, values, init: object = None) -> Var:
    """An enumerated variable; ``init`` defaults to the first value."""
    values = tuple(values)
    return Var(name, "enum", values[0] if init is None and values else init, 0, max(len(values) - 1, 0), values)


def Int(name: str, lo: int, hi: int, init: "int | None" = None) -> Var:
    """A bounded integer variable ``lo..hi``; ``init`` defaults to ``lo``."""
    return Var(name, "int", lo if init is None else init, lo, hi)
