"""``btfsm experiment``, ``btfsm sweep``, ``btfsm sim`` and the scenarios of ``btfsm conform``.

Each command's flags (``args_NAME``) sit beside its handler (``cli_NAME``), as listed in
``btfsm.cli.COMMANDS`` (``btfsm conform``'s are in ``btfsm.commands``, which picks the
scenarios here or a recorded run). Flag values are checked when parsed
(``btfsm.validators``); every file
is written atomically (``btfsm.outputs``). ``btfsm experiment`` saves each finished trial in
``--out/trials/`` and a re-run with the same ``--out`` reuses the finished trials whose
spec matches (``--fresh`` ignores them), so an interrupted experiment (Ctrl-C: exit 130)
can be re-run to completion with the same results as an uninterrupted run.
"""
from __future__ import annotations

import json
import os
import sys
import time
from typing import Any, cast

from btfsm import cliargs
from btfsm.cliargs import MAX_FRAMES, MAX_SIM_TIME, MAX_WORKERS
from btfsm.errors import UsageError
from btfsm.validators import finite_float, input_text, int_range, output_dir, output_file, seed_int

__all__ = ["args_experiment", "cli_experiment", "args_sim", "cli_sim", "cli_conform", "args_sweep", "cli_sweep",
           "select_ks"]


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


def needs(*modules) -> None:
    """Before any work: the ImportError the CLI reports (one line, exit 2, how to install)
    for the first of ``modules`` that is not installed."""
    import importlib.util

    for m in modules:
        if importlib.util.find_spec(m) is None:
            raise ModuleNotFoundError(f"No module named '{m}'", name=m)


def picture_modules(args) -> tuple:
    """The packages ``--render`` (matplotlib) and ``--gif`` (matplotlib, PIL) draw with."""
    return (("matplotlib",) if args.render or args.gif else ()) + (("PIL",) if args.gif else ())


def args_experiment(sp) -> None:
    sp.add_argument("--k", type=int_range(1, 40), action="append", default=[], help="run this k (1..40; repeatable)")
    sp.add_argument("--trials", type=int_range(1, 40), help="run this many k values spread evenly over 1..40")
    sp.add_argument("--variant", action="append", choices=("preemptive", "baseline"), help="default: both")
    sp.add_argument("--workers", type=int_range(1, MAX_WORKERS), default=os.cpu_count() or 1,
                    help="parallel processes (default: all cores)")
    sp.add_argument("--time", type=finite_float(0, MAX_SIM_TIME, lo_open=True), default=1500.0,
                    help="time limit per trial in simulated seconds (default 1500, the paper's protocol)")
    sp.add_argument("--out", default="out/experiment", type=output_dir,
                    help="folder for trials.csv, trials.json, the figure and the finished trials "
                         "(trials/*.json); a re-run with the same --out reuses finished trials")
    sp.add_argument("--fresh", action="store_true", help="ignore finished trials saved in --out")
    sp.add_argument("--quiet", action="store_true", help="no progress bar")
    cliargs.json(sp, "the summary")


