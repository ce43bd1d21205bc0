"""Model files: format, schema, templates, errors, round trips, fuzzing, ``btfsm validate``."""
from __future__ import annotations

import io
import json
import os
import re
import subprocess
import sys
import types
from pathlib import Path

import jsonschema
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from memo_strategies import st

from btfsm import ModelError
from btfsm.files import (builtin_models, dump_model, dumps_model, expand_templates, load_data, load_model,
                         loads_data, loads_model, model_from_data, model_to_data)
from btfsm.models.registry import SAME_FORM

from strategies import random_models

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = sorted(p for p in (ROOT / "models" / "examples").glob("*.yaml") if not p.name.endswith(".btfsm.yaml"))  # not side files of XML models
SCHEMA = json.loads((ROOT / "btfsm" / "schema" / "model.schema.json").read_text())
VALIDATOR = jsonschema.Draft202012Validator(SCHEMA)
# the fuzzers below: a fast default; tests/test_files_fuzz.py runs 800+ mutated files in every
# run, BTFSM_LONG=1 these three times as many as the fast default
FUZZ = 3 if os.environ.get("BTFSM_LONG") == "1" else 1


def _error(text, fmt="yaml") -> str:
    with pytest.raises(ModelError) as info:
        loads_model(text, fmt, file_name="m." + fmt)
    return str(info.value)


def _cli(*args, env=None):
    return subprocess.run([sys.executable, "-m", "btfsm.cli", *map(str, args)], capture_output=True, text=True,
                          cwd=ROOT, env=env, timeout=120)


# ---------------------------------------------------------------- examples and schema


def test_examples_exist():
    assert {p.name for p in EXAMPLES} >= {"two_area.yaml", "templated.yaml"}


def test_schema_is_valid_draft_2020_12():
    jsonschema.Draft202012Validator.check_schema(SCHEMA)
    assert SCHEMA["$schema"] == "https://json-schema.org/draft/2020-12/schema"


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_examples_validate_against_schema_and_load(path):
    data = load_data(path)
    errors = [f"{list(e.absolute_path)}: {e.message[:200]}" for e in VALIDATOR.iter_errors(data)]
    assert errors == []
    model = load_model(path)
    assert list(VALIDATOR.iter_errors(model_to_data(model))) == []
    assert loads_model(dumps_model(model)) == model
    assert loads_model(dumps_model(model, "json"), "json") == model


@pytest.mark.parametrize("bad", [
    {"name": "x", "extra": 1},
    {"description": "no name"},
    {"name": "x", "variables": {"a": "boolean"}},
    {"name": "x", "variables": {"a": {"int": [0]}}},
    {"name": "x", "primitives": {"p": [{"success": {}, "failure": {}}]}},
    {"name": "x", "tree": {"Condition": "c", "Action": "a", "expr": "true"}},
    {"name": "x", "tree": {"Condition": "c", "exp": "true"}},
    {"name": "x", "tree": {"ReactiveSequence": "r", "children": [{"Inverter": "i"}]}},
    {"name": "x", "fsms": {"f": {"goals": ["g"], "states": ["a"], "edges": [{"from": "a", "to": "a", "on": "ok"}]}}},
    {"name": "x", "fsms": {"f": {"goals": ["g"], "states": ["a"], "markers": [{"state": "a", "outcome": "running"}]}}},
    {"name": "x", "fsms": {"f": {"goals": ["g"], "states": [{"use": "t", "whith": {}}]}}},
    {"name": "x", "environment": [{"choice": "c"}]},
    {"name": "x", "templates": {"t": {"params": ["X"], "bogus": []}}},
    {"name": "x", "tick_rate": 0},
])
def test_schema_rejects_shape_errors(bad):
    assert list(VALIDATOR.iter_errors(bad)) != []
    with pytest.raises(ModelError):
        model_from_data(bad)


