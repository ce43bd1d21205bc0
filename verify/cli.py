"""``btfsm check``, ``btfsm bound`` and ``btfsm export``: each one's flags (``args_NAME``)
beside its handler (``cli_NAME``), as listed in ``btfsm.cli.COMMANDS``.

``btfsm check MODEL [--property NAME]... [--json] [--max-states N] [--counterexample-dir DIR]``
(flag values are checked when parsed, ``btfsm.validators``; files are written atomically by
``btfsm.outputs``)
exits 0 when every property holds, 1 when one is violated (its counterexample is printed),
2 on bad input or usage (an unknown property name lists the known ones), 3 when the state
budget was hit and some property is undecided. On a terminal, a progress bar (states,
states/s, transitions; ``btfsm.progress``) goes to stderr for explorations longer than a
second.
"""
from __future__ import annotations

import json
import os
import sys
from typing import cast

from btfsm import cliargs, reserve
from btfsm.validators import finite_float, input_file, input_text, output_dir, output_file

__all__ = ["args_check", "cli_check", "args_export", "cli_export", "args_bound", "cli_bound"]


def args_check(sp) -> None:
    cliargs.model(sp)
    sp.add_argument("--property", action="append", default=[], metavar="NAME", type=input_text)
    cliargs.json(sp, "the report")
    cliargs.max_states(sp)
    cliargs.budgets(sp)
    sp.add_argument("--counterexample-dir", type=output_dir, help="write each counterexample as JSON into this folder")
    cliargs.html(sp, "the verdicts and each counterexample")
    sp.add_argument("--quiet", "-q", action="store_true", help="no warnings and no information lines, only verdicts and failures")
    sp.add_argument("--verbose", "-v", action="store_true", help="list every warning, determinism gap and note")
    sp.add_argument("--goal-level", choices=("open", "tree"), default="open",
                    help="goal-reachability: judge each FSM as an open system (open, default) or only the "
                         "requests the tree can actually make (tree)")
    sp.add_argument("--engine", choices=("auto", "traced", "scalar"), default="auto",
                    help="model-level exploration engine (default auto: traced, scalar where it cannot trace); "
                         "both give the same system")
    sp.add_argument("--scheduler", type=input_text, default=None, metavar="ADDRESS",
                    help="check workable-reachability and no-dead-states (model level) with the states partitioned "
                         "across Dask workers: tcp://HOST:PORT (a running scheduler; the model file must be at the "
                         "same path on its workers) or local:N (an embedded cluster of N worker processes)")
    cliargs.response(sp, required=False)
    sp.add_argument("--within", type=finite_float(0, None), metavar="S", default=None,
                    help="with --trigger/--response: the bound in seconds (property 'response')")
    _args_timed(sp)


def _args_timed(sp) -> None:
    """``--timed`` and its ``--scene`` (``btfsm check`` and ``btfsm bound``; handled by ``_timed``)."""
    sp.add_argument("--timed", action="store_true",
                    help="first give every primitive the bind table drives a duration derived from the scene "
                         "(--scene, else the model's own scene); docs/verification.md 2.1")
    sp.add_argument("--scene", metavar="FILE", type=input_file, default=None,
                    help="with --timed: the scene file (docs/cell.md) to derive the durations from")


