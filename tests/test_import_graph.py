"""The import graph of btfsm: data flows one way.

Every import between btfsm's own modules (at the top of a file or inside a function)
is an edge; the graph has no cycle, and no module imports another module's private
(underscore) names. Imports under ``if TYPE_CHECKING:`` are not edges: they never run
(the type checker reads them), so a Protocol's module may name the types of its
arguments (``btfsm.oracles.Oracle`` takes a ``btfsm.semantics.Site``) and its users
may name the Protocol.
"""
from __future__ import annotations

import ast
from functools import lru_cache
from pathlib import Path

import networkx as nx

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = {"btfsm": ROOT / "btfsm", "btfsm.verify": ROOT / "verify", "btfsm.models": ROOT / "models",
            "btfsm.sim": ROOT / "sim"}


def _modules():
    out = {}
    for pkg, folder in PACKAGES.items():
        for path in folder.rglob("*.py"):
            rel = path.relative_to(folder).with_suffix("")
            parts = [p for p in rel.parts if p != "__init__"]
            name = ".".join([pkg, *parts])
            out[name] = (path, path.name == "__init__.py")
    return out


MODULES = _modules()


def _resolve(module, is_pkg, node):
    if node.level == 0:
        return node.module or ""
    base = module.split(".") if is_pkg else module.split(".")[:-1]
    base = base[: len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def _own(name):
    """The btfsm module an import names (the longest known prefix), or None."""
    while name:
        if name in MODULES:
            return name
        name = name.rpartition(".")[0]
    return None


def _type_checking_only(tree) -> set:
    """The import nodes inside the module's ``if TYPE_CHECKING:`` (or
    ``typing.TYPE_CHECKING``) blocks (at its top level, where such blocks are)."""
    out = set()
    for node in tree.body:
        if isinstance(node, ast.If) and ast.unparse(node.test) in ("TYPE_CHECKING", "typing.TYPE_CHECKING"):
            for stmt in node.body:
                out.update(id(n) for n in ast.walk(stmt) if isinstance(n, (ast.Import, ast.ImportFrom)))
    return out


@lru_cache(maxsize=None)  # the sources do not change while the tests run: parsed once
def import_edges() -> tuple:
    """(importer, imported, names) for every import between btfsm's own modules that runs."""
    edges = []
    for module, (path, is_pkg) in MODULES.items():
        tree = ast.parse(path.read_text(), str(path))
        skip = _type_checking_only(tree)
        for node in ast.walk(tree):
            if id(node) in skip:
                continue
            if isinstance(node, ast.Import):
                for alias in node.names:
                    target = _own(alias.name)
                    if target and target != module:
                        edges.append((module, target, ()))
            elif isinstance(node, ast.ImportFrom):
                base = _resolve(module, is_pkg, node)
                for alias in node.names:
                    sub = f"{base}.{alias.name}"
                    if sub in MODULES:  # from package import submodule
                        edges.append((module, sub, ()))
                    elif _own(base) and _own(base) != module:
                        edges.append((module, _own(base), (alias.name,)))
    return tuple(edges)


def test_the_walk_sees_the_known_edges():
    edges = {(a, b) for a, b, _ in import_edges()}
    assert ("btfsm.verify.promela", "btfsm.verify.stepspec") in edges
    assert ("btfsm.sim.trial", "btfsm.sim.protocol") in edges
    assert len(MODULES) > 50


def test_type_checking_imports_are_not_edges():
    tree = ast.parse("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .semantics import Site\n"
                     "import json\n")
    skipped = _type_checking_only(tree)
    kinds = [(type(n).__name__, id(n) in skipped) for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom))]
    assert sorted(kinds) == [("Import", False), ("ImportFrom", False), ("ImportFrom", True)]


def test_no_import_cycles():
    g = nx.DiGraph()
    g.add_edges_from((a, b) for a, b, _ in import_edges())
    cycles = [sorted(c) for c in nx.strongly_connected_components(g) if len(c) > 1]
    assert cycles == []


def test_no_private_names_imported_across_modules():
    bad = [(a, b, n) for a, b, names in import_edges() for n in names if n.startswith("_") and n != "__version__"]
    assert bad == []