def test_two_area_uses_most_features():
    m = load_model(ROOT / "models/examples/two_area.yaml")
    kinds = {v.kind for v in m.variables}
    assert kinds == {"bool", "enum", "int"}
    arm = m.fsm("arm")
    assert any(e.direct for e in arm.edges) and any(e.guard is not None for e in arm.edges)
    assert any(e.effects for e in arm.edges) and any(mk.direct for mk in arm.markers)
    assert arm.params and arm.retarget == "withdraw"
    assert {type(n).__name__ for n in m.nodes()} >= {"Parallel", "ReactiveFallback", "ReactiveSequence", "Retry",
                                                      "Guard", "Effects", "Condition", "Action", "SkillRequest"}
    assert any(type(e).__name__ == "EnvChoice" for e in m.environment)
    assert m.invariants and m.workable is not None and m.terminal is not None
    assert m.warnings == () and m.program.lints == []


def test_templated_example_expands_three_rotations():
    m = load_model(ROOT / "models/examples/templated.yaml")
    arm = m.fsm("arm")
    assert len(arm.states) == 15 and len(arm.edges) == 33 and len(arm.markers) == 18
    assert "bins to conveyor" in [s.id for s in arm.states] and "conveyor to bins" in [s.id for s in arm.states]
    assert arm.goals == ("withdraw", "pick_bins", "place_bins", "pick_agv", "place_agv", "pick_conveyor", "place_conveyor")
    eff = next(n for n in m.nodes() if n.name == "after_conveyor_pick")
    assert [k for k, _ in eff.on_success] == ["belt_part"]  # a lone placeholder took a mapping
    assert next(n for n in m.nodes() if n.name == "after_bins_pick").on_success == ()


# ---------------------------------------------------------------- round trips


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(random_models(), st.sampled_from(["yaml", "json"]))
def test_round_trip_random_models(model, fmt):
    text = dumps_model(model, fmt)
    back = loads_model(text, fmt)
    assert back == model
    assert dumps_model(back, fmt) == text
    assert list(VALIDATOR.iter_errors(model_to_data(model))) == []


@pytest.mark.parametrize("name", sorted(set(builtin_models()) - SAME_FORM))  # another model's states, other numbers
def test_builtin_models_round_trip(name):
    model = load_model(name)
    for fmt in ("yaml", "json"):
        assert loads_model(dumps_model(model, fmt), fmt) == model
    assert list(VALIDATOR.iter_errors(model_to_data(model))) == []


def test_docs_example_loads():
    import re

    doc = (ROOT / "docs" / "model-files.md").read_text()
    text = re.search(r"## A complete small example.*?```yaml\n(.*?)```", doc, re.S).group(1)
    m = loads_model(text)
    assert (len(m.variables), len(m.fsms), len(m.fsms[0].states), len(m.nodes())) == (2, 1, 4, 7)


_LABEL = st.text(min_size=1, max_size=60).filter(str.isprintable).filter(
    lambda t: not re.search(r"\$\{[A-Za-z_][A-Za-z0-9_]*\}", t))  # names cannot hold placeholders


@settings(max_examples=150, deadline=None)
@given(st.text(), _LABEL, _LABEL, st.sampled_from(["yaml", "json"]))
def test_any_text_round_trips(description, name, invariant, fmt):
    """Any label (one line of printable text) and any description survive a dump."""
    from btfsm import FSM, Model, State
    m = Model(name, fsms=[FSM("f", [State(name), State("d:" + name[::-1])], goals=["g:" + name])],
              invariants={invariant: "true"}, description=description)
    assert loads_model(dumps_model(m, fmt), fmt) == m


def test_dump_to_path_and_stream(tmp_path):
    m = load_model(ROOT / "models/examples/two_area.yaml")
    for name in ("m.yaml", "m.yml", "m.json"):
        dump_model(m, tmp_path / name)
        assert load_model(tmp_path / name) == m
    buf = io.StringIO()
    dump_model(m, buf, "json")
    assert loads_model(buf.getvalue(), "json") == m
    assert json.loads(buf.getvalue())["name"] == "two-area-file"


def test_dumped_yaml_reads_the_same_with_plain_pyyaml():
    m = load_model(ROOT / "models/examples/two_area.yaml")
    assert yaml.safe_load(dumps_model(m)) == model_to_data(m)  # 'on' is quoted for YAML 1.1 readers


# ---------------------------------------------------------------- YAML details


def test_yaml_core_scalars():
    d = loads_data("on: direct\nyes: no\nn: 010\nh: 0x1F\no: 0o17\nf: 1e3\nz: ~\nt: True\ns: 1:20\nb: 0b11\nd: 2021-01-02")
    assert d == {"on": "direct", "yes": "no", "n": 10, "h": 31, "o": 15, "f": 1000.0, "z": None, "t": True,
                 "s": "1:20", "b": "0b11", "d": "2021-01-02"}


