"""The typed expression language of guards, conditions, contracts and effects.

One AST, three ways in and four ways out:

* in: Python operators on ``v.name`` builders, the string syntax (a safe subset of
  Python expressions, parsed with ``ast`` and never executed), and model files;
* out: text (``to_text``), a Python closure over a state list (``compile_fn``),
  numpy over state columns (``to_numpy_source``) and z3 (``to_z3``).

>>> e = parse("queue > 0 and not holding")
>>> to_text(e)
'queue > 0 and not holding'
>>> e == ((v.queue > 0) & ~v.holding).node
True
>>> from btfsm.world import Bool, Int
>>> scope = Scope.of([Int("queue", 0, 3), Bool("holding")])
>>> f = compile_fn(e, scope, "guard")
>>> f([2, 0]), f([2, 1])
(True, False)
"""
from __future__ import annotations

import ast
import warnings
from dataclasses import dataclass
from typing import Any, Mapping, Union, cast

from .errors import DomainError, ModelError

__all__ = [
    "Expr", "Const", "Name", "Unary", "BoolOp", "Compare", "BinOp", "Call", "IfElse",
    "E", "v", "since", "flat", "parse", "as_expr", "to_text", "names_in",
    "Type", "BOOL", "INT", "Slot", "Scope", "check", "check_effects",
    "compile_fn", "compile_effects", "to_python_source", "to_numpy_source", "to_z3",
    "TRUE", "FALSE", "is_true", "MAX_DEPTH", "MAX_LENGTH", "INT_LIMIT", "depth", "int_range", "int_text",
]

MAX_DEPTH = 64  # nesting of an expression (operators inside operators)
MAX_LENGTH = 100_000  # characters of an expression in the string syntax (a split FSM's widened requirements reach 12,000)
INT_LIMIT = 2 ** 53  # every int constant, bound and intermediate value lies in -INT_LIMIT..INT_LIMIT


# --------------------------------------------------------------------------- AST


class Expr:
    """Base of the AST nodes. Nodes are frozen dataclasses compared by structure."""

    __slots__ = ()

    def __str__(self) -> str:
        return to_text(self)


@dataclass(frozen=True)
class Const(Expr):
    value: Union[bool, int, str]  # a str is an enum literal


@dataclass(frozen=True)
class Name(Expr):
    id: str  # a variable, a parameter, or "fsm.state" / "fsm.goal"


@dataclass(frozen=True)
class Unary(Expr):
    op: str  # "not" | "-"
    arg: Expr


@dataclass(frozen=True)
class BoolOp(Expr):
    op: str  # "and" | "or"
    args: tuple


@dataclass(frozen=True)
class Compare(Expr):
    op: str  # == != < <= > >=
    left: Expr
    right: Expr


@dataclass(frozen=True)
class BinOp(Expr):
    op: str  # + - * // %
    left: Expr
    right: Expr


@dataclass(frozen=True)
class Call(Expr):
    fn: str  # min | max | abs
    args: tuple


@dataclass(frozen=True)
class IfElse(Expr):
    cond: Expr
    then: Expr
    other: Expr


TRUE, FALSE = Const(True), Const(False)


def is_true(e: "Expr | None") -> bool:
    """Whether ``e`` is absent or the constant true (an unguarded element)."""
    return e is None or e == TRUE


# --------------------------------------------------------------------------- Python-operator builder


