"""btfsm's ``btcpp`` profile against real BehaviorTree.CPP 4 (``behaviortreepy``), tick by tick.

Hypothesis draws random trees over every control and decorator node the exporter writes
(thresholds and counts included) with async actions (stateful: RUNNING possible), instant
actions and conditions whose answers are a pure function of (leaf, tick). Each tree goes
through ``btfsm.interop.btcpp_export.to_btcpp_xml`` into the real engine and through
``Program.step`` under ``semantics: btcpp``; the root status and the leaf callbacks (start,
run, halt, tick, cond, in order) must be identical on every tick. docs/semantics.md 8.1.
"""
from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, given, settings
from memo_strategies import st

pytest.importorskip("behaviortreepy")

from btcpp_peer import compare  # noqa: E402

TICKS = 10
LONG = bool(os.environ.get("BTFSM_LONG"))
TREES = 8000 if LONG else 1000  # ticked with tick_exactly_once()
TREES_ONCE = 4000 if LONG else 300  # ticked with tick_once()
TREES_LOOPY = 2000 if LONG else 60  # small trees of wake-up loops, some of which never return

_COMPOSITES = ("ReactiveSequence", "MemorySequence", "SequenceWithMemory", "ReactiveFallback", "MemoryFallback",
               "Parallel", "ParallelAll", "IfThenElse", "WhileDoElse")
_DECORATORS = ("Inverter", "ForceSuccess", "ForceFailure", "Retry", "Repeat", "KeepRunningUntilFailure", "RunOnce")


def _has_skill(spec) -> bool:
    if spec[0] in ("async", "sync", "cond", "skill"):
        return spec[0] == "skill"
    body = spec[2]
    return any(_has_skill(c) for c in body) if isinstance(body, list) else _has_skill(body)


@st.composite
def trees(draw, depth=4):
    counter = iter(range(1000))
    made = []  # SubTrees written so far without skill requests: (tree ID, child), reusable

    def node(d):
        if d == 0 or (d < depth and draw(st.integers(0, 3)) == 0):  # the root is never a leaf
            kind = draw(st.sampled_from(("async", "async", "sync", "cond", "skill")))
            alphabet = "SFR" if kind in ("async", "skill") else "SF"
            table = "".join(draw(st.lists(st.sampled_from(alphabet), min_size=TICKS, max_size=TICKS)))
            return (kind, f"L{next(counter)}", table)
        name = f"n{next(counter)}"
        if draw(st.integers(0, 4)) == 0:  # a SubTree: a new <BehaviorTree>, or one written before again
            if made and draw(st.booleans()):
                ident, child = draw(st.sampled_from(made))
            else:
                ident, child = f"T{name}", node(d - 1)
                if not _has_skill(child):
                    made.append((ident, child))
            return ("SubTree", name, child, {"tree_id": ident})
        if draw(st.booleans()):
            t = draw(st.sampled_from(_COMPOSITES))
            lo, hi = (2, 3) if t in ("IfThenElse", "WhileDoElse") else (1, 4)
            kids = [node(d - 1) for _ in range(draw(st.integers(lo, hi)))]
            n = len(kids)
            params = {}
            if t == "Parallel":
                s = draw(st.integers(-n - 1, n))  # 0 (and -n-1): BT.CPP decides after the first child
                f = draw(st.integers(-n - 1, n))
                params = {"success_threshold": s, "failure_threshold": f}
            elif t == "ParallelAll":
                params = {"max_failures": draw(st.integers(1, n))}
            return (t, name, kids, params)
        t = draw(st.sampled_from(_DECORATORS))
        params = {}
        if t == "Retry":
            params = {"attempts": draw(st.integers(1, 3))}
        elif t == "Repeat":
            params = {"times": draw(st.integers(1, 3))}
        elif t == "RunOnce":
            params = {"then_skip": False}
        return (t, name, node(d - 1), params)
    return node(depth)