def test_dump_quotes_strings_that_would_read_as_other_types():
    from btfsm import Action, Model, ReactiveSequence, success
    odd = ["1e3", "0o17", "on", "yes", "true", "~", "010", "0x1F", ".5", "- x", "a: b", "#c"]
    m = Model("m", tree=ReactiveSequence("root", [Action(f"a{i}", outcomes=[success()], args={"v": s}) for i, s in enumerate(odd)]))
    assert loads_model(dumps_model(m)) == m


@pytest.mark.parametrize("text, needle", [
    ("name: x\nvariables: {a: bool, a: bool}", "variables: duplicate key 'a' (line 2)"),
    ("name: x\nvariables: {a: bool", "YAML syntax error at line 2"),
    ("name: !!python/object:os.system x", "unsupported YAML tag"),
    ("name: x\nfsms: {a: &x [*x]}", "an alias refers to a value that contains it"),
    ("name: x\ntick_rate: !!int abc", "tick_rate: 'abc' is not an integer"),
    ("name: x\n---\nname: y", "YAML syntax error"),
    ("", "the file is empty"),
    ("- a\n- b", "expected a mapping with the model, got a list"),
    ("name: x\n? [a, b]\n: c", "a mapping key must be a plain value"),
    ("name: x\ndescription: \"\\x00\"\nextra: [" + "[" * 200 + "]" * 200 + "]", "nested"),
])
def test_yaml_problems_are_one_clear_model_error(text, needle):
    msg = _error(text)
    assert needle in msg and "\n" not in msg and msg.startswith("m.yaml")


def test_alias_bomb_is_refused():
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 10) + "]" for i in range(1, 9)]
    assert "more than" in _error("name: x\n" + "\n".join(lines))


def test_json_problems():
    assert "duplicate key 'name'" in _error('{"name": "x", "name": "y"}', "json")
    assert "NaN is not allowed" in _error('{"name": "x", "tick_rate": NaN}', "json")
    assert "JSON syntax error at line 1, column" in _error('{"name": ', "json")
    assert "nested" in _error('{"name": "x", "d": ' + "[" * 5000 + "]" * 5000 + "}", "json")


def test_not_utf8_and_unknown_extension(tmp_path):
    p = tmp_path / "m.yaml"
    p.write_bytes(b"name: \xff\xfe")
    with pytest.raises(ModelError, match="not UTF-8"):
        load_model(p)
    q = tmp_path / "m.txt"
    q.write_text("name: x")
    with pytest.raises(ModelError, match="extension"):
        load_model(q)


# ---------------------------------------------------------------- shape and model errors


FSM_HEAD = "name: x\nvariables: {n: {int: [0, 3]}}\nfsms:\n  arm:\n    goals: [go]\n    states: [a, b]\n"


