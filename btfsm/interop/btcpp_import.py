"""BehaviorTree.CPP XML v4 in: an XML tree (plus an optional side file) as btfsm model data.

``xml_to_data(xml_bytes, xml_name, side, side_name)`` reads a BehaviorTree.CPP 4 XML
document (``<root BTCPP_format="4">``, one or more ``<BehaviorTree ID>``, ``SubTree``
with port remapping, ``TreeNodesModel``) and returns an ``XmlImport``: the data of a btfsm
model file (the dict ``btfsm.files.model_from_data`` reads), the model warnings the import
makes, and the XML line of every tree element (to put line numbers on later errors).
``btfsm.files.load_xml_model`` is the loader every command uses for ``.xml`` files.

The side file is a partial btfsm model file (``variables``, ``primitives``, ``fsms``,
``environment``, ``invariants``, ``resources``, ``semantics``...) plus two keys of its
own: ``nodes`` (how one XML node, by name or ID, is modelled) and ``main_tree``. The
conventions are in docs/model-files.md, section "BehaviorTree.CPP XML models".

XML is read with expat, without any DTD: a DOCTYPE, an entity declaration or an external
entity is refused, so no entity expansion ("billion laughs") or external file can happen.

>>> r = xml_to_data(b'<root BTCPP_format="4"><BehaviorTree ID="T"><Sequence>'
...                 b'<Ok/><AlwaysSuccess/></Sequence></BehaviorTree></root>', "t.xml", {"primitives": {"Ok": ["success"]}})
>>> r.data["tree"]["MemorySequence"], [c.get("Action") for c in r.data["tree"]["children"]]
('Sequence', ['Ok', 'AlwaysSuccess'])
>>> r.data["semantics"], r.warnings
('btcpp', [])
"""
from __future__ import annotations

import difflib
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import cast
from xml.parsers import expat

from ..bt import NODE_TYPES, Composite, Decorator, arity_allows, arity_text, btcpp_tags, file_fields
from ..errors import ModelError, collected
from ..expr import as_expr, names_in
from ..world import check_label
from .groot import read_models as read_node_models

__all__ = ["XmlImport", "xml_to_data", "side_file_for", "parse_xml", "CONTROLS", "DECORATORS", "REFUSED",
           "MAX_ELEMENTS", "MAX_DEPTH", "MAX_INLINED", "SIDE_KEYS"]

MAX_ELEMENTS = 200_000  # elements in one XML document
MAX_DEPTH = 100  # nesting of XML elements
MAX_INLINED = 100_000  # tree nodes after SubTrees are inlined (a SubTree "bomb" stops here)
MAX_OUTCOMES = 64  # outcomes an undeclared leaf gets for the values its output ports may write



#: BT.CPP control tag -> (btfsm type key, {XML attribute: (btfsm field, default)}).
CONTROLS = btcpp_tags(None, Composite)
#: BT.CPP decorator tag -> (btfsm type key, {XML attribute: (btfsm field, default)}).
DECORATORS = btcpp_tags(None, Decorator)
#: BT.CPP built-in leaves with fixed outcomes.
BUILTIN_LEAVES = {"AlwaysSuccess": ["success"], "AlwaysFailure": ["failure"]}
#: BT.CPP nodes btfsm does not model, and why (an error unless the side file abstracts them).
REFUSED = {
    "Script": "runs script code on the blackboard",
    "ScriptCondition": "evaluates script code on the blackboard",
    "SetBlackboard": "writes the blackboard from the XML",
    "UnsetBlackboard": "erases a blackboard entry",
    "Precondition": "evaluates a script before its child",
    "Sleep": "waits for wall-clock time",
    "Delay": "waits for wall-clock time before its child",
    "Timeout": "fails its child after wall-clock time",
    "Switch2": "switches on a blackboard value", "Switch3": "switches on a blackboard value",
    "Switch4": "switches on a blackboard value", "Switch5": "switches on a blackboard value",
    "Switch6": "switches on a blackboard value",
    "LoopInt": "loops over a blackboard queue", "LoopDouble": "loops over a blackboard queue",
    "LoopString": "loops over a blackboard queue", "LoopBool": "loops over a blackboard queue",
    "WasEntryUpdated": "reads blackboard sequence ids", "SkipUnlessUpdated": "reads blackboard sequence ids",
    "WaitValueUpdate": "reads blackboard sequence ids", "EntryUpdated": "reads blackboard sequence ids",
    "ManualSelector": "asks a human", "PopFromQueue": "pops a blackboard queue", "QueueSize": "reads a blackboard queue",
    "ReactiveSequenceWithMemory": "is not a BehaviorTree.CPP 4 node",
}
#: Script attributes (pre- and post-conditions) that every BT.CPP 4 node may carry.
SCRIPT_ATTRS = ("_skipIf", "_successIf", "_failureIf", "_while", "_onSuccess", "_onFailure", "_onHalted", "_post")
#: Attributes that are documentation only (Groot2 writes them).
DOC_ATTRS = ("_description", "_uid", "_fullpath")
#: Side-file keys the importer itself reads (every other key is passed to the model).
SIDE_KEYS = ("nodes", "main_tree", "node_library", "node_models")
_PORT_TAGS = ("input_port", "output_port", "inout_port")
_MODEL_KINDS = ("Action", "Condition", "Control", "Decorator", "SubTree")
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_REF = re.compile(r"\{(@?)([^{}]*)\}\Z")
#: BT.CPP's ``convertFromString<bool>``: these spellings exactly (no spaces), nothing else
BOOLS = ("true", "True", "TRUE", "1", "false", "False", "FALSE", "0")
_BOOL_TYPES = ("bool",)
_OUTCOMES = re.compile(r"btfsm outcomes:(?P<list>.*)\Z", re.S)
_EXPR = re.compile(r"btfsm expr:(?P<expr>.*)\Z", re.S)
_SKILL = re.compile(r"btfsm SkillRequest: fsm (?P<fsm>[^,]+), goal (?P<goal>.+?)(?:, params (?P<params>.*))?\Z", re.S)