@st.composite
def loopy_trees(draw):
    """A root of 2-3 children that emit wake-up signals (Retry/Repeat of bound 2-3,
    SequenceWithMemory) or are leaves: where tick_once() re-ticks, and may never return."""
    counter = iter(range(100))

    def leaf():
        kind = draw(st.sampled_from(("async", "sync", "sync", "cond")))
        alphabet = "SFR" if kind == "async" else "SF"
        return (kind, f"L{next(counter)}", "".join(draw(st.lists(st.sampled_from(alphabet), min_size=TICKS,
                                                                  max_size=TICKS))))

    def looping():
        t = draw(st.sampled_from(("Retry", "Repeat", "SequenceWithMemory", "leaf")))
        name = f"n{next(counter)}"
        if t == "leaf":
            return leaf()
        if t == "SequenceWithMemory":
            return (t, name, [leaf() for _ in range(draw(st.integers(2, 3)))], {})
        return (t, name, leaf(), {"attempts" if t == "Retry" else "times": draw(st.integers(2, 3))})
    t = draw(st.sampled_from(("ReactiveSequence", "ReactiveFallback", "Parallel", "MemorySequence", "IfThenElse",
                              "WhileDoElse")))
    n = 3 if t in ("IfThenElse", "WhileDoElse") else draw(st.integers(2, 3))
    return (t, "root", [looping() for _ in range(n)], {})


def _show(spec, a, b, xml):
    lines = [f"spec: {spec}", xml]
    for k, (x, y) in enumerate(zip(a, b)):
        mark = "  " if x == y else "!!"
        lines.append(f"{mark} tick {k}: btcpp {x}\n{mark}         btfsm {y}")
    return "\n".join(lines)


@settings(derandomize=True, max_examples=TREES, deadline=None, database=None,
          suppress_health_check=list(HealthCheck))
@given(trees(), st.integers(0, 2**32))
def test_peer_btcpp_random_trees(spec, seed):
    a, b, xml = compare(spec, TICKS, seed)
    assert a == b, _show(spec, a, b, xml)


@settings(derandomize=True, max_examples=TREES_ONCE, deadline=None, database=None,
          suppress_health_check=list(HealthCheck))
@given(trees(), st.integers(0, 2**32))
def test_peer_btcpp_random_trees_tick_once(spec, seed):
    """The same trees ticked with tick_once() (rule 'tickOnce', the default tick)."""
    a, b, xml = compare(spec, TICKS, seed, tick="once")
    assert a == b, _show(spec, a, b, xml)


@settings(derandomize=True, max_examples=TREES_LOOPY, deadline=None, database=None,
          suppress_health_check=list(HealthCheck))
@given(loopy_trees())
def test_peer_btcpp_tick_once_loops(spec):
    """tick_once() on trees of wake-up loops: where btfsm predicts that a tick never
    returns, the real engine runs in a child process and must loop there too (LOOP)."""
    a, b, xml = compare(spec, TICKS, tick="once")
    assert a == b, _show(spec, a, b, xml)


# ---------------------------------------------------------------- the exporter


_EVERY_NODE = """
name: every-node
semantics: btcpp
variables: {t: {int: [0, 3], init: 3}}
environment: [{event: clock, effects: {t: (t + 1) % 4}}]
primitives:
  go: [success, failure, running]
  beep: [success, failure]
tree:
  ReactiveSequence: root
  children:
    - Condition: ready
      expr: t != 2
    - Parallel: par
      success_threshold: -1
      failure_threshold: 2
      children:
        - IfThenElse: ite
          children:
            - {Action: a1, primitive: go}
            - {Inverter: inv, child: {Action: a2, primitive: beep}}
            - {ForceSuccess: fs, child: {Action: a3, primitive: go}}
        - WhileDoElse: wde
          children:
            - {Condition: c2, expr: t < 2}
            - {Retry: retry, attempts: 2, child: {Action: a4, primitive: go}}
        - ParallelAll: pall
          max_failures: 1
          children:
            - {Repeat: rep, times: 2, child: {Action: a5, primitive: beep}}
            - {KeepRunningUntilFailure: krf, child: {Action: a6, primitive: go}}
        - SequenceWithMemory: swm
          children:
            - {RunOnce: once, then_skip: false, child: {Action: a7, primitive: go}}
            - {ForceFailure: ff, child: {Action: a8, primitive: beep}}
        - MemoryFallback: fb
          children:
            - {MemorySequence: seq, children: [{Action: a9, primitive: go}]}
            - {ReactiveFallback: rfb, children: [{Action: a10, primitive: beep}]}
"""