def cli_check(args) -> int:
    from btfsm.errors import UsageError

    from .search import DEFAULT_MAX_STATES, DEFAULT_MAX_TRANSITIONS, describe_hit
    from .properties import PROPERTIES
    from .report import check

    props = list(args.property or [])
    unknown = [p for p in props if p not in PROPERTIES]
    if unknown:
        raise UsageError(f"unknown property {', '.join(repr(p) for p in unknown)}; known properties: {', '.join(PROPERTIES)}")
    if args.scheduler:
        return _check_partitioned(args, props)
    max_states = DEFAULT_MAX_STATES if args.max_states is None else args.max_states
    max_transitions, max_seconds = _budgets(args, DEFAULT_MAX_TRANSITIONS)
    from btfsm.progress import ExplorationProgress

    html = args.html
    if html:
        from btfsm.html import require_dot

        require_dot()
    model = _with_response(_timed(_load(args), args), args)
    if args.trigger and props and "response" not in props:
        props.append("response")
    progress = ExplorationProgress()
    report = None
    try:
        report = check(model, props or None, max_states=max_states, max_transitions=max_transitions,
                       max_seconds=max_seconds, progress=progress, engine=args.engine,
                       goal_level=args.goal_level)
    except MemoryError as exc:
        reserve.release(exc)  # the reserve, and the exploration's frames the traceback holds
    if report is None:  # reported outside the handler: nothing of the exploration is left
        reserve.release()
        progress.done()
        print(f"btfsm check: out of memory while exploring {model.name}; lower --max-states", file=sys.stderr)
        return 3
    progress.done()
    written = _write_counterexamples(report, args.counterexample_dir) if args.counterexample_dir else []
    if args.json:
        print(json.dumps(report.to_json(), default=_plain))
    else:
        print(report.format_text(quiet=args.quiet, verbose=args.verbose))
        if not report.complete:
            hit = sorted({describe_hit(s.get("budget"), max_states, max_transitions, max_seconds) or "budget"
                          for s in report.systems if not s["complete"]})
            print(f"({' and '.join(hit)} hit: explored {report.states:,} states, {report.transitions:,} transitions "
                  f"in {report.seconds:.2f} s; raise it to decide the rest)")
        for path in written:
            print(f"counterexample written: {path}")
    if html:
        from btfsm.html import check_page, write_page

        write_page(html, model, **check_page(model, report))
        if not args.json:
            print(f"html report written: {html}")
    return report.exit_code


PARTITIONED = ("workable-reachability", "no-dead-states")


