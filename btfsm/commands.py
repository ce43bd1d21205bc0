"""The commands of the core: ``btfsm validate``, ``run``, ``replay``, ``import`` and
``conform``, each one's flags (``args_NAME``) beside its handler (``cli_NAME``), as listed
in ``btfsm.cli.COMMANDS`` (the dispatcher, exit codes and error handling are there).
The shared flag groups and the bounds of flag values are ``btfsm.cliargs``."""
from __future__ import annotations

import json
import os
import sys

from . import cliargs
from .errors import UsageError
from .profiles import SEMANTICS, TICKS
from .validators import finite_float, input_file, int_range, output_file, probability, seed_int

__all__ = ["args_validate", "cli_validate", "args_run", "cli_run", "args_replay", "cli_replay", "args_import",
           "cli_import", "args_conform", "cli_conform"]


def args_validate(sp) -> None:
    cliargs.model(sp)
    sp.add_argument("--strict", action="store_true", help="exit 1 when there are warnings")
    cliargs.json(sp, "the summary and warnings")


def cli_validate(args) -> int:
    """``btfsm validate MODEL [--strict] [--json]``: the text report is ``btfsm.files.cli_validate``."""
    from .files import cli_validate as validate_text
    from .files import load_cli_model

    if _is_scene_file(args.model):
        return _validate_scene(args)
    if not args.json:
        return validate_text(args)
    model = load_cli_model(args)
    warnings = [{"element": element, "text": text} for element, text in
                list(model.warnings) + list(model.program.lints)]
    print(json.dumps({"file": args.model, "model": model.name, "ok": True,
                      "variables": len(model.variables), "fsms": len(model.fsms),
                      "states": sum(len(f.states) for f in model.fsms), "tree_nodes": len(model.nodes()),
                      "warnings": warnings}))
    return 1 if warnings and args.strict else 0


def _is_scene_file(path: str) -> bool:
    """A scene file: named ``*.scene.yaml`` (``.yml``, ``.json``), or a mapping with
    ``robots`` and without a model's ``fsms`` / ``tree``."""
    if not isinstance(path, str) or not os.path.isfile(path):
        return False
    if ".scene." in os.path.basename(path):
        return True
    from .files import load_data

    try:
        data = load_data(path, file_name=path)
    except Exception:  # noqa: BLE001 - not readable as data: the model loader reports it
        return False
    return isinstance(data, dict) and "robots" in data and not ({"fsms", "tree"} & set(data))


def _validate_scene(args) -> int:
    """``btfsm validate my.scene.yaml``: load and check a scene file on its own."""
    from btfsm.sim.scene import load_scene

    sc = load_scene(args.model)
    parts = sum(n for a in sc.areas.values() for n in a["parts"].values())
    summary = {"file": args.model, "scene": sc.name, "ok": True, "areas": len(sc.areas), "belts": len(sc.belts),
               "walls": len(sc.walls), "sensors": len(sc.sensors), "robots": len(sc.robots), "parts": parts}
    if args.json:
        print(json.dumps(summary))
    else:
        print(f"{args.model}: ok (scene {sc.name}: {len(sc.areas)} areas, {len(sc.belts)} belts, {len(sc.walls)} walls, "
              f"{len(sc.sensors)} sensors, {len(sc.robots)} robots, {parts} parts)")
    return 0


def args_run(sp) -> None:
    cliargs.model(sp)
    sp.add_argument("--ticks", type=int_range(0, cliargs.MAX_TICKS), default=100, help=f"0..{cliargs.MAX_TICKS:,}")
    sp.add_argument("--seed", type=seed_int, default=0)
    sp.add_argument("--p-env", type=probability, default=0.2,
                    help="probability (0..1) of each enabled environment event per tick")
    sp.add_argument("--trace", type=output_file(), help="write the JSON Lines trace here")


