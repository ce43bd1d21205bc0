#!/usr/bin/env python3
"""Simulated seconds per wall second of btfsm.sim.cell, beside the shared reference pymunk cell.

* trial (the product path): the checked ARIAC model (preemptive, k = 1) in the btfsm
  Runtime at 10 Hz, bound to the cell by ``btfsm.sim.binding``, physics at 240 Hz, for the
  first ``--sim-seconds`` of the trial;
* cell: physics at 240 Hz with a small scripted kitting controller at 10 Hz (the cell's
  own cost, without the runtime);
* reference: ``pymunk_cell_bench.py --view top`` run as a subprocess (it excludes a 2 s
  warm-up from its timing; ours times the whole run);
* ``--experiment``: also time the full 80-trial experiment on ``--workers`` processes;
* scenes (issue 11): the same kind of trial (checked model in the Runtime at 10 Hz) in a
  scene-described cell (``btfsm.sim.scene``, kinematic, 100 Hz world steps): the
  two-area example and the machine-tending cell, 10 seeds each, run to completion; the
  table puts the hard-coded ARIAC trial (before) and the scene trials (after) side by side.

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

from btfsm.sim.cell import BELT, Cell, CellConfig, Place, periodic_arrivals  # noqa: E402

DEFAULT_REFERENCE = os.path.join(os.path.dirname(ROOT), "shared", "bench", "pymunk_cell_bench.py")
TICK_STEPS = 24  # 10 Hz at dt = 1/240


class KittingController:
    """Sequence-with-memory of (start, done) steps per task; a new task when idle."""

    def __init__(self, cell: Cell):
        self.cell = cell
        self.plan: list = []
        self.started = False
        self.picks = 0

    def tick(self) -> None:
        if not self.plan:
            self.plan = self._next_task()
            self.started = False
        if not self.plan:
            return
        start, done = self.plan[0]
        if not self.started:
            start()
            self.started = True
        elif done():
            self.plan.pop(0)
            self.started = False

    def _next_task(self) -> list:
        c = self.cell
        slots = c.free_slots()
        if not slots:
            return []
        belt = [pid for pid, _ in c.detections if c.place_of(pid) == BELT and c.time_to_wall(pid) > 4.0]
        if belt:
            return self._belt_pick(belt[0]) + self._place(slots[0])
        for k in (2, 3):
            pid = c.next_bin_part(k)
            if pid is not None:
                return self._bin_pick(pid) + self._place(slots[0])
        return []

    def _arrived(self) -> bool:
        return self.cell.arm.arrived

    def _move(self, pose_fn) -> tuple:
        return (lambda: self.cell.arm.move_to(*pose_fn()), self._arrived)

    def _grasped(self) -> bool:
        return self.cell.gripper.attached_part is not None

    def _lift(self) -> tuple:
        c = self.cell
        return self._move(lambda: (c.arm.pose[0], c.arm.pose[1], c.arm.pose[2] + c.config.clearance))

    def _bin_pick(self, pid: int) -> list:
        c = self.cell
        return [self._move(lambda: c.pose_above(pid)),
                (lambda: (c.gripper.enable(), c.arm.move_to(*c.pose_at(pid))), self._grasped),
                self._lift()]

    def _belt_pick(self, pid: int) -> list:
        c = self.cell
        return [(lambda: c.arm.track(pid, c.pose_above(pid)[2]), self._arrived),
                (lambda: (c.gripper.enable(), c.arm.track(pid, c.pose_at(pid)[2])), self._grasped),
                self._lift()]

    def _place(self, slot: int) -> list:
        c = self.cell

        def release():
            c.gripper.disable()
            self.picks += 1
        return [self._move(lambda: c.pose_above(Place.tray(slot))),
                self._move(lambda: c.pose_at(Place.tray(slot))),
                (release, lambda: True),
                self._move(lambda: c.pose_above(Place.tray(slot)))]


def run_ours(sim_seconds: float, seed: int = 1) -> dict:
    cfg = CellConfig()
    cell = Cell(cfg, seed=seed, arrivals=periodic_arrivals(30.2, 1 + int(sim_seconds // 30.2)))
    ctrl = KittingController(cell)
    ticks = int(round(sim_seconds / cfg.dt)) // TICK_STEPS
    t0 = time.perf_counter()
    for _ in range(ticks):
        ctrl.tick()
        cell.step(TICK_STEPS)
    wall = time.perf_counter() - t0
    steps = ticks * TICK_STEPS
    return {"steps_per_s": steps / wall, "sim_s_per_wall_s": steps * cfg.dt / wall,
            "wall_s": wall, "places": ctrl.picks, "tray_count": cell.tray_count,
            "lost": len(cell.lost_parts), "detections": len(cell.detections),
            "digest": cell.digest()[:16]}


def run_trial_bench(sim_seconds: float) -> dict:
    from btfsm.sim.experiment import TrialSpec
    from btfsm.sim.trial import run_trial

    spec = TrialSpec("preemptive", 1, time_limit=sim_seconds)
    t0 = time.perf_counter()
    r = run_trial(spec)
    wall = time.perf_counter() - t0
    return {"sim_s_per_wall_s": r.sim_time / wall, "wall_s": wall, "sim_s": r.sim_time,
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

    trial = median_run(lambda: run_trial_bench(args.sim_seconds), args.repeats)
    print(f"trial (btfsm runtime 10 Hz + physics 240 Hz): {trial['sim_s_per_wall_s']:8.1f} sim-s/wall-s  "
          f"(runs {trial['all']}; {trial['ticks']} ticks, {trial['skills']} skills, tray {trial['tray']})  "
          f"target >= 200x: {'met' if trial['sim_s_per_wall_s'] >= 200 else 'NOT met'}")
    ours = median_run(lambda: run_ours(args.sim_seconds), args.repeats)
    print(f"cell (scripted controller):                   {ours['sim_s_per_wall_s']:8.1f} sim-s/wall-s  "
          f"{ours['steps_per_s']:9.0f} steps/s  (runs {ours['all']}; places {ours['places']}, "
          f"tray {ours['tray_count']}, lost {ours['lost']}, detections {ours['detections']})")
    result = {"sim_seconds": args.sim_seconds, "trial": trial, "ours": ours}
    scenes = [median_run(lambda m=m, f=f: run_scene_bench(m, f), args.repeats) for m, f in SCENES]
    print("\nbefore/after (issue 11): a trial of a checked model in the Runtime at 10 Hz, simulated s per wall s")
    print(f"  {'cell':56} {'sim-s/wall-s':>12}  target >= 500x")
    print(f"  {'before: ARIAC kitting cell (hard-coded, pymunk 240 Hz)':56} {trial['sim_s_per_wall_s']:12.1f}  "
          f"{'met' if trial['sim_s_per_wall_s'] >= 500 else 'NOT met'}")
    for sc in scenes:
        label = f"after: scene {sc['scene']} (kinematic, 100 Hz)"
        print(f"  {label:56} {sc['sim_s_per_wall_s']:12.1f}  {'met' if sc['sim_s_per_wall_s'] >= 500 else 'NOT met'}"
              f"  (runs {sc['all']}; {sc['runs']} seeds, {sc['completed']} completed, {sc['sim_s']:.0f} sim s)")
    result["scenes"] = scenes
    if os.path.exists(args.reference):
        ref = median_run(lambda: run_reference(args.reference, args.sim_seconds), args.repeats)
        print(f"reference cell:                               {ref['sim_s_per_wall_s']:8.1f} sim-s/wall-s  "
              f"{ref['steps_per_s']:9.0f} steps/s  (runs {ref['all']}; picks {ref['picks']})")
        print(f"ratio trial/reference: {trial['sim_s_per_wall_s'] / ref['sim_s_per_wall_s']:.2f}   "
              f"cell/reference: {ours['sim_s_per_wall_s'] / ref['sim_s_per_wall_s']:.2f}")
        result.update(reference=ref, ratio=trial["sim_s_per_wall_s"] / ref["sim_s_per_wall_s"])
    else:
        print(f"reference not found at {args.reference}; skipped")
    if args.experiment:
        exp = run_experiment_bench(args.workers)
        print(f"experiment: {exp['trials']} trials, {exp['sim_s']:,.0f} simulated s in {exp['wall_s']:.1f} s wall on "
              f"{exp['workers']} workers; lost {exp['lost']}  target <= 180 s: {'met' if exp['wall_s'] <= 180 else 'NOT met'}")
        result["experiment"] = exp
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(result, fh, indent=2)


if __name__ == "__main__":
    main()
