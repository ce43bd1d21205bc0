"""Issue 20.3, every error at once: a BehaviorTree.CPP tree with 20 blackboard entries btfsm
cannot type gets 20 errors from one ``btfsm validate`` (and ``btfsm check``) run, each with
file, line and element; ``--json`` lists them; exit 2."""
from __future__ import annotations

import json

import pytest

from btfsm import cli
from btfsm.errors import ModelError, ModelErrors
from btfsm.files import load_xml_model


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