@pytest.mark.parametrize("text, needle", [
    (FSM_HEAD + "    edges:\n      - {from: a, to: b}\n      - {from: b, to: nowhere}\n",
     "m.yaml: fsms.arm.edges[1].to: unknown state 'nowhere' (line 9)"),
    (FSM_HEAD + "    edges:\n      - {from: a, to: b}\n      - {from: b, to: a, guard: n > 7}\n",
     "fsms.arm.edges[1].guard: constant 7 is outside the domain of n (0..3) in 'n > 7' (line 9)"),
    (FSM_HEAD + "    edges:\n      - {from: a, to: b, gaurd: 'true'}\n",
     "fsms.arm.edges[0].gaurd: unknown field 'gaurd' (did you mean 'guard'?) (line 8)"),
    (FSM_HEAD + "    edges:\n      - {from: a, to: b, on: sucess}\n", "fsms.arm.edges[0].on: expected success, failure, running or direct"),
    (FSM_HEAD + "    markers: [{state: a, outcome: running}]\n", "fsms.arm.markers[0].outcome: expected success or failure"),
    (FSM_HEAD + "    edges: [{from: a, to: b, guard: 'n >'}]\n", "fsms.arm.edges[0].guard: syntax error"),
    (FSM_HEAD + "    edges: [{from: a, to: b, effects: {n: 'n + 1', m: 1}}]\n", "fsms.arm.edges[0].effects.m: unknown variable 'm'"),
    ("name: x\nvariables: {n: {int: [0, 3]}}\nprimitives:\n  work: [running, {success: {n: n + true}}]\ntree: {Action: w, primitive: work}\n",
     "primitives.work[1].success.n: 'true' is bool, expected int in 'n + true' (line 4)"),
    ("name: x\ntree:\n  ReactiveSequence: root\n  children:\n    - {Condition: c, expr: 'true'}\n"
     "    - {Retry: r, attempts: 0, child: {Condition: d, expr: 'false'}}\n", "tree.children[1].attempts: must be at least 1 (line 6)"),
    ("name: x\ntree: {Condtion: c, expr: 'true'}", "did you mean 'Condition'"),
    ("name: x\ntree: {Condition: c, Action: a}", "a node has exactly one type"),
    ("name: x\ntree: {Inverter: i}", "tree: missing field 'child'"),
    ("name: x\nvariables: {a: boolean}", "variables.a: unknown type 'boolean'"),
    ("name: x\nvariables: {a: {enum: [p, q], init: r}}", "variables.a: initial value: 'r' is not in the domain"),
    ("name: x\nvariables: {a: {int: [3, 0]}}", "variables.a: int a needs integer bounds"),
    ("name: x\nvariables: {a: {int: [0, 3], init: 1.5}}", "variables.a.init: expected an integer, got a number"),
    ("name: x\ntick_rate: true", "tick_rate: expected a finite number"),
    ("name: x\ntick_rate: .inf", "tick_rate: expected a finite number"),
    ("name: x\ntick_rate: 0", "tick_rate: must be a positive number"),
    ("name: x\nenvironment:\n  - choice: c\n    options:\n      - {event: a}\n      - {event: b, effects: {q: true}}",
     "environment[0].options[1].effects.q: unknown variable 'q' (line 6)"),
    ("name: x\nfsms:\n  arm: {goals: [go], states: [a], markers: [{state: a}]}\ntree: {SkillRequest: s, fsm: arm, goal: come}",
     "tree.goal: 'come' is not a goal of arm (go)"),
    ("name: x\ninvariants: {ok: [1]}", "invariants.ok: expected an expression (a string such as \"queue > 0\"), got a list"),
    ("name: x\ninvariants: {ok: 'x >'}", "invariants.ok: syntax error"),
    ("description: no name", "missing field 'name'"),
    ("name: x\nvariabls: {}", "unknown field 'variabls' (did you mean 'variables'?)"),
    ("name: x\nfsms: {arm: {goals: [go], states: [a], edges: [{from: a, to: a, goals: ['*', go]}], terminal: ['*']}}",
     "fsms.arm.terminal: '*' (all goals) is only allowed in edges and markers"),
    ("name: x\ntree: {Action: a, outcomes: [{success: {}, failure: {}}]}", "tree.outcomes[0]: an outcome is"),
    ("name: x\ntree: {Action: a, args: {to: {x: 1}}}", "tree.args.to: an argument is a constant"),
])
def test_errors_name_file_element_and_line(text, needle):
    msg = _error(text)
    assert needle in msg, msg
    assert "\n" not in msg


# ---------------------------------------------------------------- templates


TEMPLATE_HEAD = """
name: t
templates:
  chain:
    params: [X]
    states: ["at_${X}"]
    edges: [{from: "at_${X}", to: home, goals: "go_${X}"}]
    goals: ["go_${X}"]
    markers: [{state: home, goals: "go_${X}"}]
"""


def _fsm(states="[home, {use: chain, for_each: [{X: a}, {X: b}]}]", goals="[{use: chain, for_each: [{X: a}, {X: b}]}]",
         edges="[{use: chain, for_each: [{X: a}, {X: b}]}]", markers="[{use: chain, with: {X: a}}]", head=TEMPLATE_HEAD):
    return head + f"fsms:\n  f:\n    goals: {goals}\n    states: {states}\n    edges: {edges}\n    markers: {markers}\n"


