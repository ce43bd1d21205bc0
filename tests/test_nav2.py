"""The ``nav2`` node library and Groot2 node models (docs/semantics.md 8.3, docs/interop.md).

The table tests replay the scenarios of navigation2's own unit tests
(``nav2_behavior_tree/test/plugins/{control,decorator}/test_*.cpp`` at commit a3a9704):
each Nav2 ``DummyNode`` child is a leaf whose answer the table scripts, and the rows pin
the root status, which leaves are ticked (``TableOracle`` fails on any other) and the
halts. Every tree goes through the XML importer with ``--node-library nav2``, so the
mapping of Nav2's tags is under test too. The Python bindings of BehaviorTree.CPP
(``behaviortreepy`` 0.1.4) cannot register a custom ControlNode or DecoratorNode (only
``register_simple_decorator``, which always ticks its child first), so there is no
in-engine port to compare with; Nav2's scenarios are the reference.

The vendored trees (tests/data/nav2, Apache-2.0, see its LICENSE and README) are Nav2's
shipped ``nav2_bt_navigator/behavior_trees`` at that commit, checked as they are.
"""
from __future__ import annotations

import os
import textwrap
from pathlib import Path

import pytest

from btfsm import ModelError
from btfsm.files import load_xml_model
from btfsm.oracles import SucceedOracle

from core_strategies import Tick, run_rows

ROOT = Path(__file__).resolve().parents[1]
NAV2 = ROOT / "tests" / "data" / "nav2"
TREES = sorted((NAV2 / "behavior_trees").glob("*.xml"))


def _xml(tmp_path, body: str, name="t.xml", **kw):
    path = tmp_path / name
    path.write_text(f'<root BTCPP_format="4"><BehaviorTree ID="T">{textwrap.dedent(body)}</BehaviorTree></root>')
    return load_xml_model(path, node_library="nav2", **kw)


# ---------------------------------------------------------------- controls: Nav2's test tables

def test_pipeline_sequence(tmp_path):
    """test_pipeline_sequence.cpp: test_behavior, test_failure (SKIPPED rows: not modelled)."""
    m = _xml(tmp_path, '<PipelineSequence name="p"><a/><b/><c/></PipelineSequence>')
    run_rows(m, [
        Tick("a:R", "R", running="p a"),
        Tick("a:S b:R", "R", running="p b"),
        Tick("a:R b:S c:R", "R", running="p a c"),  # a runs again before the furthest child: go on
        Tick("a:R b:S c:S", "S", running="", halts="a"),  # all done: every child halted
    ])
    run_rows(m, [Tick("a:F", "F", running=""), Tick("a:S b:F", "F"), Tick("a:S b:S c:F", "F"),
                 Tick("a:S b:S c:R", "R", running="p c"),
                 Tick("a:F", "F", running="", halts="c")])  # FAILURE halts the running stage


def test_recovery_node(tmp_path):
    """test_recovery_node.cpp: test_running, test_success_one_retry, test_failure_one_retry."""
    m = _xml(tmp_path, '<RecoveryNode name="r"><a/><b/></RecoveryNode>')
    run_rows(m, [Tick("a:R", "R", running="r a"), Tick("a:F b:R", "R", running="r b")])
    run_rows(m, [Tick("a:S", "S"), Tick("a:F b:S a:S", "S", running="")])  # the retry within the tick
    run_rows(m, [Tick("a:F b:F", "F"), Tick("a:F b:S a:F", "F", running="")])  # one retry, then FAILURE
    m6 = _xml(tmp_path, '<RecoveryNode name="r" number_of_retries="2"><a/><b/></RecoveryNode>')
    steps = run_rows(m6, [Tick("a:F b:S a:R", "R", running="r a"), Tick("a:F b:R", "R", running="r b"),
                          Tick("b:S a:F", "F", running="")])  # the count (2) survives the RUNNING ticks
    assert m6.program.decode(steps[1][0].state)["r:retries"] == 1


