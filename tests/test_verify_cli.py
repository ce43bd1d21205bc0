"""``btfsm check`` (and the replay of its counterexamples): exit codes, text, JSON."""
from __future__ import annotations

import json
import re
import os
import subprocess
import sys

import pytest

from btfsm import Action, Int, Model, success
from btfsm.cli import main

files = pytest.importorskip("btfsm.files")


def _write(tmp_path, model, name="m.yaml"):
    path = tmp_path / name
    path.write_text(files.dumps_model(model), encoding="utf-8")
    return str(path)


def _counter(expr="min(n + 1, 3)", **kw):
    return Model("cnt", [Int("n", 0, 3)], tree=Action("inc", outcomes=[success(n=expr)]), **kw)


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    return code, out, err


def test_all_hold_exit_0(tmp_path, capsys):
    code, out, err = _run(capsys, "check", _write(tmp_path, _counter(invariants={"range": "n <= 3"})))
    assert code == 0
    assert "model cnt:" in out and "invariants" in out and "VIOLATED" not in out


def test_violation_exit_1_prints_counterexample(tmp_path, capsys):
    code, out, _ = _run(capsys, "check", _write(tmp_path, _counter(invariants={"small": "n < 3"})), "--property", "invariants")
    assert code == 1
    assert "VIOLATED" in out and "invariant 'small'" in out and "step 3" in out


def test_unknown_property_exit_2_lists_names(tmp_path, capsys):
    code, _, err = _run(capsys, "check", _write(tmp_path, _counter()), "--property", "liveness")
    assert code == 2
    assert "'liveness'" in err and "workable-reachability" in err and "request-latency" in err


def test_budget_exit_3(tmp_path, capsys):
    code, out, _ = _run(capsys, "check", _write(tmp_path, _counter(invariants={"range": "n <= 3"})), "--max-states", "2",
                        "--property", "invariants")
    assert code == 3
    assert "INCOMPLETE" in out and "undecided" in out


@pytest.mark.parametrize("text,needle", [
    ("name: bad\nvariables: {n: {int: [0, 3]}}\ntree: {Condition: c, expr: 'm > 1'}\n", "m"),
    ("name: bad\nvariables: [\n", "bad.yaml"),
])
def test_malformed_model_exit_2(tmp_path, capsys, text, needle):
    path = tmp_path / "bad.yaml"
    path.write_text(text, encoding="utf-8")
    code, out, err = _run(capsys, "check", str(path))
    assert code == 2 and out == ""
    assert "bad.yaml" in err and needle in err and len(err.strip().splitlines()) == 1


def test_missing_file_and_bad_budget_exit_2(tmp_path, capsys):
    assert _run(capsys, "check", str(tmp_path / "nope.yaml"))[0] == 2
    code, _, err = _run(capsys, "check", _write(tmp_path, _counter()), "--max-states", "0")
    assert code == 2 and "--max-states" in err


def test_json_is_one_object(tmp_path, capsys):
    code, out, _ = _run(capsys, "check", _write(tmp_path, _counter("n + 1")), "--json")
    assert code == 1
    d = json.loads(out)
    assert {"model", "states", "transitions", "seconds", "properties"} <= set(d)
    assert d["model"] == "cnt" and d["complete"] is True
    props = {p["name"]: p for p in d["properties"]}
    assert props["domain"]["holds"] is False and props["domain"]["counterexample"]["property"] == "domain"
    assert props["workable-reachability"]["holds"] is True and props["workable-reachability"]["counterexample"] is None


def test_json_incomplete_has_null_verdicts(tmp_path, capsys):
    code, out, _ = _run(capsys, "check", _write(tmp_path, _counter(workable="n == 0")), "--json", "--max-states", "2",
                        "--property", "workable-reachability")
    assert code == 3
    d = json.loads(out)
    assert d["complete"] is False and d["properties"][0]["holds"] is None
    assert d["properties"][0]["verdict"] == "undecided"


def test_properties_with_nothing_to_check_say_not_applicable(tmp_path, capsys):
    """A tree without skill FSMs or declarations: only no-dead-states and lints apply;
    the others print "not applicable (why)", never "holds", and do not fail the check."""
    path = _write(tmp_path, _counter())
    code, out, _ = _run(capsys, "check", path)
    assert code == 0
    verdicts = dict(line.split(None, 1) for line in out.splitlines()[1:] if line.startswith("  "))
    assert verdicts.pop("no-dead-states") == "holds" and verdicts.pop("lints").endswith("warning(s)")
    assert verdicts["goal-reachability"] == "not applicable (no skill FSM)"
    assert verdicts["domain"] == "holds"  # n is an int variable: its writes are checked
    del verdicts["domain"]
    assert all(v.startswith("not applicable (") for v in verdicts.values()), verdicts
    code, out, _ = _run(capsys, "check", path, "--json")
    props = {p["name"]: p for p in json.loads(out)["properties"]}
    assert props["response"]["verdict"] == "not-applicable" and props["response"]["holds"] is True
    assert props["response"]["why"] == "no 'responses:' declared"
    assert props["no-dead-states"]["verdict"] == "holds" and "why" not in props["no-dead-states"]


