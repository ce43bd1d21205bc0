"""An interrupted ``btfsm experiment`` exits 130, leaves no half-written file, and a re-run
with the same ``--out`` finishes it with the results of an uninterrupted run."""
from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time

import pytest

import btfsm.sim.experiment as experiment
from btfsm.cli import main

ARGS = ["--k", "1", "--k", "2", "--time", "30", "--quiet"]


def _run(argv, capsys):
    code = main([str(a) for a in argv])
    got = capsys.readouterr()
    return code, got.out, got.err


def _no_temporaries(folder):
    return [p for p in folder.rglob(".*.tmp*")] == []


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """trials.json of an uninterrupted run."""
    out = tmp_path_factory.mktemp("ref")
    assert main(["experiment", *ARGS, "--workers", "1", "--out", str(out)]) == 0
    return json.loads((out / "trials.json").read_text())


def test_interrupt_then_resume_gives_the_same_results(reference, tmp_path, capsys, monkeypatch):
    real = experiment._run_one
    calls = []

    def interrupted_after_two(spec):
        if len(calls) == 2:
            raise KeyboardInterrupt
        calls.append(spec)
        return real(spec)

    monkeypatch.setattr(experiment, "_run_one", interrupted_after_two)
    code, out, err = _run(["experiment", *ARGS, "--workers", "1", "--out", tmp_path], capsys)
    assert code == 130 and err.splitlines()[-1] == "btfsm experiment: interrupted" and "Traceback" not in err
    assert sorted(os.listdir(tmp_path / "trials")) == ["preemptive-k01.json", "preemptive-k02.json"]
    assert not (tmp_path / "trials.json").exists() and _no_temporaries(tmp_path)

    monkeypatch.setattr(experiment, "_run_one", real)
    code, out, err = _run(["experiment", *ARGS, "--workers", "1", "--out", tmp_path, "--json"], capsys)
    data = json.loads(out)
    assert code == 0 and data["reused"] == 2 and data["trials"] == 4 and "2 finished trial(s) reused" in err
    assert json.loads((tmp_path / "trials.json").read_text()) == reference == data["results"]
    assert _no_temporaries(tmp_path)


def test_rerun_reuses_only_matching_specs(reference, tmp_path, capsys):
    assert _run(["experiment", *ARGS, "--workers", "1", "--out", tmp_path], capsys)[0] == 0
    # a damaged trial file and a trial of another spec are run again
    (tmp_path / "trials" / "baseline-k01.json").write_text('{"format": 1, "spec": ')
    code, out, _ = _run(["experiment", "--k", "1", "--k", "2", "--time", "31", "--quiet", "--workers", "1",
                         "--out", tmp_path, "--json"], capsys)
    assert code == 0 and json.loads(out)["reused"] == 0
    code, out, _ = _run(["experiment", *ARGS, "--workers", "1", "--out", tmp_path, "--json"], capsys)
    assert code == 0 and json.loads(out)["reused"] == 0  # the --time 31 run replaced the files
    code, out, _ = _run(["experiment", *ARGS, "--workers", "1", "--out", tmp_path, "--json"], capsys)
    assert json.loads(out)["reused"] == 4 and json.loads(out)["results"] == reference
    code, out, _ = _run(["experiment", *ARGS, "--workers", "1", "--out", tmp_path, "--json", "--fresh"], capsys)
    assert json.loads(out)["reused"] == 0 and json.loads(out)["results"] == reference


def test_load_finished_ignores_foreign_files(tmp_path):
    specs = experiment.trial_specs([3], ("baseline",), time_limit=5.0)
    res = experiment.run_experiment(specs, progress=False, save_dir=str(tmp_path))
    assert experiment.load_finished(specs, str(tmp_path)) == {0: res[0]}
    other = experiment.trial_specs([3], ("baseline",), time_limit=6.0)
    assert experiment.load_finished(other, str(tmp_path)) == {}
    path = experiment.trial_file(str(tmp_path), specs[0])
    old = json.dumps({"format": 1, "spec": dataclasses.asdict(specs[0]), "result": dataclasses.asdict(res[0])})
    for text in ("", "[]", "null", '{"format": 2}', json.dumps({"format": 2, "spec": {}, "result": {}}), old):
        with open(path, "w") as fh:
            fh.write(text)
        assert experiment.load_finished(specs, str(tmp_path)) == {}


def test_real_ctrl_c_with_workers_then_resume(tmp_path):
    """SIGINT to a 2-worker experiment: exit 130, one line, no worker traceback; re-run completes.

    The signal is sent right after the first trial is saved; 8 trials of 300 simulated
    seconds leave the run well inside its trials then (a loaded machine may still let it
    finish: then its files must be complete and the re-run reuses every trial)."""
    ks = [a for k in (1, 2, 3, 4) for a in ("--k", str(k))]
    cmd = [sys.executable, "-c", "import sys; from btfsm.cli import main; sys.exit(main(sys.argv[1:]))",
           "experiment", *ks, "--time", "300", "--quiet", "--workers", "2", "--out", str(tmp_path)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        # generous limits: on a loaded machine the first trial can take minutes, and a
        # signal sent before it (during start-up) would test something else
        deadline = time.time() + 600
        trials = tmp_path / "trials"

        def saved_one() -> bool:  # a finished trial file: the folder (and a temporary) appear first
            return trials.is_dir() and any(
                p.suffix == ".json" and not p.name.startswith(".") for p in trials.iterdir())
        while time.time() < deadline and proc.poll() is None and not saved_one():
            time.sleep(0.02)
        assert saved_one(), "no trial was saved in 600 s"
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert _no_temporaries(tmp_path)
    saved = len(os.listdir(tmp_path / "trials"))
    if proc.returncode == 0:  # finished before the signal arrived: nothing to resume
        assert saved == 8 and json.loads((tmp_path / "trials.json").read_text())
    else:
        assert proc.returncode == 130, err
        assert err.strip().splitlines()[-1] == "btfsm experiment: interrupted" and "Traceback" not in err
        assert 1 <= saved <= 8
        if saved < 8:
            assert not (tmp_path / "trials.json").exists()
    done = subprocess.run(cmd + ["--json"], capture_output=True, text=True, timeout=300)
    data = json.loads(done.stdout)
    assert done.returncode == 0 and data["reused"] == saved and data["trials"] == 8