# ============================================================================ XML reading


@dataclass
class El:
    """One XML element: tag, attributes (in document order), line, children, text."""
    tag: str
    attrs: dict
    line: int
    children: list = field(default_factory=list)
    text: str = ""

    def where(self) -> str:
        return f"line {self.line}: <{self.tag}>"


class _Stop(Exception):
    def __init__(self, line, problem):
        super().__init__(problem)
        self.line, self.problem = line, problem


def parse_xml(data: bytes, file: str) -> El:
    """The root element of an XML document, without any DTD (a DOCTYPE, entity declaration
    or external entity is a ModelError), at most ``MAX_ELEMENTS`` elements ``MAX_DEPTH`` deep.

    >>> parse_xml(b'<root><a x="1"/></root>', "f").children[0].attrs
    {'x': '1'}
    >>> parse_xml(b'<!DOCTYPE r [<!ENTITY a "b">]><r/>', "f.xml")
    Traceback (most recent call last):
    btfsm.errors.ModelError: f.xml: line 1: a DOCTYPE (DTD) is refused: DTDs and entities are not read
    """
    p = expat.ParserCreate()
    p.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)
    stack: list = []
    top: list = []
    count = [0]

    def refuse(what):
        def handler(*_):
            raise _Stop(p.CurrentLineNumber, f"{what} is refused: DTDs and entities are not read")
        return handler

    def start(tag, attrs):
        count[0] += 1
        if count[0] > MAX_ELEMENTS:
            raise _Stop(p.CurrentLineNumber, f"more than {MAX_ELEMENTS} XML elements")
        if len(stack) >= MAX_DEPTH:
            raise _Stop(p.CurrentLineNumber, f"<{tag}>: XML nested more than {MAX_DEPTH} levels deep")
        el = El(tag, dict(attrs), p.CurrentLineNumber)
        (stack[-1].children if stack else top).append(el)
        stack.append(el)

    def end(_tag):
        stack.pop()

    def text(s):
        if stack and len(stack[-1].text) < 100_000:
            stack[-1].text += s

    p.StartDoctypeDeclHandler = refuse("a DOCTYPE (DTD)")
    p.EntityDeclHandler = refuse("an entity declaration")
    p.UnparsedEntityDeclHandler = refuse("an entity declaration")
    p.ExternalEntityRefHandler = refuse("an external entity")
    p.StartElementHandler, p.EndElementHandler, p.CharacterDataHandler = start, end, text
    try:
        p.Parse(data, True)
    except _Stop as exc:
        raise ModelError(f"line {exc.line}", exc.problem, file) from None
    except expat.ExpatError as exc:
        raise ModelError(f"line {exc.lineno}", f"XML syntax error: {expat.ErrorString(exc.code)} "
                                               f"(column {exc.offset + 1})", file) from None
    except RecursionError:  # pragma: no cover - the depth limit comes first
        raise ModelError("", "XML nested too deeply", file) from None
    return top[0]


# ============================================================================ XML -> data


@dataclass
class XmlImport:
    """The result of ``xml_to_data``: model ``data``, ``warnings`` ((element, text) pairs as
    in ``Model.warnings``) and ``lines``: data path of a tree element -> its "line N: <tag>"."""
    data: dict
    warnings: list
    lines: dict

    def locate(self, exc: ModelError, xml_name: str) -> ModelError:
        """``exc`` (raised while building the model from ``data``) at its XML line when
        it is about the tree; unchanged otherwise."""
        el = exc.element or ""
        cut = len(el)
        while cut > 0:
            head = el[:cut]
            if head in self.lines:
                rest = el[cut:]
                return ModelError(self.lines[head] + (f" ({rest.lstrip('.')})" if rest else ""),
                                  re.sub(r" \(line \d+\)$", "", exc.problem), xml_name)
            cut = max(el.rfind(".", 0, cut), el.rfind("[", 0, cut))
        return exc