def test_round_robin_wrap_around(tmp_path):
    """test_round_robin_node.cpp (its fixture sets wrap_around="true"): test_failure, test_behavior."""
    m = _xml(tmp_path, '<RoundRobin name="rr" wrap_around="true"><a/><b/><c/></RoundRobin>')
    run_rows(m, [Tick("a:F b:R", "R"), Tick("b:F c:R", "R"), Tick("c:F", "F", running="")])
    run_rows(m, [Tick("a:R", "R"), Tick("a:F b:R", "R"), Tick("b:S", "S"), Tick("c:R", "R"),
                 Tick("c:F a:R", "R"), Tick("a:F b:S", "S", running="")])


def test_round_robin_without_wrap_around(tmp_path):
    """test_wrap_around_disabled, and what its code does at the end of the children: the last
    child's SUCCESS ends the run with FAILURE (round_robin_node.cpp breaks out of its loop
    before it looks at the status). Nav2's shipped trees use this default."""
    m = _xml(tmp_path, '<RoundRobin name="rr"><a/><b/><c/></RoundRobin>')
    run_rows(m, [Tick("a:F b:F c:F", "F")])
    run_rows(m, [Tick("a:S", "S"), Tick("b:S", "S"), Tick("c:S", "F"), Tick("a:S", "S")])  # the position is kept
    run_rows(m, [Tick("a:R", "R"), Tick("a:F b:R", "R", running="rr b"), Tick("b:S", "S"), Tick("c:F", "F")])


def test_round_robin_halt_resets_the_position(tmp_path):
    m = _xml(tmp_path, '<ReactiveSequence name="root"><stop/><RoundRobin name="rr"><a/><b/></RoundRobin>'
                       '</ReactiveSequence>')
    run_rows(m, [Tick("stop:S a:S", "S"), Tick("stop:S b:R", "R"), Tick("stop:F", "F", halts="b rr"),
                 Tick("stop:S a:F b:F", "F")])  # halted while running: back to the first child


# ---------------------------------------------------------------- decorators: the abstractions

def test_rate_controller(tmp_path):
    """test_rate_controller.cpp: SUCCESS at once, then RUNNING and SUCCESS by turns as the
    period elapses; each row is one answer of the gate 'rc/elapsed'."""
    m = _xml(tmp_path, '<RateController name="rc" hz="1.0"><a/></RateController>')
    run_rows(m, [Tick("rc/elapsed:S a:S", "S"),
                 Tick("rc/elapsed:R", "R", running="rc rc/elapsed"), Tick("rc/elapsed:S a:S", "S"),
                 Tick("rc/elapsed:R", "R"), Tick("rc/elapsed:S a:R", "R", running="rc a"),
                 Tick("a:R", "R"),  # a running child is ticked without asking the clock
                 Tick("a:F", "F", running="")])


@pytest.mark.parametrize("tag,question", [("SpeedController", "elapsed"), ("DistanceController", "travelled"),
                                          ("GoalUpdatedController", "goal_updated")])
def test_throttling_decorators(tmp_path, tag, question):
    """test_goal_updated_controller.cpp's rows (ticked, ticked, not ticked: RUNNING, ticked);
    SpeedController and DistanceController throttle the same way on time or distance."""
    m = _xml(tmp_path, f'<{tag} name="d"><a/></{tag}>')
    g = f"d/{question}"
    run_rows(m, [Tick(f"{g}:S a:S", "S"), Tick(f"{g}:S a:S", "S"), Tick(f"{g}:R", "R"), Tick(f"{g}:S a:S", "S")])


def test_single_trigger(tmp_path):
    """test_single_trigger_node.cpp, including the run after a halt."""
    m = _xml(tmp_path, '<ReactiveSequence name="root"><go/><SingleTrigger name="st"><a/></SingleTrigger>'
                       '</ReactiveSequence>')
    run_rows(m, [Tick("go:S st/first_time:S a:S", "S"), Tick("go:S st/first_time:F", "F"),
                 Tick("go:S st/first_time:F", "F"),
                 Tick("go:S st/first_time:S a:R", "R"), Tick("go:S a:S", "S"), Tick("go:S st/first_time:F", "F")])


