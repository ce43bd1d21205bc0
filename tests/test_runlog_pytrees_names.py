"""``btfsm conform --log`` on a py_trees recording whose behaviours share names: the model
(``from_pytrees``) calls the second 'a' 'a_2' (``node_names``), the recording keeps py_trees'
names; the check names the recorded nodes by the same rule, so the run conforms."""
from __future__ import annotations

import io

import pytest

py_trees = pytest.importorskip("py_trees")

from btfsm.interop.pytrees import RunRecorder, from_pytrees, node_names  # noqa: E402
from btfsm.verify.runlog import check_pytrees_run, read_pytrees_run  # noqa: E402


def test_duplicate_and_unsafe_names_conform():
    B = py_trees.behaviours
    root = py_trees.composites.Sequence("a", memory=False, children=[
        B.Success(name="a"), py_trees.decorators.PassThrough(name="p", child=B.Success(name="a")),
        B.Success(name="a_2"), B.Success(name="line\nbreak"), B.Running(name="")])
    assert [n for _, n in node_names(root)] == ["a", "a_3", "a_4", "a_2", "line_break", "unnamed"]
    model = from_pytrees(root, {}, name="dups")
    tree, out = py_trees.trees.BehaviourTree(root), io.StringIO()
    tree.visitors.append(RunRecorder(out))
    for _ in range(3):
        tree.tick()
    run = read_pytrees_run(out.getvalue(), "run.jsonl")
    verdict = check_pytrees_run(model, run)
    assert verdict.conforms, verdict.first
    # a recording of a tree whose leaf has another name is still refused
    other = out.getvalue().replace('"a_2"', '"b"', 1)
    with pytest.raises(Exception, match="the recorded tree is not the model's tree"):
        check_pytrees_run(model, read_pytrees_run(other, "run.jsonl"))