def side_file_for(xml_path) -> "Path | None":
    """The side file found beside ``xml_path``: ``STEM.btfsm.yaml`` (or ``.yml``/``.json``)."""
    p = Path(xml_path)
    for ext in (".btfsm.yaml", ".btfsm.yml", ".btfsm.json"):
        cand = p.with_name(p.stem + ext)
        if cand.is_file():
            return cand
    return None


def xml_to_data(xml: bytes, xml_name: str, side: "dict | None" = None, side_name: "str | None" = None, *,
                library=None, models: "dict | None" = None, main_tree: "str | None" = None,
                include=None) -> XmlImport:
    """BT.CPP XML v4 (bytes) plus side-file data -> btfsm model data (see the module doc).

    ``library``: a node library (``btfsm.interop.libraries.load_library``); ``models``:
    ``{ID: groot.NodeModel}`` from node model files (used for IDs the XML's own
    ``TreeNodesModel`` does not define); ``main_tree`` overrides the side file's and the
    XML's choice; ``include(path, including_file) -> (root element, shown name)`` reads an
    ``<include path=...>`` (None: includes are refused)."""
    imp = _Importer(xml_name, side or {}, side_name)
    imp.library, imp.extra_models, imp.main_override, imp.include = library, models or {}, main_tree, include
    try:
        out = imp.run(parse_xml(xml, xml_name))
    except ModelError as exc:  # a problem that stops the import, after the entries found so far
        raise cast(ModelError, collected(imp.errors + [exc])) from None
    if imp.errors:  # every blackboard entry that cannot be a variable, at once
        raise cast(ModelError, collected(imp.errors))
    return out


