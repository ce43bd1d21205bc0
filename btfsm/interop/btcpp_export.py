"""A btfsm model's tree as BehaviorTree.CPP XML v4 (what ``btfsm export --format btcpp``
writes).

``to_btcpp_xml(model) -> str``: one ``<BehaviorTree>`` (ID: the model's name, also
``main_tree_to_execute``) and a ``<TreeNodesModel>`` declaring every leaf ID, so
BehaviorTree.CPP and Groot2 load it once the leaves are registered. The node mapping
(docs/semantics.md section 8.1):

* controls: ``MemorySequence`` -> ``Sequence``, ``SequenceWithMemory``,
  ``ReactiveSequence``, ``MemoryFallback`` -> ``Fallback``, ``ReactiveFallback``,
  ``Parallel`` -> ``Parallel success_count failure_count`` (all children: -1),
  ``ParallelAll max_failures``, ``IfThenElse``, ``WhileDoElse``;
* decorators: ``Inverter``, ``ForceSuccess``, ``ForceFailure``, ``Retry`` ->
  ``RetryUntilSuccessful num_attempts``, ``Repeat num_cycles``,
  ``KeepRunningUntilFailure``, ``RunOnce then_skip``;
* ``SubTree`` -> ``<SubTree ID="tree_id" name="node"/>`` and a ``<BehaviorTree ID="tree_id">``
  holding its child (written once per ID; SubTrees of one ID whose children differ get the
  IDs ``tree_id_2``, ``tree_id_3``...);
* leaves are callbacks the user registers by ID, written in the compact form ``<ID
  name="node" .../>`` (BehaviorTree.CPP's parser looks the tag of a ReactiveSequence's
  children up as a registered ID, so ``<Action ID=...>`` is refused there): an ``Action``
  is ``<primitive name="node">`` with its args as input ports; a ``Condition`` is
  ``<node name="node">`` (its btfsm expression is the description of its TreeNodesModel
  entry); a ``SkillRequest`` is ``<node name="node">`` (a stateful action in
  BehaviorTree.CPP). An ID must therefore be an XML name (``[A-Za-z_][A-Za-z0-9_.-]*``):
  anything else is a ModelError naming the node.

``Guard`` and ``Effects`` have no BehaviorTree.CPP counterpart with the same rules: the
export refuses them (``ModelError`` naming the node), as it refuses a model without a tree.
Every name and value is XML-escaped.

>>> from btfsm import Model, ReactiveFallback, Condition, Action, Bool, Primitive
>>> m = Model("demo", variables=[Bool("done")], primitives=[Primitive("work")],
...           tree=ReactiveFallback("root", [Condition("is_done", "done"), Action("work")]))
>>> print(to_btcpp_xml(m), end="")
<?xml version="1.0" encoding="UTF-8"?>
<root BTCPP_format="4" main_tree_to_execute="demo">
  <BehaviorTree ID="demo">
    <ReactiveFallback name="root">
      <is_done name="is_done"/>
      <work name="work"/>
    </ReactiveFallback>
  </BehaviorTree>
  <TreeNodesModel>
    <Condition ID="is_done">
      <description>done</description>
    </Condition>
    <Action ID="work"/>
  </TreeNodesModel>
</root>
"""
from __future__ import annotations

import re

from ..bt import (NODE_TYPES, Action, Composite, Condition, Decorator, Effects, Guard, Parallel, SkillRequest, SubTree,
                  btcpp_tags, file_fields)
from ..errors import ModelError
from ..expr import to_text

__all__ = ["to_btcpp_xml", "xml_attr", "TAGS"]

TAGS = {NODE_TYPES[key]: tag for lib in (None, "nav2") for kind in (Composite, Decorator)
        for tag, (key, _) in btcpp_tags(lib, kind).items()}
"""btfsm node type -> BehaviorTree.CPP XML tag (controls and decorators, BT.CPP's and Nav2's; ``btfsm.bt`` declares them)."""

_XML_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_.-]*\Z")
_ESCAPES = {"&": "&amp;", "<": "&lt;", ">": "&gt;", '"': "&quot;", "'": "&apos;",
            "\n": "&#10;", "\r": "&#13;", "\t": "&#9;"}