def cli_experiment(args) -> int:
    from dataclasses import asdict

    from .experiment import (VARIANTS, format_table, load_finished, plot_reaction_times, run_experiment, summarize,
                             trial_specs, write_results)
    from btfsm.outputs import ensure_output_dir

    needs("matplotlib")  # the figure, drawn after every trial ran
    ks = select_ks(args.k, args.trials)
    variants = tuple(dict.fromkeys(args.variant)) if args.variant else VARIANTS
    time_limit = args.time
    specs = trial_specs(ks, variants, time_limit=time_limit)
    ensure_output_dir(args.out)
    finished = {} if args.fresh else load_finished(specs, args.out)
    reused = f"; {len(finished)} finished trial(s) reused from {args.out}" if finished else ""
    print(f"experiment: {len(specs)} trials ({', '.join(variants)}; k = {_ks_text(ks)}) on {args.workers} "
          f"worker(s){reused}", file=sys.stderr)
    t0 = time.perf_counter()
    results = run_experiment(specs, workers=args.workers, progress=not args.quiet, save_dir=args.out,
                             finished=finished)
    wall = time.perf_counter() - t0
    csv_path, json_path = write_results(results, args.out)
    png = plot_reaction_times(results, os.path.join(args.out, "reaction_times.png"))
    summary = summarize(results)
    errors = [r for r in results if r.conformance_error]
    sim_time = sum(r.sim_time for r in results)
    if args.json:
        print(json.dumps({"trials": len(results), "reused": len(finished), "time_limit": time_limit,
                          "ks": ks, "variants": list(variants), "summary": summary, "simulated_s": sim_time,
                          "files": {"csv": csv_path, "json": json_path, "figure": png},
                          "conformance_errors": [{"variant": r.variant, "k": r.k, "error": r.conformance_error}
                                                 for r in errors],
                          "results": [asdict(r) for r in results]}))
        return 1 if errors else 0
    print(format_table(summary))
    reused_text = f" ({len(finished)} reused)" if finished else ""
    print(f"\n{len(results)} trials{reused_text}, {sim_time:,.0f} simulated s in {wall:.1f} s wall "
          f"({sim_time / max(wall, 1e-9):,.0f}x real time on {args.workers} worker(s))")
    print(f"trials: {csv_path}, {json_path}")
    print(f"figure: {png}")
    for r in errors[:5]:
        print(f"conformance: {r.variant} k={r.k}: {r.conformance_error}")
    return 1 if errors else 0


def _ks_text(ks) -> str:
    return f"{ks[0]}..{ks[-1]}" if ks == list(range(ks[0], ks[-1] + 1)) and len(ks) > 2 else ", ".join(map(str, ks))


def _scene_of(args, model):
    """The Scene a command runs ``model`` in: ``--scene``, else the model's default scene
    when the kitting cell cannot run it, else None (the kitting cell)."""
    from .conformance import is_kitting_model
    from .scene import load_scene
    from .scene_trial import scene_for

    path = args.scene
    if path is None:
        if is_kitting_model(model):
            return None
        path = scene_for(model, args.model)
        if path is None:
            return None
    return load_scene(path)


def _sim_scene(args, model, scene) -> int:
    from btfsm.outputs import atomic_path

    from .scene import incident_text
    from .scene_trial import run_scene

    frames: list
    frames, every = [], max(1, round(model.tick_rate / args.fps)) if args.gif else 0
    seen = {}

    def on_tick(rt, world):
        seen["world"] = world
        if args.gif and rt.clock.tick % every == 0 and len(frames) < args.max_frames:
            frames.append(world.snapshot())

    run = run_scene(model, scene, args.seed, args.time, check_invariant=True, on_tick=on_tick)
    counts = ", ".join(f"{k} {v}" for k, v in run.counts.items())
    print(f"{model.name} in scene {scene.name} (seed {run.seed}): "
          f"{'completed' if run.completed else 'NOT completed'} at t = {run.time:.1f} s after {run.ticks} ticks; "
          f"areas: {counts or '-'}; lost {run.lost}")
    if run.mismatch is not None:
        print(f"conformance: {run.mismatch}")
    incidents = seen["world"].incidents if "world" in seen else []
    for incident in incidents[:20]:  # what physics did uncommanded
        print(f"incident: {incident_text(incident)}")
    if len(incidents) > 20:
        print(f"incident: ... {len(incidents) - 20} more")
    if args.render:
        from .scene_render import render_scene

        with atomic_path(args.render) as tmp:
            render_scene(scene, seen["world"].snapshot(), tmp, title=f"{model.name} in {scene.name}")
        print(f"picture: {args.render}")
    if args.gif and frames:
        from .scene_render import write_gif

        with atomic_path(args.gif) as tmp:
            n = write_gif(scene, frames, tmp, fps=args.fps, title=f"{model.name} in {scene.name}")
        print(f"animation: {args.gif} ({n} frames)")
    return 1 if run.mismatch is not None else 0


