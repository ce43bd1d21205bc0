"""Issue 20.3, every error at once: a BehaviorTree.CPP tree with 20 blackboard entries btfsm
cannot type gets 20 errors from one ``btfsm validate`` (and ``btfsm check``) run, each with
file, line and element; ``--json`` lists them; exit 2. A YAML model file with five typos
gets five errors (up to 20), none that follows from another."""
from __future__ import annotations

import itertools
import json
import os
from pathlib import Path

import pytest
from hypothesis import given, settings
from memo_strategies import st

from btfsm import cli
from btfsm.errors import ModelError, ModelErrors
from btfsm.files import load_xml_model

ROOT = Path(__file__).resolve().parent.parent


def _tree(tmp_path, leaves: str):
    path = tmp_path / "t.xml"
    path.write_text(f'<root BTCPP_format="4"><BehaviorTree ID="T"><Sequence>\n{leaves}\n</Sequence></BehaviorTree></root>')
    return path


def _untyped(n):
    return "\n".join(f'<Action ID="A{i}" x="{{v{i}}}"/>' for i in range(n))


@pytest.mark.parametrize("command", ["validate", "check"])
def test_twenty_untyped_entries_give_twenty_errors(tmp_path, capsys, command):
    path = _tree(tmp_path, _untyped(20))
    assert cli.main([command, str(path)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert err[-1] == f"btfsm {command}: 20 errors"
    assert len(err) == 21 and "Traceback" not in "".join(err)
    for i, line in enumerate(err[:-1]):  # line i + 2 of the file holds entry v<i>
        assert line.startswith(f"btfsm {command}: error: {path}: line {i + 2}: <Action>: port x: blackboard entry "
                               f"{{v{i}}} has no declared type"), line


def test_json_lists_every_error(tmp_path, capsys):
    path = _tree(tmp_path, _untyped(20))
    assert cli.main(["validate", str(path), "--json"]) == 2
    doc = json.loads(capsys.readouterr().out)["error"]
    assert doc["exit_code"] == 2 and len(doc["errors"]) == 20
    assert [e["element"] for e in doc["errors"]] == [f"line {i + 2}: <Action>" for i in range(20)]
    assert {e["file"] for e in doc["errors"]} == {str(path)}


def test_entries_then_a_problem_that_stops_the_import(tmp_path):
    """An entry used twice is reported once; a structural problem met later ends the list."""
    path = _tree(tmp_path, _untyped(3) + '\n<Action ID="B" y="{v0}"/>\n<Frobnicate><A/></Frobnicate>')
    with pytest.raises(ModelErrors) as exc:
        load_xml_model(path)
    errors = exc.value.errors
    assert [e.element for e in errors] == ["line 2: <Action>", "line 3: <Action>", "line 4: <Action>",
                                           "line 6: <Frobnicate>"]
    assert "unknown node type with children" in errors[-1].problem


def test_one_problem_is_one_error(tmp_path):
    with pytest.raises(ModelError) as exc:
        load_xml_model(_tree(tmp_path, _untyped(1)))
    assert not isinstance(exc.value, ModelErrors) and exc.value.element == "line 2: <Action>"


# ------------------------------------------------------------------ YAML model files
FIRST = (ROOT / "docs" / "examples" / "first_model.yaml").read_text()


def _typos(tmp_path, pairs, name="m.yaml"):
    text = FIRST
    for old, new in pairs:
        assert old in text, old
        text = text.replace(old, new, 1)
    path = tmp_path / name
    path.write_text(text)
    return path


def _problems(capsys, path, n):
    """The error lines of ``btfsm validate PATH`` (exit 2, no traceback, n errors)."""
    assert cli.main(["validate", str(path)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert "Traceback" not in "".join(err) and err[-1] == f"btfsm validate: {n} errors", err
    assert all(x.startswith(f"btfsm validate: error: {path}: ") for x in err[:-1])
    return [x[len(f"btfsm validate: error: {path}: "):] for x in err[:-1]]


def test_five_misspelt_fields_give_five_errors(tmp_path, capsys):
    """Problems of a model file's shape are collected element by element: a misspelt
    field, type or node type each, with the element's path and line; a field misspelt is
    not also reported missing."""
    path = _typos(tmp_path, [("cup_seen: bool ", "cup_seen: bol "),
                             ("{from: home, to: reach, goals: fetch}", "{form: home, to: reach, goals: fetch}"),
                             ("{state: put_away, goals: stow}", "{state: put_away, goals: stow, gaurd: holding}"),
                             ("{Condition: has_cup, expr: holding}", "{Condtion: has_cup, expr: holding}"),
                             ("effects: {cup_seen: true}}", "efects: {cup_seen: true}}")])
    got = _problems(capsys, path, 5)
    assert [x.split(":")[0] for x in got] == ["variables.cup_seen", "fsms.arm.edges[0].form", "fsms.arm.markers[1].gaurd",
                                              "tree.children[0].children[0]", "environment[0].efects"]
    assert "unknown field 'form' (did you mean 'from'?) (line 15)" in got[1]
    assert not any("missing field" in x for x in got)
    assert "(did you mean 'Condition'?)" in got[3] and got[4].endswith("(line 37)")


def test_five_misspelt_names_give_five_errors(tmp_path, capsys):
    """The model's checks stop at a problem; the loader takes the element out (an edge,
    a marker, a request, a condition's expression...) and checks again, so each misspelt
    name is reported, in the file's order."""
    path = _typos(tmp_path, [("{from: home, to: reach, goals: fetch}", "{from: home, to: raech, goals: fetch}"),
                             ("{from: reach, to: grasp, goals: fetch}", "{from: reach, to: grasp, goals: fecth}"),
                             ("expr: holding}", "expr: holdin}"),
                             ("fsm: arm, goal: fetch", "fsm: amr, goal: fetch"),
                             ("{success: {holding: true}}", "{success: {holdig: true}}")])
    assert _problems(capsys, path, 5) == [
        "fsms.arm.states[2].outcomes[0].success.holdig: unknown variable 'holdig' (line 12)",
        "fsms.arm.edges[0].to: unknown state 'raech' (line 15)",
        "fsms.arm.edges[1].goals: unknown goal 'fecth' (line 16)",
        "tree.children[0].children[0].expr: unknown name 'holdin' in 'holdin' (line 30)",
        "tree.children[1].children[1].fsm: unknown FSM 'amr' (line 35)"]
    assert cli.main(["validate", str(path), "--json"]) == 2
    doc = json.loads(capsys.readouterr().out)["error"]
    assert len(doc["errors"]) == 5 and doc["errors_stopped"] is False and {e["file"] for e in doc["errors"]} == {str(path)}


def test_no_error_that_follows_from_another(tmp_path, capsys):
    """A variable misspelt where it is declared is one problem, however often it is used;
    a declaration with a bad shape is reported alone (its uses would follow from it)."""
    path = _typos(tmp_path, [("  holding: bool ", "  holdng: bool ")])
    got = _problems_or_one(capsys, path)
    assert got == ["fsms.arm.states[2].outcomes[0].success.holding: unknown variable 'holding' (line 12); also used at "
                   "4 more place(s) (line 13, 30, 31, 35)"]
    path = _typos(tmp_path, [("  holding: bool ", "  holding: bol ")], "shape.yaml")
    got = _problems_or_one(capsys, path)
    assert len(got) == 1 and got[0].startswith("variables.holding: unknown type 'bol'")


def _problems_or_one(capsys, path):
    assert cli.main(["validate", str(path)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and "Traceback" not in err[0], err
    return [err[0][len(f"btfsm validate: error: {path}: "):]]


def test_at_most_twenty_errors(tmp_path, capsys):
    path = tmp_path / "many.yaml"
    path.write_text("name: many\nvariables:\n" + "".join(f"  v{i}: {{int: [0, {i}], init: x}}\n" for i in range(25)))
    assert cli.main(["validate", str(path)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 21 and err[-1].startswith("btfsm validate: 20 errors (the first ones")
    assert err[0].startswith(f"btfsm validate: error: {path}: variables.v0.init: expected an integer")


#: typos of first_model.yaml, each one problem of the model's checks, independent of the others
NAME_TYPOS = [("{from: home, to: reach, goals: fetch}", "{from: home, to: raech, goals: fetch}"),
              ("{from: reach, to: grasp, goals: fetch}", "{from: reach, to: grasp, goals: fecth}"),
              ("{state: grasp, goals: fetch}", "{state: grasps, goals: fetch}"),
              ("expr: holding}", "expr: holdin}"),
              ("goal: stow, post", "goal: stwo, post"),
              ("fsm: arm, goal: fetch", "fsm: amr, goal: fetch"),
              ("guard: not cup_seen", "guard: not cupseen"),
              ("{success: {holding: true}}", "{success: {holdig: true}}"),
              ("{state: put_away, goals: stow}", "{state: put_away, goals: stw}"),
              ("{from: put_away, to: home, goals: [stow, fetch]}", "{from: put_away, to: home, goals: [stow, fetch], guard: n > 1}")]
#: typos of its shape (misspelt fields, types, node types)
SHAPE_TYPOS = [("cup_seen: bool ", "cup_seen: bol "),
               ("{from: home, to: reach, goals: fetch}", "{form: home, to: reach, goals: fetch}"),
               ("{state: put_away, goals: stow}", "{state: put_away, goals: stow, gaurd: holding}"),
               ("{Condition: has_cup, expr: holding}", "{Condtion: has_cup, expr: holding}"),
               ("effects: {cup_seen: true}}", "efects: {cup_seen: true}}"),
               ("{id: reach, outcomes: [running, success]}", "{id: reach, outcomes: [runing, success]}"),
               ("{state: grasp, goals: fetch}", "{state: grasp, goals: fetch, goals: stow}"),
               ("goal: stow, post: not holding}", "goal: stow, post: not holding, fsm: arm}")]


#: first_model.yaml with comment lines where the typos below put a declaration (so that
#: no typo moves the lines of the others)
SPARE = (FIRST.replace("variables:\n", "variables:\n  # spare var1\n  # spare var2\n  # spare var3\n", 1)
         .replace("      - {id: put_away", "      # spare state\n      - {id: put_away", 1)
         .replace("fsms:\n", "# spare prims\nfsms:\n  # spare fsm\n", 1).replace("environment:\n", "# spare resources\nenvironment:\n", 1)
         .replace("    goals: [fetch, stow]\n", "    goals: [fetch, stow]\n    # spare arm\n", 1)
         + "  # spare event\n")
#: typos of SPARE, each one problem that the model's checks found alone before (a duplicate
#: name, a variable's declaration, a cycle of direct edges...), some with uses of what they
#: declare; independent of each other and of NAME_TYPOS
CHECK_TYPOS = [[("      # spare state", "      - reach")],
               [("goals: [fetch, stow]", "goals: [fetch, stow, fetch]")],
               [("{Condition: sees_cup, expr: cup_seen}", "{Condition: has_cup, expr: cup_seen}")],
               [("  # spare var1", "  arm: bool"), ("cup_seen: false}}", "cup_seen: false, arm: true}}")],
               [("  # spare var2", "  level: {int: [5, 1], init: 9}"),
                ("goals: stow, when: direct}      #", "goals: stow, when: direct, guard: level > 2}      #")],
               [("  # spare var3", "  mode: {enum: [a, b, a], init: c}")],
               [("  # spare event", "  - {event: cup_appears}")],
               [("{from: home, to: put_away, goals: stow}", "{from: home, to: reach, goals: stow, when: direct}")],
               [("{id: reach, outcomes: [running, success]}", "{id: reach, outcomes: [running, success, running]}")],
               [("# spare prims", "primitives: {grasp: [success]}")],
               [("# spare resources", "resources: {arm_use: [stow, nosuch]}")],
               [("    # spare arm", "    retarget: sideways")],
               [("  # spare fsm", "  k: {goals: [g], states: [a], params: {cup_seen: bool}, markers: [{state: a, guard: cup_seen}]}")]]


def _messages(text) -> list:
    from btfsm.files import loads_model

    try:
        loads_model(text, file_name="m.yaml")
    except ModelErrors as exc:
        return [str(e) for e in exc.errors]
    except ModelError as exc:
        return [str(exc)]
    return []


def _typo(text: str, typo) -> str:
    """``text`` with one typo made: an ``(old, new)`` pair or a list of them."""
    for old, new in [typo] if isinstance(typo[0], str) else typo:
        assert old in text, old
        text = text.replace(old, new, 1)
    return text


@pytest.mark.parametrize("base, typos", [(FIRST, NAME_TYPOS), (FIRST, SHAPE_TYPOS), (SPARE, NAME_TYPOS + CHECK_TYPOS)],
                         ids=["names", "shape", "checks"])
def test_any_set_of_typos_gives_exactly_their_errors(base, typos):
    """For any subset of independent typos, the loader reports exactly the errors each
    typo gives alone: nothing missing, nothing that follows from another (a
    hypothesis-drawn subset per example; 6 of them, 200 with BTFSM_LONG=1)."""
    assert _messages(base) == []
    alone = []
    for typo in typos:
        one = _messages(_typo(base, typo))
        assert len(one) == 1, one
        alone.append(one[0])

    @settings(max_examples=200 if os.environ.get("BTFSM_LONG") else 6, deadline=None, derandomize=True, database=None)
    @given(st.sets(st.integers(0, len(typos) - 1), min_size=1, max_size=19))  # under the 20 errors reported
    def run(chosen):
        text = base
        for i in sorted(chosen):
            text = _typo(text, typos[i])
        assert sorted(_messages(text)) == sorted(alone[i] for i in chosen)

    run()


# ------------------------------------------- duplicates, declarations, cycles, templates
def _all_problems(capsys, path):
    """The error lines of ``btfsm validate PATH``: exit 2, no traceback, the count line when
    there are several."""
    assert cli.main(["validate", str(path)]) == 2
    err = capsys.readouterr().err.splitlines()
    assert "Traceback" not in "".join(err), err
    if len(err) > 1:
        assert err[-1] == f"btfsm validate: {len(err) - 1} errors", err
        err = err[:-1]
    prefix = f"btfsm validate: error: {path}: "
    assert all(x.startswith(prefix) for x in err), err
    return [x[len(prefix):] for x in err]


#: (edits of first_model.yaml, the errors of btfsm validate): each problem once, at the
#: element it is in (a duplicate: the later one), nothing that follows from it
MODEL_CHECK_CASES = {
    "duplicate state": ([("      - {id: put_away", "      - reach\n      - {id: put_away")],
                        ["fsms.arm.states[3]: duplicate state 'reach' (line 13)"]),
    "three of one state": ([("      - {id: put_away", "      - reach\n      - {id: reach, outcomes: [{success: {hold: true}}]}\n"
                                                    "      - {id: put_away")],
                           ["fsms.arm.states[3]: duplicate state 'reach' (line 13)",
                            "fsms.arm.states[4]: duplicate state 'reach' (line 14)"]),
    "duplicate goal": ([("goals: [fetch, stow]", "goals: [fetch, stow, fetch]")],
                       ["fsms.arm.goals: duplicate goal 'fetch' (line 8)"]),
    "duplicate edge id": ([("{from: home, to: reach, goals: fetch}", "{from: home, to: reach, goals: fetch, id: e}"),
                           ("{from: grasp, to: home, goals: fetch}", "{from: grasp, to: home, goals: fetch, id: e}")],
                          ["fsms.arm.edges[2]: duplicate edge id 'e' (line 17)"]),
    "duplicate marker id": ([("{state: grasp, goals: fetch}", "{state: grasp, goals: fetch, id: m}"),
                             ("{state: put_away, goals: stow}", "{state: put_away, goals: stow, id: m}")],
                            ["fsms.arm.markers[1]: duplicate marker id 'm' (line 24)"]),
    "duplicate outcome": ([("{id: reach, outcomes: [running, success]}", "{id: reach, outcomes: [running, success, running]}")],
                          ["fsms.arm.states[1].outcomes: duplicate name 'running' (line 11)"]),
    "duplicate node, a typo in it": ([("{Condition: sees_cup, expr: cup_seen}", "{Condition: has_cup, expr: cup_sen}")],
                                     ["tree.children[1].children[0]: duplicate node name 'has_cup' (node names are trace ids) "
                                      "(line 34)",
                                      "tree.children[1].children[0].expr: unknown name 'cup_sen' in 'cup_sen' (line 34)"]),
    "a node of the tree and of a state": ([("      - home  ", "      - {id: home, subtree: {Condition: sees_cup, expr: cup_seen}}  ")],
                                          ["fsms.arm.states[0].subtree: duplicate node name 'sees_cup' (node names are trace "
                                           "ids) (line 10)"]),
    "duplicate event": ([("effects: {cup_seen: true}}", "effects: {cup_seen: true}}\n  - {event: cup_appears}")],
                        ["environment[1]: duplicate name 'cup_appears' (line 38)"]),
    "duplicate option": ([("environment:", "environment:\n  - {choice: c, options: [{event: x}, {event: x}]}")],
                         ["environment[0].options[1]: duplicate name 'x' (line 37)"]),
    "an FSM and a variable": ([("  holding: bool ", "  arm: bool\n  holding: bool "), ("guard: not cup_seen", "guard: not arm"),
                               ("{success: {holding: true}}", "{success: {holding: true, arm: true}}")],
                              ["fsms.arm: name 'arm' is used twice (line 8)"]),
    "a primitive declared twice": ([("fsms:", "primitives: {grasp: [success]}\nfsms:"),
                                    ("{success: {holding: true}}", "{success: {holdig: true}}")],
                                   ["fsms.arm.states[2]: primitive 'grasp' is declared twice with different outcomes (line 13)",
                                    "fsms.arm.states[2].outcomes[0].success.holdig: unknown variable 'holdig' (line 13)"]),
    "int bounds": ([("  holding: bool ", "  level: {int: [5, 1], init: 9}\n  holding: bool "),
                    ("guard: not cup_seen", "guard: level > 3"),
                    ("{success: {holding: true}}", "{success: {holding: true, level: level + 1}}")],
                   ["variables.level: int level needs integer bounds lo <= hi, got 5..1 (line 5)"]),
    "enum initial value": ([("  holding: bool ", "  mode: {enum: [a, b], init: c}\n  holding: bool "),
                            ("guard: not cup_seen", "guard: mode == 'b'")],
                           ["variables.mode: initial value: 'c' is not in the domain of mode (one of a, b) (line 5)"]),
    "enum repeats a value": ([("  holding: bool ", "  mode: {enum: [a, b, a]}\n  holding: bool "),
                              ("guard: not cup_seen", "guard: mode == 'b' and mode != ''")],
                             ["variables.mode: enum mode repeats a value (line 5)",
                              "environment[0].guard: '' is not one of a, b in \"mode == 'b' and mode != ''\" (line 38)"]),
    "a reserved variable name": ([("  holding: bool ", "  max: bool\n  holding: bool "),
                                  ("{success: {holding: true}}", "{success: {holding: true, max: true}}")],
                                 ["variables.max: variable name 'max' is reserved (line 5)"]),
    "a parameter's bounds": ([("    goals: [fetch, stow]", "    goals: [fetch, stow]\n    params: {t: {int: [3, 0], init: 7}}"),
                              ("goal: fetch, post", "goal: fetch, params: {t: 2}, post"),
                              ("goal: stow, post", "goal: stow, params: {t: 1}, post")],
                             ["fsms.arm.params.t: int t needs integer bounds lo <= hi, got 3..0 (line 9)"]),
    "parameters that hide a variable": (
        [("fsms:", "fsms:\n  k: {goals: [g], states: [a], params: {holding: bool}, markers: [{state: a, guard: holding}]}\n"
                   "  j: {goals: [g], states: [a], params: {holding: {int: [0, 1]}}, markers: [{state: a, guard: holdin}]}")],
        ["fsms.k.params.holding: parameter 'holding' hides a variable (line 7)",
         "fsms.j.params.holding: parameter 'holding' hides a variable (line 8)",
         "fsms.j.markers[0].guard: unknown name 'holdin' in 'holdin' (line 8)"]),
    "FSMs of which nothing can be checked": (
        [("fsms:", "fsms:\n  nog: {goals: [], states: [s]}\n  nos: {goals: [g], states: []}"),
         ("{Condition: sees_cup, expr: cup_seen}", "{Condition: sees_cup, expr: \"cup_seen and nos.state == 's'\"}"),
         ("    - ReactiveSequence: fetch_cup", "    - {SkillRequest: r2, fsm: nog, goal: g}\n    - ReactiveSequence: fetch_cup")],
        ["fsms.nog.goals: an FSM needs at least one goal (line 7)", "fsms.nos: has no states (line 8)"]),
    "a retarget": ([("    goals: [fetch, stow]", "    goals: [fetch, stow]\n    retarget: sideways")],
                   ["fsms.arm.retarget: must be one of immediate, withdraw (line 9)"]),
    "a state that runs both": ([("      - {id: reach, outcomes: [running, success]}",
                                 "      - {id: reach, primitive: nosuch, subtree: {Condition: c0, expr: yy}}")],
                               ["fsms.arm.states[1]: runs both a primitive and a subtree (line 11)",
                                "fsms.arm.states[1].subtree.expr: unknown name 'yy' in 'yy' (line 11)"]),
    "a re-entrant request": ([("      - home  ", "      - {id: home, subtree: {ReactiveSequence: again, children: ["
                                                "{SkillRequest: back, fsm: arm, goal: stow}, {Condition: c0, expr: yy}]}}  ")],
                             ["fsms.arm.states[0].subtree: requests FSM 'arm' while 'arm' is being ticked (a re-entrant request) "
                              "(line 10)",
                              "fsms.arm.states[0].subtree.children[1].expr: unknown name 'yy' in 'yy' (line 10)"]),
    "a choice without options": ([("environment:", "responses: {r: {trigger: 'event:ch', response: holding}}\n"
                                                   "environment:\n  - {choice: ch, options: []}")],
                                 ["environment[0]: a choice needs options (line 38)"]),
    "options of a choice": ([("environment:", "environment:\n  - {choice: ch, options: [{event: e1, guard: zz}, "
                                              "{event: e2, effects: {qq: true}}]}"),
                             ("guard: not cup_seen", "guard: not cupseen")],
                            ["environment[0].options[0].guard: unknown name 'zz' in 'zz' (line 37)",
                             "environment[0].options[1].effects.qq: unknown variable 'qq' (line 37)",
                             "environment[1].guard: unknown name 'cupseen' in 'not cupseen' (line 38)"]),
    "a direct-edge cycle, a typo in its edge": (
        [("{from: put_away, to: home, goals: [stow, fetch]}", "{from: home, to: reach, goals: stow, when: direct, guard: typo}")],
        ["fsms.arm.edges[6]: direct edges form a cycle for goal 'stow': reach -> home -> reach (a direct chain must end) "
         "(line 21)",
         "fsms.arm.edges[6].guard: unknown name 'typo' in 'typo' (line 21)"]),
    "resource members": ([("environment:", "resources: {arm1: [stow, nosuch, has_cup, stow, fetch], arm2: [zz]}\nenvironment:")],
                         ["resources.arm1[1]: unknown node 'nosuch' (line 36)",
                          "resources.arm1[2]: 'has_cup' is a Condition; a resource lists Action and SkillRequest nodes (line 36)",
                          "resources.arm1[3]: 'stow' is listed twice (line 36)",
                          "resources.arm2[0]: unknown node 'zz' (line 36)"]),
}


@pytest.mark.parametrize("case", list(MODEL_CHECK_CASES))
def test_model_check_problems_are_reported_together(tmp_path, capsys, case):
    """A duplicate name, a variable's or parameter's declaration, a cycle of direct edges, a
    resource's member: reported with the others, once, and nothing that follows from them
    (the later duplicate goes, a declaration is repaired, the closing edge is not direct)."""
    edits, expected = MODEL_CHECK_CASES[case]
    assert _all_problems(capsys, _typos(tmp_path, edits)) == expected


TEMPLATED = """name: t
templates:
  chain:
    params: [X]
    edges:
      - {from: a, to: "${X}"}
  bad:
    params: [Y]
    edges: [{from: a, to: "${Z}"}]
  dup: {params: [K], states: [{id: s, "${K}": 1, primitive: p}]}
fsms:
  f:
    goals: [g]
    states: [a, b, {use: dup, with: {K: id}}]
    edges:
      - {use: chian, with: {X: b}}
      - {use: bad, with: {Y: b}}
      - {use: chain, with: {X: b, Q: 1}}
      - {use: chain}
      - {use: chain, with: {X: b}}
tree: {use: nosuch}
"""


def test_template_problems_are_reported_together(tmp_path, capsys):
    """Each template definition and each use is checked on its own: a definition with a
    problem is reported and its uses are not; a use with a problem is reported."""
    path = tmp_path / "t.yaml"
    path.write_text(TEMPLATED)
    assert _all_problems(capsys, path) == [
        "templates.bad.edges[0].to: placeholder '${Z}' is not a parameter of this template (line 9)",
        "fsms.f.states[2]: duplicate key 'id' after substitution (line 10)",
        "fsms.f.edges[0].use: unknown template 'chian' (templates: chain, bad, dup) (line 16)",
        "fsms.f.edges[2].with: unknown parameter(s) Q: template 'chain' takes X (line 18)",
        "fsms.f.edges[3].with: missing parameter(s) X: template 'chain' takes X (line 19)",
        "tree.use: unknown template 'nosuch' (templates: chain, bad, dup) (line 21)"]


@pytest.mark.parametrize("name, text, expected", [
    ("m.yaml", "name: m\nvariables:\n  a: bool\n  a: {int: [0, 3]}\nfsms:\n  f:\n    goals: [g]\n    states: [s, t]\n"
     "    edges: [{from: s, to: t, to: s, gaurd: a}]\ntree: {Condition: c, expr: 'a > 1', expr: zz}\nvariables: {c: bool}\n",
     ["variables: duplicate key 'a' (line 4)", "fsms.f.edges[0]: duplicate key 'to' (line 9)",
      "fsms.f.edges[0].gaurd: unknown field 'gaurd' (did you mean 'guard'?) (line 9)",
      "tree: duplicate key 'expr' (line 10)", "duplicate key 'variables' (line 11)"]),
    ("m.json", '{"name": "x", "name": "y", "variables": {"a": "bool", "a": "bol"}, "tree": {"Condition": "c", "expr": "zz"}, '
     '"fsms": {"f": {"goals": ["g"], "states": ["s", "t"], "edges": [{"from": "s", "to": "t", "to": "s"}]}}}',
     ["duplicate key 'name'", "variables: duplicate key 'a'", "fsms.f.edges[0]: duplicate key 'to'"]),
])
def test_keys_given_twice_are_reported_with_the_shape(tmp_path, capsys, name, text, expected):
    """A key given twice in a mapping is reported with the problems of the file's shape
    (its later value is left out: 'expr: zz' is not read); the model's checks wait until
    there is none, since what a later value declares would be reported unknown."""
    path = tmp_path / name
    path.write_text(text)
    assert _all_problems(capsys, path) == expected


def test_a_template_name_that_is_not_a_name(tmp_path, capsys):
    """A definition named 5 has a problem: 'use: 5' is not reported; a list or a mapping
    as a use's name is reported, however many definitions have problems."""
    path = tmp_path / "t.yaml"
    path.write_text("name: t\ntemplates:\n  5: {states: [a]}\nfsms:\n  f: {goals: [g], states: [{use: [a]}, {use: {x: 1}}, {use: 5}]}\n")
    assert _all_problems(capsys, path) == [
        "templates: template name 5 is not an identifier (line 3)",
        "fsms.f.states[0].use: unknown template ['a'] (templates: 5) (line 5)",
        "fsms.f.states[1].use: unknown template {'x': 1} (templates: 5) (line 5)"]


TEMPLATES_OK = """name: t
templates:
  chain:
    params: [X]
    edges:
      - {from: a, to: "${X}"}
  back:
    params: [Y]
    edges: [{from: "${Y}", to: a}]
  st: {params: [K], states: [{id: "${K}"}]}
fsms:
  f:
    goals: [g]
    states: [a, {use: st, with: {K: b}}]
    edges:
      - {use: chain, with: {X: b}}
      - {use: back, with: {Y: b}}
    markers: [{state: b}]
"""
#: typos of TEMPLATES_OK, each one problem of a template's definition or use, independent
TEMPLATE_TYPOS = [('to: "${X}"', 'to: "${Z}"'), ("{use: back, with: {Y: b}}", "{use: bakc, with: {Y: b}}"),
                  ("{use: st, with: {K: b}}", "{use: st, with: {K: b, Q: 1}}"), ("params: [Y]", "params: [Y, Y]"),
                  ("markers: [{state: b}]", "markers: [{state: b}, {use: st, for_each: 1}]")]


def test_any_set_of_template_typos_gives_exactly_their_errors():
    """The subset property for templates: a definition with a problem is reported, not
    its uses (nor a hint that would leave its name out); each use on its own."""
    assert _messages(TEMPLATES_OK) == []
    alone = [_messages(_typo(TEMPLATES_OK, t)) for t in TEMPLATE_TYPOS]
    assert all(len(one) == 1 for one in alone), alone
    for chosen in itertools.chain.from_iterable(itertools.combinations(range(len(TEMPLATE_TYPOS)), k)
                                                for k in range(2, len(TEMPLATE_TYPOS) + 1)):
        text = TEMPLATES_OK
        for i in chosen:
            text = _typo(text, TEMPLATE_TYPOS[i])
        assert sorted(_messages(text)) == sorted(alone[i][0] for i in chosen), chosen


def test_yaml_syntax_stops_at_its_first_problem(tmp_path, capsys):
    """PyYAML (and json) stop at the first syntax error: what follows it is not read (the
    second unclosed bracket, line 23, is not reported)."""
    path = _typos(tmp_path, [("goals: [fetch, stow]", "goals: [fetch, stow"), ("{state: grasp, goals: fetch}", "{state: grasp")])
    assert _all_problems(capsys, path) == ["YAML syntax error at line 9, column 11: expected ',' or ']', but got ':'"]
