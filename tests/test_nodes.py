"""A node type is declared once (docs/nodes.md): its class in btfsm/bt.py, its rule in
btfsm/semantics.py. The schema's node part is what the classes say; every type has a rule
and a row in docs/semantics.md; the table below says which other files name each type
(a new type adds its row, which shows the files it touched); the worked example of
docs/nodes.md loads, compiles, ticks, dumps, validates and model-checks.
"""
from __future__ import annotations

import io
import json
import re
import tokenize
from pathlib import Path

import jsonschema
import pytest

from btfsm.bt import NODE_TYPES, arity_text, file_fields, names_in
from btfsm.errors import ModelError
from btfsm.files import dumps_model, loads_data, loads_model
from btfsm.files.schema import SCHEMA_FILE, node_definitions, shipped_node_definitions
from btfsm.oracles import ScriptOracle
from btfsm.semantics import CAN_RUN, RULES, SLOTS
from btfsm.status import Status

ROOT = Path(__file__).resolve().parent.parent

#: node type -> the files besides btfsm/bt.py, btfsm/semantics.py and btfsm/__init__.py
#: whose code names it (docstrings and comments aside): the engines' rules that are not
#: facts of the type (py_trees' constructors, what BT.CPP cannot express), drawings, and
#: the leaves everything works with
ELSEWHERE = {
    "ReactiveSequence": {"btfsm/interop/pytrees.py"},
    "MemorySequence": {"btfsm/interop/pytrees.py"},
    "ReactiveFallback": {"btfsm/interop/pytrees.py"},
    "MemoryFallback": {"btfsm/interop/pytrees.py"},
    "Parallel": {"btfsm/interop/btcpp_export.py", "btfsm/interop/pytrees.py", "btfsm/show.py",
                 "verify/properties/exclusive.py"},
    "SequenceWithMemory": set(), "ParallelAll": set(), "IfThenElse": set(), "WhileDoElse": set(),
    "PipelineSequence": set(), "RecoveryNode": set(), "RoundRobin": set(),
    "Inverter": set(), "ForceSuccess": set(), "ForceFailure": set(),
    "Retry": {"btfsm/interop/pytrees.py", "btfsm/show.py"},
    "Repeat": {"btfsm/interop/pytrees.py", "btfsm/show.py"},
    "KeepRunningUntilFailure": {"btfsm/interop/pytrees.py"},
    "RunOnce": set(),
    "Guard": {"btfsm/interop/btcpp_export.py", "btfsm/interop/pytrees.py", "btfsm/show.py", "verify/explore.py"},
    "Effects": {"btfsm/interop/btcpp_export.py", "btfsm/interop/pytrees.py", "btfsm/show.py", "verify/explore.py"},
    "SubTree": {"btfsm/interop/btcpp_export.py", "verify/runlog.py"},
    "Condition": {"btfsm/interop/btcpp_export.py", "btfsm/interop/pytrees.py", "btfsm/show.py", "verify/explore.py",
                  "verify/properties/lints.py", "verify/runlog.py"},
    "Action": {"btfsm/files/reading.py", "btfsm/files/repair.py", "btfsm/interop/btcpp_export.py", "btfsm/interop/pytrees.py", "btfsm/model.py",
               "btfsm/show.py", "sim/durations.py", "verify/explore.py", "verify/properties/lints.py"},
    "SkillRequest": {"btfsm/files/repair.py", "btfsm/interop/btcpp_export.py", "btfsm/interop/pytrees.py", "btfsm/model.py", "btfsm/show.py",
                     "sim/trial.py", "verify/explore.py", "verify/promela.py", "verify/properties/lints.py",
                     "verify/skills.py", "verify/smv.py", "verify/stepspec.py", "verify/treegoals.py"},
    "FailureIsRunning": set(), "RunningIsFailure": set(), "RunningIsSuccess": set(),
}
HOME = {"btfsm/bt.py", "btfsm/semantics.py", "btfsm/__init__.py"}


def _named_in_code():
    """node type -> the source files whose code (not docstrings or comments) names it."""
    out = {k: set() for k in NODE_TYPES}
    for folder in ("btfsm", "verify", "sim", "models"):
        for path in (ROOT / folder).rglob("*.py"):
            rel = path.relative_to(ROOT).as_posix()
            for tok in tokenize.generate_tokens(io.StringIO(path.read_text()).readline):
                if tok.type == tokenize.NAME and tok.string in out:
                    out[tok.string].add(rel)
    return out