def _check_partitioned(args, props) -> int:
    """``btfsm check --scheduler ADDRESS``: the properties of ``PARTITIONED`` with the
    states partitioned across Dask workers (``btfsm.verify.distributed``); exit 0 when they
    hold, 1 when one is violated (counted, without a counterexample path), 2 on bad input
    or a scheduler that cannot be reached."""
    import importlib.util
    import re

    from btfsm.errors import UsageError
    from btfsm.files import load_model

    other = [p for p in props if p not in PARTITIONED]
    if other:
        raise UsageError(f"--scheduler: only {' and '.join(PARTITIONED)} run partitioned, not {', '.join(other)}")
    for flag in ("max_states", "max_transitions", "max_seconds", "trigger", "response", "within", "html",
                 "counterexample_dir"):
        if getattr(args, flag) is not None:
            raise UsageError(f"--{flag.replace('_', '-')} does not go with --scheduler (the partitioned check has no "
                             "budgets, no counterexample paths and no response properties)")
    if args.timed or args.scene:
        raise UsageError("--timed and --scene do not go with --scheduler (the partitioned check has no response "
                         "properties)")
    local = re.fullmatch(r"local(?::([0-9]+))?", args.scheduler)
    if local is None and not re.fullmatch(r"(tcp|tls|inproc)://[^\s]+", args.scheduler):
        raise UsageError(f"--scheduler: expected tcp://HOST:PORT or local:N, got {args.scheduler!r}")
    workers = int(local.group(1) or 2) if local else 0
    if local and not 1 <= workers <= 64:
        raise UsageError(f"--scheduler local:N: N from 1 to 64, got {workers}")
    if importlib.util.find_spec("distributed") is None:
        raise ModuleNotFoundError("No module named 'distributed'", name="distributed")
    opts = {"semantics": args.semantics, "tick": args.tick, "node_library": args.node_library,
            "nodes": tuple(args.nodes or ()), "main_tree": args.main_tree}
    model = _load(args)  # bad input is reported here, before any cluster starts
    from .distributed import check_distributed, cluster
    from .properties import not_applicable
    from .traced import Untraceable

    try:
        with cluster(None if local else args.scheduler, workers or 2) as client:
            where = f"{len(client.scheduler_info()['workers'])} Dask worker(s) " + (
                "(an embedded local cluster)" if local else f"of {args.scheduler}")
            r = check_distributed(client, load_model, (args.model,), opts)
    except Untraceable as exc:
        raise UsageError(f"{args.model}: the partitioned check needs a model the traced engine can follow ({exc})") from None
    except (OSError, TimeoutError) as exc:
        raise UsageError(f"--scheduler: cannot reach the Dask scheduler at {args.scheduler}: {exc}") from None
    c = r.counts
    verdicts = r.verdicts
    skipped = {p: not_applicable(model, p) for p in PARTITIONED}
    asked = props or list(PARTITIONED)
    out = {"model": model.name, "partitioned": True, "workers": len(c.per_partition), "states": c.states,
           "transitions": c.transitions, "steps": c.levels, "seconds": round(r.seconds, 3),
           "per_partition": c.per_partition, "states_sent": c.states_sent,
           "results": {p: ("not applicable" if skipped[p] else verdicts[p]) for p in asked},
           "traps": r.traps, "dead_states": r.dead, "sink_states": r.sinks,
           "not_checked": "no-dead-states: the FSM-level non-progress cycles (run without --scheduler)"}
    if args.json:
        print(json.dumps(out))
    else:
        print(f"{model.name}: {c.states:,} states, {c.transitions:,} transitions on {where}, {c.levels} steps (the busiest worker), "
              f"{r.seconds:.2f} s (states per worker {', '.join(f'{k:,}' for k in c.per_partition)}; "
              f"{c.states_sent:,} states sent)")
        for p in asked:
            if skipped[p]:
                print(f"  {p}: not applicable ({skipped[p]})")
            elif p == "workable-reachability":
                print(f"  {p}: " + ("holds" if verdicts[p] else f"VIOLATED: {r.traps:,} reachable state(s) can never get "
                                    "back to a workable state (run without --scheduler for the counterexample)"))
            else:
                sinks = ", ".join(f"{k} ({v:,} states)" for k, v in r.sinks.items() if v)
                print(f"  {p} (model level: dead and sink states): " + (
                    "holds" if verdicts[p] else f"VIOLATED: {r.dead:,} dead state(s)" + (f"; FSM token on a sink: {sinks}"
                                                                                         if sinks else "")))
                print("    not checked partitioned: the FSM-level non-progress cycles (run without --scheduler)")
    return 1 if any(v is False for v in out["results"].values()) else 0


def _timed(model, args):
    """``--timed``: ``model`` with every primitive its scene's bind table drives given a
    duration derived from the scene (``btfsm.sim.durations.derive_scene``); the table is
    printed (to stderr with --json)."""
    from btfsm.errors import UsageError

    if not args.timed:
        if args.scene:
            raise UsageError("--scene goes with --timed (durations derived from the scene)")
        return model
    from btfsm.sim.durations import derive_scene, print_scene_table, timed_in_scene
    from btfsm.sim.scene import load_scene
    from btfsm.sim.scene_trial import scene_for

    path = args.scene or scene_for(model, args.model)
    if path is None:
        raise UsageError(f"--timed: no scene for {model.name} (MODEL.scene.yaml beside it, or a shipped one named "
                         "after it): give --scene FILE")
    scene = load_scene(path)
    table = derive_scene(model, scene)
    print_scene_table(model, scene, table, file=sys.stderr if args.json else sys.stdout)
    return timed_in_scene(model, scene, (), table)