def args_sim(sp) -> None:
    cliargs.model(sp)
    sp.add_argument("--k", type=int_range(1, 40), default=1, help="belt parts every 30 + 0.2 k s (1..40, default 1)")
    sp.add_argument("--time", type=finite_float(0, MAX_SIM_TIME, lo_open=True), default=1500.0,
                    help="time limit in simulated seconds")
    sp.add_argument("--render", metavar="PNG", type=output_file(".png"), help="draw the cell at the end of the run")
    sp.add_argument("--gif", metavar="GIF", type=output_file(".gif"), help="write an animation of the run")
    sp.add_argument("--fps", type=finite_float(0.01, 100.0), default=2.0,
                    help="animation frames per simulated second (0.01..100)")
    sp.add_argument("--max-frames", type=int_range(1, MAX_FRAMES), default=600)
    cliargs.scene(sp)
    sp.add_argument("--seed", type=seed_int, default=0, help="with a scene: the seed of its random arrivals and faults")
    sp.add_argument("--worst", type=int_range(1, 2), metavar="N", default=None,
                    help="the kitting cell's worst response to N (1 or 2) belt parts, searched over their arrival "
                         "ticks in the model's job (docs/cell.md, 'The cell's worst case')")
    sp.add_argument("--step", type=int_range(1, 1000), metavar="TICKS", default=None,
                    help="with --worst: the grid's step (default: every tick for 1 part; 10 ticks for the coarse "
                         "grid of 2 parts, refined at every tick)")
    sp.add_argument("--at-phase", action="store_true",
                    help="with --worst: also the model's worst response to an arrival at the cell's worst phase, "
                         "and its conditioned twin's (explores the models)")
    sp.add_argument("--workers", type=int_range(1, MAX_WORKERS), default=None,
                    help="with --worst: worker processes (default: the CPU count; the result does not depend on "
                         "their number)")
    sp.add_argument("--misses", type=int_range(0, 3), metavar="K", default=None,
                    help="with --worst: also force up to K (0..3) of the cell's grasp attempts before the response "
                         "to miss, every set of them (the gripper lets the part go: an outcome the model's "
                         "environment may choose); the worst without a forced miss is printed beside")


def _sim_worst(args, model) -> int:
    from .conformance import variant_of
    from .worst import report, search_pair, search_single

    if args.scene is not None or args.render or args.gif:
        raise UsageError("--worst searches the kitting cell and prints a table: not with --scene, --render or --gif")
    variant_of(model)  # UsageError unless the kitting cell runs the model
    workers = args.workers or os.cpu_count() or 1
    misses = args.misses or 0
    if args.worst == 1:
        found = search_single(model, workers=workers, step=args.step or 1, misses=misses)
    else:
        found = search_pair(model, workers=workers, coarse=args.step or 10, misses=misses)
    text, code = report(model, found, phase_models=args.at_phase)
    print(text)
    return code