def test_path_longer_on_approach_and_goal_updater(tmp_path):
    m = _xml(tmp_path, '<PathLongerOnApproach name="pl" path="{path}" prox_len="3.0"><GoalUpdater '
                       'input_goal="{goal}" output_goal="{g2}"><a/></GoalUpdater></PathLongerOnApproach>')
    run_rows(m, [Tick("pl/longer_path:F", "S"), Tick("pl/longer_path:S a:R", "R"), Tick("pl/longer_path:S a:F", "F")])
    assert "GoalUpdater" not in {n.name for n in m.tree_nodes()} if hasattr(m, "tree_nodes") else True


# ---------------------------------------------------------------- leaves, ports, models

def test_leaves_get_outcomes_and_port_types_from_the_library(tmp_path):
    m = _xml(tmp_path, '<Sequence><GoalUpdated/><ControllerSelector selected_controller="{c}" '
                       'default_controller="FollowPath"/><PlannerSelector selected_planner="{p}"/>'
                       '<TruncatePathLocal input_path="{path}" output_path="{rest}"/>'
                       '<FollowPath path="{path}" controller_id="{c}"/><Spin/><ClearEntireCostmap/></Sequence>')
    prims = {p.name: sorted(o.status.name for o in p.outcomes) for p in m.primitives}
    assert prims["GoalUpdated"] == ["FAILURE", "SUCCESS"]  # a condition
    assert prims["ControllerSelector"] == ["SUCCESS"]  # a selector with a default cannot fail
    assert prims["PlannerSelector"] == ["FAILURE", "SUCCESS"]  # BT::SyncActionNode without a default
    assert prims["TruncatePathLocal"] == ["FAILURE", "SUCCESS"]  # its tick() never returns RUNNING
    assert prims["FollowPath"] == prims["ClearEntireCostmap"] == ["FAILURE", "RUNNING", "SUCCESS"]
    assert m.variables == ()  # {path} (nav_msgs::msg::Path) and {c} (string) are not finite: left out
    assert not m.warnings
    nodes = {n.name: n for n in _walk(m.tree)}
    assert nodes["FollowPath"].duration == (0.05, None) and nodes["Spin"].duration == (0.05, None)
    assert nodes["ClearEntireCostmap"].duration is None  # a service node may answer on its first tick


def test_an_action_server_leaf_answers_running_on_its_first_tick(tmp_path):
    """The library's one assumption (BtActionNode: the result comes on a later tick than the goal)."""
    m = _xml(tmp_path, '<Sequence name="s"><FollowPath/></Sequence>')
    run_rows(m, [Tick("FollowPath:R", "R"), Tick("FollowPath:S", "S"), Tick("FollowPath:R", "R"),
                 Tick("FollowPath:F", "F")])
    step = m.program.step(m.program.initial, SucceedOracle())  # SUCCESS on the first tick: no transition
    assert step.state is None and step.violations[0][0] == "timing"



def test_undeclared_port_and_unknown_node_are_refused(tmp_path):
    with pytest.raises(ModelError, match=r"port 'pth' is not declared for FollowPath"):
        _xml(tmp_path, '<FollowPath pth="{path}"/>')
    with pytest.raises(ModelError, match=r"line 1: <inverter>: unknown node type with children .*did you mean 'Inverter'"):
        _xml(tmp_path, '<inverter><GoalUpdated/></inverter>')
    with pytest.raises(ModelError, match=r"PersistentSequence keeps its child index on the blackboard"):
        _xml(tmp_path, '<PersistentSequence current_child_idx="{i}"><a/></PersistentSequence>')


def test_without_the_library_nav2_nodes_are_refused(tmp_path):
    path = tmp_path / "t.xml"
    path.write_text('<root BTCPP_format="4"><BehaviorTree ID="T"><PipelineSequence><a/></PipelineSequence>'
                    '</BehaviorTree></root>')
    with pytest.raises(ModelError, match="unknown node type with children"):
        load_xml_model(path)