def test_template_expansion_basic():
    m = loads_model(_fsm())
    f = m.fsm("f")
    assert [s.id for s in f.states] == ["home", "at_a", "at_b"]
    assert f.goals == ("go_a", "go_b")
    assert [(e.source, e.goals) for e in f.edges] == [("at_a", ("go_a",)), ("at_b", ("go_b",))]
    assert [m_.goals for m_ in f.markers] == [("go_a",)]


def test_expand_templates_is_pure_data_and_does_not_mutate():
    data = loads_data(_fsm())
    before = json.dumps(data, sort_keys=True)
    out = expand_templates(data)
    assert json.dumps(data, sort_keys=True) == before
    assert "templates" not in out and out["fsms"]["f"]["states"] == ["home", "at_a", "at_b"]


@pytest.mark.parametrize("text, needle", [
    (_fsm(states="[home, {use: chian, with: {X: a}}]"), "fsms.f.states[1].use: unknown template 'chian' (templates: chain)"),
    (_fsm(states="[home, {use: chain}]"), "fsms.f.states[1].with: missing parameter(s) X: template 'chain' takes X"),
    (_fsm(states="[home, {use: chain, with: {X: a, Y: b}}]"), "unknown parameter(s) Y"),
    (_fsm(states="[home, {use: chain, with: {X: a}, for_each: [{X: b}]}]"), "given in both with and for_each"),
    (_fsm(states="[home, {use: chain, with: {X: a}, extra: 1}]"), "unknown field 'extra'"),
    (_fsm(states="[home, 'at_${X}']"), "fsms.f.states[1]: unresolved placeholder in 'at_${X}'"),
    (_fsm(head=TEMPLATE_HEAD.replace('states: ["at_${X}"]', 'states: ["at_${Y}"]')),
     "templates.chain.states[0]: placeholder '${Y}' is not a parameter of this template"),
    (_fsm(head=TEMPLATE_HEAD.replace('states: ["at_${X}"]', 'states: ["at_${X"]')), "malformed placeholder"),
    (_fsm(head=TEMPLATE_HEAD.replace("    markers:", "    bogus: []\n    markers:")), "templates.chain.bogus: unknown field 'bogus'"),
    (_fsm(states="[home, {use: chain, with: {X: [1, 2]}}]"), "only a lone '${X}' can stand for it"),
    (_fsm(states="[home, {use: chain, for_each: {X: a}}]"), "for_each: expected a list of parameter mappings"),
])
def test_template_errors(text, needle):
    msg = _error(text)
    assert needle in msg, msg


def test_template_missing_section_and_value_positions():
    head = "name: t\ntemplates:\n  only_states:\n    params: []\n    states: [s]\n"
    assert "has no 'edges' section (it has: states)" in _error(head + "fsms: {f: {goals: [g], states: [s], edges: [{use: only_states}]}}")
    node = ("name: t\ntemplates:\n  leaf:\n    params: [N]\n    node: {Condition: 'c_${N}', expr: 'true'}\n"
            "tree: {ReactiveSequence: r, children: [{Inverter: i, child: {use: leaf, with: {N: 1}}}]}\n")
    m = loads_model(node)
    assert [n.name for n in m.nodes()] == ["r", "i", "c_1"]
    assert "for_each can only be used inside a list" in _error(node.replace("with: {N: 1}", "for_each: [{N: 1}]"))


def test_whole_fsm_from_a_template_and_nested_templates():
    text = """
name: t
templates:
  pair:
    params: [A]
    states: ["${A}_1", "${A}_2"]
  machine:
    params: [NAME, GOALS]
    fsm:
      goals: "${GOALS}"
      states: [{use: pair, with: {A: "${NAME}"}}]
      edges: [{from: "${NAME}_1", to: "${NAME}_2"}]
fsms:
  left: {use: machine, with: {NAME: l, GOALS: [go, stop]}}
  right: {use: machine, with: {NAME: r, GOALS: [go]}}
"""
    m = loads_model(text)
    assert [s.id for s in m.fsm("left").states] == ["l_1", "l_2"] and m.fsm("left").goals == ("go", "stop")
    assert m.fsm("right").edges[0].goals == ("go",)