def xml_attr(text: object, element: str = "") -> str:
    """``text`` escaped for a double-quoted XML attribute or element content. Characters
    XML 1.0 cannot hold at all are a ModelError naming ``element``.

    >>> xml_attr('a < "b" & \\'c\\'')
    'a &lt; &quot;b&quot; &amp; &apos;c&apos;'
    """
    out = []
    for c in str(text):
        if c in _ESCAPES:
            out.append(_ESCAPES[c])
        elif (ord(c) < 0x20 or 0xD800 <= ord(c) <= 0xDFFF or ord(c) in (0xFFFE, 0xFFFF)):
            raise ModelError(element or "tree", f"character {ord(c):#x} cannot be written in XML")
        else:
            out.append(c)
    return "".join(out)


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (tuple, list)):
        return ";".join(_value(x) for x in v)
    return str(v)


def _port(v, none) -> str:
    """A node field's value as its BT.CPP port value (``none``: BT.CPP's value for None)."""
    return _value(none if v is None else v)


def to_btcpp_xml(model) -> str:
    """The model's tree as a BehaviorTree.CPP XML v4 document (see the module doc)."""
    if model.tree is None:
        raise ModelError("tree", "btcpp export needs a tree; the model has none")
    leaves: dict = {}  # ID -> (kind, ports, description, node name)
    lines: list = []
    trees: dict = {model.name: (lines, None)}  # BehaviorTree ID -> (lines, leaves) (the main tree first)
    _node(model.tree, 2, lines, leaves, trees, facts=_port_facts(model))
    name = xml_attr(model.name, "name")
    out = ['<?xml version="1.0" encoding="UTF-8"?>', f'<root BTCPP_format="4" main_tree_to_execute="{name}">']
    for ident, (body, _) in trees.items():
        out += [f'  <BehaviorTree ID="{xml_attr(ident, "name")}">', *body, "  </BehaviorTree>"]
    out.append("  <TreeNodesModel>")
    for ident, (kind, ports, desc, _) in leaves.items():
        body = [f'      <{d}_port name="{xml_attr(p)}" type="{xml_attr(ty)}"/>' for p, (d, ty) in ports.items()]
        if desc is not None:
            body.append(f"      <description>{xml_attr(desc)}</description>")
        if body:
            out += [f'    <{kind} ID="{xml_attr(ident)}">', *body, f"    </{kind}>"]
        else:
            out.append(f'    <{kind} ID="{xml_attr(ident)}"/>')
    out += ["  </TreeNodesModel>", "</root>"]
    return "\n".join(out) + "\n"


def _port_facts(model):
    """(variable -> C++ type, primitive -> the variables its outcomes write)."""
    types = {}
    for var in model.variables:
        kind = getattr(var, "kind", None) or type(var).__name__.lower()
        types[var.name] = {"bool": "bool", "int": "int"}.get(kind, "std::string")
    writes = {}
    for name, prim in model.all_primitives().items():
        writes[name] = {k for o in prim.outcomes for k, _ in o.effects}
    return types, writes


def _action_port(facts, primitive, value):
    """(direction, C++ type) of an Action's port, as far as the model knows them: a
    blackboard entry ``{var}`` of a world variable is an output port when the primitive's
    outcomes write ``var``, else an input port, typed as the variable (bool, int; an enum
    is a string); a constant is an input port typed by its value."""
    types, writes = facts
    if isinstance(value, str) and value.startswith("{") and value.endswith("}") and value[1:-1] in types:
        var = value[1:-1]
        return ("output" if var in writes.get(primitive, ()) else "input"), types[var]
    if isinstance(value, bool):
        return "input", "bool"
    if isinstance(value, int):
        return "input", "int"
    if isinstance(value, float):
        return "input", "double"
    return "input", "std::string"


def _declare(leaves, ident, kind, ports, desc, node):
    old = leaves.get(ident)
    if old is None:
        leaves[ident] = (kind, dict(ports), desc, node)
        return
    if old[0] != kind or old[2] != desc:  # one ID is one leaf type: same kind, same description
        raise ModelError(f"tree.{node}", f"BehaviorTree.CPP ID '{ident}' is also used by node '{old[3]}' for another leaf")
    for p, (d, ty) in dict(ports).items():  # one port used two ways: inout, and a string when the types differ
        if p in old[1] and old[1][p] != (d, ty):
            od, oty = old[1][p]
            old[1][p] = (od if od == d else "inout", oty if oty == ty else "std::string")
        else:
            old[1].setdefault(p, (d, ty))


