"""Groot2 node models: ``<TreeNodesModel>`` read as the source of port kinds, directions and types.

A node model file (Groot2's palette, or Nav2's ``nav2_tree_nodes.xml``) is a ``<root>`` with
one or more ``<TreeNodesModel>``; each entry is ``<Action|Condition|Control|Decorator|SubTree
ID="...">`` with ports ``<input_port>``, ``<output_port>``, ``<inout_port>`` or
``<bidirectional_port>`` (BehaviorTree.CPP 3's name for inout, which Nav2's file still uses),
each with ``name``, ``type``, ``default`` and its description as text, and an optional
``<description>`` or ``<MetadataFields>``. ``read_models`` turns one ``<TreeNodesModel>``
element into ``{ID: NodeModel}``; ``models_of_document`` reads a whole file (the same XML
limits and refusals as the tree reader: no DTD, no entities) (parsed by ``btcpp_import.parse_xml``).

>>> from btfsm.interop.btcpp_import import parse_xml
>>> el = parse_xml(b'<root BTCPP_format="4"><TreeNodesModel><Control ID="P">'
...                b'<bidirectional_port name="i" type="int">the index</bidirectional_port>'
...                b'</Control></TreeNodesModel></root>', "m.xml")
>>> m = read_models(el.children[0], "m.xml")["P"]
>>> m.kind, m.ports["i"].direction, m.ports["i"].type
('Control', 'inout', 'int')
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ..errors import ModelError

__all__ = ["Port", "NodeModel", "read_models", "models_of_document", "PORT_TAGS", "MODEL_KINDS"]

#: port element -> direction
PORT_TAGS = {"input_port": "input", "output_port": "output", "inout_port": "inout", "bidirectional_port": "inout"}
MODEL_KINDS = ("Action", "Condition", "Control", "Decorator", "SubTree")


@dataclass(frozen=True)
class Port:
    direction: str  # input, output, inout
    type: str = ""
    default: "str | None" = None


@dataclass(frozen=True)
class NodeModel:
    kind: str
    ports: dict = field(default_factory=dict)  # name -> Port
    description: str = ""
    element: object = None  # the XML element (for error lines)
    file: str = ""

    def as_tuple(self) -> tuple:
        """The importer's form: (kind, {port: (direction, type, default)}, description, element)."""
        return (self.kind, {k: (p.direction, p.type, p.default) for k, p in self.ports.items()},
                self.description, self.element)


def read_models(tnm, file: str) -> dict:
    """``{ID: NodeModel}`` of one ``<TreeNodesModel>`` element; a ModelError (file, line,
    element) for anything that is not a node model."""
    out: dict = {}
    for el in tnm.children:
        if el.tag not in MODEL_KINDS:
            raise ModelError(el.where(), f"unknown element in TreeNodesModel (expected {', '.join(MODEL_KINDS)})", file)
        ident = el.attrs.get("ID")
        if not ident:
            raise ModelError(el.where(), "a TreeNodesModel entry needs an ID", file)
        ports, desc = {}, el.attrs.get("description", "")
        for p in el.children:
            if p.tag in PORT_TAGS:
                pname = p.attrs.get("name")
                if not pname:
                    raise ModelError(p.where(), "a port needs a name", file)
                ports[pname] = Port(PORT_TAGS[p.tag], p.attrs.get("type", ""), p.attrs.get("default"))
            elif p.tag == "description":
                desc = p.text.strip()
            elif p.tag != "MetadataFields":
                raise ModelError(p.where(), "unknown element in a node model (expected input_port, output_port, "
                                            "inout_port, bidirectional_port, description)", file)
        if ident in out:
            raise ModelError(el.where(), f"node model '{ident}' is defined twice (first at line {out[ident].element.line})",
                             file)
        out[ident] = NodeModel(el.tag, ports, desc, el, file)
    return out


def models_of_document(root, shown: str) -> dict:
    """``{ID: NodeModel}`` of every ``<TreeNodesModel>`` of a node model file (Groot2's
    palette export, Nav2's ``nav2_tree_nodes.xml``), given its parsed root element
    (``btcpp_import.parse_xml``; ``btfsm.files.load_xml_model`` reads them from the paths its ``nodes`` name).
    BehaviorTrees in it are not read."""
    if root.tag != "root":
        raise ModelError(root.where(), "expected <root> as the document element of a node model file", shown)
    out: dict = {}
    found = False
    for el in root.children:
        if el.tag == "TreeNodesModel":
            found = True
            out.update(read_models(el, shown))
    if not found:
        raise ModelError(root.where(), "no <TreeNodesModel> in the file (a node model file is what Groot2 exports "
                                       "as its palette)", shown)
    return out