def _with_response(model, args):
    """The model plus the requirement given by ``--trigger``/``--response``/``--within`` (named 'cli')."""
    import dataclasses

    from btfsm.errors import ModelError, UsageError
    from btfsm.timing import Response

    trig, resp, within = args.trigger, args.response, args.within
    if trig is None and resp is None:
        if within is not None:
            raise UsageError("--within needs --trigger and --response")
        return model
    if trig is None or resp is None:
        raise UsageError("--trigger and --response go together")
    try:
        req = Response("cli", trig, resp, within)  # the model widens a split state to its copies
        return dataclasses.replace(model, responses=tuple(model.responses) + (req,))
    except (ModelError, SyntaxError, ValueError) as exc:
        raise UsageError(f"--trigger/--response: {getattr(exc, 'problem', None) or exc}") from None


def args_bound(sp) -> None:
    cliargs.model(sp)
    cliargs.response(sp, required=True)
    sp.add_argument("--output", "-o", type=output_file(".json"), default=None,
                    help="write the worst-case run as a counterexample file (replay it with btfsm replay)")
    sp.add_argument("--within", type=finite_float(0, None), default=None, metavar="S",
                    help="also the worst first late response: over runs that answered every earlier trigger within S "
                         "seconds (an event trigger whose minimum interval exceeds S); -o then writes that run")
    _args_timed(sp)
    cliargs.json(sp, "the figures")
    cliargs.max_states(sp)
    cliargs.budgets(sp)


