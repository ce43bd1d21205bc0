"""``btfsm experiment``, ``btfsm sim`` and ``btfsm conform``."""
from __future__ import annotations

import os
import sys
import time

from btfsm.cli import UsageError

__all__ = ["cli_experiment", "cli_sim", "cli_conform", "select_ks", "variant_of"]


def select_ks(ks, trials) -> list:
    """The k values to run: ``--k`` as given, else ``--trials`` evenly spread over 1..40."""
    if ks:
        bad = [k for k in ks if not 1 <= k <= 40]
        if bad:
            raise UsageError(f"--k must be in 1..40, got {bad}")
        return sorted(set(ks))
    if trials is None:
        return list(range(1, 41))
    if not 1 <= trials <= 40:
        raise UsageError("--trials must be in 1..40")
    if trials == 1:
        return [1]
    return sorted({round(1 + i * 39 / (trials - 1)) for i in range(trials)})


def variant_of(model) -> str:
    """Which experiment variant a model is (the cell binding runs the ARIAC models)."""
    from .binding import CellBinding

    missing = CellBinding.unsupported(model)
    if missing:
        raise UsageError(f"{model.name}: the kitting cell cannot run this model ({missing})")
    return "baseline" if model.name.endswith("baseline") or model.name == "original" else "preemptive"


def cli_experiment(args) -> int:
    from .experiment import (VARIANTS, format_table, plot_reaction_times, run_experiment, summarize,
                             trial_specs, write_results)

    ks = select_ks(args.k, args.trials)
    variants = tuple(args.variant) if args.variant else VARIANTS
    if args.workers < 1:
        raise UsageError("--workers must be at least 1")
    specs = trial_specs(ks, variants)
    print(f"experiment: {len(specs)} trials ({', '.join(variants)}; k = {_ks_text(ks)}) on {args.workers} worker(s)",
          file=sys.stderr)
    t0 = time.perf_counter()
    results = run_experiment(specs, workers=args.workers, progress=not args.quiet)
    wall = time.perf_counter() - t0
    csv_path, json_path = write_results(results, args.out)
    png = plot_reaction_times(results, os.path.join(args.out, "reaction_times.png"))
    summary = summarize(results)
    print(format_table(summary))
    sim_time = sum(r.sim_time for r in results)
    print(f"\n{len(results)} trials, {sim_time:,.0f} simulated s in {wall:.1f} s wall "
          f"({sim_time / wall:,.0f}x real time on {args.workers} worker(s))")
    print(f"trials: {csv_path}, {json_path}")
    print(f"figure: {png}")
    errors = [r for r in results if r.conformance_error]
    for r in errors[:5]:
        print(f"conformance: {r.variant} k={r.k}: {r.conformance_error}")
    return 1 if errors else 0


def _ks_text(ks) -> str:
    return f"{ks[0]}..{ks[-1]}" if ks == list(range(ks[0], ks[-1] + 1)) and len(ks) > 2 else ", ".join(map(str, ks))


def cli_sim(args) -> int:
    from btfsm.files import load_model

    from .experiment import TrialSpec
    from .render import Recorder, render_png
    from .trial import run_trial

    model = load_model(args.model)
    variant = variant_of(model)
    if not 1 <= args.k <= 40:
        raise UsageError("--k must be in 1..40")
    from .binding import CellBinding

    dialect = CellBinding.dialect_of(model)
    spec = TrialSpec(variant, args.k, parts=model.var(dialect.tray_var).hi, time_limit=args.time)
    recorder = Recorder(every_steps=1, max_frames=args.max_frames) if args.gif else None
    every = max(1, round(model.tick_rate / args.fps)) if args.gif else 0
    last = {}

    def on_tick(rt, cell):
        st, goal = rt.fsm_state(dialect.fsm)
        last["text"] = f"{dialect.fsm}: {st}\ngoal: {goal or '-'}"
        last["cell"] = cell
        if recorder is not None and rt.clock.tick % every == 0:
            recorder.capture(cell, last["text"])

    r = run_trial(spec, model, on_tick=on_tick)
    print(f"{model.name}: k={args.k} (dTa = {30 + 0.2 * args.k:.1f} s): "
          f"{'completed' if r.completed else 'NOT completed'} at t = {r.sim_time:.1f} s, tray {r.tray}, "
          f"skills {r.skills}, preemptions {r.preemptions}, belt parts {r.conveyor_arrivals}, "
          f"picked {r.conveyor_picks}, lost {r.lost}")
    if r.reaction_times:
        print(f"reaction times [s]: {', '.join(f'{t:.1f}' for t in r.reaction_times)}")
    if r.conformance_error:
        print(f"conformance: {r.conformance_error}")
    if args.render:
        print(f"picture: {render_png(last['cell'], args.render, title=model.name, fsm_state=last.get('text'))}")
    if recorder is not None:
        frames = recorder.write_gif(args.gif, fps=args.fps)
        print(f"animation: {args.gif} ({frames} frames)")
    return 1 if r.conformance_error else 0


def cli_conform(args) -> int:
    from btfsm.files import load_model

    from .conformance import PathMonitor, random_scenarios, run_scenario

    model = load_model(args.model)
    variant = variant_of(model)
    monitor = None
    if not args.no_path:
        from btfsm.verify.explore import explore

        ts = explore(model, max_states=args.max_states)
        if not ts.complete:
            raise UsageError(f"{model.name}: exploration hit --max-states {args.max_states}; raise it or use --no-path")
        monitor = PathMonitor(ts)
        print(f"{model.name}: checked system has {len(ts.states):,} states; monitoring runtime paths against it")
    from .binding import CellBinding

    parts = model.var(CellBinding.dialect_of(model).tray_var).hi
    scenarios = random_scenarios(args.scenarios, args.seed, variant, parts=parts,
                                 time_limit=args.time, drops=args.drops)
    failed = 0
    for i, sc in enumerate(scenarios):
        res = run_scenario(sc, model, monitor)
        status = "ok" if res.mismatch is None else "MISMATCH"
        print(f"scenario {i}: seed {sc.seed}, {len(sc.detections)} belt parts, "
              f"{'drop region ' + str(sc.drop_regions[0]) if sc.drop_regions else 'no drop region'}: "
              f"{res.ticks} ticks, {status}" + (f"\n  first mismatch at {res.mismatch}" if res.mismatch else ""))
        failed += res.mismatch is not None
    print(f"{len(scenarios) - failed} of {len(scenarios)} scenarios conform")
    return 1 if failed else 0