class E:
    """Builds AST nodes with Python operators: ``(v.queue > 0) & ~v.holding``.

    ``&``, ``|`` and ``~`` are and, or and not (Python's ``and``/``or``/``not`` cannot be
    overloaded, so using them raises TypeError). Beside a comparison a plain ``str`` is an
    enum value (``v.mode == "busy"``); elsewhere strings are the string syntax. ``.node`` is
    the AST.
    """

    __slots__ = ("node",)

    def __init__(self, node: Expr):
        self.node = node

    def __bool__(self):
        raise TypeError("use &, | and ~ (not and/or/not) to combine btfsm expressions")

    def _bin(self, cls, op, other, swap=False):
        # a plain str beside a comparison is an enum value (v.mode == "busy"), not syntax
        b = Const(other) if cls is Compare and isinstance(other, str) else as_expr(other)
        a = self.node
        return E(cls(op, b, a) if swap else cls(op, a, b))

    def __eq__(self, o): return self._bin(Compare, "==", o)  # type: ignore[override]
    def __ne__(self, o): return self._bin(Compare, "!=", o)  # type: ignore[override]
    def __lt__(self, o): return self._bin(Compare, "<", o)
    def __le__(self, o): return self._bin(Compare, "<=", o)
    def __gt__(self, o): return self._bin(Compare, ">", o)
    def __ge__(self, o): return self._bin(Compare, ">=", o)
    def __add__(self, o): return self._bin(BinOp, "+", o)
    def __radd__(self, o): return self._bin(BinOp, "+", o, True)
    def __sub__(self, o): return self._bin(BinOp, "-", o)
    def __rsub__(self, o): return self._bin(BinOp, "-", o, True)
    def __mul__(self, o): return self._bin(BinOp, "*", o)
    def __rmul__(self, o): return self._bin(BinOp, "*", o, True)
    def __floordiv__(self, o): return self._bin(BinOp, "//", o)
    def __mod__(self, o): return self._bin(BinOp, "%", o)
    def __neg__(self): return E(Unary("-", self.node))
    def __invert__(self): return E(Unary("not", self.node))
    def __and__(self, o): return E(flat("and", self.node, as_expr(o)))
    def __rand__(self, o): return E(flat("and", as_expr(o), self.node))
    def __or__(self, o): return E(flat("or", self.node, as_expr(o)))
    def __ror__(self, o): return E(flat("or", as_expr(o), self.node))
    __hash__ = None  # type: ignore[assignment]

    def isin(self, *values) -> "E":
        """``x in (a, b)`` as ``x == a or x == b`` (strings are enum values)."""
        return E(flat("or", *(Compare("==", self.node, Const(x) if isinstance(x, str) else as_expr(x))
                               for x in values)))

    def __repr__(self) -> str:
        return f"E({to_text(self.node)!r})"


def flat(op: str, *args: Expr) -> Expr:
    """``args`` joined by ``op`` ("and" or "or"), an argument that is itself an ``op``
    spliced in: the shape the parser gives the same text (``a or (b or c)`` is one "or")."""
    out: list = []
    for a in args:
        out.extend(a.args if isinstance(a, BoolOp) and a.op == op else (a,))
    return out[0] if len(out) == 1 else BoolOp(op, tuple(out))


class _Vars:
    """``v.queue`` is the expression of variable ``queue``; ``v["arm.state"]`` for dotted names."""

    def __getattr__(self, name: str) -> E:
        if name.startswith("__"):
            raise AttributeError(name)
        return E(Name(name))

    def __getitem__(self, name: str) -> E:
        return E(Name(name))


v = _Vars()


def since(event: str) -> E:
    """``since(E)``: the ticks since environment event E last happened, 0 on the tick it
    happens, saturated at its minimum interval in ticks (its value before it ever
    happened); an int that only events with a ``min_interval`` of 2 ticks or more have
    (rule 'Event spacing', docs/semantics.md 6.1 and 7). A name of the scope, read like a
    variable by every translation: ``Program`` puts ``since(E)`` in its scope.

    >>> to_text(parse("since(arrive) >= 90")), parse("since(arrive)") == since("arrive").node
    ('since(arrive) >= 90', True)
    """
    return E(Name(f"since({event})"))

#: what ``as_expr`` accepts (the fields of the model's classes take any of these)
ExprLike = Union["Expr", E, str, int]


def as_expr(x: object) -> Expr:
    """Any accepted form (AST, builder, string syntax, bool, int) as an AST node."""
    if isinstance(x, Expr):
        return x
    if isinstance(x, E):
        return x.node
    if isinstance(x, bool) or isinstance(x, int):
        return Const(x)
    if isinstance(x, str):
        return parse(x)
    raise TypeError(f"not an expression: {x!r}")


# --------------------------------------------------------------------------- string syntax

_CMP = {ast.Eq: "==", ast.NotEq: "!=", ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">="}
_ARITH = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.FloorDiv: "//", ast.Mod: "%"}
_FUNCS = {"min": 2, "max": 2, "abs": 1}


class _SyntaxProblem(Exception):
    pass


def parse(text: str) -> Expr:
    """Parse the string syntax (Python-like: ``and or not``, comparisons, ``+ - * // %``,
    ``min max abs``, ``a if c else b``, ``x in ('a', 'b')``, ``arm.state``, ``true false``).

    Raises ModelError (with no element; callers add it) on anything else. Never executes code.
    """
    if not isinstance(text, str):
        raise ModelError("", f"expected an expression string, got {type(text).__name__}")
    if len(text) > MAX_LENGTH:
        raise ModelError("", f"expression {_shown(text)} is {len(text)} characters long (limit {MAX_LENGTH})")
    too_deep = ModelError("", f"expression {_shown(text)} is nested too deeply (limit {MAX_DEPTH})")
    try:
        with warnings.catch_warnings():  # "invalid escape sequence" and the like: not ours to print
            warnings.simplefilter("ignore")
            tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        if "nested" in str(exc.msg) or "too many" in str(exc.msg):
            raise too_deep from None
        raise ModelError("", f"syntax error in {_shown(text)} at column {exc.offset}: {exc.msg}") from None
    except (RecursionError, MemoryError):
        raise too_deep from None
    except ValueError as exc:
        raise ModelError("", f"cannot parse {_shown(text)}: {exc}") from None
    try:
        e = _from_py(tree.body)
    except _SyntaxProblem as exc:
        raise ModelError("", f"in {_shown(text)}: {exc}") from None
    except RecursionError:
        raise too_deep from None
    if depth(e) > MAX_DEPTH:
        raise too_deep
    return e