def cli_bound(args) -> int:
    """``btfsm bound MODEL --trigger T --response R [-o CE.json] [--json]``: the exact best and
    worst response time. Exit 0 when the worst case is bounded, 1 when some behaviour never
    responds (the lasso is written with -o), 2 bad input, 3 budget hit."""
    from btfsm.errors import ModelError, UsageError
    from btfsm.positions import widen_to_copies
    from btfsm.timing import Response

    from .explore import explore
    from .properties.response import INF, ResponseBound, counterexample
    from .search import DEFAULT_MAX_STATES, DEFAULT_MAX_TRANSITIONS, describe_hit

    model = _timed(_load(args), args)
    try:
        req = widen_to_copies(Response("bound", args.trigger, args.response), model)
    except (ModelError, SyntaxError, ValueError) as exc:
        raise UsageError(f"--trigger/--response: {getattr(exc, 'problem', None) or exc}") from None
    max_states = DEFAULT_MAX_STATES if args.max_states is None else args.max_states
    max_transitions, max_seconds = _budgets(args, DEFAULT_MAX_TRANSITIONS)
    from btfsm.progress import ExplorationProgress

    progress = ExplorationProgress()
    ts = None
    try:
        ts = explore(model, max_states=max_states, max_transitions=max_transitions, max_seconds=max_seconds,
                     progress=lambda s, t, sec: progress("model", s, t, sec))
    except MemoryError as exc:
        reserve.release(exc)
    if ts is None:
        reserve.release()
        progress.done()
        print(f"btfsm bound: out of memory while exploring {model.name}; lower --max-states", file=sys.stderr)
        return 3
    progress.done()
    try:
        rb = ResponseBound(ts, req)
    except ModelError as exc:
        raise UsageError(f"{exc.element}: {exc.problem}") from None
    worst, best = rb.worst, rb.best

    def figure(t):
        return None if t is None or t == INF else t

    out = {"model": model.name, "trigger": args.trigger, "response": args.response, "tick_rate": model.tick_rate,
           "states": ts.n_states, "transitions": ts.n_transitions, "complete": ts.complete,
           "triggers": int(rb.triggers.size), "unbounded": worst == INF,
           "worst_ticks": figure(worst), "worst_seconds": None if figure(worst) is None else rb.seconds(worst),
           "best_ticks": figure(best), "best_seconds": None if figure(best) is None else rb.seconds(best)}
    within = args.within
    first = None
    if within is not None and worst is not None and ts.complete:
        first = rb.first_late(int(round(within * model.tick_rate)))
        if first is None:
            raise UsageError("--within: the first late response needs an event trigger (event:NAME) whose "
                             "min_interval exceeds the bound")
        out.update(first_late_ticks=figure(first[0]),
                   first_late_seconds=None if figure(first[0]) is None else rb.seconds(first[0]))
    conditioned = _conditioned_first_late(args, within, first, max_states, max_transitions, max_seconds)
    if conditioned is not None:
        out["conditioned"] = conditioned
    written = None
    if args.output and first is not None:
        _w, path, k = first
        ce = counterexample(rb, path, k, None, f"the worst first late response: '{args.response}' {_w} tick(s) "
                            f"({rb.seconds(_w):g} s) after '{args.trigger}', every earlier one within {within:g} s",
                            None)
        ce.violation["worst_ticks"] = _w  # this run's figure (the worst over all runs is larger)
        from btfsm.outputs import atomic_write_text

        atomic_write_text(args.output, json.dumps(ce.to_json(), indent=1, default=_plain) + "\n")
        written = args.output
    elif args.output and worst is not None and (witness := rb.worst_witness()) is None:
        # only on a budget-cut system: the unbounded figure comes from states left unexpanded
        print(f"btfsm bound: no worst-case run written to {args.output}: the explored part holds no run that never "
              "responds (the unbounded figure comes from states the budget left unexplored)", file=sys.stderr)
    elif args.output and worst is not None:
        path, k, loop = cast(tuple, witness)
        summary = (f"'{args.response}' may never come after '{args.trigger}'" if worst == INF else
                   f"the worst case: '{args.response}' {worst} tick(s) ({rb.seconds(worst):g} s) after '{args.trigger}'")
        ce = counterexample(rb, path, k, loop, summary, None)
        from btfsm.outputs import atomic_write_text

        atomic_write_text(args.output, json.dumps(ce.to_json(), indent=1, default=_plain) + "\n")
        written = args.output
    if args.json:
        print(json.dumps(dict(out, counterexample=written)))
    else:
        print(f"{model.name}: {ts.n_states:,} states, {ts.n_transitions:,} transitions; trigger '{args.trigger}' "
              f"occurs in {rb.triggers.size:,} state(s)")
        if worst is None:
            print("the trigger never occurs: no response time")
        else:
            def fmt(t):
                return "unbounded (some behaviour never responds)" if t == INF else f"{t} ticks = {rb.seconds(t):g} s"
            print(f"worst case: {fmt(worst)}")
            print(f"best case:  {fmt(best)}")
            if first is not None:
                print(f"worst first late response (every earlier trigger answered within {within:g} s): "
                      f"{fmt(first[0])}")
            if conditioned is not None:
                c = conditioned
                shown = "unbounded" if c["first_late_ticks"] is None else \
                    f"{c['first_late_ticks']} ticks = {c['first_late_seconds']:g} s"
                print(f"worst first late response, durations conditioned on {c['assumption']} ({c['model']}, "
                      f"{c['states']:,} states; it decides --within {within:g}, a figure above {within:g} s is a run "
                      f"of the model, not a bound): {shown}")
        if written:
            print(f"{'first late' if first is not None else 'worst-case'} run written: {written} "
                  f"(btfsm replay {written} {args.model})")
    if not ts.complete:
        hit = describe_hit(ts.stopped, max_states, max_transitions, max_seconds) or "budget"
        print(f"({hit} hit: the figures cover the {ts.n_states:,} states explored; not decided)", file=sys.stderr)
        return 3
    return 1 if worst == INF else 0


