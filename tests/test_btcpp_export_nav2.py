"""``btfsm export --format btcpp``: ports keep the direction and type the model knows
(issue 20.6), Nav2's controls are written back as Nav2 writes them, and the nav2 library's
gates (its model of Nav2's throttling decorators) are refused naming the node. Round trip:
export, import again (``--node-library nav2``, the rest from the side file), the same
transition system."""
from __future__ import annotations

import textwrap
from pathlib import Path

import pytest
import yaml

from btfsm import ModelError
from btfsm.files import load_xml_model, loads_model, model_to_data
from btfsm.interop.btcpp_export import to_btcpp_xml
from btfsm.verify.explore import explore

ROOT = Path(__file__).resolve().parents[1]

MODEL = textwrap.dedent("""
    name: nav
    semantics: btcpp
    variables: {holding: bool, n: {int: [0, 2]}, zone: {enum: [a, b]}}
    primitives:
      grab: [{success: {holding: true}}, failure, running]
      look: [success, failure]
      count: [{success: {n: "min(n + 1, 2)"}}, failure]
    tree:
      RecoveryNode: nav
      retries: 2
      children:
        - PipelineSequence: pipe
          children:
            - {Action: grab_it, primitive: grab, args: {holding: "{holding}", speed: 0.5, tries: 3, careful: true}}
            - {Action: look_at, primitive: look, args: {where: "{zone}", n: "{n}"}}
        - RoundRobin: recover
          wrap_around: true
          children:
            - {Action: count_up, primitive: count, args: {n: "{n}"}}
            - {Action: look_again, primitive: look, args: {label: hello}}
    """)


def _systems(model):
    ts = explore(model)
    return ts.n_states, ts.n_transitions, sorted(map(repr, ts.labels)), sorted(map(tuple, ts.states.tolist()))


def test_ports_and_nav2_controls_round_trip(tmp_path):
    model = loads_model(MODEL)
    xml = to_btcpp_xml(model)
    assert '<RecoveryNode name="nav" number_of_retries="2">' in xml and '<PipelineSequence name="pipe">' in xml
    assert '<RoundRobin name="recover" wrap_around="true">' in xml
    grab = xml[xml.index('<Action ID="grab">'):xml.index("</Action>", xml.index('<Action ID="grab">'))]
    assert '<output_port name="holding" type="bool"/>' in grab  # grab's outcomes write it
    assert '<input_port name="speed" type="double"/>' in grab and '<input_port name="tries" type="int"/>' in grab
    assert '<input_port name="careful" type="bool"/>' in grab
    look = xml[xml.index('<Action ID="look">'):xml.index("</Action>", xml.index('<Action ID="look">'))]
    assert '<input_port name="where" type="std::string"/>' in look and '<input_port name="n" type="int"/>' in look
    assert '<input_port name="label" type="std::string"/>' in look
    assert '<output_port name="n" type="int"/>' in xml  # count writes n
    side = {k: v for k, v in model_to_data(model).items() if k != "tree"}
    (tmp_path / "m.xml").write_text(xml)
    (tmp_path / "m.btfsm.yaml").write_text(yaml.safe_dump(side, sort_keys=False))
    back = load_xml_model(tmp_path / "m.xml", node_library="nav2")
    assert _systems(back) == _systems(model)
    again = to_btcpp_xml(back)  # the blackboard ports again as they were (constants come back as text)
    assert '<output_port name="holding" type="bool"/>' in again and '<output_port name="n" type="int"/>' in again


def test_a_nav2_gate_is_refused_naming_the_node():
    model = load_xml_model(ROOT / "tests/data/nav2/behavior_trees/navigate_w_replanning_time.xml", node_library="nav2")
    with pytest.raises(ModelError) as exc:
        to_btcpp_xml(model)
    assert exc.value.element == "tree.RateController/elapsed"
    assert "gate for Nav2's RateController" in exc.value.problem and "cannot write it back" in exc.value.problem