def int_text(n: int) -> str:
    """``n`` for a message: its digits, or its size when it is very long."""
    if abs(n).bit_length() <= 128:
        return str(n)
    return f"{'-' if n < 0 else ''}(a number of about {int(abs(n).bit_length() * 0.30103) + 1} digits)"


def _shown(text: str, limit: int = 60) -> str:
    """``text`` quoted for an error message: one line, at most ``limit`` characters."""
    t = repr(text if len(text) <= limit else text[:limit - 3] + "...")
    return t


def depth(e: Expr, limit: int = MAX_DEPTH) -> int:
    """The nesting depth of ``e`` (a constant or a name is 1), counted without recursion
    and at most ``limit + 1`` (enough to tell that ``e`` is too deep).

    >>> depth(parse("a and (b or not c)"))
    4
    """
    best, stack = 0, [(e, 1)]
    while stack:
        x, d = stack.pop()
        best = max(best, d)
        if d > limit:
            return d
        stack.extend((k, d + 1) for k in _kids(x))
    return best


def _kids(e) -> tuple:
    if isinstance(e, Unary):
        return (e.arg,)
    if isinstance(e, (BoolOp, Call)):
        return tuple(e.args) if isinstance(e.args, (tuple, list)) else ()
    if isinstance(e, (Compare, BinOp)):
        return (e.left, e.right)
    if isinstance(e, IfElse):
        return (e.cond, e.then, e.other)
    return ()


def _from_py(n: ast.AST) -> Expr:
    if isinstance(n, ast.BoolOp):
        return flat("and" if isinstance(n.op, ast.And) else "or", *(_from_py(a) for a in n.values))
    if isinstance(n, ast.UnaryOp):
        if isinstance(n.op, ast.Not):
            return Unary("not", _from_py(n.operand))
        if isinstance(n.op, ast.USub):
            inner = _from_py(n.operand)
            if isinstance(inner, Const) and type(inner.value) is int:
                return Const(-inner.value)
            return Unary("-", inner)
        if isinstance(n.op, ast.UAdd):
            return _from_py(n.operand)
    if isinstance(n, ast.BinOp) and type(n.op) in _ARITH:
        return BinOp(_ARITH[type(n.op)], _from_py(n.left), _from_py(n.right))
    if isinstance(n, ast.Compare):
        left: "Expr | None"
        parts, left = [], _from_py(n.left)
        for op, right_node in zip(n.ops, n.comparators):
            if isinstance(op, (ast.In, ast.NotIn)):
                if not isinstance(right_node, (ast.Tuple, ast.List, ast.Set)) or not right_node.elts:
                    raise _SyntaxProblem("'in' needs a literal tuple such as ('a', 'b')")
                if left is None:
                    raise _SyntaxProblem("'in' cannot be chained")
                alts = [Compare("==", left, _from_py(x)) for x in right_node.elts]
                part = flat("or", *alts)
                parts.append(Unary("not", part) if isinstance(op, ast.NotIn) else part)
                left = None
                continue
            if type(op) not in _CMP:
                raise _SyntaxProblem(f"operator {type(op).__name__} is not supported")
            if left is None:
                raise _SyntaxProblem("'in' cannot be chained")
            right = _from_py(right_node)
            parts.append(Compare(_CMP[type(op)], left, right))
            left = right
        return flat("and", *parts)
    if isinstance(n, ast.Name):
        low = n.id.lower()
        if low in ("true", "false"):
            return Const(low == "true")
        return Name(n.id)
    if isinstance(n, ast.Attribute) and isinstance(n.value, ast.Name):
        return Name(f"{n.value.id}.{n.attr}")
    if isinstance(n, ast.Constant):
        if isinstance(n.value, (bool, int, str)):
            return Const(n.value)
        raise _SyntaxProblem(f"constant {n.value!r} is not a bool, int or enum name")
    if isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id == "since":
        if len(n.args) != 1 or n.keywords or not isinstance(n.args[0], ast.Name):
            raise _SyntaxProblem("since() takes one environment event's name: since(arrive)")
        return since(n.args[0].id).node
    if isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id in _FUNCS and not n.keywords:
        if len(n.args) != _FUNCS[n.func.id]:
            raise _SyntaxProblem(f"{n.func.id}() takes {_FUNCS[n.func.id]} argument(s)")
        return Call(n.func.id, tuple(_from_py(a) for a in n.args))
    if isinstance(n, ast.IfExp):
        return IfElse(_from_py(n.test), _from_py(n.body), _from_py(n.orelse))
    raise _SyntaxProblem(f"{type(n).__name__} is not part of the expression language")