def test_counterexample_dir_and_replay(tmp_path, capsys):
    model = _write(tmp_path, _counter("n + 1", invariants={"small": "n < 3"}))
    ce_dir = tmp_path / "ces"
    code, _, _ = _run(capsys, "check", model, "--counterexample-dir", str(ce_dir))
    assert code == 1
    written = sorted(os.listdir(ce_dir))
    # MODEL.PROPERTY.HASH.json: a second run with another violation does not overwrite
    assert [re.sub(r"\.[0-9a-f]{10}\.json$", "", n) for n in written] == ["cnt.domain", "cnt.invariants"]
    for name in written:
        code, out, _ = _run(capsys, "replay", str(ce_dir / name), model)
        assert code == 0 and "confirmed" in out
    code, _, _ = _run(capsys, "check", _write(tmp_path, _counter("n + 1", invariants={"small": "n < 2"}), "m2.yaml"),
                      "--counterexample-dir", str(ce_dir), "--property", "invariants")
    assert len(os.listdir(ce_dir)) == 3 and set(written) < set(os.listdir(ce_dir))
    # a counterexample that does not reproduce: exit 1
    ce = json.loads((ce_dir / written[1]).read_text())
    ce["steps"][0]["state"]["n"] = 2
    (ce_dir / "wrong.json").write_text(json.dumps(ce))
    code, out, _ = _run(capsys, "replay", str(ce_dir / "wrong.json"), model)
    assert code == 1 and "differs" in out


def test_export_unknown_fsm_is_a_usage_error(tmp_path, capsys):
    code, _, err = _run(capsys, "export", _write(tmp_path, _counter()), "--format", "dot", "--fsm", "arm")
    assert code == 2 and "no FSM named 'arm'" in err


def test_entry_point_subprocess(tmp_path):
    """The installed command: exit code and no traceback, as a user sees it."""
    model = _write(tmp_path, _counter(invariants={"small": "n < 3"}))
    proc = subprocess.run([sys.executable, "-m", "btfsm.cli", "check", model, "--property", "invariants", "--json"],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert json.loads(proc.stdout)["properties"][0]["holds"] is False


def test_progress_line_on_stderr_for_long_explorations(tmp_path):
    """An exploration longer than a second shows a progress bar on stderr when stderr is a
    terminal (a pseudo-terminal here); stdout stays clean."""
    import os
    import pty
    import subprocess
    import sys
    import threading

    from btfsm.files import dump_model
    from btfsm.models.pickplace import pickplace

    path = tmp_path / "pp18.json"
    dump_model(pickplace(18), str(path))  # about 4 s of exploration (the bar shows after 1 s)
    master, slave = pty.openpty()
    chunks = []

    def drain():
        while True:
            try:
                data = os.read(master, 65536)
            except OSError:
                return
            if not data:
                return
            chunks.append(data)

    reader = threading.Thread(target=drain, daemon=True)
    reader.start()
    cmd = [sys.executable, "-m", "btfsm.cli", "check", str(path), "--property", "invariants", "--max-states", "7000000"]
    try:
        out = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=slave, text=True, timeout=300)
    finally:
        os.close(slave)
        reader.join(10)
        os.close(master)
    assert out.returncode == 0
    shown = b"".join(chunks).decode("utf-8", "replace")
    assert "states/s" in shown and "model" in shown and "transitions" in shown  # the tqdm bar
    assert "6053248 states" in out.stdout.replace(",", "")
    # not a terminal, no bar: tests/test_progress.py runs the command with a bar that is
    # due at once (no delay) and sees it on a fake terminal, nothing on a pipe


def test_quiet_verbose_and_goal_level_flags(capsys):
    code, out, _ = _run(capsys, "check", "ariac-preemptive", "--quiet")
    assert code == 0 and "warning(s):" not in out and "gap" not in out and "contracts" in out
    code, out, _ = _run(capsys, "check", "ariac-preemptive")
    assert re.search(r"^\d+ warning\(s\): \d+ edge\(s\) never fire, .*\(--verbose lists them\)$", out, re.M)
    assert "fsms.arm." not in out
    code, out, _ = _run(capsys, "check", "ariac-preemptive", "--verbose", "--property", "lints")
    assert "fsms.arm.goals: goal 'pick_agv' is never requested" in out
    code, out, _ = _run(capsys, "check", "original", "--property", "goal-reachability", "--goal-level", "tree")
    assert code == 0 and "goal-reachability  holds" in out
