#!/usr/bin/env python3
"""Simulated seconds per wall second of btfsm's scene cells, beside the shared reference pymunk cell.

* ARIAC trial (the product path): the checked ARIAC model (preemptive, k = 1) in the btfsm
  Runtime at 10 Hz, in the ARIAC scene (``models/scenes/ariac.yaml``, physical world (pymunk)
  at 240 Hz) bound by ``btfsm.sim.binding.KittingBinding``, for the first ``--sim-seconds``;
* scenes: the same kind of trial in the two-area example and the machine-tending cell
  (physical, 100 Hz world steps), 10 seeds each, run to completion;
* reference: ``pymunk_cell_bench.py --view top`` run as a subprocess (a pymunk kitting
  cell with a scripted controller; it excludes a 2 s warm-up from its timing; ours runs
  one untimed 2-second trial first (imports: pymunk, the model's compilation caches) and
  then times whole trials, building the world included; needs pymunk: ``pip install .[bench]``);
* ``--experiment``: also time the full 80-trial experiment on ``--workers`` processes.

The hard-coded pymunk cell (``sim/cell.py``, "before" in issue 11) is gone; its figures,
measured with this script's earlier version in the same session, are in BENCHMARKS.md.

    python3 benchmarks/sim_cell.py [--sim-seconds 120] [--repeats 3] [--experiment] [--json out.json]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)

def _shared_reference() -> str:
    """``shared/bench/pymunk_cell_bench.py`` beside the project root, or beside one of its
    parents (a git worktree of the project lives deeper than its main clone)."""
    first = os.path.join(os.path.dirname(ROOT), "shared", "bench", "pymunk_cell_bench.py")
    d = ROOT
    while os.path.dirname(d) != d:
        p = os.path.join(os.path.dirname(d), "shared", "bench", "pymunk_cell_bench.py")
        if os.path.exists(p):
            return p
        d = os.path.dirname(d)
    return first  # not found: the usual place, for the message


DEFAULT_REFERENCE = _shared_reference()


def run_trial_bench(sim_seconds: float) -> dict:
    from btfsm.sim.experiment import TrialSpec
    from btfsm.sim.trial import run_trial

    spec = TrialSpec("preemptive", 1, time_limit=sim_seconds)
    t0, c0 = time.perf_counter(), time.process_time()
    r = run_trial(spec)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return {"sim_s_per_wall_s": r.sim_time / wall, "wall_s": wall, "sim_s": r.sim_time,
            "sim_s_per_cpu_s": r.sim_time / cpu, "cpu_s": cpu,
            "ticks": r.ticks, "skills": r.skills, "tray": r.tray}


SCENES = (("two-area", "models/scenes/two_area.yaml"),
          ("models/examples/machine_tending.yaml", "models/scenes/machine_tending.yaml"))


def run_scene_bench(model_ref: str, scene_file: str, seeds: int = 10) -> dict:
    from btfsm.files import load_model
    from btfsm.sim.scene import load_scene
    from btfsm.sim.scene_trial import run_scene

    model, scene = load_model(os.path.join(ROOT, model_ref) if model_ref.endswith(".yaml") else model_ref), \
        load_scene(os.path.join(ROOT, scene_file))
    t0 = time.perf_counter()
    runs = [run_scene(model, scene, seed) for seed in range(seeds)]
    wall = time.perf_counter() - t0
    sim = sum(r.time for r in runs)
    return {"sim_s_per_wall_s": sim / wall, "wall_s": wall, "sim_s": sim, "ticks": sum(r.ticks for r in runs),
            "completed": sum(r.completed for r in runs), "runs": seeds, "scene": scene.name}


def run_experiment_bench(workers: int) -> dict:
    from btfsm.sim.experiment import run_experiment, summarize, trial_specs

    t0 = time.perf_counter()
    results = run_experiment(trial_specs(), workers=workers, progress=False)
    wall = time.perf_counter() - t0
    s = summarize(results)
    return {"wall_s": wall, "trials": len(results), "workers": workers,
            "sim_s": sum(r.sim_time for r in results),
            "lost": {v: s[v]["lost"] for v in s}}


def run_reference(path: str, sim_seconds: float) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "ref.json")
        subprocess.run([sys.executable, path, "--view", "top", "--sim-seconds", str(sim_seconds),
                        "--json", out], check=True, capture_output=True)
        with open(out) as fh:
            return json.load(fh)["bench"]


def median_run(fn, repeats: int, key: str = "sim_s_per_wall_s") -> dict:
    runs = [fn() for _ in range(repeats)]
    mid = statistics.median(r[key] for r in runs)
    return dict(min(runs, key=lambda r: abs(r[key] - mid)), all=[round(r[key], 1) for r in runs])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--sim-seconds", type=float, default=120.0)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--reference", default=DEFAULT_REFERENCE)
    ap.add_argument("--json", help="also write the result to this file")
    ap.add_argument("--experiment", action="store_true", help="also time the full 80-trial experiment")
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()

    run_trial_bench(2.0)  # warm-up, untimed: imports and caches (the reference skips its first 2 s)
    trial = median_run(lambda: run_trial_bench(args.sim_seconds), args.repeats)
    result = {"sim_seconds": args.sim_seconds, "trial": trial}
    scenes = [median_run(lambda m=m, f=f: run_scene_bench(m, f), args.repeats) for m, f in SCENES]
    print("a trial of a checked model in the Runtime at 10 Hz, simulated s per wall s")
    print(f"load average (1, 5, 15 min): {os.getloadavg()}")
    print(f"  {'cell':56} {'sim-s/wall-s':>12}  target >= 800x (ARIAC), 500x (others)")
    print(f"  {'scene ariac (physical, 240 Hz), preemptive k = 1':56} {trial['sim_s_per_wall_s']:12.1f}  "
          f"{'met' if trial['sim_s_per_wall_s'] >= 800 else 'NOT met'}  (runs {trial['all']}; {trial['ticks']} ticks, "
          f"{trial['skills']} skills, tray {trial['tray']}; {trial['sim_s_per_cpu_s']:.0f} sim s per CPU s)")
    for sc in scenes:
        label = f"scene {sc['scene']} (physical, 100 Hz)"
        print(f"  {label:56} {sc['sim_s_per_wall_s']:12.1f}  {'met' if sc['sim_s_per_wall_s'] >= 500 else 'NOT met'}"
              f"  (runs {sc['all']}; {sc['runs']} seeds, {sc['completed']} completed, {sc['sim_s']:.0f} sim s)")
    result["scenes"] = scenes
    if os.path.exists(args.reference):
        ref = median_run(lambda: run_reference(args.reference, args.sim_seconds), args.repeats)
        print(f"  {'reference pymunk cell (scripted controller, 240 Hz)':56} {ref['sim_s_per_wall_s']:12.1f}  "
              f"(runs {ref['all']}; picks {ref['picks']})")
        ratio = trial["sim_s_per_wall_s"] / ref["sim_s_per_wall_s"]
        print(f"ratio ARIAC trial / reference: {ratio:.2f}  target >= 3: {'met' if ratio >= 3 else 'NOT met'}")
        result.update(reference=ref, ratio=trial["sim_s_per_wall_s"] / ref["sim_s_per_wall_s"])
    else:
        print(f"reference not found at {args.reference}; skipped")
    if args.experiment:
        exp = run_experiment_bench(args.workers)
        print(f"experiment: {exp['trials']} trials, {exp['sim_s']:,.0f} simulated s in {exp['wall_s']:.1f} s wall on "
              f"{exp['workers']} workers; lost {exp['lost']}  target <= 60 s: {'met' if exp['wall_s'] <= 60 else 'NOT met'}")
        result["experiment"] = exp
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(result, fh, indent=2)


if __name__ == "__main__":
    main()