def _load_in_btcpp(xml, stateful=("go",), sync=("beep",), conditions=("ready", "c2")):
    import behaviortreepy as bt

    factory = bt.BehaviorTreeFactory()
    for name in stateful:
        factory.register_simple_stateful_action(name, lambda n: bt.NodeStatus.RUNNING, lambda n: bt.NodeStatus.SUCCESS)
    for name in sync:
        factory.register_simple_action(name, lambda n: bt.NodeStatus.SUCCESS)
    for name in conditions:
        factory.register_simple_condition(name, lambda n: bt.NodeStatus.SUCCESS)
    return factory.create_tree_from_text(xml)


def test_export_cli_btcpp_loads_in_real_engine(tmp_path, capsys):
    """`btfsm export MODEL --format btcpp -o FILE` writes XML that BehaviorTree.CPP loads
    and ticks (every control and decorator node, TreeNodesModel)."""
    from btfsm.cli import main

    model = tmp_path / "every.yaml"
    model.write_text(_EVERY_NODE)
    out = tmp_path / "every.xml"
    assert main(["export", str(model), "--format", "btcpp", "-o", str(out)]) == 0
    xml = out.read_text()
    assert '<root BTCPP_format="4" main_tree_to_execute="every-node">' in xml
    assert '<go name="a1"/>' in xml and '<beep name="a5"/>' in xml and '<Action ID="beep"/>' in xml
    assert '<Condition ID="ready">' in xml and "<description>t != 2</description>" in xml
    tree = _load_in_btcpp(xml)
    for _ in range(4):
        tree.tick_exactly_once()
    assert main(["export", str(model), "--format", "btcpp"]) == 0
    assert capsys.readouterr().out == xml


def test_export_btcpp_escapes_and_refuses():
    """Names and expressions are escaped; Guard/Effects and IDs that are not XML names are
    ModelErrors naming the node."""
    from btfsm import Action, Bool, Condition, Guard, MemorySequence, Model, Primitive
    from btfsm.errors import ModelError
    from btfsm.interop.btcpp_export import to_btcpp_xml

    m = Model('a "quoted" & <odd> model', variables=[Bool("x")], primitives=[Primitive("work")],
              tree=MemorySequence("s<&>'\"", [Condition("is_x", "x and not x"), Action("w 1", "work")]))
    xml = to_btcpp_xml(m)
    assert 'main_tree_to_execute="a &quot;quoted&quot; &amp; &lt;odd&gt; model"' in xml
    assert '<Sequence name="s&lt;&amp;&gt;&apos;&quot;">' in xml and '<work name="w 1"/>' in xml
    tree = _load_in_btcpp(xml, stateful=(), sync=("work",), conditions=("is_x",))
    assert str(tree.tick_exactly_once()).endswith("SUCCESS")
    args = to_btcpp_xml(Model("a", primitives=[Primitive("move")],
                              tree=Action("m", "move", args={"speed": 3, "fast": True, "via": [1, 2]})))
    assert '<move name="m" fast="true" speed="3" via="1;2"/>' in args
    assert '<input_port name="fast" type="bool"/>' in args  # a port per arg, typed by its value (register it with ports)
    assert '<input_port name="speed" type="int"/>' in args and '<input_port name="via" type="std::string"/>' in args
    with pytest.raises(ModelError, match="Guard has no BehaviorTree.CPP counterpart"):
        to_btcpp_xml(Model("g", variables=[Bool("x")], primitives=[Primitive("work")],
                           tree=Guard("g", Action("w", "work"), "x")))
    with pytest.raises(ModelError, match="not an XML name"):
        to_btcpp_xml(Model("g", primitives=[Primitive("two words")], tree=Action("w", "two words")))


def test_export_refuses_py_trees_selected_children():
    from btfsm import Model
    from btfsm.bt import Action, Parallel
    from btfsm.errors import ModelError
    from btfsm.interop.btcpp_export import to_btcpp_xml

    from btfsm import running, success
    tree = Parallel("p", [Action("a", outcomes=[success()]), Action("b", outcomes=[running()])], selected=("a",))
    with pytest.raises(ModelError, match="SuccessOnSelected"):
        to_btcpp_xml(Model("m", tree=tree))