def test_template_recursion_and_error_origin():
    loop = "name: t\ntemplates:\n  a:\n    params: []\n    states: [{use: b}]\n  b:\n    params: []\n    states: [{use: a}]\n" \
           "fsms: {f: {goals: [g], states: [{use: a}]}}"
    assert "template 'a' uses itself (a -> b -> a)" in _error(loop)
    bad = _fsm(head=TEMPLATE_HEAD.replace('edges: [{from: "at_${X}", to: home, goals: "go_${X}"}]',
                                          'edges: [{from: "at_${X}", to: home, goals: "go_${X}", guard: "${X} > 1"}]'))
    msg = _error(bad)  # both uses of the template, each with its origin
    assert msg == ("2 problems: m.yaml: fsms.f.edges[0].guard: unknown name 'a' in 'a > 1' "
                   "(line 7, in template 'chain' used at line 14 with X=a); "
                   "m.yaml: fsms.f.edges[1].guard: unknown name 'b' in 'b > 1' "
                   "(line 7, in template 'chain' used at line 14 with X=b)")


# ---------------------------------------------------------------- load_model and the registry


def test_unknown_name_lists_builtins(monkeypatch):
    fake = types.ModuleType("btfsm.models.registry")
    fake.BUILTIN = {"two": "examples/two_area.yaml", "pp": "tests_fake_builder:build", "broken": "nope"}
    monkeypatch.setitem(sys.modules, "btfsm.models.registry", fake)
    with pytest.raises(ModelError, match="built-in models: broken, pp, two"):
        load_model("no_such_model")
    assert load_model("two") == load_model(ROOT / "models/examples/two_area.yaml")
    builder = types.ModuleType("tests_fake_builder")
    builder.build = lambda: load_model(ROOT / "models/examples/templated.yaml")
    monkeypatch.setitem(sys.modules, "tests_fake_builder", builder)
    assert load_model("pp").name == "templated"
    with pytest.raises(ModelError, match="neither module:function nor a model file"):
        load_model("broken")
    builder.build = lambda: 42
    with pytest.raises(ModelError, match="returned int, not a Model"):
        load_model("pp")


def test_load_model_missing_file_and_folder(tmp_path):
    with pytest.raises(ModelError, match="cannot read"):
        load_model(tmp_path / "missing.yaml")
    with pytest.raises(ModelError, match="is a folder"):
        load_model(str(tmp_path))
    assert str(load_model(ROOT / "models/examples/two_area.yaml", file_name="shown.yaml").name) == "two-area-file"
    with pytest.raises(ModelError, match="^shown.yaml: "):
        load_model(tmp_path / "missing.yaml", file_name="shown.yaml")