def cli_run(args) -> int:
    """Run with seeded random outcomes. The run stops at the first violation (a domain
    error, a tick the model cannot take or a conformance error, a contract violation):
    one line on stderr, exit 1; the trace holds every tick up to it (the violating tick
    itself when it completed, as a contract violation does)."""
    from .errors import ConformanceError, DomainError
    from .files import load_cli_model
    from .formats import printable
    from .oracles import RandomOracle
    from .runtime import Runtime

    model = load_cli_model(args)
    if args.ticks < 0:
        raise UsageError("--ticks must be >= 0")
    if args.trace:
        _check_trace_target(args.trace, args.model)
    rt = Runtime(model, fallback=RandomOracle(args.seed, args.p_env), trace=args.trace)
    env_rng = RandomOracle(args.seed + 1, args.p_env)
    rt_oracle_events = _random_events(model, env_rng)
    counts = {"RUNNING": 0, "SUCCESS": 0, "FAILURE": 0}
    problem = None
    try:
        for _ in range(args.ticks):
            tick = rt.clock.tick
            try:
                step = rt.tick(rt_oracle_events(rt))
            except DomainError as exc:
                problem = f"tick {tick}: domain error: {exc}"
                break
            except ConformanceError as exc:  # a tick the model cannot take, or a refused answer
                text = str(exc)
                prefix = f"tick {tick}: "
                problem = f"{prefix}blocked: {text[len(prefix):] if text.startswith(prefix) else text}"
                break
            counts[step.status.name] += 1
            if step.violations:
                exclusive = [v for v in step.violations if v[0] == "exclusive"]
                if exclusive:
                    v = exclusive[0]
                    problem = (f"tick {tick}: exclusive resource '{v[1]}': '{v[2]}' "
                               + (f"started while '{v[3]}' was running" if v[4] == "start" else f"and '{v[3]}' are both running"))
                    break
                nodes = ", ".join(f"'{v[1]}'" for v in step.violations)
                problem = (f"tick {tick}: contract violation: {nodes} replied SUCCESS while its post-condition "
                           "is false")
                break
    except KeyboardInterrupt:
        _finish_run(rt)  # the ticks done so far make a complete trace
        raise
    except BaseException:
        if rt.trace is not None:
            rt.trace.discard()
        raise
    _finish_run(rt)
    done = sum(counts.values())
    print(f"{model.name}: {done} ticks ({done / model.tick_rate:g} s), root "
          + ", ".join(f"{k} {v}" for k, v in counts.items()))
    print("final: " + ", ".join(f"{k}={v}" for k, v in rt.vars.items()))
    for f in model.fsms:
        st, goal = rt.fsm_state(f.name)
        print(f"fsm {f.name}: state '{st}', goal {goal}")
    if args.trace:
        print(f"trace: {printable(args.trace)}")
    if problem is not None:
        sys.stdout.flush()
        print(f"btfsm run: stopped at {printable(problem)}", file=sys.stderr)
        return 1
    return 0


def _finish_run(rt) -> None:
    """Write the rest of the trace and put it in place; on failure leave nothing behind."""
    try:
        rt.close()
    except BaseException:
        if rt.trace is not None:
            rt.trace.discard()
        raise


def _check_trace_target(trace, model_ref) -> None:
    """Refuse a --trace path that is a folder or the model file itself."""
    from .formats import printable as printable_path

    if os.path.isdir(trace):
        raise UsageError(f"--trace {printable_path(trace)}: is a directory")
    try:
        same = os.path.exists(trace) and os.path.exists(model_ref) and os.path.samefile(trace, model_ref)
    except OSError:
        same = False
    if same:
        raise UsageError(f"--trace {printable_path(trace)}: is the model file; give the trace another name")


def _random_events(model, rng):
    """Seeded environment: each enabled event happens with probability p, choices uniform."""
    prog = model.program

    def events(rt):
        s = list(rt.state)
        out = []
        for i, (name, guard, eff, options) in enumerate(prog.env):
            if options is not None:
                enabled = [k for k, o in enumerate(options) if o[1] is None or o[1](s)]
                if enabled:
                    k = enabled[rng.choose(i, enabled)]
                    out.append(options[k][0])
                    if options[k][2] is not None:
                        options[k][2](s)
            elif (guard is None or guard(s)) and rng.env(i):
                out.append(name)
                if eff is not None:
                    eff(s)
        return out
    return events


