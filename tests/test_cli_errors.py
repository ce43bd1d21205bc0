"""The CLI's top-level handler: every error is one line with the documented exit code.

Table tests: an exception raised by a command -> exit code, kind and message; the same under
``--json`` (one JSON object on stdout); ``--debug`` adds the traceback of internal errors
only; Ctrl-C and SIGTERM on real processes.
"""
from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import threading

import pytest

import btfsm.cli as cli
from btfsm.errors import ConformanceError, DomainError, ModelError, Terminated, UsageError


def _run(argv, capsys):
    try:
        code = cli.main(argv)
    except SystemExit as exc:
        code = exc.code
    got = capsys.readouterr()
    return code, got.out, got.err


def _missing_matplotlib():
    exc = ModuleNotFoundError("No module named 'matplotlib'")
    exc.name = "matplotlib"
    return exc


# exception raised by the command -> (exit code, kind, substrings of the one line)
TABLE = [
    (ModelError("fsms.arm.edges[3].guard", "unknown name 'x'", "m.yaml"), 2, "model",
     ["btfsm validate: error: m.yaml: fsms.arm.edges[3].guard: unknown name 'x'"]),
    (ModelError("", "no such file", None), 2, "model", ["btfsm validate: error: no such file"]),
    (UsageError("--what: 'x' is not 'tree'"), 2, "usage", ["error: --what: 'x' is not 'tree'"]),
    (FileNotFoundError(errno.ENOENT, "No such file or directory", "in.yaml"), 2, "file",
     ["error: in.yaml: No such file or directory"]),
    (PermissionError(errno.EACCES, "Permission denied", "out.json"), 2, "file", ["out.json: Permission denied"]),
    (DomainError("n", 9, "fsms.arm.edges[0]"), 1, "violation",
     ["btfsm validate: violation: fsms.arm.edges[0]: writes n = 9, outside its domain"]),
    (ConformanceError("the implementation replied SUCCESS"), 1, "violation", ["replied SUCCESS"]),
    (MemoryError(), 3, "budget", ["btfsm validate: incomplete: out of memory", "--max-states"]),
    (_missing_matplotlib(), 2, "usage", ["needs the Python package 'matplotlib'", "btfsm[sim]"]),
    (KeyboardInterrupt(), 130, "interrupted", ["btfsm validate: interrupted"]),
    (Terminated(), 143, "terminated", ["btfsm validate: terminated"]),
    (ZeroDivisionError("division by zero"), 70, "internal",
     ["internal error (a bug in btfsm): ZeroDivisionError: division by zero", cli.REPORT_HINT, "--debug"]),
    (RuntimeError("two\nlines\r\u2028here"), 70, "internal", ["two\\nlines\\r\\u2028here"]),
    (ModelError("a\nb", "c\x85d", "f\ry"), 2, "model", ["f\\ry: a\\nb: c\\x85d"]),
    (RecursionError("maximum recursion depth exceeded"), 70, "internal", ["RecursionError"]),
    (OSError("no filename"), 70, "internal", ["OSError: no filename"]),
]


@pytest.fixture
def raising(monkeypatch):
    """Make ``btfsm validate`` raise a given exception."""

    def install(exc):
        def handler(args):
            raise exc

        monkeypatch.setattr(cli, "_handler", lambda spec: handler)

    return install


@pytest.mark.parametrize("exc,code,kind,needles", TABLE, ids=[f"{type(t[0]).__name__}-{i}" for i, t in enumerate(TABLE)])
def test_exception_to_one_line(exc, code, kind, needles, raising, capsys):
    raising(exc)
    got, out, err = _run(["validate", "two-area"], capsys)
    assert got == code
    assert out == "" and "Traceback" not in err
    assert len(err.splitlines()) == 1, err
    for needle in needles:
        assert needle in err, (needle, err)


@pytest.mark.parametrize("exc,code,kind,needles", TABLE, ids=[f"{type(t[0]).__name__}-{i}" for i, t in enumerate(TABLE)])
def test_exception_under_json(exc, code, kind, needles, raising, capsys):
    raising(exc)
    got, out, err = _run(["validate", "two-area", "--json"], capsys)
    assert got == code and err == ""
    assert len(out.splitlines()) == 1
    error = json.loads(out)["error"]
    assert error["exit_code"] == code and error["kind"] == kind and error["command"] == "validate"
    assert set(error) >= {"kind", "type", "command", "file", "element", "problem", "message", "exit_code"}
    if isinstance(exc, ModelError):
        assert (error["file"], error["element"], error["problem"]) == (exc.file, exc.element or None, exc.problem)
    for needle in needles:
        assert needle in error["message"]


def test_debug_prints_the_traceback_of_an_internal_error_only(raising, capsys):
    raising(ZeroDivisionError("boom"))
    for argv in (["--debug", "validate", "two-area"], ["validate", "two-area", "--debug"]):
        code, out, err = _run(argv, capsys)
        assert code == 70 and "Traceback" in err and "ZeroDivisionError: boom" in err
    raising(ModelError("x", "bad", "m.yaml"))
    code, out, err = _run(["--debug", "validate", "two-area"], capsys)
    assert code == 2 and "Traceback" not in err and len(err.splitlines()) == 1