_PREC = {"or": 1, "and": 2, "not": 3, "cmp": 4, "+": 5, "-": 5, "*": 6, "//": 6, "%": 6, "neg": 7, "atom": 8}


def to_text(e: Expr) -> str:
    """The string syntax of ``e``; ``parse(to_text(e)) == e`` for parser-made trees."""
    return _text(e)[0]


def _text(e: Expr) -> tuple[str, int]:
    def wrap(sub: Expr, prec: int, strict: bool = False) -> str:
        t, p = _text(sub)
        return f"({t})" if p < prec or (strict and p == prec) else t

    if isinstance(e, Const):
        if isinstance(e.value, bool):
            return ("true" if e.value else "false"), _PREC["atom"]
        if isinstance(e.value, str):
            return repr(e.value), _PREC["atom"]
        text = str(e.value) if abs(e.value).bit_length() < 4000 else hex(e.value)  # str() refuses > 4300 digits
        return text, (_PREC["atom"] if e.value >= 0 else _PREC["neg"])
    if isinstance(e, Name):
        return e.id, _PREC["atom"]
    if isinstance(e, Unary):
        if e.op == "not":
            return "not " + wrap(e.arg, _PREC["not"]), _PREC["not"]
        return "-" + wrap(e.arg, _PREC["neg"], True), _PREC["neg"]
    if isinstance(e, BoolOp):
        p = _PREC[e.op]
        return f" {e.op} ".join(wrap(a, p, True) for a in e.args), p
    if isinstance(e, Compare):
        p = _PREC["cmp"]
        return f"{wrap(e.left, p, True)} {e.op} {wrap(e.right, p, True)}", p
    if isinstance(e, BinOp):
        p = _PREC[e.op]
        return f"{wrap(e.left, p)} {e.op} {wrap(e.right, p, True)}", p
    if isinstance(e, Call):
        return f"{e.fn}({', '.join(to_text(a) for a in e.args)})", _PREC["atom"]
    if isinstance(e, IfElse):
        return f"{wrap(e.then, 1, True)} if {wrap(e.cond, 1, True)} else {wrap(e.other, 0)}", 0
    raise TypeError(f"not an expression node: {e!r}")


def names_in(e: "Expr | None") -> frozenset:
    """The variable names ``e`` reads."""
    if e is None:
        return frozenset()
    out, stack = set(), [e]
    while stack:
        x = stack.pop()
        if isinstance(x, Name):
            out.add(x.id)
        else:
            stack.extend(_kids(x))
    return frozenset(out)


# --------------------------------------------------------------------------- types and scopes


@dataclass(frozen=True)
class Type:
    kind: str  # "bool" | "int" | "enum"
    values: tuple = ()

    def __str__(self) -> str:
        return f"enum({', '.join(self.values)})" if self.kind == "enum" else self.kind


BOOL, INT = Type("bool"), Type("int")


@dataclass(frozen=True)
class Slot:
    """Where a name lives in the state vector, its type and (for ints) its bounds."""

    index: int
    type: Type
    lo: int = 0
    hi: int = 1
    writable: bool = True


class Scope(dict):
    """Name -> Slot. Build with ``Scope.of(vars)`` or from a compiled model's layout."""

    @classmethod
    def of(cls, variables, start: int = 0) -> "Scope":
        scope = cls()
        for i, var in enumerate(variables, start):
            scope[var.name] = Slot(i, Type(var.kind, var.values) if var.kind == "enum" else Type(var.kind), var.lo, var.hi)
        return scope


def check(e: Expr, scope: Mapping[str, Slot], element: str, expected: "Type | None" = None) -> Type:
    """Type-check ``e``; return its type. Unknown names, type errors and out-of-domain
    constants raise ModelError naming ``element``."""
    if not isinstance(e, Expr):
        raise ModelError(element, f"not an expression: {type(e).__name__}")
    if depth(e) > MAX_DEPTH:
        raise ModelError(element, f"expression nested too deeply (limit {MAX_DEPTH})")
    bad = _malformed(e)
    if bad:
        raise ModelError(element, f"malformed expression: {bad}")
    try:
        t = _check(e, scope, expected)
        _ranges(e, scope, t)
        return t
    except _SyntaxProblem as exc:
        raise ModelError(element, f"{exc} in {_shown(to_text(e))}") from None


