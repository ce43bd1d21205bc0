"""benchmarks/profiles_tick.py: each profile does what its real engine does on the
benchmark's tree (so the timings compare), and the exclusive-resource counts are as the
issue says (none under btfsm, some under btcpp/pytrees). Skipped without the engines."""
from __future__ import annotations

import importlib.util
import pathlib

import pytest

from btfsm.status import Status

pytest.importorskip("py_trees")
pytest.importorskip("behaviortreepy")

_PATH = pathlib.Path(__file__).resolve().parents[1] / "benchmarks" / "profiles_tick.py"
_spec = importlib.util.spec_from_file_location("profiles_tick", _PATH)
profiles_tick = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(profiles_tick)

TICKS = 3000


def test_profiles_agree_with_the_real_engines():
    runs = {s: profiles_tick.run_btfsm(s, TICKS) for s in ("btfsm", "btcpp", "pytrees")}
    cpp, py = profiles_tick.run_btcpp(TICKS), profiles_tick.run_pytrees(TICKS)
    assert profiles_tick.compare(runs["btcpp"], cpp)["differing_ticks"] == 0
    assert profiles_tick.compare(runs["pytrees"], py)["differing_ticks"] == 0
    # the tree does preempt: halt before start changes the callback order somewhere
    assert profiles_tick.compare(runs["btfsm"], cpp)["differing_ticks"] > 0
    assert any(("halt" in [c for _, c in tick]) for tick in cpp[0])
    assert runs["btfsm"][2] == 0 and runs["btcpp"][2] > 0 and runs["pytrees"][2] > 0


def test_main_json_runs(capsys):
    assert profiles_tick.main(["--ticks", "200", "--repeats", "1", "--check-ticks", "200", "--json"]) == 0
    assert '"claimed_equal"' in capsys.readouterr().out


def test_step_oracle_runs_the_runtime_ticks():
    """The timed bare ``Program.step`` (``_StepOracle``) goes through the same ticks as the
    Runtime whose callbacks are compared with the engines: same root status every tick."""
    n = 300
    _, roots, _ = profiles_tick.run_btfsm("btcpp", n)
    prog, clock = profiles_tick.build_model(n, "btcpp").program, profiles_tick._Clock()
    oracle, s, got = profiles_tick._StepOracle(prog, clock), prog.initial, []
    for k in range(1, n + 1):
        clock.t = k
        step = prog.step(s, oracle)
        s = step.state
        got.append(Status(step.status).name)
    assert got == roots and len(set(roots)) == 3