def test_each_node_type_is_named_where_the_table_says():
    named = _named_in_code()
    assert set(ELSEWHERE) == set(NODE_TYPES)
    assert {k: v - HOME - {f for f in v if f.startswith("models/")} for k, v in named.items()} == ELSEWHERE
    assert all("btfsm/bt.py" in v for v in named.values())


def test_the_schema_node_part_is_generated_from_the_classes():
    """``python -m btfsm.files.schema`` rewrites it when this fails."""
    assert shipped_node_definitions(SCHEMA_FILE) == node_definitions()


def test_every_node_type_has_a_rule_and_a_row():
    doc = (ROOT / "docs" / "semantics.md").read_text()
    rows = {name for cell in re.findall(r"^\| ([^|]*)\|", doc, re.M) for name in re.findall(r"`(\w+)", cell)}
    for key, cls in NODE_TYPES.items():
        assert cls in RULES, key
        assert key in rows, f"{key} has no row in docs/semantics.md"


def test_engine_names_and_child_counts_come_from_the_classes():
    from btfsm.interop.btcpp_export import TAGS
    from btfsm.interop.btcpp_import import CONTROLS, DECORATORS
    from btfsm.interop.nav2 import CONTROLS as NAV2
    from btfsm.profiles import PROFILES

    assert {cls.__name__: tag for cls, tag in TAGS.items()} == names_in("btcpp")  # Nav2's controls too
    assert {v[0] for v in {**CONTROLS, **DECORATORS, **NAV2}.values()} == set(names_in("btcpp"))
    assert PROFILES["btcpp"].node_name("Retry") == "RetryUntilSuccessful"
    assert PROFILES["pytrees"].node_name("Guard") == "EternalGuard"
    assert arity_text(NODE_TYPES["IfThenElse"]) == "2 or 3 children"
    with pytest.raises(ModelError, match=r"<string>: tree: RecoveryNode needs exactly 2 children, got 1"):
        loads_model("name: m\ntree: {RecoveryNode: r, children: [{Action: a, outcomes: [success]}]}\n")


def _doc_blocks():
    text = (ROOT / "docs" / "nodes.md").read_text()
    part = text[text.index("## A worked example"):]
    return re.findall(r"```python\n(.*?)```", part, re.S)[0], re.findall(r"```yaml\n(.*?)```", part, re.S)[0]


@pytest.fixture
def worked_example():
    code, yaml_text = _doc_blocks()
    tables = (NODE_TYPES, RULES, SLOTS, CAN_RUN)
    before = [dict(x) for x in tables]
    ns: dict = {}
    exec(compile(code, "docs/nodes.md", "exec"), ns)
    try:
        yield ns["StatusOverride"], yaml_text
    finally:
        for table, old in zip(tables, before):
            table.clear()
            table.update(old)


def test_the_worked_example_of_docs_nodes(worked_example):
    from btfsm.interop.btcpp_export import to_btcpp_xml
    from btfsm.verify import check

    cls, yaml_text = worked_example
    assert [f.name for f in file_fields(cls)] == ["success"]
    m = loads_model(yaml_text)
    assert type(m.tree) is cls and m.tree.success is False
    prog = m.program
    # the child's outcomes are [success, failure, running]: choice 0, 1, 2
    got = [Status(prog.step(prog.initial, ScriptOracle([k])).status).name for k in range(3)]
    assert got == ["FAILURE", "FAILURE", "RUNNING"]
    text = dumps_model(m)
    assert "StatusOverride: root" in text and "success: false" in text and loads_model(text) == m
    schema = json.loads(SCHEMA_FILE.read_text())
    schema["$defs"] = {**schema["$defs"], **node_definitions()}
    assert "node_StatusOverride" in schema["$defs"]
    assert list(jsonschema.Draft202012Validator(schema).iter_errors(loads_data(yaml_text))) == []
    bad = loads_data(yaml_text.replace("success: false", "success: 3"))
    assert list(jsonschema.Draft202012Validator(schema).iter_errors(bad))
    with pytest.raises(ModelError, match=r"tree\.success: expected true or false, got an integer \(line 4\)"):
        loads_model(yaml_text.replace("success: false", "success: 3"))
    with pytest.raises(ModelError, match="node type StatusOverride cannot be exported to BehaviorTree.CPP"):
        to_btcpp_xml(m)
    report = check(m)
    assert report.complete and report.states > 0
