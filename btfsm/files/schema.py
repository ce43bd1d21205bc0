"""The node part of the model-file JSON Schema (``btfsm/schema/model.schema.json``),
generated from the node classes (``btfsm.bt``): one ``node_TYPE`` definition per node
type and the ``node`` definition that picks one by its type key.

``python -m btfsm.files.schema`` writes them into the shipped schema file;
tests/test_nodes.py checks that the file holds exactly what this module generates.
"""
from __future__ import annotations

import json
from pathlib import Path

from ..bt import NODE_TYPES, Composite, Decorator, file_fields
from .reading import node_required

__all__ = ["node_definitions", "shipped_node_definitions", "SCHEMA_FILE", "write_schema"]

SCHEMA_FILE = Path(__file__).resolve().parent.parent / "schema" / "model.schema.json"

#: node field kind (``btfsm.bt.FILE_KINDS``) -> the JSON Schema of its value
_KIND_SCHEMA: dict[str, dict] = {
    "int": {"type": "integer"}, "opt_int": {"type": ["integer", "null"]},
    "bool": {"type": "boolean"}, "opt_bool": {"type": ["boolean", "null"]},
    "string": {"type": "string"},
    "names": {"type": ["array", "string", "null"], "items": {"type": "string"}},
    "expr": {"$ref": "#/$defs/expr"}, "opt_expr": {"$ref": "#/$defs/opt_expr"},
    "effects": {"$ref": "#/$defs/effects"},
    "outcomes": {"anyOf": [{"$ref": "#/$defs/outcomes"}, {"type": "null"}]},
    "args": {"$ref": "#/$defs/args"}, "duration": {"$ref": "#/$defs/duration"},
    "params": {"type": ["object", "null"], "additionalProperties": {"$ref": "#/$defs/expr"}},
}


def _description(cls) -> str:
    """The first sentence of the class's docstring, on one line."""
    text = " ".join((cls.__doc__ or cls.__name__).split())
    return text.split(". ")[0].rstrip(".")


def node_definitions() -> dict:
    """``$defs`` entries: ``node`` and ``node_TYPE`` for every type in ``NODE_TYPES``."""
    out: dict = {"node": {
        "description": "A tree node: exactly one key naming its type (whose value is the node's name), plus that type's fields.",
        "type": "object",
        "oneOf": [{"required": [key]} for key in NODE_TYPES],
        "allOf": [{"if": {"required": [key]}, "then": {"$ref": f"#/$defs/node_{key}"}} for key in NODE_TYPES],
    }}
    for key, cls in NODE_TYPES.items():
        props: dict = {key: {"type": "string", "minLength": 1}}
        for f in file_fields(cls):
            props[f.name] = {**_KIND_SCHEMA[f.metadata["file"]], **f.metadata["schema"]}
            if f.metadata["doc"]:
                props[f.name]["description"] = f.metadata["doc"]
        if issubclass(cls, Composite):
            lo, hi = cls.arity
            kids: dict = {"type": "array", "items": {"anyOf": [{"$ref": "#/$defs/node"}, {"$ref": "#/$defs/use_in_list"}]}}
            if lo:
                kids["minItems"] = lo
            if hi is not None:
                kids["maxItems"] = hi
            props["children"] = kids
        elif issubclass(cls, Decorator):
            props["child"] = {"$ref": "#/$defs/node_or_use"}
        out[f"node_{key}"] = {"title": key, "description": _description(cls), "type": "object",
                              "required": [key, *node_required(cls)], "additionalProperties": False,
                              "properties": props}
    return out


def _generated(key: str) -> bool:
    """Whether ``$defs[key]`` is a definition this module generates (``node``, ``node_TYPE``)."""
    return key == "node" or (key.startswith("node_") and key[5:6].isupper())


def write_schema(path: Path = SCHEMA_FILE) -> None:
    """Replace the node definitions in the schema file at ``path`` by the generated ones."""
    schema = json.loads(path.read_text(encoding="utf-8"))
    defs = {k: v for k, v in schema["$defs"].items() if not _generated(k)}
    generated = node_definitions()
    first = list(schema["$defs"]).index("node")  # the node definitions stay where they were
    items = list(defs.items())
    schema["$defs"] = dict(items[:first] + list(generated.items()) + items[first:])
    path.write_text(json.dumps(schema, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")


def shipped_node_definitions(path: Path = SCHEMA_FILE) -> dict:
    """The node definitions the schema file at ``path`` holds (to compare with ``node_definitions``)."""
    defs = json.loads(path.read_text(encoding="utf-8"))["$defs"]
    return {k: v for k, v in defs.items() if _generated(k)}


if __name__ == "__main__":
    write_schema()
