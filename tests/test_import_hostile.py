"""No import path raises anything but ``ModelError`` (issue 18, point 4).

Hypothesis draws trees for both importers with names from a hostile alphabet (unicode,
spaces, line breaks, template placeholders, keywords, very long names, btfsm's own
suffixes ``_2`` and ``#2``) and from collisions (a leaf and a guard of one name, two
guards whose variables would collide), with ``leaves=`` / side-file entries of every
shape. ``from_pytrees`` and ``load_xml_model`` either return a model or raise
``ModelError``; a py_trees tree whose leaves are all described imports (py_trees runs it,
so btfsm must not refuse it for its names).
"""
from __future__ import annotations

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from memo_strategies import st

from btfsm import Guard, Model, walk
from btfsm.errors import ModelError
from btfsm.files import load_xml_model

py_trees = pytest.importorskip("py_trees")

from btfsm.interop.pytrees import from_pytrees, node_names  # noqa: E402

NAMES = ["a", "a_2", "a#2", "a", "Tür offen", "g 1", "g_1", "g-1", "", " ", "x\ny", "${x}", "{x}", "é" * 300,
         "if", "true", "1", "ok", "\u200b", "a\ud800", "<&>", '"q"', "T", "Sequence", "a.b", "x" * 257]
SETTINGS = settings(max_examples=150, derandomize=True, deadline=None, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                           HealthCheck.function_scoped_fixture])


class Custom(py_trees.behaviour.Behaviour):
    """A user's leaf: btfsm cannot know its outcomes."""

    def update(self):
        return py_trees.common.Status.SUCCESS


@st.composite
def pytrees_tree(draw, depth=3, blackboard=False):
    """A py_trees tree; every leaf is a ``Running``/``Success``/``Failure`` or a custom leaf."""
    B, C, D = py_trees.behaviours, py_trees.composites, py_trees.decorators
    name = draw(st.sampled_from(NAMES))
    kinds = ["leaf", "custom"] + (["check", "set"] if blackboard else []) + (["seq", "sel", "par", "inv", "retry", "repeat", "guard", "pass"] if depth else [])
    k = draw(st.sampled_from(kinds))
    if k == "leaf":
        return draw(st.sampled_from([B.Running, B.Success, B.Failure]))(name=name)
    if k == "custom":
        return Custom(name)
    if k in ("check", "set"):
        import operator
        key = draw(st.sampled_from(NAMES[:8] + ["k.a"]))
        value = draw(st.sampled_from([1, 2, "a", True, None, lambda: 1]))
        if k == "set":
            return B.SetBlackboardVariable(name, key, value, overwrite=draw(st.booleans()))
        op = draw(st.sampled_from([operator.eq, operator.lt, operator.contains]))
        return B.CheckBlackboardVariableValue(name, py_trees.common.ComparisonExpression(key, value, op))
    if k in ("seq", "sel", "par"):
        kids = [draw(pytrees_tree(depth - 1, blackboard)) for _ in range(draw(st.integers(1, 3)))]
        if k == "par":
            return C.Parallel(name, policy=py_trees.common.ParallelPolicy.SuccessOnAll(), children=kids)
        return (C.Sequence if k == "seq" else C.Selector)(name, memory=draw(st.booleans()), children=kids)
    child = draw(pytrees_tree(depth - 1, blackboard))
    if k == "inv":
        return D.Inverter(name, child)
    if k == "retry":
        return D.Retry(name, child, draw(st.sampled_from([-1, 0, 1, 3, 2.5, float("nan")])))
    if k == "repeat":
        return D.Repeat(name, child, draw(st.sampled_from([-1, 0, 1, 3, 2.5])))
    if k == "pass":
        return D.PassThrough(name, child)
    return D.EternalGuard(name, child, condition=lambda: True)


LEAF_SPECS = st.sampled_from([["success", "failure"], "running", ["running", "success"], "nope", 3, None, [],
                              "x > ", "false", "true", ["success", 7], {"a": 1}])


@pytest.mark.filterwarnings("ignore::btfsm.interop.pytrees.PytreesImportWarning")
@SETTINGS
@given(pytrees_tree(blackboard=True), st.dictionaries(st.sampled_from(NAMES), LEAF_SPECS, max_size=4),
       st.dictionaries(st.sampled_from(NAMES), LEAF_SPECS, max_size=2), st.booleans(),
       st.dictionaries(st.sampled_from(NAMES[:8] + [3]), st.sampled_from([1, "a", True, [1], None]), max_size=2))
