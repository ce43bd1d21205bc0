"""The full ``btfsm check`` next to the explorations it makes: wall time and peak memory.

Usage: ``python3 benchmarks/check_memory.py [--sizes 12 18 24] [--json]``

For pick/place at Q=D=B=n (``btfsm.models.pickplace``, written to a model file first), two
child processes run one after the other, each measured from outside:

* **explore**: the explorations a full check makes and nothing else: the model-level
  system (``explore``), let go, then FSM ``skill`` as an open system (``explore_fsm``),
  with the same engine and budgets as the check;
* **check**: ``btfsm check FILE --json`` with every property, budgets large enough for the
  whole system (``--max-states``/``--max-transitions``), so every property is decided.

Wall time is the parent's clock around each child (start-up and imports included on both
sides); peak memory is the child's peak resident set (``os.wait4``'s ``ru_maxrss``, the
child alone). The ratios check / explore are what issue 24 bounds (at most 2x each).
Timing is read only here.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")

EXPLORE = """
import sys
from btfsm.files import load_model
from btfsm.verify.explore import explore, explore_fsm
m = load_model(sys.argv[1])
limits = dict(max_states=int(sys.argv[2]), max_transitions=int(sys.argv[3]))
ts = explore(m, **limits)
out = [(ts.n_states, ts.n_transitions, ts.complete)]
del ts
for f in m.fsms:
    ts = explore_fsm(m, f.name, **limits)
    out.append((ts.n_states, ts.n_transitions, ts.complete))
    del ts
print(out)
"""


def measured(cmd) -> tuple:
    """(wall seconds, peak RSS in MB, stdout, exit code) of one child process."""
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, cwd=ROOT)
    out = p.stdout.read()
    _, status, usage = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    p.returncode = os.waitstatus_to_exitcode(status)
    return wall, usage.ru_maxrss / 1024, out.decode(), p.returncode


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[12, 18])
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    sys.path.insert(0, ROOT)
    from btfsm.files import dump_model
    from btfsm.models.pickplace import pickplace

    py = sys.executable
    btfsm = [py, "-c", "import sys; from btfsm.cli import main; sys.exit(main())"]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.sizes:
            path = os.path.join(tmp, f"pickplace{n}.json")
            dump_model(pickplace(n), path)
            states, transitions = str(2000 * n ** 3), str(20000 * n ** 3)  # above the system (1,323 n^3 states)
            ew, em, eout, erc = measured([py, "-c", EXPLORE, path, states, transitions])
            cw, cm, cout, crc = measured(btfsm + ["check", path, "--json", "--max-states", states,
                                                  "--max-transitions", transitions])
            report = json.loads(cout)
            verdicts = {p["name"]: p["verdict"] for p in report["properties"]}
            row = {"n": n, "systems": [(s["kind"], s["states"], s["transitions"]) for s in report["systems"]],
                   "explore_s": round(ew, 2), "explore_mb": round(em), "check_s": round(cw, 2), "check_mb": round(cm),
                   "time_ratio": round(cw / ew, 2), "memory_ratio": round(cm / em, 2), "exit": crc,
                   "undecided": sorted(k for k, v in verdicts.items() if v == "undecided"),
                   "explored": eout.strip(), "explore_exit": erc,
                   "explore_in_check_s": [round(s["seconds"], 2) for s in report["systems"]],
                   "property_s": {p["name"]: round(p["seconds"], 2) for p in report["properties"] if p["seconds"] >= 0.05}}
            rows.append(row)
            if not args.json:
                print(f"n={n}: {', '.join(f'{k} {s:,} states {t:,} transitions' for k, s, t in row['systems'])}")
                print(f"  explore only: {ew:7.2f} s {em:8.0f} MB peak RSS")
                print(f"  full check:   {cw:7.2f} s {cm:8.0f} MB peak RSS (exit {crc}; undecided: "
                      f"{', '.join(row['undecided']) or 'none'})")
                print(f"  in the check: explorations {' + '.join(map(str, row['explore_in_check_s']))} s; properties "
                      f"(their explorations included) {', '.join(f'{k} {v}' for k, v in row['property_s'].items())} s")
                print(f"  check / explore: time {cw / ew:.2f}x, memory {cm / em:.2f}x", flush=True)
    if args.json:
        print(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