def cli_sim(args) -> int:
    from btfsm.files import load_cli_model
    from btfsm.outputs import atomic_path

    from .conformance import variant_of
    from .experiment import TrialSpec
    from .trial import run_trial

    needs(*picture_modules(args))
    model = load_cli_model(args)
    if args.worst:
        return _sim_worst(args, model)
    if args.step is not None or args.at_phase or args.workers is not None or args.misses is not None:
        raise UsageError("--step, --at-phase, --workers and --misses go with --worst")
    if args.gif and not (args.fps > 0 and args.max_frames >= 1):
        raise UsageError("--gif needs --fps > 0 and --max-frames >= 1")
    scene = _scene_of(args, model)
    if scene is not None:
        return _sim_scene(args, model, scene)
    variant = variant_of(model)
    if not 1 <= args.k <= 40:
        raise UsageError("--k must be in 1..40")
    if args.gif and not (args.fps > 0 and args.max_frames >= 1):
        raise UsageError("--gif needs --fps > 0 and --max-frames >= 1")
    from .binding import Dialect, dialect_of

    dialect = cast(Dialect, dialect_of(model))
    spec = TrialSpec(variant, args.k, parts=model.var(dialect.tray_var).hi, time_limit=args.time)
    frames: list = []
    every = max(1, round(model.tick_rate / args.fps)) if args.gif else 0
    last = {}

    def on_tick(rt, world):
        st, goal = rt.fsm_state(dialect.fsm)
        last["text"] = f"{dialect.fsm}: {st}, goal: {goal or '-'}"
        last["world"] = world
        if args.gif and rt.clock.tick % every == 0 and len(frames) < args.max_frames:
            frames.append(world.snapshot())

    r = run_trial(spec, model, on_tick=on_tick)
    print(f"{model.name}: k={args.k} (dTa = {30 + 0.2 * args.k:.1f} s): "
          f"{'completed' if r.completed else 'NOT completed'} at t = {r.sim_time:.1f} s, tray {r.tray}, "
          f"skills {r.skills}, preemptions {r.preemptions}, belt parts {r.conveyor_arrivals}, "
          f"picked {r.conveyor_picks}, lost {r.lost}")
    if r.reaction_times:
        print(f"reaction times [s]: {', '.join(f'{t:.1f}' for t in r.reaction_times)}")
    if r.conformance_error:
        print(f"conformance: {r.conformance_error}")
    world = last["world"]
    if args.render:
        from .scene_render import render_scene

        with atomic_path(args.render) as tmp:
            render_scene(world.scene, world.snapshot(), tmp, title=f"{model.name} ({last.get('text')})")
        print(f"picture: {args.render}")
    if args.gif and frames:
        from .scene_render import write_gif

        with atomic_path(args.gif) as tmp:
            n = write_gif(world.scene, frames, tmp, fps=args.fps, title=model.name)
        print(f"animation: {args.gif} ({n} frames)")
    return 1 if r.conformance_error else 0


def cli_conform(args) -> int:
    from btfsm.files import load_cli_model

    from .conformance import conform, variant_of

    html = args.html
    if html:
        from btfsm.html import require_dot

        require_dot()
    model = load_cli_model(args)
    as_json = args.json
    scene = _scene_of(args, model)
    if scene is None:
        variant_of(model)  # a model the cell cannot run is an error before anything is explored
    rows = []
    views: Any = None
    if html:
        from .cell_view import ConformViews

        views = ConformViews(model)

    def explored(states):
        if not as_json:
            print(f"{model.name}: checked system has {states:,} states; monitoring runtime paths against it")

    def show(i, sc, res):
        if views is not None:
            views.result(i, sc, res)
        if scene is not None:
            rows.append({"scenario": i, "seed": sc.seed, "scene": scene.name, "ticks": res.ticks,
                         "drop_regions": [list(d) for d in sc.drop_regions],
                         "completed": res.completed, "lost": res.lost, "conforms": res.mismatch is None,
                         "mismatch": None if res.mismatch is None else str(res.mismatch)})
        else:
            rows.append({"scenario": i, "seed": sc.seed, "belt_parts": len(sc.detections),
                         "drop_regions": [list(d) if isinstance(d, (tuple, list)) else str(d) for d in sc.drop_regions],
                         "ticks": res.ticks, "conforms": res.mismatch is None,
                         "mismatch": None if res.mismatch is None else str(res.mismatch)})
        if not as_json and scene is not None:
            status = "ok" if res.mismatch is None else "MISMATCH"
            drop = f", drop region {sc.drop_regions[0]}" if sc.drop_regions else ""
            print(f"scenario {i}: seed {sc.seed} in scene {scene.name}{drop}: {res.ticks} ticks, "
                  f"{'completed' if res.completed else 'not completed'}, lost {res.lost}, {status}"
                  + (f"\n  first mismatch at {res.mismatch}\n  replay: btfsm sim {args.model} --scene {scene.file} "
                     f"--seed {sc.seed}" if res.mismatch else ""))
        elif not as_json:
            status = "ok" if res.mismatch is None else "MISMATCH"
            print(f"scenario {i}: seed {sc.seed}, {len(sc.detections)} belt parts, "
                  f"{'drop region ' + str(sc.drop_regions[0]) if sc.drop_regions else 'no drop region'}: "
                  f"{res.ticks} ticks, {status}" + (f"\n  first mismatch at {res.mismatch}" if res.mismatch else ""))

    time_limit = args.time if scene is None or args.time != 700.0 else None  # a scene's own limit by default
    out = conform(model, args.scenarios, args.seed, time_limit, args.drops, path=not args.no_path,
                  max_states=args.max_states, on_explored=explored, on_result=show, scene=scene, views=views)
    if out.incomplete:
        print(f"btfsm conform: incomplete: exploring {model.name} hit --max-states {args.max_states:,}; "
              f"raise it or use --no-path", file=sys.stderr)
        return 3
    failed = len(out.failed)
    if as_json:
        print(json.dumps({"model": model.name, "checked_states": out.checked_states,
                          "scenarios": rows, "conforming": len(rows) - failed, "total": len(rows)},
                         default=str))
    else:
        print(f"{len(rows) - failed} of {len(rows)} scenarios conform")
    if html:
        from btfsm.html import write_page

        write_page(html, model, **views.page(rows))
        if not as_json:
            print(f"html: {html}")
    return 1 if failed else 0