class _Importer:
    def __init__(self, file, side, side_name):
        self.file, self.side_name = file, side_name or file
        if not isinstance(side, dict):
            raise ModelError("", "the side file must be a mapping (a partial btfsm model file)", self.side_name)
        if "tree" in side:
            raise ModelError("tree", "the tree comes from the XML file; a side file has no tree", self.side_name)
        self.side = side
        nodes = side.get("nodes") or {}
        if not isinstance(nodes, dict):
            raise ModelError("nodes", "expected a mapping of XML node names or IDs to how they are modelled", self.side_name)
        self.nodes = nodes
        vars_ = side.get("variables") or {}
        if not isinstance(vars_, dict):
            raise ModelError("variables", "expected a mapping of variable names to types", self.side_name)
        self.variables = dict(vars_)
        prims = side.get("primitives") or {}
        if not isinstance(prims, dict):
            raise ModelError("primitives", "expected a mapping of primitive names to outcome lists", self.side_name)
        self.side_prims = prims
        main = side.get("main_tree")
        if main is not None and not isinstance(main, str):
            raise ModelError("main_tree", "expected the ID of a BehaviorTree", self.side_name)
        self.primitives: dict = {}  # generated primitives (undeclared and built-in leaves)
        self.inline: set = set()  # primitives declared inline at one leaf
        self.explicit: dict = {}  # ID -> the kinds its explicit <Action/Condition ID=...> forms give
        self.trees: dict = {}
        self.models: dict = {}  # TreeNodesModel: ID -> (kind, {port: (direction, type)}, description, element)
        self.names: set = set()
        self.suffix: dict = {}  # name -> the last k of "name#k" given
        self.count = 0
        self.warnings: list = []
        self.lines: dict = {}
        self.used_nodes: set = set()
        self.pending: list = []
        self.errors: list = []  # problems that do not stop the import (blackboard entries), reported together
        self.bad_vars: set = set()
        self.library, self.extra_models, self.main_override, self.include = None, {}, None, None

    def fail(self, el, problem):
        return ModelError(el.where() if el is not None else "", problem, getattr(el, "file", None) or self.file)

    # ---------------------------------------------------------------- document
    def run(self, root: El) -> XmlImport:
        if root.tag != "root":
            raise self.fail(root, "expected <root BTCPP_format=\"4\"> as the document element")
        for a, v in root.attrs.items():
            if a == "BTCPP_format":
                if v.strip() == "3":
                    raise self.fail(root, "BTCPP_format=\"3\": only BehaviorTree.CPP XML version 4 is read: convert "
                                          "this version 3 file with BehaviorTree.CPP's script convert_v3_to_v4.py (or "
                                          "Groot2), then check the result")
                if v.strip() != "4":
                    raise self.fail(root, f"BTCPP_format=\"{v}\": only BehaviorTree.CPP XML version 4 is read")
            elif a != "main_tree_to_execute":
                raise self.fail(root, f"unknown attribute '{a}' (expected BTCPP_format, main_tree_to_execute)")
        self.document(root, (self.file,))
        self.finish_models()
        return self.main_part(root)

    def document(self, root: El, chain: tuple):
        """Read the BehaviorTrees, node models and includes of one XML document."""
        for el in root.children:
            if el.tag == "BehaviorTree":
                tid = el.attrs.get("ID")
                if not tid:
                    raise self.fail(el, "a BehaviorTree needs an ID")
                if tid in self.trees:
                    raise self.fail(el, f"BehaviorTree ID '{tid}' is defined twice (first at line {self.trees[tid].line})")
                extra = [a for a in el.attrs if a not in ("ID",) + DOC_ATTRS]
                if extra:
                    raise self.fail(el, f"unknown attribute '{extra[0]}' (a BehaviorTree has an ID)")
                if len(el.children) != 1:
                    raise self.fail(el, f"BehaviorTree '{tid}' must have exactly one root node, has {len(el.children)}")
                self.trees[tid] = el
            elif el.tag == "TreeNodesModel":
                self.read_models(el)
            elif el.tag == "include":
                self.read_include(el, chain)
            else:
                raise self.fail(el, "unknown element under <root> (expected BehaviorTree, TreeNodesModel, include)")

    def read_include(self, el: El, chain: tuple):
        if self.include is None:
            raise self.fail(el, "<include> of other XML files is not read here: load the tree from its file")
        extra = [a for a in el.attrs if a != "path"]
        if extra:
            raise self.fail(el, f"unknown attribute '{extra[0]}' of <include> (btfsm reads path=, relative to the "
                                "including file; ros_pkg= is not supported)")
        if not el.attrs.get("path", "").strip():
            raise self.fail(el, "an <include> needs a path")
        try:
            sub, shown = self.include(el.attrs["path"].strip(), getattr(el, "file", None) or self.file)
        except ModelError as exc:
            raise self.fail(el, exc.problem) from None
        if shown in chain:
            raise self.fail(el, f"recursive <include>: {' -> '.join(chain + (shown,))}")
        if sub.tag != "root":
            raise ModelError(sub.where(), "expected <root BTCPP_format=\"4\"> as the document element", shown)
        _mark(sub, shown)
        self.document(sub, chain + (shown,))

    def finish_models(self):
        extra = dict(self.library.models) if self.library is not None else {}
        extra.update(self.extra_models)
        for ident, m in extra.items():
            self.models.setdefault(ident, m.as_tuple())

    def main_part(self, root: El) -> XmlImport:
        if not self.trees:
            raise self.fail(root, "no <BehaviorTree> in the file")
        self.explicit = _explicit_kinds(self.trees.values())
        main = self.main_override or self.side.get("main_tree") or root.attrs.get("main_tree_to_execute")
        if main is None:
            if len(self.trees) != 1:
                raise self.fail(root, f"{len(self.trees)} BehaviorTrees ({', '.join(self.trees)}) and no "
                                      "main_tree_to_execute: say which one runs (or main_tree: ID in the side file)")
            main = next(iter(self.trees))
        if main not in self.trees:
            how = " (--main-tree)" if main == self.main_override else ""
            raise self.fail(root, f"main tree '{main}'{how} is not defined (trees: {', '.join(self.trees)})")
        tree = self.node(self.trees[main].children[0], "tree", _Scope.root(), (main,), "")
        self.resolve_pending()
        data = {"name": self.side.get("name", main)}
        for k, v in self.side.items():
            if k not in SIDE_KEYS and k not in ("name", "variables", "primitives"):
                data[k] = v
        data.setdefault("semantics", "btcpp")
        if self.variables:
            data["variables"] = self.variables
        prims = dict(self.side_prims)
        prims.update({k: v for k, v in self.primitives.items() if k not in prims})
        if prims:
            data["primitives"] = prims
        data["tree"] = tree
        unused = [k for k in self.nodes if k not in self.used_nodes]
        if unused:
            raise ModelError(f"nodes.{unused[0]}", "names no node of the XML tree (by name or ID)", self.side_name)
        return XmlImport(data, self.warnings, self.lines)

    def read_models(self, tnm: El):
        file = getattr(tnm, "file", None) or self.file
        for ident, m in read_node_models(tnm, file).items():
            self.models[ident] = m.as_tuple()

    # ---------------------------------------------------------------- nodes
    def unique(self, name: str, el: El) -> str:
        try:
            check_label(name, "", "node name")
        except ModelError as exc:
            raise self.fail(el, exc.problem) from None
        base = name
        while name in self.names:
            k = self.suffix[base] = self.suffix.get(base, 1) + 1
            name = f"{base}#{k}"
        self.names.add(name)
        return name

    def node(self, el: El, path: str, scope, stack: tuple, prefix: str) -> dict:
        self.count += 1
        if self.count > MAX_INLINED:
            raise self.fail(el, f"the tree has more than {MAX_INLINED} nodes once SubTrees are inlined")
        for a in el.attrs:
            if a in SCRIPT_ATTRS:
                raise self.fail(el, f"script attribute {a}=\"{el.attrs[a]}\" is not modelled by btfsm "
                                    "(rewrite it as a condition or an action declared in the side file)")
        tag = el.tag
        if tag == "SubTree":
            return self.subtree(el, path, scope, stack, prefix)
        if tag in ("Action", "Condition", "Control", "Decorator") and "ID" in el.attrs:
            ident, kind = el.attrs["ID"], tag
        else:
            ident, kind = tag, None
        name_attr = el.attrs.get("name")
        shown = name_attr or ident
        if ident in CONTROLS or ident in DECORATORS:
            return self.inner(el, ident, path, scope, stack, prefix)
        if self.library is not None and self.library.knows(ident):
            return self.library.inner(self, el, ident, path, scope, stack, prefix)
        decl = self.declaration(prefix + shown, shown, ident)
        if ident in REFUSED and decl is None and shown not in self.side_prims and ident not in self.side_prims:
            raise self.fail(el, f"{ident} {REFUSED[ident]}: not modelled by btfsm (declare '{shown}' under "
                                f"nodes: or primitives: in the side file to model it explicitly)")
        if el.children:
            if decl is not None and isinstance(decl, dict) and decl.get("abstract") == "child":
                if len(el.children) != 1:
                    raise self.fail(el, "abstract: child needs exactly one child node")
                self.used_nodes.add(self.node_key(prefix + shown, shown, ident))
                return self.node(el.children[0], path, scope, stack, prefix)
            model = self.models.get(ident)
            what = f"declared as a {model[0]} in TreeNodesModel" if model else "not a BehaviorTree.CPP 4 control or decorator"
            known = list(CONTROLS) + list(DECORATORS)
            lib = ""
            if self.library is not None:
                what += f" nor one of the {self.library.name} node library"
                lib = f" and the {self.library.name} library's"
                known += self.library.inner_ids()
            close = [k for k in known if k.lower() == ident.lower()] or difflib.get_close_matches(ident, known, 1, 0.7)
            hint = f"; did you mean '{close[0]}'? (BehaviorTree.CPP refuses it too: tags are case-sensitive)" \
                if close else ""
            raise self.fail(el, f"unknown node type with children ({what}){hint}; btfsm models the standard controls "
                                f"and decorators{lib}: {', '.join(known)}")
        return self.leaf(el, ident, kind, shown, path, scope, prefix)

    def node_key(self, *keys):
        """The ``nodes`` key that declares a node: (for a leaf) its unique name as ``btfsm
        import`` prints it (``pick#2``), its full name (SubTree prefix included), its name,
        its ID; None when there is none."""
        return next((k for k in keys if k in self.nodes), None)

    def declaration(self, *keys):
        key = self.node_key(*keys)
        return None if key is None else self.nodes[key]

    def inner(self, el, tag, path, scope, stack, prefix):
        key, attrs = (CONTROLS if tag in CONTROLS else DECORATORS)[tag]
        name = self.unique(prefix + (el.attrs.get("name") or tag), el)
        out = {key: name}
        self.lines[path] = el.where()
        for a, v in el.attrs.items():
            if a in ("name", "ID") + DOC_ATTRS:
                continue
            if a not in attrs:
                known = ", ".join(attrs) or "none besides name"
                raise self.fail(el, f"unknown attribute '{a}' (attributes of {tag}: {known})")
            fname, default = attrs[a]
            if _REF.match(v.strip()):
                raise self.fail(el, f"{a}=\"{v}\" reads the blackboard: not modelled by btfsm (give a constant)")
            field = {f.name: f for f in file_fields(NODE_TYPES[key])}[fname]
            if field.metadata["file"] in ("bool", "opt_bool"):
                val = _bool(v)
                if val is None:
                    raise self.fail(el, f"{a}=\"{v}\": expected true or false ({', '.join(BOOLS)}, as BT.CPP reads a bool)")
            else:
                try:
                    val = int(v.strip())
                except ValueError:
                    raise self.fail(el, f"{a}=\"{v}\": expected an integer") from None
                low = field.metadata["at_least"]
                if low is not None and val < low:
                    raise self.fail(el, f"{a}=\"{v}\": btfsm needs a bound of at least {low} (-1, forever, cannot be "
                                        "model-checked as a count; use a bound, or KeepRunningUntilFailure)")
            if val != default:
                out[fname] = val
        if tag in CONTROLS and not el.children:
            raise self.fail(el, f"a {tag} needs children")  # BT.CPP's rule (btfsm runs an empty one)
        if not arity_allows(NODE_TYPES[key], len(el.children)):
            raise self.fail(el, f"a {tag} has {arity_text(NODE_TYPES[key])}, has {len(el.children)}")
        if tag in DECORATORS:
            out["child"] = self.node(el.children[0], f"{path}.child", scope, stack, prefix)
        else:
            out["children"] = [self.node(c, f"{path}.children[{i}]", scope, stack, prefix)
                               for i, c in enumerate(el.children)]
        return out

    def subtree(self, el, path, scope, stack, prefix):
        sid = el.attrs.get("ID")
        if not sid:
            raise self.fail(el, "a SubTree needs an ID")
        if el.children:
            raise self.fail(el, "a SubTree element has no children (its tree is the BehaviorTree with its ID)")
        if sid not in self.trees:
            raise self.fail(el, f"SubTree ID '{sid}' names no BehaviorTree (trees: {', '.join(self.trees)})")
        if sid in stack:
            raise self.fail(el, f"recursive SubTree: {' -> '.join(stack + (sid,))}")
        auto = el.attrs.get("_autoremap", "false")
        if _bool(auto) is None:
            raise self.fail(el, f"_autoremap=\"{auto}\": expected true or false ({', '.join(BOOLS)}, as BT.CPP reads a bool)")
        remap = {}
        for a, v in el.attrs.items():
            if a in ("ID", "name", "_autoremap") + DOC_ATTRS:
                continue
            if a.startswith("_"):
                raise self.fail(el, f"unknown attribute '{a}'")
            remap[a] = scope.value(v.strip(), a) if _REF.match(v.strip()) else ("lit", v)
        inst = el.attrs.get("name") or sid
        sub = scope.child(remap, _bool(auto), _ident(prefix + inst))
        # a SubTree node (BT.CPP's SubTreeNode: it resets its child when the child finishes)
        out = {"SubTree": self.unique(prefix + inst, el)}
        self.lines[path] = el.where()
        if sid != out["SubTree"]:
            out["tree_id"] = sid
        out["child"] = self.node(self.trees[sid].children[0], f"{path}.child", sub, stack + (sid,), f"{prefix}{inst}/")
        return out

    # ---------------------------------------------------------------- leaves
    def leaf(self, el, ident, kind, shown, path, scope, prefix):
        name = self.unique(prefix + shown, el)
        self.lines[path] = el.where()
        model = self.models.get(ident)
        if kind is None and model is not None:
            kind = model[0]
        if kind is None and len(self.explicit.get(ident, ())) == 1:
            # BT.CPP runs whatever is registered under the ID, whichever form names it: a
            # compact <ID/> is of the kind an explicit <Condition ID=...> of it says
            kind = next(iter(self.explicit[ident]))
        if kind in ("Control", "Decorator"):
            raise self.fail(el, f"{ident} is declared as a {kind} in TreeNodesModel but has no children")
        ports = {}
        for a, v in el.attrs.items():
            if a in ("name", "ID") + DOC_ATTRS:
                continue
            if a.startswith("_"):
                raise self.fail(el, f"unknown attribute '{a}'")
            if model is not None and a not in model[1]:
                raise self.fail(el, f"port '{a}' is not declared for {ident} in TreeNodesModel "
                                    f"(ports: {', '.join(model[1]) or 'none'})")
            ports[a] = v
        # blackboard references -> world variables
        args, written = {}, []
        for a, v in ports.items():
            m = _REF.match(v.strip())
            if not m:
                args[a] = v
                continue
            res = scope.value(v.strip(), a)
            if res[0] == "lit":
                args[a] = res[1]
                continue
            var = res[1]
            ptype = model[1][a][1] if model is not None else ""
            if not self.declare_var(el, var, a, ptype):
                args[a] = v  # an entry the node library leaves out of the model (kept as text)
                continue
            args[a] = "{" + var + "}"
            if model is not None and model[1][a][0] in ("output", "inout"):
                written.append(var)
        decl = self.declaration(name, prefix + shown, shown, ident)
        if decl is not None:
            key = self.node_key(name, prefix + shown, shown, ident)
            self.used_nodes.add(key)
            return self.declared(el, name, ident, key, decl, args)
        for key in (shown, ident):
            if key in self.side_prims:
                out = {"Action": name, "primitive": key}
                if args:
                    out["args"] = args
                return out
        desc = model[2] if model is not None else ""
        if _OUTCOMES.match(desc):
            statuses = [x.strip().lower() for x in _OUTCOMES.match(desc)["list"].split(",")]
            allowed = ("success", "failure") if kind == "Condition" else ("running", "success", "failure")
            if not statuses or any(x not in allowed for x in statuses) or len(set(statuses)) != len(statuses):
                raise self.fail(model[3], f"description '{desc}': expected 'btfsm outcomes: ' and a list of "
                                          f"distinct statuses from {', '.join(allowed)}")
            if self.primitives.setdefault(ident, statuses) != statuses:  # pragma: no cover - one model per ID
                raise self.fail(model[3], "two node models for one ID")
            out = {"Action": name, "primitive": ident}
            if args:
                out["args"] = args
            return out
        if _EXPR.match(desc) and kind == "Condition":
            return {"Condition": name, "expr": _EXPR.match(desc)["expr"].strip()}
        if model is not None and model[2] and _SKILL.match(model[2]) and kind == "Action":
            got = self.from_description(el, name, kind, model[2])
            if got is not None:
                return got
        if self.library is not None:
            got = self.library.leaf(self, el, name, ident, kind, written, args)
            if got is not None:
                return got
        if ident in BUILTIN_LEAVES and not ports:
            self.primitives.setdefault(ident, BUILTIN_LEAVES[ident])
            return {"Action": name, "primitive": ident}
        out: dict = {}
        later = (out, el, name, ident, kind, shown, written, args, model[2] if model is not None else "")
        if kind == "Condition" and later[-1]:
            self.pending.append(later)  # its description may name variables declared further on
        else:
            self.undeclared(*later)
        return out

    def resolve_pending(self):
        for out, el, name, ident, kind, shown, written, args, desc in self.pending:
            got = self.from_description(el, name, kind, desc)
            if got is not None:
                out.update(got)
            else:
                self.undeclared(out, el, name, ident, kind, shown, written, args, desc)

    def undeclared(self, out, el, name, ident, kind, shown, written, args, desc):
        statuses = ["success", "failure"] if kind == "Condition" else ["running", "success", "failure"]
        outcomes = self.havoc(el, statuses, written)
        what = "RUNNING, SUCCESS or FAILURE" if kind != "Condition" else "SUCCESS or FAILURE"
        extra = f" and write any value to {', '.join(written)}" if written else ""
        names = f"'{shown}' or '{ident}'" if shown != ident else f"'{ident}'"
        model = "its node model's description is not a btfsm expression over declared variables" if desc else \
            "no usable node model"
        self.warnings.append((f"tree.{name}", f"{self.file}: {el.where()}: no declared outcomes (no side-file entry "
                                              f"for {names}, {model}): it may return any of {what}{extra}"))
        out.update({"Action": name, "primitive": ident if not written else name})
        if written:
            out["outcomes"] = outcomes
        else:
            prev = self.primitives.setdefault(ident, outcomes)
            if prev != outcomes or ident in self.side_prims:
                # another leaf of this ID has other outcomes: its own primitive, a fresh name
                prim, k = name, 1
                while prim in self.primitives or prim in self.side_prims or prim in self.inline:
                    k += 1
                    prim = f"{name}_{k}"
                self.inline.add(prim)
                out["primitive"] = prim
                out["outcomes"] = outcomes
        if args:
            out["args"] = args

    def havoc(self, el, statuses, written):
        """Outcomes: every status, times every value the written variables can take."""
        combos = [{}]
        for var in written:
            dom = self.domain(var)
            if dom is None or len(combos) * len(dom) * len(statuses) > MAX_OUTCOMES:
                raise self.fail(el, f"writes {var} but declares no outcomes, and its values are too many to "
                                    "enumerate: declare the leaf under primitives: or nodes: in the side file")
            combos = [dict(c, **{var: d}) for c in combos for d in dom]
        if combos == [{}]:
            return list(statuses)
        out = []
        for st in statuses:
            for c in combos:
                label = st + "(" + ", ".join(f"{k}={_text(v)}" for k, v in c.items()) + ")"
                out.append({st: c, "name": label})
        return out

    def domain(self, var):
        spec = self.variables.get(var)
        if spec == "bool" or (isinstance(spec, dict) and "bool" in spec):
            return [False, True]
        if isinstance(spec, dict) and "enum" in spec and isinstance(spec["enum"], list):
            return [repr(str(x)) for x in spec["enum"]]
        if isinstance(spec, dict) and isinstance(spec.get("int"), list) and len(spec["int"]) == 2:
            lo, hi = spec["int"]
            if isinstance(lo, int) and isinstance(hi, int) and 0 <= hi - lo < MAX_OUTCOMES:
                return list(range(lo, hi + 1))
        return None

    def declare_var(self, el, var, port, ptype) -> bool:
        """Make the entry ``var`` a world variable (True), or leave it out of the model
        when the node library says its type is not finite (False)."""
        if var in self.variables:
            return True
        if var in self.bad_vars:  # reported at its first use
            return False
        if not _IDENT.match(var):
            self.bad_vars.add(var)
            self.errors.append(self.fail(el, f"port {port}: blackboard entry '{var}' is not an identifier, so it "
                                             "cannot be a btfsm world variable"))
            return False
        if ptype in _BOOL_TYPES:
            self.variables[var] = "bool"
            return True
        if self.library is not None and ptype and self.library.opaque(ptype):
            return False
        why = f"has type {ptype}, which is not finite" if ptype else "has no declared type (no TreeNodesModel port type)"
        self.bad_vars.add(var)
        self.errors.append(self.fail(el, f"port {port}: blackboard entry {{{var}}} {why}: declare '{var}' under "
                                         "variables: in the side file (bool, enum or int range) to model it"))
        return False

    def declared(self, el, name, ident, key, decl, args):
        if not isinstance(decl, dict):
            raise ModelError(f"nodes.{key}", "expected a mapping (expr:, fsm:/goal:, outcomes:, primitive: or "
                                               "abstract: child)", self.side_name)
        keys = set(decl)
        if "expr" in keys:
            _only(keys, {"expr"}, key, self.side_name)
            return {"Condition": name, "expr": decl["expr"]}
        if "fsm" in keys or "goal" in keys:
            _only(keys, {"fsm", "goal", "params", "pre", "post"}, key, self.side_name)
            return {"SkillRequest": name, **decl}
        if "outcomes" in keys or "primitive" in keys:
            _only(keys, {"outcomes", "primitive"}, key, self.side_name)
            out = {"Action": name, "primitive": decl.get("primitive", ident)}
            if "outcomes" in decl:
                out["outcomes"] = decl["outcomes"]
            if args:
                out["args"] = args
            return out
        if decl.get("abstract") == "child":
            raise self.fail(el, "abstract: child is for a node with one child; this one has none")
        raise ModelError(f"nodes.{key}", "expected one of expr:, fsm:/goal:, outcomes:, primitive:, abstract: child",
                         self.side_name)

    def from_description(self, el, name, kind, desc):
        """btfsm's own exporter writes a condition's expression and a skill request's
        fsm/goal/params as the TreeNodesModel description."""
        m = _SKILL.match(desc)
        if m and kind == "Action":
            out = {"SkillRequest": name, "fsm": m["fsm"].strip(), "goal": m["goal"].strip()}
            if m["params"]:
                params = {}
                for part in m["params"].split(", "):
                    k, eq, v = part.partition("=")
                    if not eq:
                        return None
                    params[k.strip()] = v.strip()
                out["params"] = params
            return out
        if kind != "Condition":
            return None
        try:
            e = as_expr(desc)
        except (ModelError, ValueError, SyntaxError, RecursionError):
            return None
        known = set(self.variables)
        fsms = self.side.get("fsms") or {}
        if all(n in known or n.split(".")[0] in fsms for n in names_in(e)):
            return {"Condition": name, "expr": desc}
        return None


