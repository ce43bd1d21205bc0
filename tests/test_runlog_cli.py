"""``btfsm conform --log RUN MODEL``: exit 0 when the recorded run conforms, 1 with the
first transition that is not a step of the model, 2 with one line for a malformed
recording or one whose tree is not the model's."""
from __future__ import annotations

import json
import os
import struct
import subprocess
import sys

import pytest

from btfsm.cli import main

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PICK = os.path.join(ROOT, "models", "examples", "pick_place_btcpp.xml")
RECORD = os.path.join(ROOT, "docs", "examples", "btcpp_record.py")


@pytest.fixture(scope="module")
def logs(tmp_path_factory):
    pytest.importorskip("behaviortreepy")
    folder = tmp_path_factory.mktemp("cli")
    good, bad = str(folder / "run.btlog"), str(folder / "stuck.btlog")
    subprocess.run([sys.executable, RECORD, good], check=True, capture_output=True)
    subprocess.run([sys.executable, RECORD, bad, "--stuck-sensor"], check=True, capture_output=True)
    return good, bad


def _run(capsys, *argv):
    code = main(["conform", *argv])
    out, err = capsys.readouterr()
    return code, out, err


def test_a_recorded_run_conforms(logs, capsys):
    code, out, err = _run(capsys, "--log", logs[0], PICK)
    assert code == 0, err
    assert out.startswith(f"{logs[0]}: conforms to pick-place-btcpp under btcpp: ")
    assert "explained by a run of 40 tick(s)" in out


def test_a_stuck_sensor_is_found(logs, capsys):
    code, out, err = _run(capsys, "--log", logs[1], PICK)
    assert code == 1
    assert "does not conform to pick-place-btcpp under btcpp: transition " in out
    assert "'arm_work/agv_branch/has_part' (<IsHolding>, uid 8) IDLE -> SUCCESS is not a step of the model; " \
           "the model allows FAILURE here" in out
    code, out, _ = _run(capsys, "--log", logs[1], PICK, "--json")
    first = json.loads(out)["first"]
    assert code == 1 and first["status"] == "SUCCESS" and first["model_allows"] == ["FAILURE"] and first["uid"] == 8


def test_the_search_budget_exits_3(logs, capsys):
    code, _, err = _run(capsys, "--log", logs[0], PICK, "--max-states", "1")
    assert code == 3 and err.startswith("btfsm conform: incomplete: more than --max-states 1 configurations")


def _broken(data):
    n = struct.unpack_from("<i", data, 19)[0]
    body = 19 + 4 + n + 8
    wrong_uid = data[:body + 6] + (99).to_bytes(2, "little") + data[body + 8:]
    wrong_status = data[:body + 8] + bytes([7]) + data[body + 9:]
    return {
        "not a BehaviorTree.CPP FileLogger2 log": b"hello",
        "FileLogger2 protocol version 2": data[:18] + b"\x02" + data[19:],
        "the file ends inside a transition (4 of its 9 bytes)": data[:body + 4],
        "the file ends inside the tree's XML": data[:100],
        "node uid 99 is not in the log's tree": wrong_uid,
        "status 7 (expected 0 IDLE to 4 SKIPPED)": wrong_status,
    }


def test_malformed_logs_exit_2_with_one_line(logs, capsys, tmp_path):
    data = open(logs[0], "rb").read()
    for problem, content in _broken(data).items():
        path = tmp_path / "broken.btlog"
        path.write_bytes(content)
        code, out, err = _run(capsys, "--log", str(path), PICK)
        assert code == 2, (problem, out, err)
        assert err.startswith(f"btfsm conform: error: {path}: ") and problem in err and err.count("\n") == 1, err


def test_a_log_of_another_tree_is_refused(logs, capsys, tmp_path):
    other = tmp_path / "other.xml"
    other.write_text('<root BTCPP_format="4"><BehaviorTree ID="T"><Sequence name="s"><A name="a"/><B name="b"/>'
                     "</Sequence></BehaviorTree></root>")
    code, _, err = _run(capsys, "--log", logs[0], str(other))
    assert code == 2
    assert "the recorded tree is not the model's tree: at 'arm_work' (<ReactiveFallback>, uid 1) vs model node 's' " \
           "(MemorySequence): a ReactiveFallback in the recording" in err


