#!/usr/bin/env python3
"""btfsm vs SPIN on the pick/place benchmark (Q = D = B = n), run side by side.

For each size it

* builds ``btfsm.models.pickplace.pickplace(n)`` and explores it with the vectorised engine
  (``btfsm.verify.vector.reach``: states and BFS parents) and, at the sizes given by
  ``--generic``, on the generic path (``btfsm.verify.explore.explore``, the path every model
  takes: every transition, labels, statuses; its default engine is ``btfsm.verify.traced``)
  and at the sizes given by ``--scalar`` with its scalar engine (one step per
  transition, the reference the traced engine is tested against);
* generates SPIN's verifier from the hand-written reference model
  (``--pml``, default /work/shared/bench/spin/pickplace.pml) with
  ``spin -o2 -DQMAX=n -DDMAX=n -DBMAX=n -a``, ``gcc -O2 -DSAFETY -DNOCLAIM -DMEMLIM=16000``
  and runs ``./pan -m1000000 -w26``;
* optionally (``--export-spin``) runs the same SPIN pipeline on btfsm's own Promela
  export of the model (``btfsm.verify.export``);
* checks every state count against SPIN's (10,288 / 104,860 / 1,305,694 / 6,053,248 /
  18,291,250 at n = 3 / 6 / 12 / 18 / 24) and prints states/s, time and peak memory
  beside SPIN's, with the ratios.

Every btfsm run happens in its own subprocess (``--worker``), so its peak RSS
(``resource.getrusage``) is its own; ``base`` is the RSS after the imports, before
exploring. SPIN's memory is pan's own "total actual memory usage" line and its RSS.
Runs are sequential, never concurrent. Exit code 1 when a count is wrong.

Usage: ``python3 benchmarks/pickplace.py [--sizes 6 12 18 24] [--generic 6] [--scalar 6] [--json]``
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

from btfsm.models.pickplace import SPIN_STATES, pickplace  # noqa: E402

__all__ = ["worker", "run_worker", "run_spin_reference", "run_spin_export", "main", "DEFAULT_PML"]

DEFAULT_PML = "/work/shared/bench/spin/pickplace.pml"


def _rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def worker(engine: str, n: int) -> dict:
    """Explore pickplace(n) with one engine in this process; the measurements."""
    from btfsm.verify.explore import explore  # imports (numpy among them) before the clock starts
    from btfsm.verify.vector import reach

    m = pickplace(n)
    m.program  # compile before timing
    base = _rss_mb()
    t0, c0 = time.perf_counter(), time.process_time()
    if engine == "vector":
        r = reach(m)
        states, trans, dead, complete = r.n_states, r.n_transitions, len(r.dead), r.complete
    else:
        ts = explore(m, engine="scalar" if engine == "scalar" else "auto")
        states, trans, dead, complete = ts.n_states, ts.n_transitions, len(ts.dead), ts.complete
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"engine": engine, "n": n, "states": states, "transitions": trans, "dead": dead, "complete": complete,
            "seconds": wall, "cpu_seconds": cpu, "rss_mb": _rss_mb(), "base_rss_mb": base}


def run_worker(engine: str, n: int) -> dict:
    proc = subprocess.run([sys.executable, os.path.abspath(__file__), "--worker", engine, str(n)],
                          capture_output=True, text=True, cwd=ROOT)
    if proc.returncode != 0:
        raise RuntimeError(f"{engine} worker for n={n} failed:\n{proc.stderr[-3000:]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _spin(text: str, n: int, defines=()) -> dict:
    from btfsm.verify.promela import compile_pan, run_pan

    work = tempfile.mkdtemp(prefix="btfsm_bench_spin_")
    try:
        t0 = time.perf_counter()
        pan = compile_pan(text, work, spin_flags=defines, cc_flags=("-DSAFETY", "-DNOCLAIM", "-DMEMLIM=16000"))
        build = time.perf_counter() - t0
        r = run_pan(pan, ("-m1000000", "-w26"), timeout=3600)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return {"n": n, "states": r.states, "transitions": r.transitions, "errors": r.errors,
            "seconds": r.seconds, "wall": r.wall, "mem_states_mb": r.memory_states_mb,
            "mem_total_mb": r.memory_total_mb, "rss_mb": r.rss_mb, "build_seconds": build}


def run_spin_reference(pml: str, n: int) -> dict:
    """SPIN on the hand-written reference model at size n."""
    with open(pml, encoding="utf-8") as fh:
        text = fh.read()
    return _spin(text, n, (f"-DQMAX={n}", f"-DDMAX={n}", f"-DBMAX={n}"))


def run_spin_export(n: int) -> dict:
    """SPIN on btfsm's Promela export of pickplace(n)."""
    from btfsm.verify.export import export

    return _spin(export(pickplace(n), "promela"), n)