_OPS = {Unary: ("not", "-"), BoolOp: ("and", "or"), Compare: tuple(_CMP.values()), BinOp: tuple(_ARITH.values())}


def _malformed(e: Expr) -> "str | None":
    """What is wrong with a tree built by hand (an unknown operator, a wrong arity, a
    constant that is not bool/int/str...), or None. Parser-made trees are well formed."""
    stack: list = [e]
    while stack:
        x = stack.pop()
        if type(x) in _OPS and x.op not in _OPS[type(x)]:
            return f"unknown {type(x).__name__} operator {str(x.op)[:20]!r}"
        if isinstance(x, Const) and not isinstance(x.value, (bool, int, str)):
            return f"constant of type {type(x.value).__name__}"
        if isinstance(x, Name) and not isinstance(x.id, str):
            return f"name of type {type(x.id).__name__}"
        if isinstance(x, (BoolOp, Call)) and not isinstance(x.args, tuple):
            return f"{type(x).__name__} arguments are not a tuple"
        if isinstance(x, BoolOp) and len(x.args) < 1:
            return "'and'/'or' without operands"
        if isinstance(x, Call) and (x.fn not in _FUNCS or len(x.args) != _FUNCS[x.fn]):
            return f"unknown call {str(x.fn)[:20]!r} with {len(x.args)} argument(s)"
        if not isinstance(x, (Const, Name, Unary, BoolOp, Compare, BinOp, Call, IfElse)):
            return f"{type(x).__name__} is not an expression node"
        kids = _kids(x)
        if not all(isinstance(k, Expr) for k in kids):
            return f"an operand of {type(x).__name__} is not an expression"
        stack.extend(kids)
    return None


def int_range(e: Expr, scope: Mapping[str, Slot]) -> "tuple[int, int]":
    """The values a checked int expression can take, by interval arithmetic over the
    bounds of its variables (a superset of the exact range).

    >>> from btfsm.world import Int
    >>> int_range(parse("n * 3 - 1"), Scope.of([Int("n", 0, 4)]))
    (-1, 11)
    """
    return _ranges(e, scope, INT)


