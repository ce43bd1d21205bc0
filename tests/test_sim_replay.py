"""Counterexamples replayed in the cell; the original's freeze against the corrected model."""
import shutil
import subprocess
import sys

import pytest

from btfsm.models import ariac, original
from btfsm.sim.replay import replay_in_cell, triggers_of

verify = pytest.importorskip("verify")


def _counterexample(model, prop):
    res = verify.check(model, properties=[prop]).result(prop)
    assert res.holds is False
    return res.counterexample.to_json()


def test_original_freezes_in_the_cell_while_a_belt_part_is_lost():
    model = original.original_preemptive()
    ce = _counterexample(model, "workable-reachability")
    assert [ev for _, ev in triggers_of(ce, "movement_manager")] == ["arrive"]
    out = replay_in_cell(model, ce, time_limit=90.0)
    assert len(out.injected) == 1 and len(out.lost) == 1
    assert out.shows_loss_while_frozen
    state, t0, t1 = out.frozen
    assert t1 - t0 >= 16.0 and state in ("release on agv", "detach approach on agv (place)", "escape agv")


def test_corrected_model_serves_the_same_situation():
    """The same event in the same situation (arrival during the release at the tray)."""
    ce = {"initial": {"arm.state": "approach_bins"},
          "steps": [{"env": [], "state": {"arm.state": "release_agv"}},
                    {"env": ["arrive"], "state": {"arm.state": "release_agv"}}]}
    out = replay_in_cell(ariac.preemptive(), ce, time_limit=90.0)
    assert len(out.injected) == 1 and out.lost == []
    assert not out.shows_loss_while_frozen


def test_cli_replay_cell(tmp_path):
    ce_dir = tmp_path / "ce"
    run = [sys.executable, "-m", "btfsm.cli"]
    chk = subprocess.run(run + ["check", "original-preemptive", "--property", "workable-reachability",
                                "--counterexample-dir", str(ce_dir)], capture_output=True, text=True, timeout=300)
    assert chk.returncode == 1, chk.stderr
    [ce] = list(ce_dir.glob("*.json"))
    png = tmp_path / "freeze.png"
    page = tmp_path / "r.html"
    rep = subprocess.run(run + ["replay", str(ce), "original-preemptive", "--cell", "--render", str(png), "--time", "70"]
                         + (["--html", str(page)] if shutil.which("dot") else []),
                         capture_output=True, text=True, timeout=300)
    assert rep.returncode == 0, rep.stderr
    assert "LOST" in rep.stdout and "without a move" in rep.stdout
    assert png.exists()
    if shutil.which("dot"):  # the HTML report: the counterexample, then the cell run with its pictures
        from btfsm.html import read_page

        runs = read_page(page)["runs"]
        assert [r["kind"] for r in runs] == ["counterexample", "cell"]
        cell = runs[1]
        assert 2 <= len(cell["pictures"]) <= 40 and cell["ticks"][1].get("picture") == 0
        assert any(t["fsm"]["movement_manager"][0] == "release on agv" for t in cell["ticks"])