def _refuse_gate(n, where):
    """The nav2 library models Nav2's throttling decorators as a composition with a gate
    action (``RateController.elapsed``...): Nav2's node and its parameters (``hz``...) are
    not in the model, so the export cannot write it back."""
    from .nav2 import GATES

    ident, _, question = n.primitive.partition(".")
    if ident in GATES and GATES[ident][0] == question:
        raise ModelError(where, f"'{n.name}' is the nav2 node library's gate for Nav2's {ident} (its "
                                f"{'period' if question == 'elapsed' else question.replace('_', ' ')} as a free answer): "
                                f"the model no longer holds the {ident} node and its parameters, so the btcpp export "
                                "cannot write it back")


def _leaf_tag(ident, where) -> str:
    if not _XML_NAME.match(ident) or ident.lower().startswith("xml"):
        raise ModelError(where, f"BehaviorTree.CPP ID '{ident}' is not an XML name ([A-Za-z_][A-Za-z0-9_.-]*); "
                                "rename it to export the tree")
    return ident


def _node(n, depth, lines, leaves, trees, strip="", facts=None):
    """Write node ``n``; inside a SubTree, names lose the SubTree's ``strip`` prefix
    (``INSTANCE/``), which the importer adds again."""
    pad = "  " * depth
    where = f"tree.{n.name}"
    shown = n.name[len(strip):] if strip and n.name.startswith(strip) and len(n.name) > len(strip) else n.name
    name = xml_attr(shown, where)
    if isinstance(n, Action):
        _refuse_gate(n, where)
        ports = {k: _action_port(facts, n.primitive, v) for k, v in n.args}
        attrs = "".join(f' {xml_attr(k, where)}="{xml_attr(_value(v), where)}"' for k, v in n.args)
        _declare(leaves, n.primitive, "Action", ports, None, n.name)
        lines.append(f'{pad}<{_leaf_tag(n.primitive, where)} name="{name}"{attrs}/>')
        return
    if isinstance(n, Condition):
        _declare(leaves, shown, "Condition", (), to_text(n.expr), n.name)
        lines.append(f'{pad}<{_leaf_tag(shown, where)} name="{name}"/>')
        return
    if isinstance(n, SkillRequest):
        params = ", ".join(f"{k}={to_text(e)}" for k, e in n.params)
        desc = f"btfsm SkillRequest: fsm {n.fsm}, goal {n.goal}" + (f", params {params}" if params else "")
        _declare(leaves, shown, "Action", (), desc, n.name)
        lines.append(f'{pad}<{_leaf_tag(shown, where)} name="{name}"/>')
        return
    if isinstance(n, SubTree):
        body: list = []
        mine: dict = {}  # the leaves of this SubTree's tree, declared once per tree written
        _node(n.child, 2, body, mine, trees, n.name + "/", facts)
        tree = (body, {lid: d[:3] for lid, d in mine.items()})  # with the leaves of SubTrees inside
        ident, k = n.tree_id, 1
        while trees.get(ident, tree) != tree:  # another tree under this ID: the next free one
            k += 1
            ident = f"{n.tree_id}_{k}"
        trees.setdefault(ident, tree)
        for lid, (kind, ports, desc, node) in mine.items():
            _declare(leaves, lid, kind, ports, desc, node)
        lines.append(f'{pad}<SubTree ID="{xml_attr(ident, where)}" name="{name}"/>')
        return
    if isinstance(n, (Guard, Effects)):
        raise ModelError(where, f"{type(n).__name__} has no BehaviorTree.CPP counterpart with the same rules; "
                                "the btcpp export cannot write it")
    tag = TAGS.get(type(n))
    if tag is None:
        raise ModelError(where, f"node type {type(n).__name__} cannot be exported to BehaviorTree.CPP")
    if isinstance(n, Parallel) and n.selected:
        raise ModelError(f"{where}.selected", "selected children (py_trees' SuccessOnSelected) have no "
                                              "BehaviorTree.CPP counterpart; the btcpp export cannot write them")
    # every field with a BT.CPP port, always (Parallel's synchronise has none: BT.CPP never
    # re-ticks finished children)
    attrs = "".join(f' {f.metadata["btcpp"]}="{_port(getattr(n, f.name), f.metadata["btcpp_none"])}"'
                    for f in file_fields(type(n)) if f.metadata["btcpp"])
    lines.append(f'{pad}<{tag} name="{name}"{attrs}>')
    for child in n.children_of():
        _node(child, depth + 1, lines, leaves, trees, strip, facts)
    lines.append(f"{pad}</{tag}>")