def test_groot_node_models_every_port_kind(tmp_path):
    """A TreeNodesModel file (--nodes) types the ports; bidirectional_port is inout."""
    (tmp_path / "models.xml").write_text(
        '<root BTCPP_format="4"><TreeNodesModel><Action ID="Pick"><input_port name="part" type="bool"/>'
        '<output_port name="held" type="bool">text</output_port><inout_port name="n" type="bool"/>'
        '<bidirectional_port name="m" type="bool"/></Action><Condition ID="Ok"/></TreeNodesModel></root>')
    path = tmp_path / "t.xml"
    path.write_text('<root BTCPP_format="4"><BehaviorTree ID="T"><Sequence><Ok/><Pick part="{p}" held="{h}" '
                    'n="{n}" m="{m}"/></Sequence></BehaviorTree></root>')
    m = load_xml_model(path, nodes=[tmp_path / "models.xml"])
    assert sorted(v.name for v in m.variables) == ["h", "m", "n", "p"]
    prims = {p.name: p for p in m.primitives}
    assert sorted({o.status.name for o in prims["Ok"].outcomes}) == ["FAILURE", "SUCCESS"]  # a Condition
    pick = next(n for n in _walk(m.tree) if n.name == "Pick")
    assert len(pick.outcomes) == 3 * 8  # writes h, n, m (output, inout, bidirectional): every value
    with pytest.raises(ModelError, match=r"port 'x' is not declared for Pick"):
        path.write_text('<root BTCPP_format="4"><BehaviorTree ID="T"><Pick x="1"/></BehaviorTree></root>')
        load_xml_model(path, nodes=[tmp_path / "models.xml"])


def _walk(n):
    yield n
    for c in n.children_of():
        yield from _walk(c)


def test_main_tree_include_and_numbered_keys(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "lib.xml").write_text(
        '<root BTCPP_format="4"><BehaviorTree ID="Lib"><Sequence><act/><act/></Sequence></BehaviorTree></root>')
    (tmp_path / "t.xml").write_text('<root BTCPP_format="4"><include path="sub/lib.xml"/>'
                                    '<BehaviorTree ID="A"><SubTree ID="Lib"/></BehaviorTree>'
                                    '<BehaviorTree ID="B"><AlwaysSuccess/></BehaviorTree></root>')
    (tmp_path / "t.btfsm.yaml").write_text("nodes:\n  Lib/act#2: {outcomes: [success], primitive: act2}\n")
    m = load_xml_model(tmp_path / "t.xml", main_tree="A")
    acts = {n.name: n for n in _walk(m.tree) if n.name.startswith("Lib/act")}
    assert sorted(acts) == ["Lib/act", "Lib/act#2"] and acts["Lib/act#2"].primitive == "act2"
    (tmp_path / "t.btfsm.yaml").unlink()
    assert load_xml_model(tmp_path / "t.xml", main_tree="B").name == "B"
    with pytest.raises(ModelError, match=r"main tree 'C' \(--main-tree\) is not defined"):
        load_xml_model(tmp_path / "t.xml", main_tree="C")
    (tmp_path / "sub" / "lib.xml").write_text('<root BTCPP_format="4"><include path="../t.xml"/></root>')
    with pytest.raises(ModelError, match=r"recursive <include>"):
        load_xml_model(tmp_path / "t.xml", main_tree="B")
    (tmp_path / "sub" / "lib.xml").write_text('<root BTCPP_format="4"><include path="../../x.xml"/></root>')
    with pytest.raises(ModelError, match=r"leads outside the folder"):
        load_xml_model(tmp_path / "t.xml", main_tree="B")


def test_btcpp_format_3_is_refused_with_the_converter(tmp_path):
    path = tmp_path / "t.xml"
    path.write_text('<root BTCPP_format="3"><BehaviorTree ID="T"><AlwaysSuccess/></BehaviorTree></root>')
    with pytest.raises(ModelError, match=r"line 1: <root>: BTCPP_format=\"3\".*convert_v3_to_v4.py"):
        load_xml_model(path)


# ---------------------------------------------------------------- Nav2's shipped trees

def test_nav2_trees_are_vendored():
    assert len(TREES) == 15 and (NAV2 / "LICENSE").is_file() and (NAV2 / "README.md").is_file()


def _check(capsys, *args):
    from btfsm import cli
    code = cli.main(["check", *map(str, args)])
    out = capsys.readouterr()
    return code, out.out, out.err