def _ranges(e: Expr, scope, t: "Type | None"):
    """(lo, hi) of an int expression (None for others); raise _SyntaxProblem when a
    constant, a bound or an intermediate value may leave -INT_LIMIT..INT_LIMIT."""
    if isinstance(e, Const):
        if type(e.value) is int:
            r = (e.value, e.value)
        else:
            return None
    elif isinstance(e, Name):
        slot = scope.get(e.id)
        if slot is None or slot.type != INT:
            return None
        r = (slot.lo, slot.hi)
    elif isinstance(e, Unary):
        a = _ranges(e.arg, scope, None)
        if e.op == "not" or a is None:
            return None
        r = (-a[1], -a[0])
    elif isinstance(e, BinOp):
        a, b = _ranges(e.left, scope, INT), _ranges(e.right, scope, INT)
        if a is None or b is None:
            return None
        if e.op == "+":
            r = (a[0] + b[0], a[1] + b[1])
        elif e.op == "-":
            r = (a[0] - b[1], a[1] - b[0])
        elif e.op == "*":
            p = (a[0] * b[0], a[0] * b[1], a[1] * b[0], a[1] * b[1])
            r = (min(p), max(p))
        elif e.op == "//":  # checked: a positive constant divisor
            r = (a[0] // b[0], a[1] // b[0])
        else:
            r = (0, b[0] - 1)
    elif isinstance(e, Call):
        rs = [_ranges(x, scope, INT) for x in e.args]
        if any(x is None for x in rs):
            return None
        if e.fn == "abs":
            lo, hi = rs[0]
            r = (lo, hi) if lo >= 0 else (-hi, -lo) if hi <= 0 else (0, max(-lo, hi))
        elif e.fn == "min":
            r = (min(rs[0][0], rs[1][0]), min(rs[0][1], rs[1][1]))
        else:
            r = (max(rs[0][0], rs[1][0]), max(rs[0][1], rs[1][1]))
    elif isinstance(e, IfElse):
        _ranges(e.cond, scope, BOOL)
        a, b = _ranges(e.then, scope, None), _ranges(e.other, scope, None)
        if a is None or b is None:
            return None
        r = (min(a[0], b[0]), max(a[1], b[1]))
    else:
        for k in _kids(e):
            _ranges(k, scope, None)
        return None
    if r[0] < -INT_LIMIT or r[1] > INT_LIMIT:
        far = r[0] if r[0] < -INT_LIMIT else r[1]
        what = f"constant {int_text(far)}" if isinstance(e, Const) else f"'{_shown(to_text(e))[1:-1]}' can reach {int_text(far)}"
        raise _SyntaxProblem(f"{what}: int values must stay within -2**53..2**53")
    return r


def _check(e: Expr, scope, expected: "Type | None") -> Type:
    if isinstance(e, Const):
        if isinstance(e.value, bool):
            return BOOL
        if isinstance(e.value, int):
            return INT
        if expected is not None and expected.kind == "enum":
            if e.value not in expected.values:
                raise _SyntaxProblem(f"'{e.value}' is not one of {', '.join(expected.values)}")
            return expected
        raise _SyntaxProblem(f"'{e.value}' can only be compared with or assigned to an enum")
    if isinstance(e, Name):
        slot = scope.get(e.id)
        if slot is None and e.id.startswith("since("):
            raise _SyntaxProblem(f"{e.id}: no environment event {e.id[6:-1]!r} with a min_interval of 2 ticks or more "
                                 "(since() reads the ticks since it last happened, docs/semantics.md 7)")
        if slot is None:
            hint = " (quote enum values: 'name')" if expected is not None and expected.kind == "enum" else ""
            raise _SyntaxProblem(f"unknown name '{e.id}'{hint}")
        return slot.type
    if isinstance(e, Unary):
        if e.op == "not":
            _want(_check(e.arg, scope, BOOL), BOOL, e.arg)
            return BOOL
        _want(_check(e.arg, scope, INT), INT, e.arg)
        return INT
    if isinstance(e, BoolOp):
        for a in e.args:
            _want(_check(a, scope, BOOL), BOOL, a)
        return BOOL
    if isinstance(e, Compare):
        lt = None if _is_literal(e.left) else _check(e.left, scope, None)
        rt = _check(e.right, scope, lt)
        if lt is None:
            lt = _check(e.left, scope, rt)
        if lt != rt:
            raise _SyntaxProblem(f"cannot compare {lt} with {rt}")
        if e.op not in ("==", "!=") and lt != INT:
            raise _SyntaxProblem(f"'{e.op}' needs ints, got {lt}")
        _check_in_domain(e.left, e.right, scope)
        _check_in_domain(e.right, e.left, scope)
        return BOOL
    if isinstance(e, BinOp):
        _want(_check(e.left, scope, INT), INT, e.left)
        _want(_check(e.right, scope, INT), INT, e.right)
        if e.op in ("//", "%") and not (isinstance(e.right, Const) and type(e.right.value) is int and e.right.value > 0):
            raise _SyntaxProblem(f"'{e.op}' needs a positive integer constant on its right")
        return INT
    if isinstance(e, Call):
        for a in e.args:
            _want(_check(a, scope, INT), INT, a)
        return INT
    if isinstance(e, IfElse):
        _want(_check(e.cond, scope, BOOL), BOOL, e.cond)
        a = None if _is_literal(e.then) else _check(e.then, scope, expected)
        b = _check(e.other, scope, a or expected)
        a = a or _check(e.then, scope, b)
        if a != b:
            raise _SyntaxProblem(f"branches have different types {a} and {b}")
        return a
    raise _SyntaxProblem(f"not an expression: {e!r}")


def _is_literal(e: Expr) -> bool:
    """An enum literal, or a choice between enum literals: its type comes from context."""
    if isinstance(e, IfElse):
        return _is_literal(e.then) and _is_literal(e.other)
    return isinstance(e, Const) and isinstance(e.value, str)


def _want(got: Type, want: Type, e: Expr) -> None:
    if got != want:
        raise _SyntaxProblem(f"'{to_text(e)}' is {got}, expected {want}")


def _check_in_domain(var_side: Expr, const_side: Expr, scope) -> None:
    # a negated constant counts as the constant it denotes (the parser folds ``-4`` to one)
    while (isinstance(const_side, Unary) and const_side.op == "-" and isinstance(const_side.arg, Const)
           and type(const_side.arg.value) is int):
        const_side = Const(-const_side.arg.value)
    if isinstance(var_side, Name) and isinstance(const_side, Const) and type(const_side.value) is int:
        slot = scope[var_side.id]
        if slot.type == INT and not slot.lo <= const_side.value <= slot.hi:
            raise _SyntaxProblem(f"constant {int_text(const_side.value)} is outside the domain of {var_side.id} ({slot.lo}..{slot.hi})")


def check_effects(effects, scope: Mapping[str, Slot], element: str) -> None:
    """Check ``((var, expr), ...)``: known writable targets, each once, matching types."""
    seen = set()
    for name, value in effects:
        where = f"{element}.{name}"
        slot = scope.get(name)
        if slot is None:
            raise ModelError(where, f"unknown variable '{name}'")
        if not slot.writable:
            raise ModelError(where, f"'{name}' cannot be assigned")
        if name in seen:
            raise ModelError(where, f"'{name}' is assigned twice")
        seen.add(name)
        got = check(value, scope, where, slot.type)
        if got != slot.type:
            raise ModelError(where, f"assigns {got} to {name}, which is {slot.type}")
        if isinstance(value, Const) and type(value.value) is int and slot.type == INT and not slot.lo <= value.value <= slot.hi:
            raise ModelError(where, f"constant {int_text(value.value)} is outside the domain of {name} ({slot.lo}..{slot.hi})")


# --------------------------------------------------------------------------- translations


def to_python_source(e: Expr, scope: Mapping[str, Slot], col: str = "s") -> str:
    """Python source reading slots as ``s[i]`` (checked ``e`` only; holds no user text)."""
    return _src(e, scope, col, None)


def _src(e: Expr, scope, col: str, expected: "Type | None") -> str:
    if isinstance(e, Const):
        if isinstance(e.value, bool):
            return "True" if e.value else "False"
        if isinstance(e.value, int):
            return str(int(e.value))
        return str(cast(Type, expected).values.index(e.value))  # enum literal, checked
    if isinstance(e, Name):
        slot = scope[e.id]
        return f"{col}[{int(slot.index)}]"
    if isinstance(e, Unary):
        return f"(not {_src(e.arg, scope, col, BOOL)})" if e.op == "not" else f"(-{_src(e.arg, scope, col, INT)})"
    if isinstance(e, BoolOp):
        return "(" + f" {e.op} ".join(_src(a, scope, col, BOOL) for a in e.args) + ")"
    if isinstance(e, Compare):
        lt, rt = _types(e.left, e.right, scope)
        return f"({_src(e.left, scope, col, lt)} {e.op} {_src(e.right, scope, col, rt)})"
    if isinstance(e, BinOp):
        return f"({_src(e.left, scope, col, INT)} {e.op} {_src(e.right, scope, col, INT)})"
    if isinstance(e, Call):
        return f"{e.fn}({', '.join(_src(a, scope, col, INT) for a in e.args)})"
    if isinstance(e, IfElse):
        return f"({_src(e.then, scope, col, expected)} if {_src(e.cond, scope, col, BOOL)} else {_src(e.other, scope, col, expected)})"
    raise TypeError(e)


def _types(a: Expr, b: Expr, scope) -> tuple:
    """The types both sides of a checked comparison resolve to (enum literals included)."""
    ta = None if _is_literal(a) else _check(a, scope, None)
    tb = _check(b, scope, ta)
    return (ta or tb), tb


_SAFE_BUILTINS = {"__builtins__": {}, "min": min, "max": max, "abs": abs}


def compile_fn(e: Expr, scope: Mapping[str, Slot], element: str, expected: "Type | None" = None):
    """Check ``e`` and return ``f(state_list) -> value``. A bool result is truthy or falsy
    (a Python bool, or a stored 0/1 when ``e`` is a bare bool variable)."""
    t = check(e, scope, element, expected)
    if expected is not None and t != expected:
        raise ModelError(element, f"'{to_text(e)}' is {t}, expected {expected}")
    src = _src(e, scope, "s", t)
    return eval(f"lambda s: {src}", dict(_SAFE_BUILTINS))  # noqa: S307 - generated from a checked AST


def compile_effects(effects, scope: Mapping[str, Slot], element: str, names: "Mapping[int, str] | None" = None):
    """Check ``((var, expr), ...)`` and return ``apply(s)`` that assigns all of them at once
    (right-hand sides read the state before any write) and raises DomainError out of domain.
    Returns None for no effects."""
    check_effects(effects, scope, element)
    if not effects:
        return None
    lines, writes = ["def _apply(s):"], []
    for k, (name, value) in enumerate(effects):
        slot = scope[name]
        src = _src(value, scope, "s", slot.type)
        if slot.type == BOOL:
            src = f"(1 if {src} else 0)"
        lines.append(f"    v{k} = {src}")
        if slot.type == INT:
            lines.append(f"    if not {int(slot.lo)} <= v{k} <= {int(slot.hi)}: _err({k}, v{k})")
        writes.append(f"    s[{int(slot.index)}] = v{k}")
    lines += writes
    targets = [name for name, _ in effects]

    def _err(k: int, value: int):
        raise DomainError(targets[k], value, element)

    ns = dict(_SAFE_BUILTINS, _err=_err)
    exec("\n".join(lines), ns)  # noqa: S102 - generated from a checked AST, no user text
    fn: Any = ns["_apply"]
    fn.targets = tuple(scope[n].index for n in targets)
    return fn


def to_numpy_source(e: Expr, scope: Mapping[str, Slot], col: str = "c", expected: "Type | None" = None) -> str:
    """numpy source over columns ``c[i]`` (int arrays); bools are bool arrays.
    ``expected``: the type an enum literal resolves to (e.g. an effect on an enum).
    Evaluate with ``{"np": numpy, "c": columns}``."""
    return _np(e, scope, col, check(e, scope, "numpy", expected))


def _np(e: Expr, scope, col: str, expected) -> str:
    if isinstance(e, Const):
        return _src(e, scope, col, expected)
    if isinstance(e, Name):
        slot = scope[e.id]
        ref = f"{col}[{int(slot.index)}]"
        return f"({ref} != 0)" if slot.type == BOOL else ref
    if isinstance(e, Unary):
        return f"np.logical_not({_np(e.arg, scope, col, BOOL)})" if e.op == "not" else f"(-{_np(e.arg, scope, col, INT)})"
    if isinstance(e, BoolOp):
        return "(" + (" & " if e.op == "and" else " | ").join(_np(a, scope, col, BOOL) for a in e.args) + ")"
    if isinstance(e, Compare):
        lt, rt = _types(e.left, e.right, scope)
        return f"({_np(e.left, scope, col, lt)} {e.op} {_np(e.right, scope, col, rt)})"
    if isinstance(e, BinOp):
        return f"({_np(e.left, scope, col, INT)} {e.op} {_np(e.right, scope, col, INT)})"
    if isinstance(e, Call):
        fn = {"min": "np.minimum", "max": "np.maximum", "abs": "np.abs"}[e.fn]
        return f"{fn}({', '.join(_np(a, scope, col, INT) for a in e.args)})"
    if isinstance(e, IfElse):
        return f"np.where({_np(e.cond, scope, col, BOOL)}, {_np(e.then, scope, col, expected)}, {_np(e.other, scope, col, expected)})"
    raise TypeError(e)


def to_z3(e: Expr, scope: Mapping[str, Slot], z3vars: Mapping[str, Any]):
    """A z3 term for ``e``; ``z3vars`` maps each name to a z3 Int (bools are ints 0/1).
    Constants are made in the z3 context of the variables (the main one without any)."""
    import z3

    ctx = next((v.ctx for v in z3vars.values()), None)
    return _z3(e, scope, z3vars, check(e, scope, "z3"), z3, ctx)


def _z3(e: Expr, scope, zv, expected, z3, ctx):
    if isinstance(e, Const):
        if isinstance(e.value, bool):
            return z3.BoolVal(e.value, ctx)
        if isinstance(e.value, int):
            return z3.IntVal(e.value, ctx)
        return z3.IntVal(expected.values.index(e.value), ctx)
    if isinstance(e, Name):
        return zv[e.id] == 1 if scope[e.id].type == BOOL else zv[e.id]
    if isinstance(e, Unary):
        return z3.Not(_z3(e.arg, scope, zv, BOOL, z3, ctx)) if e.op == "not" else -_z3(e.arg, scope, zv, INT, z3, ctx)
    if isinstance(e, BoolOp):
        args = [_z3(a, scope, zv, BOOL, z3, ctx) for a in e.args]
        return z3.And(*args) if e.op == "and" else z3.Or(*args)
    if isinstance(e, Compare):
        lt, rt = _types(e.left, e.right, scope)
        a, b = _z3(e.left, scope, zv, lt, z3, ctx), _z3(e.right, scope, zv, rt, z3, ctx)
        return {"==": lambda: a == b, "!=": lambda: a != b, "<": lambda: a < b,
                "<=": lambda: a <= b, ">": lambda: a > b, ">=": lambda: a >= b}[e.op]()
    if isinstance(e, BinOp):
        a, b = _z3(e.left, scope, zv, INT, z3, ctx), _z3(e.right, scope, zv, INT, z3, ctx)
        return {"+": lambda: a + b, "-": lambda: a - b, "*": lambda: a * b,
                "//": lambda: a / b, "%": lambda: a % b}[e.op]()
    if isinstance(e, Call):
        args = [_z3(a, scope, zv, INT, z3, ctx) for a in e.args]
        if e.fn == "abs":
            return z3.If(args[0] >= 0, args[0], -args[0])
        a, b = args
        return z3.If(a <= b, a, b) if e.fn == "min" else z3.If(a >= b, a, b)
    if isinstance(e, IfElse):
        return z3.If(_z3(e.cond, scope, zv, BOOL, z3, ctx), _z3(e.then, scope, zv, expected, z3, ctx), _z3(e.other, scope, zv, expected, z3, ctx))
    raise TypeError(e)
