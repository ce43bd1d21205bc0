"""Dask's overhead against the process pool for the 80-trial experiment (issue 12.5).

    python benchmarks/sweep_overhead.py [--workers 2] [--rounds 1] [--time 1500] [--json]

Both engines of ``btfsm.sim.sweep.run_sweep`` run the same 80 trials (both variants,
k = 1..40, the paper's protocol) on the same number of workers, in turns (pool, dask,
pool, dask, ...), no cache; the Dask time includes starting and closing its embedded
local cluster. Prints each wall time, the ratio dask/pool, and checks that both gave
the same results. The issue's target: Dask within 10 % of the pool.
"""
from __future__ import annotations

import argparse
import json
import time


def main(argv=None) -> int:
    from btfsm.sim.sweep import grid, run_sweep

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--rounds", type=int, default=1)
    p.add_argument("--time", type=float, default=1500.0, help="time limit per trial (simulated s)")
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    specs = grid(("preemptive", "baseline"), list(range(1, 41)), time_limit=args.time)
    times = {"processes": [], "dask": []}
    results = {}
    for _ in range(args.rounds):
        for engine in ("processes", "dask"):
            t0 = time.perf_counter()
            results[engine] = run_sweep(specs, engine=engine, workers=args.workers, progress=False)
            times[engine].append(time.perf_counter() - t0)
    same = results["processes"] == results["dask"]
    best = {k: min(v) for k, v in times.items()}
    ratio = best["dask"] / best["processes"]
    out = {"trials": len(specs), "workers": args.workers, "seconds": times, "best": best, "ratio": ratio,
           "same_results": same, "target_met": ratio <= 1.10}
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{len(specs)} trials on {args.workers} workers, {args.rounds} round(s), best of each:")
        print(f"  process pool  {best['processes']:7.1f} s")
        print(f"  dask (local)  {best['dask']:7.1f} s")
        print(f"  dask / pool   {ratio:7.3f}  (target <= 1.10: {'met' if ratio <= 1.10 else 'not met'})")
        print(f"  same results: {same}")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