def test_from_pytrees_raises_only_model_errors(root, leaves, guards, wrap, blackboard):
    subject = py_trees.trees.BehaviourTree(root) if wrap else root
    try:
        model = from_pytrees(subject, leaves=leaves, guards=guards, blackboard=blackboard)
    except ModelError as exc:
        assert "\n" not in str(exc)
        return
    assert isinstance(model, Model)


@SETTINGS
@given(pytrees_tree())
def test_from_pytrees_accepts_every_name(root):
    """With every custom leaf described, any tree of mapped nodes imports, whatever its names;
    names btfsm can carry are kept as written."""
    leaves = {b.name: ["success", "failure", "running"] for b in root.iterate() if isinstance(b, Custom)}
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = from_pytrees(root, leaves=leaves)
    names = [n.name for n in walk(model.tree)]
    assert names == [nm for _, nm in node_names(root)]
    assert len(set(names)) == len(names)
    first = {}
    for b, nm in node_names(root):
        first.setdefault(b.name, nm)
    for written, nm in first.items():
        if written and written.isprintable() and len(written) <= 256 and "${" not in written:
            assert nm == written  # the first behaviour of a name keeps it
    guards = [n for n in walk(model.tree) if isinstance(n, Guard)]
    assert len(model.variables) == len(guards)


# ---------------------------------------------------------------------------- BehaviorTree.CPP

def _attr(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace('"', "&quot;").replace("\n", "&#10;")


@st.composite
def btcpp_xml(draw, depth=3):
    """An element of BT.CPP XML whose names, IDs and port values come from NAMES."""
    name = draw(st.sampled_from(NAMES))
    named = f' name="{_attr(name)}"' if draw(st.booleans()) else ""
    kinds = ["leaf", "cond", "always"] + (["Sequence", "ReactiveFallback", "Inverter", "Parallel", "sub"] if depth else [])
    k = draw(st.sampled_from(kinds))
    if k == "leaf":
        port = f' p="{_attr(draw(st.sampled_from(NAMES + ["{" + n + "}" for n in NAMES[:8]])))}"' if draw(st.booleans()) else ""
        return f'<Action ID="{_attr(draw(st.sampled_from(NAMES)))}"{named}{port}/>'
    if k == "cond":
        return f'<Condition ID="{_attr(draw(st.sampled_from(NAMES)))}"{named}/>'
    if k == "always":
        return f"<AlwaysSuccess{named}/>"
    if k == "sub":
        return f'<SubTree ID="S"{named}/>'
    kids = "".join(draw(btcpp_xml(depth - 1)) for _ in range(1 if k == "Inverter" else draw(st.integers(1, 3))))
    return f"<{k}{named}>{kids}</{k}>"


@SETTINGS
@given(btcpp_xml(), st.dictionaries(st.sampled_from(NAMES), st.sampled_from(
    [{"outcomes": ["success"]}, {"expr": "true"}, {"expr": "x >"}, {"abstract": "child"}, "success", 3, None]), max_size=3),
    st.dictionaries(st.sampled_from(NAMES), st.sampled_from([["success", "failure"], ["running"], "x", None]), max_size=3))
def test_load_xml_model_raises_only_model_errors(tmp_path, body, nodes, prims):
    xml = (f'<root BTCPP_format="4" main_tree_to_execute="T"><BehaviorTree ID="T">{body}</BehaviorTree>'
           f'<BehaviorTree ID="S"><Action ID="{_attr(NAMES[0])}"/></BehaviorTree></root>')
    path = tmp_path / "t.xml"
    path.write_bytes(xml.encode("utf-8", "surrogatepass"))  # a lone surrogate: invalid UTF-8, refused
    side = {}
    if nodes:
        side["nodes"] = nodes
    if prims:
        side["primitives"] = prims
    (tmp_path / "t.btfsm.yaml").write_bytes(yaml.safe_dump(side, allow_unicode=True).encode("utf-8", "surrogatepass"))
    try:
        model = load_xml_model(path)
    except ModelError as exc:
        assert "\n" not in str(exc)
        return
    assert isinstance(model, Model)