def args_replay(sp) -> None:
    sp.add_argument("trace", type=input_file,
                    help="a trace (.jsonl) or a counterexample (.json from btfsm check --counterexample-dir)")
    cliargs.model(sp)
    sp.add_argument("--cell", action="store_true", help="also replay the counterexample's situation in the kitting cell "
                                                         "(or in a scene: --scene, or the model's own scene)")
    cliargs.scene(sp)
    sp.add_argument("--render", metavar="PNG", type=output_file(".png"), help="with --cell: draw the cell at the end")
    sp.add_argument("--gif", metavar="GIF", type=output_file(".gif"), help="with --cell: write an animation")
    sp.add_argument("--time", type=finite_float(0, cliargs.MAX_SIM_TIME, lo_open=True), default=120.0,
                    help="with --cell: time limit (simulated s)")
    sp.add_argument("--pace", choices=("paced", "ticks", "phase"),
                    help="with --cell, the kitting cell: paced (the default for a response counterexample: each FSM "
                         "state lasts at least as long as there), ticks (the events at the counterexample's ticks, "
                         "its failures forced, the arm at its own speed), phase (each event when the cell's FSM is at "
                         "the counterexample's state and ticks into it, its failures (grasp misses, before and after "
                         "the arrivals) forced at theirs, the arm at its own speed; prints where the response time "
                         "went)")
    cliargs.html(sp, "the counterexample or trace (with --cell: and the cell run, with pictures)")


def cli_replay(args) -> int:
    """Replay a trace (JSON Lines) or a counterexample (``.json``): exit 0 when it
    reproduces, 1 when the model does something else, 2 when the file is not a valid
    trace or counterexample (one line naming the file, the line or JSON path, the problem)."""
    from .files import load_cli_model
    from .formats import FormatError, printable
    from .trace import replay

    if args.cell:
        from btfsm.sim.cli import needs, picture_modules

        needs(*picture_modules(args))  # before any work, not after the replay
    html = args.html
    if html:
        from .html import require_dot

        require_dot()
    model = load_cli_model(args)
    if str(args.trace).endswith(".json"):
        from btfsm.verify.counterexample import load_counterexample, replay_counterexample

        try:
            ce = load_counterexample(args.trace)
        except FormatError as exc:
            raise UsageError(str(exc)) from None
        ok, text = replay_counterexample(ce, model)
        print(printable(text))
        cell = None
        if args.cell:
            from btfsm.sim.replay import replay_for_cli

            out = replay_for_cli(model, ce.to_json(), args, record=bool(html))
            text, cell = (out if html else (out, None))
            print(text)
        if html:
            from .html import replay_page, write_page

            print(f"html: {write_page(html, model, **replay_page(model, args.trace, ok, text, ce=ce, cell=cell))}")
        return 0 if ok else 1
    if args.cell:
        raise UsageError("--cell replays counterexamples (.json), not traces")
    try:
        result = replay(args.trace, model)
    except FormatError as exc:
        raise UsageError(str(exc)) from None
    if result is None:
        text = f"replay: {printable(args.trace)} reproduces exactly on {model.name}"
    else:
        text = f"replay: differs at tick {result[0]}: {printable(result[1])}"
    print(text)
    if html:
        from .html import replay_page, write_page

        print(f"html: {write_page(html, model, **replay_page(model, args.trace, result is None, text))}")
    return 0 if result is None else 1