def _fmt_rate(states, seconds):
    return f"{states / seconds:,.0f}" if seconds else "-"


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[6, 12, 18, 24], help="Q = D = B sizes (default 6 12 18 24)")
    p.add_argument("--generic", type=int, nargs="*", default=[6], help="sizes also run on the generic path, "
                   "btfsm.verify.explore.explore (default 6)")
    p.add_argument("--scalar", type=int, nargs="*", default=[], help="sizes also run with the generic path's scalar "
                   "engine (one step per transition; default none)")
    p.add_argument("--pml", default=DEFAULT_PML, help="SPIN's reference pickplace.pml")
    p.add_argument("--no-spin", action="store_true", help="skip SPIN")
    p.add_argument("--export-spin", action="store_true", help="also run SPIN on btfsm's own Promela export")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    p.add_argument("--worker", nargs=2, metavar=("ENGINE", "N"), help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.worker:
        print(json.dumps(worker(args.worker[0], int(args.worker[1]))))
        return 0
    spin_ok = not args.no_spin and shutil.which("spin") and shutil.which("gcc") and os.path.exists(args.pml)
    if not args.no_spin and not spin_ok:
        print(f"note: SPIN columns skipped (need spin, gcc and {args.pml})", file=sys.stderr)
    rows, ok = [], True
    for n in args.sizes:
        want = SPIN_STATES.get(n)
        runs = [("btfsm vector", run_worker("vector", n))]
        if n in (args.generic or []):
            runs.append(("btfsm generic", run_worker("generic", n)))
        if n in (args.scalar or []):
            runs.append(("btfsm generic, scalar", run_worker("scalar", n)))
        spin = run_spin_reference(args.pml, n) if spin_ok else None
        if spin_ok and args.export_spin:
            runs.append(("SPIN on btfsm export", run_spin_export(n)))
        for name, r in runs + ([("SPIN reference", spin)] if spin else []):
            good = want is None or r["states"] == want
            ok &= good and (spin is None or r["states"] == spin["states"])
            rows.append(dict(r, run=name, n=n, expected=want, count_ok=good))
    if args.json:
        print(json.dumps({"machine": _machine(), "rows": rows, "counts_ok": ok}, indent=1))
        return 0 if ok else 1
    print(f"pick/place benchmark, Q=D=B=n. {_machine()}")
    head = f"{'n':>3} {'run':<22} {'states':>12} {'transitions':>13} {'seconds':>8} {'states/s':>11} {'peak MB':>8} {'count':>6}"
    print(head)
    print("-" * len(head))
    for r in rows:
        secs = r.get("seconds") or 0.0
        mem = r.get("rss_mb") if r["run"].startswith("btfsm") else r.get("mem_total_mb")
        print(f"{r['n']:>3} {r['run']:<22} {r['states']:>12,} {r['transitions'] or 0:>13,} {secs:>8.2f} "
              f"{_fmt_rate(r['states'], secs):>11} {mem or 0:>8.0f} {'ok' if r['count_ok'] else 'WRONG':>6}")
    print()
    for n in args.sizes:
        vec = next(r for r in rows if r["n"] == n and r["run"] == "btfsm vector")
        spin = next((r for r in rows if r["n"] == n and r["run"] == "SPIN reference"), None)
        gen = next((r for r in rows if r["n"] == n and r["run"] == "btfsm generic"), None)
        line = f"n={n}: vector {vec['seconds']:.2f} s (cpu {vec['cpu_seconds']:.2f} s), peak RSS {vec['rss_mb']:.0f} MB (base {vec['base_rss_mb']:.0f} MB)"
        if spin:
            line += (f"; SPIN {spin['seconds']:.2f} s, {spin['mem_total_mb']:.0f} MB (pan RSS {spin['rss_mb']:.0f} MB)"
                     f" -> SPIN/vector time {spin['seconds'] / vec['seconds']:.2f}x, memory {spin['mem_total_mb'] / vec['rss_mb']:.2f}x")
        if gen:
            line += f"; generic {gen['states'] / gen['seconds']:,.0f} states/s (cpu {gen['states'] / gen['cpu_seconds']:,.0f})"
            if spin:
                line += (f", SPIN/generic time {spin['seconds'] / gen['seconds']:.2f}x, memory "
                         f"{spin['mem_total_mb'] / gen['rss_mb']:.2f}x (peak RSS {gen['rss_mb']:.0f} MB)")
        sca = next((r for r in rows if r["n"] == n and r["run"] == "btfsm generic, scalar"), None)
        if sca:
            line += f"; scalar {sca['states'] / sca['seconds']:,.0f} states/s"
            if gen:
                line += f" (generic/scalar speed {sca['seconds'] / gen['seconds']:.1f}x)"
        print(line)
    print("counts:", "all equal to SPIN's" if ok else "MISMATCH")
    return 0 if ok else 1


def _machine() -> str:
    try:
        spin_v = subprocess.run(["spin", "-V"], capture_output=True, text=True).stdout.strip()
    except OSError:
        spin_v = "spin not installed"
    return f"{platform.processor() or platform.machine()}, nproc={os.cpu_count()}, Python {platform.python_version()}, {spin_v}"


if __name__ == "__main__":
    sys.exit(main())
