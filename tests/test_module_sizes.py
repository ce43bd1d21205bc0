"""No module of the product is over 1,000 lines unless its own docstring says why (the
words "more than 1,000 lines" and the reason after them)."""
from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LIMIT = 1000


def test_long_modules_say_why():
    long = {}
    for folder in ("btfsm", "verify", "sim", "models"):
        for p in (ROOT / folder).rglob("*.py"):
            text = p.read_text(encoding="utf-8")
            if text.count("\n") > LIMIT:
                long[str(p.relative_to(ROOT))] = "more than 1,000 lines" in (ast.get_docstring(ast.parse(text)) or "")
    assert long and [name for name, says in long.items() if not says] == []
