"""Issue 20.3, every error at once: a BehaviorTree.CPP tree with 20 blackboard entries btfsm
cannot type gets 20 errors from one ``btfsm validate`` (and ``btfsm check``) run, each with
file, line and element; ``--json`` lists them; exit 2. A YAML model file with five typos
gets five errors (up to 20), none that follows from another."""
from __future__ import annotations

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
               ("{id: reach, outcomes: [running, success]}", "{id: reach, outcomes: [runing, success]}")]


def _messages(text) -> list:
    from btfsm.files import loads_model

    try:
        loads_model(text, file_name="m.yaml")
    except ModelErrors as exc:
        return [str(e) for e in exc.errors]
    except ModelError as exc:
        return [str(exc)]
    return []


@pytest.mark.parametrize("typos", [NAME_TYPOS, SHAPE_TYPOS], ids=["names", "shape"])
def test_any_set_of_typos_gives_exactly_their_errors(typos):
    """For any subset of independent typos, the loader reports exactly the errors each
    typo gives alone: nothing missing, nothing that follows from another (a
    hypothesis-drawn subset per example; 6 of them, 200 with BTFSM_LONG=1)."""
    alone = []
    for old, new in typos:
        one = _messages(FIRST.replace(old, new, 1))
        assert len(one) == 1, one
        alone.append(one[0])

    @settings(max_examples=200 if os.environ.get("BTFSM_LONG") else 6, deadline=None, derandomize=True, database=None)
    @given(st.sets(st.integers(0, len(typos) - 1), min_size=1))
    def run(chosen):
        text = FIRST
        for i in sorted(chosen):
            text = text.replace(*typos[i], 1)
        assert sorted(_messages(text)) == sorted(alone[i] for i in chosen)

    run()