def test_loader_imports_no_checker_or_simulator():
    code = ("import sys, btfsm.files as f; f.load_model('models/examples/two_area.yaml');"
            "bad = [m for m in sys.modules if m.split('.')[0] in ('verify', 'sim')]; print(bad)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert out.returncode == 0 and out.stdout.strip() == "[]", out.stderr


# ---------------------------------------------------------------- fuzzing


_KEYS = ["name", "variables", "fsms", "tree", "states", "edges", "markers", "goals", "from", "to", "on", "guard",
         "effects", "children", "child", "Condition", "Action", "ReactiveSequence", "Parallel", "expr", "use", "with",
         "for_each", "templates", "params", "bool", "enum", "int", "init", "environment", "event", "choice", "options",
         "primitives", "success", "outcomes", "invariants", "id", "state", "outcome", "tick_rate", "workable"]
_SCALARS = st.one_of(st.none(), st.booleans(), st.integers(-5, 5), st.floats(allow_nan=True), st.sampled_from(
    ["", "x", "a", "b", "bool", "success", "direct", "n > 1", "not x", "${X}", "*", "go", "int", "1 +", "[", "True"]),
    st.text(max_size=8))
_DATA = st.recursive(_SCALARS, lambda kids: st.one_of(
    st.lists(kids, max_size=4), st.dictionaries(st.one_of(st.sampled_from(_KEYS), st.text(max_size=5)), kids, max_size=5)),
    max_leaves=25)


def _only_model_errors(fn, *args):
    try:
        fn(*args)
    except ModelError as exc:
        assert "\n" not in str(exc)


@settings(max_examples=100 * FUZZ, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.dictionaries(st.sampled_from(_KEYS), _DATA, max_size=6), st.sampled_from(["yaml", "json"]))
def test_fuzz_random_data_only_raises_model_error(data, fmt):
    data.setdefault("name", "x") if isinstance(data, dict) else None
    _only_model_errors(model_from_data, data)
    try:
        text = dumps = json.dumps(data) if fmt == "json" else yaml.safe_dump(data)
    except ValueError:  # NaN in strict JSON; not a model file anyway
        return
    del dumps
    _only_model_errors(loads_model, text, fmt)


def _mutate_data(data, ops, draw_value):
    """Apply structural mutations (delete, replace, rename, duplicate) at random paths."""
    import copy

    data = copy.deepcopy(data)
    for op, pick, value in ops:
        containers = []
        stack = [data]
        while stack:
            x = stack.pop()
            if isinstance(x, dict) and x:
                containers.append(x)
                stack.extend(x.values())
            elif isinstance(x, list) and x:
                containers.append(x)
                stack.extend(x)
        if not containers:
            return data
        c = containers[pick % len(containers)]
        keys = list(c) if isinstance(c, dict) else list(range(len(c)))
        k = keys[(pick // 7) % len(keys)]
        if op == "delete":
            del c[k]
        elif op == "replace":
            c[k] = value
        elif op == "rename" and isinstance(c, dict):
            c[str(value)[:6] or "k"] = c.pop(k)
        elif op == "duplicate" and isinstance(c, list):
            c.append(c[k])
    return data


_EXAMPLE_DATA = {p.name: load_data(p) for p in EXAMPLES}
_EXAMPLE_TEXT = {p.name: p.read_text() for p in EXAMPLES}


@settings(max_examples=70 * FUZZ, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(sorted(_EXAMPLE_DATA)),
       st.lists(st.tuples(st.sampled_from(["delete", "replace", "rename", "duplicate"]), st.integers(0, 10_000), _DATA),
                min_size=1, max_size=3))
def test_fuzz_mutated_example_data(name, ops):
    _only_model_errors(model_from_data, _mutate_data(_EXAMPLE_DATA[name], ops, None))


_TEXT_EDITS = st.lists(st.tuples(st.sampled_from(["delete", "insert", "swap_lines", "dup_line"]), st.integers(0, 10**6),
                                 st.text(alphabet=" \n\t:-{}[],'\"&*!#|>%@`${}abcx0123456789", max_size=6)),
                       min_size=1, max_size=4)


def _mutate_text(text, edits):
    for op, pos, s in edits:
        i = pos % (len(text) + 1)
        lines = text.split("\n")
        j = pos % len(lines)
        if op == "delete":
            text = text[:i] + text[i + 1 + pos % 5:]
        elif op == "insert":
            text = text[:i] + s + text[i:]
        elif op == "swap_lines" and len(lines) > 1:
            k = (j + 1) % len(lines)
            lines[j], lines[k] = lines[k], lines[j]
            text = "\n".join(lines)
        elif op == "dup_line":
            text = "\n".join(lines[:j] + [lines[j]] + lines[j:])
    return text


@settings(max_examples=70 * FUZZ, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.sampled_from(sorted(_EXAMPLE_TEXT)), _TEXT_EDITS)
def test_fuzz_mutated_example_text(name, edits):
    _only_model_errors(loads_model, _mutate_text(_EXAMPLE_TEXT[name], edits), "yaml", name)


@settings(max_examples=12 * FUZZ, deadline=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(st.sampled_from(sorted(_EXAMPLE_TEXT)), _TEXT_EDITS)
def test_fuzz_cli_validate_exit_codes(tmp_path, capsys, name, edits):
    """``btfsm validate``'s main in this process (the test_cli_validate_* tests below run
    the real command)."""
    from btfsm.cli import main

    path = tmp_path / name
    path.write_text(_mutate_text(_EXAMPLE_TEXT[name], edits))
    try:
        code = main(["validate", str(path)])
    except SystemExit as exc:
        code = exc.code
    out = capsys.readouterr()
    assert code in (0, 2), out.err
    assert "Traceback" not in out.err
    if code == 2:  # one line per problem found (and then their count when there are several)
        lines = out.err.splitlines()
        problems = lines if len(lines) == 1 else lines[:-1]
        assert out.err.endswith("\n") and all(x.startswith("btfsm validate: error: ") for x in problems), out.err
        assert len(lines) == 1 or lines[-1].startswith(f"btfsm validate: {len(problems)} errors"), out.err


# ---------------------------------------------------------------- btfsm validate


def test_cli_validate_ok():
    out = _cli("validate", "models/examples/two_area.yaml")
    assert out.returncode == 0, out.stderr
    assert out.stdout == "models/examples/two_area.yaml: ok (6 variables, 1 FSM with 6 states, 14 tree nodes)\n"


def test_cli_validate_warnings_and_strict(tmp_path):
    p = tmp_path / "w.yaml"
    p.write_text("name: w\nfsms:\n  arm:\n    goals: [go]\n    states: [a, b, lonely]\n"
                 "    edges: [{from: a, to: b}]\n    markers: [{state: b}]\n"
                 "tree:\n  ReactiveSequence: both\n  children:\n    - {SkillRequest: s1, fsm: arm, goal: go}\n"
                 "    - {Action: slow, outcomes: [running, success]}\n")
    out = _cli("validate", p)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0].endswith(": ok (0 variables, 1 FSM with 3 states, 3 tree nodes)")
    assert "warning: fsms.arm.states.lonely: state 'lonely' is unreachable from 'a'" in lines
    assert any(line.startswith("warning: tree.both: reactive sequence") for line in lines)  # a lint
    strict = _cli("validate", p, "--strict")
    assert strict.returncode == 1 and strict.stdout == out.stdout


def test_cli_validate_errors_exit_2_one_line(tmp_path):
    p = tmp_path / "bad.yaml"
    p.write_text(FSM_HEAD + "    edges: [{from: a, to: b, guard: 'n >> 1'}]\n")
    for target in (p, tmp_path / "missing.yaml", "no_such_builtin"):
        out = _cli("validate", target)
        assert out.returncode == 2 and "Traceback" not in out.stderr
        assert out.stderr.count("\n") == 1 and out.stdout == ""
    assert "fsms.arm.edges[0].guard" in _cli("validate", p).stderr


MULTI_SOURCE = """name: multi
fsms:
  arm:
    goals: [work, rest]
    states: [home, a, b, c]
    edges:
      - {from: home, to: a, goals: work}
      - {from: a, to: b, goals: work}
      - {from: [a, b, c], to: home, goals: rest, when: direct, guard: "true", effects: {}, ID}
tree: {SkillRequest: go, fsm: arm, goal: work}
"""


@pytest.mark.parametrize("ident", ["", "id: back"])
def test_edge_with_a_list_of_sources_is_one_edge_per_source(ident):
    text = MULTI_SOURCE.replace(", ID}", (", " + ident if ident else "") + "}")
    one_by_one = text.replace("- {from: [a, b, c], to: home",
                              "- {from: a, to: home, goals: rest, when: direct, guard: \"true\", effects: {}, ID}\n"
                              "      - {from: b, to: home, goals: rest, when: direct, guard: \"true\", effects: {}, ID}\n"
                              "      - {from: c, to: home").replace(", ID}", (", " + ident if ident else "") + "}")
    if ident:  # written one by one, the ids must differ
        one_by_one = one_by_one.replace("id: back", "id: back/a", 1).replace("id: back}", "id: back/b}", 1) \
                               .replace("id: back}", "id: back/c}", 1)
    data = yaml.safe_load(text)
    VALIDATOR.validate(data)
    got, want = loads_model(text).fsm("arm").edges, loads_model(one_by_one).fsm("arm").edges
    assert got == want and [e.source for e in got[2:]] == ["a", "b", "c"]
    assert [e.id for e in got[2:]] == (["back/a", "back/b", "back/c"] if ident else ["a->home", "b->home", "c->home"])


@pytest.mark.parametrize("sources, needle", [
    ("[]", "fsms.arm.edges[2].from: expected a state id or a non-empty list of state ids (line 9)"),
    ("[a, 3]", "fsms.arm.edges[2].from[1]: expected a state id, got an integer (line 9)"),
    ("[a, zz]", "fsms.arm.edges[2].from: unknown state 'zz' (line 9)"),
    ("[a, b, a]", "fsms.arm.edges[2].from[2]: state 'a' is listed twice (line 9)"),
])
def test_edge_source_list_errors(sources, needle):
    assert needle in _error(MULTI_SOURCE.replace("[a, b, c]", sources).replace(", ID}", "}"))