def _conditioned_first_late(args, within, first, max_states, max_transitions, max_seconds) -> "dict | None":
    """The worst first late response of the built-in model's conditioned companion
    (``btfsm.models.registry.CONDITIONED``: its durations hold in every run up to the first
    late response, so its first late response decides the bound) when ``--within`` is at
    most what the assumption covers; None otherwise."""
    from btfsm.files import load_model
    from btfsm.positions import widen_to_copies
    from btfsm.timing import Response

    from .explore import explore
    from .properties.response import INF, ResponseBound

    try:
        from btfsm.models.registry import CONDITIONED
    except ImportError:  # the models are not installed
        return None
    entry = CONDITIONED.get(args.model)
    if first is None or entry is None or args.timed or within > entry[2] + 1e-9:
        return None
    name, assumption, _covers = entry
    model = load_model(name, semantics=args.semantics, tick=args.tick)
    ts = explore(model, max_states=max_states, max_transitions=max_transitions, max_seconds=max_seconds)
    if not ts.complete:
        return None
    rb = ResponseBound(ts, widen_to_copies(Response("bound", args.trigger, args.response), model))
    late = rb.first_late(int(round(within * model.tick_rate)))
    if late is None:
        return None
    ticks = None if late[0] == INF else late[0]
    return {"model": name, "assumption": assumption, "states": ts.n_states, "first_late_ticks": ticks,
            "first_late_seconds": None if ticks is None else rb.seconds(ticks)}


def _budgets(args, default_transitions=None):
    """(max_transitions, max_seconds) from ``--max-transitions`` and ``--max-seconds``
    (``btfsm.cliargs.budgets``; their ranges are checked when parsed)."""
    max_transitions = args.max_transitions
    return (default_transitions if max_transitions is None else max_transitions), args.max_seconds


def _plain(x):
    if hasattr(x, "item"):
        return x.item()
    if isinstance(x, (set, frozenset, tuple)):
        return list(x)
    return str(x)


def _load(args):
    from btfsm.errors import UsageError
    from btfsm.files import load_cli_model

    try:
        return load_cli_model(args)
    except OSError as exc:
        raise UsageError(f"{args.model}: {exc.strerror or exc}") from None


def _write_counterexamples(report, folder) -> list:
    """Each counterexample as ``MODEL.PROPERTY.HASH.json`` in ``folder``, written atomically;
    the paths written."""
    from btfsm.outputs import atomic_write_text, ensure_output_dir

    ensure_output_dir(folder)
    written = []
    for r in report.results:
        if r.counterexample is not None:
            path = os.path.join(folder, r.counterexample.file_name())
            atomic_write_text(path, json.dumps(r.counterexample.to_json(), indent=1, default=_plain) + "\n")
            written.append(path)
    return written


def args_export(sp) -> None:
    cliargs.model(sp)
    sp.add_argument("--format", choices=("promela", "smv", "dot", "btcpp"), required=True,
                    help="btcpp: the tree as BehaviorTree.CPP XML v4 (docs/semantics.md 8.1)")
    sp.add_argument("--fsm", type=input_text,
                    help="FSM to export at FSM level (default: the whole model when its tree is one "
                         "SkillRequest, the first FSM when there is no tree)")
    sp.add_argument("--output", "-o", type=output_file())
    cliargs.max_states(sp)
    cliargs.budgets(sp)


def cli_export(args) -> int:
    from btfsm.errors import UsageError

    model = _load(args)
    if args.fsm is not None and args.fsm not in [f.name for f in model.fsms]:
        raise UsageError(f"{args.model}: --fsm: no FSM named '{args.fsm}' in {model.name} (have: {', '.join(f.name for f in model.fsms) or 'none'})")
    from .export import export  # written separately (verify/export.py)
    from .search import BudgetExceeded

    max_transitions, max_seconds = _budgets(args)
    try:
        out = export(model, args.format, args.fsm, max_states=args.max_states,
                     max_transitions=max_transitions, max_seconds=max_seconds)
    except BudgetExceeded as exc:
        print(f"btfsm export: {exc}", file=sys.stderr)
        return 3
    if args.output:
        from btfsm.outputs import atomic_write_text

        atomic_write_text(args.output, out)
    else:
        sys.stdout.write(out if out.endswith("\n") else out + "\n")
    return 0