def _limit_lines(variants, hi) -> dict:
    """``{variant: Limit}``: the proved limit belt speed of each variant, by bisection over
    0.005 m/s steps up to ``hi`` (``btfsm.sim.speed_limit``; the durations derived at every
    speed checked)."""
    from .speed_limit import proved_limit

    out = {}
    for v in variants:
        t0 = time.perf_counter()
        out[v] = lim = proved_limit(v, hi)
        print(f"limit line: {v}: {len(lim.checks)} response checks in {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    return out


def args_sweep(sp) -> None:
    sp.add_argument("--k", type=int_range(1, 40), action="append", default=[], help="trial index k (seed and dTa(k); repeatable)")
    sp.add_argument("--trials", type=int_range(1, 40), help="this many k values spread evenly over 1..40 (default 1)")
    sp.add_argument("--variant", action="append", choices=("preemptive", "baseline"), help="default: both")
    pos = finite_float(0, 100, lo_open=True)
    sp.add_argument("--belt-speed", type=pos, nargs="+", default=[0.2], metavar="M_S", help="belt speeds, m/s (default 0.2)")
    sp.add_argument("--period", type=finite_float(1, MAX_SIM_TIME), nargs="+", default=None, metavar="S",
                    help="seconds between belt parts (default dTa(k) = 30 + 0.2 k)")
    sp.add_argument("--speed-scale", type=finite_float(0, 1, lo_open=True), nargs="+", default=[0.5], metavar="X",
                    help="the arm's velocity scaling (default 0.5, the authors')")
    sp.add_argument("--pick-window", type=finite_float(0, 1000, lo_open=True), nargs="+", default=None, metavar="S",
                    help="dt*: seconds a detected part stays pickable (default: the time the belt takes to carry it "
                         "through the arm's reach, 3.2 m / belt speed: 16 s at 0.2 m/s)")
    sp.add_argument("--time", type=finite_float(0, MAX_SIM_TIME, lo_open=True), default=1500.0,
                    help="time limit per trial in simulated seconds (default 1500)")
    sp.add_argument("--engine", choices=("dask", "processes", "inline"), default="dask",
                    help="dask (default: an embedded local cluster, or --scheduler), processes (a local pool), "
                         "inline (this process)")
    sp.add_argument("--scheduler", type=input_text, default=None, metavar="ADDRESS",
                    help="a running Dask scheduler (tcp://HOST:PORT) instead of the embedded cluster")
    sp.add_argument("--workers", type=int_range(1, MAX_WORKERS), default=os.cpu_count() or 1,
                    help="worker processes of the embedded cluster or pool (default: all cores)")
    sp.add_argument("--out", default="out/sweep", type=output_dir,
                    help="folder for sweep.csv, sweep.parquet, the figure and the finished trials (cache/); "
                         "a re-run with the same --out reuses finished trials")
    sp.add_argument("--limit-line", action="store_true",
                    help="also prove the limit belt speed of each variant (the fastest for which 'reach' holds, "
                         "by bisection over 0.005 m/s steps up to the fastest --belt-speed; a few minutes) and draw it")
    sp.add_argument("--quiet", action="store_true", help="no progress bar")


def cli_sweep(args) -> int:
    """``btfsm sweep``: the experiment over a grid of trial parameters (``btfsm.sim.sweep``)."""
    from .protocol import VARIANTS
    from .sweep import check_geometry, dask_installed, grid, plot_lost, run_sweep, write_table
    from btfsm.outputs import ensure_output_dir

    needs("matplotlib")  # the figure, drawn after every trial ran
    if args.engine == "dask" and args.scheduler:
        needs("distributed")  # a running scheduler is reached through Dask's client
    ks = select_ks(args.k, args.trials) if (args.k or args.trials) else [1]
    variants = tuple(dict.fromkeys(args.variant)) if args.variant else VARIANTS
    specs = grid(variants, ks, belt_speed=tuple(dict.fromkeys(args.belt_speed)),
                 period=tuple(dict.fromkeys(args.period)) if args.period else (None,),
                 speed_scale=tuple(dict.fromkeys(args.speed_scale)),
                 pick_window=tuple(dict.fromkeys(args.pick_window)) if args.pick_window else (None,),
                 time_limit=args.time)
    try:
        check_geometry(specs)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    ensure_output_dir(args.out)
    if args.engine == "dask" and not args.scheduler and not dask_installed():
        where = f"processes ({args.workers} worker(s); Dask is not installed: pip install 'btfsm[sim]')"
    else:
        where = args.scheduler or (f"an embedded Dask cluster of {args.workers} worker(s)" if args.engine == "dask"
                                   else f"{args.engine} ({args.workers} worker(s))")
    print(f"sweep: {len(specs)} trials ({', '.join(variants)}; k = {_ks_text(ks)}) on {where}", file=sys.stderr)
    t0 = time.perf_counter()
    results = run_sweep(specs, engine=args.engine, workers=args.workers, scheduler=args.scheduler, folder=args.out,
                        progress=not args.quiet)
    wall = time.perf_counter() - t0
    csv_path, pq_path = write_table(specs, results, args.out)
    limits = _limit_lines(variants, max(args.belt_speed)) if args.limit_line else None
    png = plot_lost(specs, results, os.path.join(args.out, "lost_vs_belt_speed.png"), limits)
    print(f"{'variant':12s} {'belt m/s':>8s} {'period s':>8s} {'scale':>6s} {'dt* s':>6s} {'trials':>6s} "
          f"{'lost':>5s} {'max reaction s':>14s}")
    groups: dict = {}
    for s, r in zip(specs, results):
        groups.setdefault((s.variant, s.belt_speed, s.period, s.speed_scale, s.pick_window), []).append(r)
    for (v, bs, per, sc, pw), rs in groups.items():
        rts = [t for r in rs for t in r.reaction_times]
        print(f"{v:12s} {bs:8g} {('dTa(k)' if per is None else f'{per:g}'):>8s} {sc:6g} {pw:6g} {len(rs):6d} "
              f"{sum(r.lost for r in rs):5d} {(f'{max(rts):.1f}' if rts else '-'):>14s}")
    print(f"{len(specs)} trials in {wall:.1f} s wall")
    for v, lim in (limits or {}).items():
        print(f"proved limit belt speed, {v}: {lim.describe()}")
    print(f"table: {csv_path}" + (f", {pq_path}" if pq_path else " (Parquet needs pyarrow)"))
    print(f"figure: {png}")
    errors = [r for r in results if r.conformance_error]
    for r in errors[:3]:
        print(f"conformance error in {r.variant} k={r.k}: {r.conformance_error}", file=sys.stderr)
    return 1 if errors else 0
