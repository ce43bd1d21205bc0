"""Check time of the ``response`` property on the timed ARIAC models (issue 12.5).

    python benchmarks/response_check.py [--parts 2 18] [--json]

For each variant and tray size: states, transitions, and the wall time of
``btfsm check MODEL --property response`` (exploration, the worst/best sweeps and the
counterexample), each in a fresh process, with the proved worst case. No other tool
decides this property, so there is no reference column; the issue's target is 2 s.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys

CHILD = r"""
import json, sys, time
from btfsm.models import ariac
from btfsm.verify.report import check
v, n = sys.argv[1], int(sys.argv[2])
t0 = time.perf_counter()
r = check(ariac.timed(getattr(ariac, v)(n_tray=n)), ["response"], max_states=50_000_000)
res = r.results[0].info["responses"]["reach"]
print(json.dumps({"variant": v, "parts": n, "states": r.states, "transitions": r.transitions,
                  "seconds": time.perf_counter() - t0, "worst_s": res["worst_seconds"], "holds": r.results[0].holds}))
"""


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--parts", type=int, nargs="+", default=[2])
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    rows = []
    for n in args.parts:
        for v in ("preemptive", "baseline"):
            out = subprocess.run([sys.executable, "-c", CHILD, v, str(n)], check=True, capture_output=True, text=True)
            rows.append(json.loads(out.stdout))
    if args.json:
        print(json.dumps(rows))
        return 0
    print(f"{'model':34s} {'states':>11s} {'transitions':>12s} {'check s':>8s} {'worst s':>8s}  target 2 s")
    for r in rows:
        name = f"ariac.timed({r['variant']}, {r['parts']} parts)"
        print(f"{name:34s} {r['states']:11,d} {r['transitions']:12,d} {r['seconds']:8.1f} {r['worst_s']:8.1f}  "
              f"{'met' if r['seconds'] < 2 else 'not met'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
