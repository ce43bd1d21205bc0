"""Every ``btfsm.NAME...`` that a docstring or comment of the product names between double
backquotes exists: a module, or a name that module defines or imports (for a class, and a
name its body defines). Read from the source (ast), nothing is imported."""
from __future__ import annotations

import ast
import re
from functools import lru_cache
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = {"btfsm": ROOT / "btfsm", "btfsm.verify": ROOT / "verify", "btfsm.models": ROOT / "models",
            "btfsm.sim": ROOT / "sim"}
REF = re.compile(r"``(btfsm(?:\.[A-Za-z_][A-Za-z0-9_]*)+)``")


def _path(module: str) -> "Path | None":
    for pkg, folder in sorted(PACKAGES.items(), key=lambda kv: -len(kv[0])):
        if module == pkg or module.startswith(pkg + "."):
            base = folder.joinpath(*module[len(pkg):].split(".")[1:])
            for p in (base / "__init__.py", base.with_suffix(".py")):
                if p.is_file():
                    return p
            return None
    return None


def _names(body) -> set:
    out = set()
    for node in body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            out.add(node.name)
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            out.update((a.asname or a.name).split(".")[0] for a in node.names)
        elif isinstance(node, (ast.Assign, ast.AnnAssign, ast.AugAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            out.update(n.id for t in targets for n in ast.walk(t) if isinstance(n, ast.Name))
        elif isinstance(node, (ast.If, ast.Try, ast.With)):
            out |= _names(node.body) | _names(getattr(node, "orelse", []))
            for h in getattr(node, "handlers", []):
                out |= _names(h.body)
    return out


@lru_cache(maxsize=None)
def _tree(path: Path) -> ast.Module:
    return ast.parse(path.read_text(encoding="utf-8"))


def _resolves(name: str) -> bool:
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        path = _path(".".join(parts[:i]))
        if path is None:
            continue
        rest, body = parts[i:], _tree(path).body
        if not rest:
            return True
        if rest[0] not in _names(body):
            return False
        cls = next((n for n in body if isinstance(n, ast.ClassDef) and n.name == rest[0]), None)
        return len(rest) == 1 or cls is None or rest[1] in _names(cls.body) | {
            t.attr for n in ast.walk(cls) if isinstance(n, (ast.Assign, ast.AnnAssign))
            for t in (n.targets if isinstance(n, ast.Assign) else [n.target]) if isinstance(t, ast.Attribute)}
    return False


def test_named_btfsm_objects_exist():
    refs = {(str(p.relative_to(ROOT)), m.group(1)) for folder in PACKAGES.values()
            for p in folder.rglob("*.py") for m in REF.finditer(p.read_text(encoding="utf-8"))}
    assert len(refs) > 100
    assert sorted((f, name) for f, name in refs if not _resolves(name)) == []