def test_broken_pipe_is_quiet(raising, capsys):
    raising(BrokenPipeError(errno.EPIPE, "Broken pipe"))
    assert _run(["validate", "two-area"], capsys)[0] == 0


def test_sigterm_handler_is_restored(capsys):
    before = signal.getsignal(signal.SIGTERM)
    assert _run(["validate", "two-area"], capsys)[0] == 0
    assert signal.getsignal(signal.SIGTERM) is before


def test_real_errors_one_line(capsys, tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("name: x\nfsms: 3\n")
    for argv, code in ((["validate", str(bad)], 2), (["validate", "no-such-model"], 2),
                       (["validate", str(tmp_path)], 2), ([], 2), (["frobnicate"], 2),
                       (["check", "two-area", "--max-states", "0"], 2)):
        got, out, err = _run(argv, capsys)
        assert got == code and len(err.splitlines()) == 1 and err.startswith("btfsm"), (argv, err)


def test_validate_json(capsys):
    code, out, err = _run(["validate", "two-area", "--json"], capsys)
    data = json.loads(out)
    assert code == 0 and data["model"] == "two-area" and data["ok"] is True and isinstance(data["warnings"], list)
    assert data["fsms"] == 1 and data["states"] > 0


def test_skills_json(capsys):
    code, out, _ = _run(["skills", "two-area", "--json"], capsys)
    first = json.loads(out)
    code2, out2, _ = _run(["skills", "two-area", "--format", "json"], capsys)
    second = json.loads(out2)
    first.pop("seconds", None), second.pop("seconds", None)
    assert code in (0, 1) and (code2, second) == (code, first) and first["model"] == "two-area"


def test_conform_json(capsys):
    code, out, _ = _run(["conform", "ariac-preemptive", "--scenarios", "2", "--time", "3", "--json"], capsys)
    data = json.loads(out)
    assert code == 0 and data["total"] == 2 and data["conforming"] == 2 and len(data["scenarios"]) == 2
    assert data["checked_states"] > 0


def test_conform_budget_exits_3(capsys):
    code, out, err = _run(["conform", "ariac-preemptive", "--scenarios", "1", "--time", "1", "--max-states", "5"], capsys)
    assert code == 3 and "--max-states" in err


# ---------------------------------------------------------------- real signals

# The child wraps btfsm.signals.check (called before every tick of the simulation loop, and
# imported by sim/loop.py after this patch) so that it says 'looping' on stderr once, when the
# loop runs its first tick: the test signals then, not after a guessed sleep (under load,
# imports and model loading can take seconds).
_CHILD = """\
import sys
import btfsm.signals as signals
original = signals.check
said = []
def check():
    if not said:
        said.append(1)
        print('looping', file=sys.stderr, flush=True)
    original()
signals.check = check
from btfsm.cli import main
sys.exit(main(sys.argv[1:]))
"""


def _spawn(*args):
    """Start ``btfsm ARGS``; return once its simulation loop runs (it prints 'looping')."""
    proc = subprocess.Popen([sys.executable, "-c", _CHILD, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    watchdog = threading.Timer(120, proc.kill)  # a child that never gets there ends the wait (EOF)
    watchdog.start()
    before = []
    try:
        for line in proc.stderr:  # EOF (the child ended early) ends the loop too
            if line.strip() == "looping":
                return proc
            before.append(line)
    finally:
        watchdog.cancel()
    proc.wait(timeout=120)
    raise AssertionError(f"the child ended before its simulation loop (exit {proc.returncode}): {''.join(before)}")


@pytest.mark.parametrize("sig,code,word", [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")])
def test_signal_ends_in_one_line(sig, code, word, tmp_path):
    proc = _spawn("sim", "ariac-preemptive", "--time", "90000", "--gif", str(tmp_path / "run.gif"))
    try:
        proc.send_signal(sig)  # inside the simulation loop (it has run at least one check)
        out, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == code, err
    assert err.strip().splitlines()[-1] == f"btfsm sim: {word}" and "Traceback" not in err
    assert os.listdir(tmp_path) == []  # no half-written animation


def test_model_errors_name_the_model_file(tmp_path, capsys):
    """An error raised after loading (here: export of a tree that is not one SkillRequest)
    names the file it came from."""
    import shutil

    path = tmp_path / "two.yaml"
    shutil.copy(os.path.join(os.path.dirname(__file__), "..", "models", "examples", "two_area.yaml"), path)
    code, out, err = _run(["export", str(path), "--format", "smv"], capsys)
    assert code == 2 and err.startswith(f"btfsm export: error: {path}: ") and len(err.splitlines()) == 1


@pytest.mark.parametrize("argv", [["--help"], ["--version"], ["check", "--help"]])
def test_help_and_version_exit_0(argv, capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(argv)
    assert exc.value.code == 0 and capsys.readouterr().out
