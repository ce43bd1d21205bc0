"""The cell's own worst response, found by search over the arrival instants (``btfsm.sim.worst``,
issue 21): checked against the counterexample replay run at every instant of a small grid
(the brute-force oracle), the same for 1 and 2 workers, and within the proof's bound.
The full searches (every tick of the job; pairs of parts) run with BTFSM_LONG=1."""
from __future__ import annotations

import math
import os
import random

import pytest

pytest.importorskip("pymunk")

from btfsm.models.registry import load_builtin  # noqa: E402
from btfsm.sim import worst  # noqa: E402
from btfsm.sim.replay import replay_in_cell  # noqa: E402

LONG = os.environ.get("BTFSM_LONG") == "1"


def _replayed(model, tick: int, settle: float = 1.0) -> float:
    """The oracle: ``replay_in_cell`` (``pace="times"``) sent one belt part before ``tick``;
    the part's response (detection to the next belt grasp's start), by the replay's count."""
    ce = {"initial": {}, "steps": [{} for _ in range(tick)] + [{"env": ["arrive"]}]}
    r = replay_in_cell(model, ce, pace="times", settle=settle)
    assert len(r.injected) == 1 and not r.mismatch, r.text()
    return dict(r.responses)[r.injected[0][2]]


def test_the_search_is_the_brute_force_worst_of_a_small_grid_whatever_the_workers():
    m = load_builtin("ariac-preemptive-timed")
    job = worst.job_ticks(m)
    assert len(job) > 300  # the 2-part job: the kit completes after about 38 s
    grid = job[::100]  # 4 instants over the job
    one = worst.search_single(m, ticks=grid, workers=1)
    two = worst.search_single(m, ticks=grid, workers=2)
    assert one.grid == two.grid and one.worst == two.worst and one.runs == len(grid)
    assert one.refused == 0  # every run of the cell keeps the model's declared durations
    oracle = {t: _replayed(m, t) for t in random.Random(21).sample(grid, len(grid))}
    assert dict(one.grid) == {(t,): r for t, r in oracle.items()}  # the same runs, measured the same way
    assert one.worst.worst == max(oracle.values()) and one.worst.ticks == (min(t for t in grid if oracle[t] == max(oracle.values())),)
    w = one.worst
    assert w.phases and w.phases[0].state and w.breakdown
    assert sum(s for _, s in w.breakdown) == pytest.approx(w.worst, abs=0.051)  # the window, split per state


def test_sim_worst_on_the_command_line(capsys):
    from btfsm.cli import main

    assert main(["sim", "ariac-preemptive-timed", "--worst", "1", "--step", "200", "--workers", "1"]) == 0
    out = capsys.readouterr().out
    assert "the cell's worst response to 1 belt part(s), by search: 2 runs" in out
    assert "part 1's phase: '" in out and "where the worst response went, per FSM state" in out


def _conditioned(name: str) -> float:
    """The conditioned proof of ``name``: the worst first late response (s) of its
    ``-no-loss`` twin (``btfsm bound NAME ... --within 16``'s last figure)."""
    from btfsm.verify.explore import explore
    from btfsm.verify.properties.response import ResponseBound

    nl = load_builtin(name + "-no-loss")
    rb = ResponseBound(explore(nl), nl.responses[0])
    return rb.first_late(rb.bound_ticks())[0] / rb.rate


@pytest.mark.skipif(not LONG, reason="searches every tick of both variants' jobs, and pairs (BTFSM_LONG=1)")
@pytest.mark.parametrize("name", ["ariac-preemptive-timed", "ariac-baseline-timed"])
def test_the_cells_worst_found_never_exceeds_the_proof(name):
    """Every tick of the 2-part job, then pairs of parts: no run of the cell breaks a
    declared duration; a response without a lost part is within the conditioned proof (the
    preemptive variant loses none); the model's own worst response at the cell's worst
    phase is at least the cell's; the replay sent one part at random instants finds no
    slower run than the search. 5.5 and 2.3 minutes (preemptive, baseline) on 2 workers at
    load average 6-7."""
    m = load_builtin(name)
    proof = _conditioned(name)
    single = worst.search_single(m, workers=2)
    job = [t for (t,), _ in single.grid]
    oracle = {t: _replayed(m, t, settle=20.0) for t in random.Random(2021).sample(job, 5)}  # random instants
    assert all(dict(single.grid)[(t,)] == r <= single.worst.worst for t, r in oracle.items())
    for found in (single, worst.search_pair(m, workers=2)):
        assert not worst.duration_refusals(found)
        w = found.worst
        assert w is not None and w.worst < math.inf
        if name == "ariac-preemptive-timed":
            assert not w.lost
        assert found.clean is not None and found.clean.worst <= proof
        at = worst.at_phase(m, w.phases[w.worst_part])
        assert at.found and at.worst >= w.worst