def args_import(sp) -> None:
    sp.add_argument("model", metavar="tree.xml", type=input_file, help="BehaviorTree.CPP XML v4 file")
    sp.add_argument("--leaves", type=input_file, default=None,
                    help="side file (a partial btfsm model file: variables, primitives, nodes, fsms, environment, "
                         "...; default: STEM.btfsm.yaml beside the XML when it exists)")
    sp.add_argument("--semantics", choices=SEMANTICS, default=None,
                    help="profile written into the model (default: the side file's, else btcpp)")
    sp.add_argument("--tick", choices=TICKS, default=None,
                    help="tick written into the model: once or exactly-once (default: the side file's, else once)")
    sp.add_argument("--output", "-o", type=output_file(".yaml", ".yml", ".json"), default=None,
                    help="model file to write (.yaml, .yml or .json; default: YAML on stdout)")
    cliargs.xml(sp)


def cli_import(args) -> int:
    """``btfsm import tree.xml [--leaves side.yaml] [-o model.yaml]``: the equivalent btfsm model file."""
    import dataclasses
    from pathlib import Path

    from .files import FORMATS, dumps_model, load_xml_model
    from .interop.btcpp_import import side_file_for
    from .outputs import atomic_write_text

    fmt = "yaml"
    if args.output is not None:
        fmt = FORMATS[Path(args.output).suffix.lower()]
        side = args.leaves if args.leaves is not None else side_file_for(args.model)
        for inp in (args.model, side):
            try:
                same = inp is not None and os.path.exists(args.output) and os.path.samefile(args.output, inp)
            except OSError:
                same = False
            if same:
                raise UsageError(f"--output {args.output}: is the input file {inp}; refusing to overwrite it")
    model = load_xml_model(args.model, leaves=args.leaves, node_library=args.node_library, nodes=args.nodes or (),
                           main_tree=args.main_tree)
    if args.semantics is not None and args.semantics != model.semantics:
        model = dataclasses.replace(model, semantics=args.semantics)
    if args.tick is not None and args.tick != model.tick:
        model = dataclasses.replace(model, tick=args.tick)
    text = dumps_model(model, fmt)
    for element, warning in model.warnings:
        print(f"warning: {element}: {warning}".replace("\n", " "), file=sys.stderr)
    if args.output is None:
        sys.stdout.write(text)
    else:
        atomic_write_text(args.output, text)
    return 0


def args_conform(sp) -> None:
    cliargs.model(sp)
    sp.add_argument("--log", type=input_file, default=None, metavar="RUN",
                    help="check this recorded run instead of running scenarios: a BehaviorTree.CPP FileLogger2 file "
                         "(.btlog, checked under btcpp) or a py_trees run written by btfsm.interop.pytrees.RunRecorder "
                         "(under pytrees); --max-states bounds the configurations the search keeps at once (default "
                         "200,000); see docs/interop.md section 5")
    sp.add_argument("--scenarios", type=int_range(1, cliargs.MAX_SCENARIOS), default=10)
    sp.add_argument("--seed", type=seed_int, default=0)
    sp.add_argument("--time", type=finite_float(0, cliargs.MAX_SIM_TIME, lo_open=True), default=700.0,
                    help="time limit per scenario (simulated s)")
    sp.add_argument("--drops", action="store_true", help="add faulty-gripper drop regions to some scenarios")
    sp.add_argument("--no-path", action="store_true", help="skip the path check against the explored system")
    cliargs.scene(sp)
    cliargs.max_states(sp)
    cliargs.json(sp, "the scenarios and the verdict")
    cliargs.html(sp, "the scenarios, and the first nonconforming one (else the first) as a run with the cell's pictures")


def cli_conform(args) -> int:
    """``btfsm conform``: ``--log RUN`` checks a recorded run (``btfsm.verify.runlog``, no
    simulator needed); otherwise the simulated scenarios of ``btfsm.sim.cli``."""
    if args.log is not None:
        from btfsm.verify.runlog import cli_conform_log

        return cli_conform_log(args)
    if args.max_states is None:
        args.max_states = 2_000_000
    from btfsm.sim.cli import cli_conform as cli_conform_scenarios

    return cli_conform_scenarios(args)