PYTREES_MODEL = '''
import py_trees
from btfsm.interop.pytrees import from_pytrees

def tree():
    return py_trees.composites.Selector("root", memory=False, children=[
        py_trees.composites.Sequence("pick", memory=False, children=[
            py_trees.behaviours.Success(name="part_seen"), py_trees.behaviours.Running(name="grasp")]),
        py_trees.behaviours.Running(name="wait")])

def model():
    return from_pytrees(tree(), {"part_seen": ["success", "failure"], "grasp": ["running", "success"],
                                 "wait": ["running"]})
'''


def test_a_recorded_py_trees_run(capsys, tmp_path):
    py_trees = pytest.importorskip("py_trees")
    from btfsm.interop.pytrees import RunRecorder

    mod = tmp_path / "robot.py"
    mod.write_text(PYTREES_MODEL)
    sys.path.insert(0, str(tmp_path))
    try:
        import robot
    finally:
        sys.path.remove(str(tmp_path))
    tree = py_trees.trees.BehaviourTree(robot.tree())
    run = tmp_path / "run.jsonl"
    recorder = RunRecorder(str(run))
    tree.visitors.append(recorder)
    for _ in range(3):
        tree.tick()
    recorder.close()
    code, out, err = _run(capsys, "--log", str(run), f"{mod}:model")
    assert code == 0, err
    assert out.startswith(f"{run}: conforms to root under pytrees: 3 tick(s) explained")
    lines = run.read_text().splitlines()
    lines[2] = lines[2].replace('[3, "RUNNING"]', '[3, "FAILURE"]')  # grasp never fails in the model
    run.write_text("\n".join(lines) + "\n")
    code, out, _ = _run(capsys, "--log", str(run), f"{mod}:model")
    assert code == 1
    assert "tick 1, visited node 2: 'grasp' (Running, node 3) returned FAILURE, which is not a step of the model; " \
           "the model allows RUNNING or SUCCESS here" in out, out
    run.write_text(lines[0] + "\n{not json\n")
    code, _, err = _run(capsys, "--log", str(run), f"{mod}:model")
    assert code == 2 and f"{run}: line 2: not JSON" in err


def _btlog(xml: str, transitions) -> bytes:
    """A FileLogger2 file: the tree's XML (with _uid attributes) and (uid, status) pairs."""
    data = b"BTCPP4-FileLogger2\x01" + struct.pack("<i", len(xml)) + xml.encode() + struct.pack("<q", 0)
    for k, (uid, status) in enumerate(transitions):
        data += (10 * k).to_bytes(6, "little") + uid.to_bytes(2, "little") + bytes([status])
    return data


def test_an_abstracted_decorator_passes_its_childs_status_on(capsys, tmp_path):
    """A node the side file abstracts as its child (``abstract: child``) is matched as a
    node that passes its child's status on (its RUNNING at the start of a tick allowed)."""
    tree = tmp_path / "t.xml"
    tree.write_text('<root BTCPP_format="4"><BehaviorTree ID="T"><Sequence name="s"><Delay name="d" delay_msec="5">'
                    '<Work name="w"/></Delay><Ok name="ok"/></Sequence></BehaviorTree></root>')
    (tmp_path / "t.btfsm.yaml").write_text("nodes: {d: {abstract: child}}\nprimitives: {Work: [running, success], "
                                           "Ok: [success]}\n")
    xml = ('<root BTCPP_format="4"><BehaviorTree ID="T" _fullpath=""><Sequence name="s" _uid="1">'
           '<Delay name="d" _uid="2"><Work name="w" _uid="3"/></Delay><Ok name="ok" _uid="4"/></Sequence>'
           '</BehaviorTree></root>')
    # tick 1: s starts, d starts, w RUNNING; tick 2: w SUCCESS (reset by d), d SUCCESS, ok (a sync action:
    # RUNNING first), s SUCCESS, resets
    good = [(1, 1), (2, 1), (3, 1), (3, 2), (3, 0), (2, 2), (4, 1), (4, 2), (2, 0), (4, 0), (1, 2), (1, 0)]
    run = tmp_path / "run.btlog"
    run.write_bytes(_btlog(xml, good))
    code, out, err = _run(capsys, "--log", str(run), str(tree))
    assert code == 0, out + err
    assert "explained by a run of 2 tick(s)" in out
    bad = good[:5] + [(2, 3)] + good[6:]  # d FAILURE while w succeeded
    run.write_bytes(_btlog(xml, bad))
    code, out, _ = _run(capsys, "--log", str(run), str(tree))
    assert code == 1 and "transition 6 (0.000050 s), tick 2: 's/d' (<Delay>, uid 2) RUNNING -> FAILURE is not a " \
                         "step of the model; the model allows SUCCESS here" in out, out
