"""How long the ARIAC arm's FSM states take in the kitting cell, measured in trials.

``measure(specs)`` runs trials of the experiment (``btfsm.sim.trial.run_trial``) and records,
for every visit of the arm FSM's token to a state, the ticks it stayed there; the maxima
are what ``btfsm.models.ariac.ARM_DURATIONS`` declares (with a margin), so that the
checker can bound the reaction time (property ``response``, docs/verification.md 2.1).
Declared durations are enforced in every run: the runtime refuses a primitive answer
outside them (a conformance error), so a trial whose motions take longer than declared
fails instead of passing silently.

What is measured, not derived: the bounds come from the cell's motions in the 80 trials
of the experiment, not from the motion profiles' worst case over every pose (that
derivation is not done; docs/verification.md 2.1 says so).

    python -m btfsm.sim.durations [--workers N]   # prints the table ARM_DURATIONS holds
"""
from __future__ import annotations

import math
from collections import defaultdict

__all__ = ["measure", "declared", "main"]


def _visits(spec) -> dict:
    from .trial import run_trial

    runs: dict = defaultdict(int)
    cur = {"state": None, "n": 0}

    def on_tick(rt, world):
        state, _ = rt.fsm_state("arm")
        if state == cur["state"]:
            cur["n"] += 1
            return
        if cur["state"] is not None:
            runs[cur["state"]] = max(runs[cur["state"]], cur["n"])
        cur["state"], cur["n"] = state, 1

    run_trial(spec, on_tick=on_tick)
    return dict(runs)


def measure(specs, workers: int = 1) -> dict:
    """``{state: the most ticks a visit lasted}`` over the trials ``specs``."""
    if workers > 1 and len(specs) > 1:
        import multiprocessing as mp

        with mp.get_context("fork").Pool(workers) as pool:
            parts = pool.map(_visits, specs)
    else:
        parts = [_visits(s) for s in specs]
    out: dict = {}
    for p in parts:
        for state, n in p.items():
            out[state] = max(out.get(state, 0), n)
    return dict(sorted(out.items()))


def declared(maxima: dict, rate: float = 10.0, margin: float = 0.1) -> dict:
    """Seconds to declare per state: a visit of n ticks ends on the n-th tick of its run,
    i.e. after (n - 1) / rate seconds (docs/semantics.md 6.1), plus ``margin``, rounded up
    to a tick.

    >>> declared({"put_agv": 14, "conveyor_to_agv": 61})
    {'put_agv': 1.5, 'conveyor_to_agv': 6.6}
    """
    return {s: math.ceil((n - 1) * (1 + margin) - 1e-9) / rate for s, n in maxima.items()}


def main(argv=None) -> int:
    import argparse

    from .protocol import VARIANTS, TrialSpec

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--workers", type=int, default=2)
    args = p.parse_args(argv)
    from btfsm.models.ariac import ARM_DURATIONS

    specs = [TrialSpec(v, k) for v in VARIANTS for k in range(1, 41)]
    maxima = measure(specs, args.workers)
    print(f"{'state':26s} {'max ticks':>9s} {'declare s':>9s} {'declared':>9s}")
    for state, n in maxima.items():
        want = declared({state: n})[state]
        have = ARM_DURATIONS.get(state)
        print(f"{state:26s} {n:9d} {want:9.1f} {have if have is not None else '-':>9}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
