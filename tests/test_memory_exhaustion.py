"""Memory exhaustion ends in the budget exit (3) and one line (issue 18, point 5): a
reserve held from the start is released, with the failed computation's frames, before
the report; should the message still not fit, a fixed line goes straight to stderr."""
from __future__ import annotations

import os
import resource
import subprocess
import sys
from pathlib import Path

import pytest

import btfsm.cli as cli
import btfsm.verify.cli as vcli
import btfsm.verify.report as vreport
from btfsm import reserve
from btfsm.cli import main

LONG = os.environ.get("BTFSM_LONG") == "1"


def _boom(*args, **kwargs):
    big = bytearray(1 << 20)  # held by this frame, freed with the traceback
    raise MemoryError(len(big))


def test_check_out_of_memory_is_exit_3_in_one_line(monkeypatch, capsys):
    monkeypatch.setattr(vreport, "check", _boom)
    code = main(["check", "pickplace3"])
    out, err = capsys.readouterr()
    assert code == 3 and out == ""
    assert err.splitlines() == ["btfsm check: out of memory while exploring pickplace3; lower --max-states"]
    assert not reserve.held()  # released before the report


@pytest.mark.parametrize("as_json", [False, True])
def test_memory_error_anywhere_is_the_budget_exit(monkeypatch, capsys, as_json):
    monkeypatch.setattr(vcli, "_load", _boom)  # before the exploration: main's handler
    code = main(["check", "pickplace3"] + (["--json"] if as_json else []))
    out, err = capsys.readouterr()
    assert code == 3
    lines = (out if as_json else err).splitlines()
    assert len(lines) == 1 and "out of memory" in lines[0]
    assert not reserve.held()


def test_a_report_that_does_not_fit_is_a_fixed_line(monkeypatch, capfd):
    monkeypatch.setattr(vcli, "_load", _boom)

    def no_room(*args):
        raise MemoryError()

    monkeypatch.setattr(cli, "_emit", no_room)
    assert main(["check", "pickplace3"]) == 3
    out, err = capfd.readouterr()
    assert out == "" and err == cli._OOM_LINE.decode()


def test_release_drops_the_chained_tracebacks():
    try:
        try:
            _boom()
        except MemoryError:
            raise MemoryError("again")
    except MemoryError as exc:
        caught = exc
    assert caught.__traceback__ is not None and caught.__context__.__traceback__ is not None
    reserve.hold(16)
    reserve.release(caught)
    assert caught.__traceback__ is None and caught.__context__.__traceback__ is None and not reserve.held()


FREE20 = "\n".join(["name: free20", "variables:", *(f"  b{i}: bool" for i in range(20)), "environment:",
                    *(f"  - {{event: flip{i}, effects: {{b{i}: not b{i}}}}}" for i in range(20))]) + "\n"


@pytest.mark.skipif(not LONG, reason="BTFSM_LONG=1: a real run under a 1 GB address-space limit (tens of seconds)")
def test_one_gigabyte_address_space(tmp_path):
    """20 free booleans, --max-states 10**9, under ``ulimit -v 1048576``: exit 3, one line."""
    model = tmp_path / "free20.yaml"
    model.write_text(FREE20)

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (1 << 30, 1 << 30))

    r = subprocess.run([sys.executable, "-m", "btfsm", "check", str(model), "--max-states", str(10 ** 9)],
                       capture_output=True, text=True, preexec_fn=limit, cwd=Path(__file__).parent, timeout=1800)
    assert r.returncode == 3, r.stderr
    assert "Traceback" not in r.stderr and len(r.stderr.splitlines()) <= 1, r.stderr  # one line (or a budget report)