@pytest.mark.parametrize("tree", TREES, ids=lambda p: p.stem)
def test_nav2_tree_loads_with_the_library(tree):
    """Every shipped tree loads and compiles as it is, no side file (the full checks are
    test_nav2_trees_check, and BTFSM_LONG=1 runs them on every tree)."""
    m = load_xml_model(tree, node_library="nav2")
    assert not m.warnings and m.semantics == "btcpp"
    assert m.program is not None


def test_nav2_trees_check(capsys):
    """``btfsm check TREE.xml --node-library nav2``: exit 0 or 1 (a finding), never an error
    nor a budget hit. The default run checks the trees without RecoveryNode retry loops
    (each well under a second); BTFSM_LONG=1 checks all 15 (minutes: the in-tick retries
    are merged, docs/semantics.md 8.3; the figures are in tests/data/nav2/README.md)."""
    chosen = TREES if os.environ.get("BTFSM_LONG") else [t for t in TREES if t.stem in SMALL]
    for tree in chosen:
        code, out, err = _check(capsys, tree, "--node-library", "nav2")
        assert code in (0, 1), (tree.name, code, err[-2000:])
        assert "under btcpp semantics" in out


SMALL = ("follow_point", "odometry_calibration", "navigate_to_pose_w_bounds_check", "navigate_w_replanning_distance",
         "navigate_w_replanning_only_if_goal_is_updated", "navigate_w_replanning_only_if_path_becomes_invalid",
         "navigate_w_replanning_speed", "navigate_w_replanning_time")


def test_docking_example_is_refused_for_its_inverter_typo(capsys):
    code, _out, err = _check(capsys, NAV2 / "docking" / "application_example.xml", "--node-library", "nav2")
    assert code == 2
    assert "application_example.xml: line 22: <inverter>: unknown node type with children" in err
    assert "did you mean 'Inverter'" in err and "Traceback" not in err


# ---------------------------------------------------------------- issue 20.4: lints in the profile's names

@pytest.mark.parametrize("semantics,text", [
    ("btfsm", "reactive sequence with several children that can run (a, b): an earlier one restarts each tick and "
              "halts the later ones; use MemorySequence"),
    ("btcpp", "ReactiveSequence with several children that can run (a, b): an earlier one restarts each tick and "
              "halts the later ones; use Sequence"),
    ("pytrees", "Sequence(memory=False) with several children that can run (a, b): an earlier one restarts each tick "
                "and halts the later ones; use Sequence(memory=True)")])
def test_lints_speak_the_profile_node_names(semantics, text):
    from btfsm import Action, Model, Outcome, ReactiveSequence, Status
    outs = (Outcome(Status.RUNNING), Outcome(Status.SUCCESS))
    m = Model("m", tree=ReactiveSequence("rs", [Action("a", outcomes=outs), Action("b", outcomes=outs)]),
              semantics=semantics)
    assert m.program.lints == [("tree.rs", text)]


def test_side_file_keys_node_library_and_node_models(tmp_path, capsys):
    (tmp_path / "m").mkdir()
    (tmp_path / "m" / "models.xml").write_text(
        '<root BTCPP_format="4"><TreeNodesModel><Condition ID="Ready"><input_port name="flag" type="bool"/>'
        '</Condition></TreeNodesModel></root>')
    (tmp_path / "t.xml").write_text('<root BTCPP_format="4"><BehaviorTree ID="T"><PipelineSequence name="p">'
                                    '<Ready flag="{f}"/><FollowPath/></PipelineSequence></BehaviorTree></root>')
    (tmp_path / "t.btfsm.yaml").write_text("node_library: nav2\nnode_models: m/models.xml\n")
    m = load_xml_model(tmp_path / "t.xml")
    assert [v.name for v in m.variables] == ["f"] and type(m.tree).__name__ == "PipelineSequence"
    (tmp_path / "t.btfsm.yaml").write_text("node_library: nav3\n")
    with pytest.raises(ModelError, match=r"t.btfsm.yaml: node_library: unknown node library 'nav3' \(one of: nav2\)"):
        load_xml_model(tmp_path / "t.xml")
    from btfsm import cli
    assert cli.main(["validate", str(tmp_path / "t.xml"), "--node-library", "nav2", "--nodes",
                     str(tmp_path / "m" / "models.xml")]) == 0
    assert "ok" in capsys.readouterr().out