class _Scope:
    """Blackboard key -> ('var', world variable) or ('lit', constant), for one SubTree instance."""

    def __init__(self, parent, remap, auto, prefix):
        self.parent, self.remap, self.auto, self.prefix = parent, remap, auto, prefix

    @classmethod
    def root(cls):
        return cls(None, {}, False, "")

    def child(self, remap, auto, prefix):
        return _Scope(self, remap, auto, prefix)

    def value(self, ref: str, port: str):
        m = cast("re.Match[str]", _REF.match(ref))  # the callers matched it
        glob, key = m.group(1), m.group(2).strip()
        if key == "=":
            key = port
        if glob:
            return ("var", key)
        return self.lookup(key)

    def lookup(self, key):
        if key in self.remap:
            return self.remap[key]
        if self.parent is None:
            return ("var", key)
        if self.auto:
            return self.parent.lookup(key)
        return ("var", f"{self.prefix}__{key}")


def _mark(el: El, file: str):
    """Tag every element of an included document with its file (for error messages)."""
    stack = [el]
    while stack:
        e = stack.pop()
        setattr(e, "file", file)  # (not a field: read with getattr)
        stack.extend(e.children)


def _explicit_kinds(trees) -> dict:
    """ID -> {"Action", "Condition"}: the kinds the explicit ``<Action ID=..>`` /
    ``<Condition ID=..>`` forms in the trees give it."""
    out: dict = {}
    stack = list(trees)
    while stack:
        el = stack.pop()
        if el.tag in ("Action", "Condition") and el.attrs.get("ID"):
            out.setdefault(el.attrs["ID"], set()).add(el.tag)
        stack.extend(el.children)
    return out


def _ident(text: str) -> str:
    out = re.sub(r"[^A-Za-z0-9_]", "_", text)
    return out if _IDENT.match(out) else "_" + out


def _bool(text: str) -> "bool | None":
    """``text`` as BT.CPP reads a bool attribute; None when BT.CPP refuses it."""
    return text in BOOLS[:4] if text in BOOLS else None


def _text(v) -> str:
    return ("true" if v else "false") if isinstance(v, bool) else str(v)


def _only(keys, allowed, ident, file):
    extra = sorted(str(k) for k in keys - allowed)
    if extra:
        raise ModelError(f"nodes.{ident}.{extra[0]}", f"unknown field (allowed here: {', '.join(sorted(allowed))})", file)
