"""The ``btfsm`` command line.

Exit codes: 0 success, 1 a property or conformance check failed, 2 bad input or usage,
3 incomplete (a budget was hit). Errors are one line on stderr, never a traceback.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys

from .errors import ModelError, UsageError

__all__ = ["main", "UsageError"]


def _handler(spec: str):
    """Import ``module:function`` lazily so each command loads only what it needs."""
    module, func = spec.split(":")
    return getattr(importlib.import_module(module), func)


COMMANDS = {
    # name: (handler, help)
    "validate": ("btfsm.files:cli_validate", "check that a model file loads; print its warnings"),
    "show": ("btfsm.show:cli_show", "draw the tree and each FSM (dot, svg, png)"),
    "run": ("btfsm.cli:cli_run", "run a model in the runtime with seeded random outcomes; write a trace"),
    "replay": ("btfsm.cli:cli_replay", "re-run a trace or counterexample and confirm it reproduces"),
    "check": ("btfsm.verify.cli:cli_check", "model-check a model; print verdicts and counterexamples"),
    "export": ("btfsm.verify.cli:cli_export", "export a model to Promela, SMV or dot"),
    "skills": ("btfsm.verify.skills:cli_skills", "derive the skill transitions a tree can request"),
    "sim": ("btfsm.sim.cli:cli_sim", "run a model in the pymunk kitting cell"),
    "experiment": ("btfsm.sim.cli:cli_experiment", "reproduce the paper's ARIAC experiment"),
    "conform": ("btfsm.sim.cli:cli_conform", "run scenarios and check runtime conformance"),
}


def build_parser() -> argparse.ArgumentParser:
    from . import __version__

    p = argparse.ArgumentParser(prog="btfsm", description="Preemptive robot skills: check BT-FSM models and run them.")
    p.add_argument("--version", action="version", version=f"btfsm {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    for name, (spec, help_text) in COMMANDS.items():
        sp = sub.add_parser(name, help=help_text, description=help_text)
        sp.set_defaults(_spec=spec)
        _ARGS.get(name, lambda sp: None)(sp)
    return p


def _args_model(sp):
    sp.add_argument("model", help="model file (.yaml/.json) or built-in model name")


def _args_validate(sp):
    _args_model(sp)
    sp.add_argument("--strict", action="store_true", help="exit 1 when there are warnings")


def _args_show(sp):
    _args_model(sp)
    sp.add_argument("--format", choices=("dot", "svg", "png"), default="dot")
    sp.add_argument("--output", "-o", help="output file or folder (default: stdout for dot)")
    sp.add_argument("--what", default="all", help="'tree', an FSM name, or 'all'")


def _args_run(sp):
    _args_model(sp)
    sp.add_argument("--ticks", type=int, default=100)
    sp.add_argument("--seed", type=int, default=0)
    sp.add_argument("--p-env", type=float, default=0.2, help="probability of each enabled environment event per tick")
    sp.add_argument("--trace", help="write the JSON Lines trace here")


def _args_replay(sp):
    sp.add_argument("trace", help="a trace (.jsonl) or a counterexample (.json from btfsm check --counterexample-dir)")
    _args_model(sp)
    sp.add_argument("--cell", action="store_true", help="also replay the counterexample's situation in the kitting cell")
    sp.add_argument("--render", metavar="PNG", help="with --cell: draw the cell at the end")
    sp.add_argument("--gif", metavar="GIF", help="with --cell: write an animation")
    sp.add_argument("--time", type=float, default=120.0, help="with --cell: time limit (simulated s)")


def _args_check(sp):
    _args_model(sp)
    sp.add_argument("--property", action="append", default=[], metavar="NAME")
    sp.add_argument("--json", action="store_true")
    sp.add_argument("--max-states", type=int, default=None)
    _args_budgets(sp)
    sp.add_argument("--counterexample-dir", help="write each counterexample as JSON into this folder")
    sp.add_argument("--engine", choices=("auto", "traced", "scalar"), default="auto",
                    help="model-level exploration engine (default auto: traced, scalar where it cannot trace); "
                         "both give the same system")


def _args_export(sp):
    _args_model(sp)
    sp.add_argument("--format", choices=("promela", "smv", "dot"), required=True)
    sp.add_argument("--fsm", help="FSM to export at FSM level (default: the whole model when its tree is one "
                                  "SkillRequest, the first FSM when there is no tree)")
    sp.add_argument("--output", "-o")
    sp.add_argument("--max-states", type=int, default=None, help="with --format dot: state budget of the exploration")
    _args_budgets(sp)


def _args_skills(sp):
    _args_model(sp)
    sp.add_argument("--format", choices=("text", "dot", "json"), default="text")
    sp.add_argument("--max-states", type=int, default=None)
    _args_budgets(sp)


def _args_budgets(sp):
    sp.add_argument("--max-transitions", type=int, default=None, help="stop exploring after this many transitions (exit 3)")
    sp.add_argument("--max-seconds", type=float, default=None, help="stop exploring after this many seconds (exit 3)")


def _args_experiment(sp):
    sp.add_argument("--k", type=int, action="append", default=[], help="run this k (1..40; repeatable)")
    sp.add_argument("--trials", type=int, help="run this many k values spread evenly over 1..40")
    sp.add_argument("--variant", action="append", choices=("preemptive", "baseline"), help="default: both")
    sp.add_argument("--workers", type=int, default=os.cpu_count() or 1, help="parallel processes (default: all cores)")
    sp.add_argument("--out", default="out/experiment", help="folder for trials.csv, trials.json and the figure")
    sp.add_argument("--quiet", action="store_true", help="no progress bar")


def _args_sim(sp):
    _args_model(sp)
    sp.add_argument("--k", type=int, default=1, help="belt parts every 30 + 0.2 k s (default 1)")
    sp.add_argument("--time", type=float, default=1500.0, help="time limit in simulated seconds")
    sp.add_argument("--render", metavar="PNG", help="draw the cell at the end of the run")
    sp.add_argument("--gif", metavar="GIF", help="write an animation of the run")
    sp.add_argument("--fps", type=float, default=2.0, help="animation frames per simulated second")
    sp.add_argument("--max-frames", type=int, default=600)


def _args_conform(sp):
    _args_model(sp)
    sp.add_argument("--scenarios", type=int, default=10)
    sp.add_argument("--seed", type=int, default=0)
    sp.add_argument("--time", type=float, default=700.0, help="time limit per scenario (simulated s)")
    sp.add_argument("--drops", action="store_true", help="add faulty-gripper drop regions to some scenarios")
    sp.add_argument("--no-path", action="store_true", help="skip the path check against the explored system")
    sp.add_argument("--max-states", type=int, default=2_000_000)


_ARGS = {"validate": _args_validate, "show": _args_show, "run": _args_run, "replay": _args_replay,
         "check": _args_check, "export": _args_export, "skills": _args_skills,
         "experiment": _args_experiment, "sim": _args_sim, "conform": _args_conform}


def main(argv=None) -> int:
    parser = build_parser()
    # sim commands add their own options; parse known args first to find the command
    args, rest = parser.parse_known_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    try:
        handler = _handler(args._spec)
        if rest and not getattr(handler, "accepts_extra", False):
            parser.parse_args(argv)  # reports the unknown option and exits 2
        return int(handler(args, rest) if getattr(handler, "accepts_extra", False) else handler(args) or 0)
    except ModelError as exc:
        print(f"btfsm {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except UsageError as exc:
        print(f"btfsm {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except (ImportError, AttributeError) as exc:
        if getattr(exc, "name", "") and str(getattr(exc, "name", "")).split(".")[0] in ("btfsm", "verify", "sim", "models"):
            print(f"btfsm {args.command}: not available in this build ({exc})", file=sys.stderr)
            return 2
        raise
    except BrokenPipeError:
        return 0
    except OSError as exc:  # a file that cannot be read or written
        where = f" {exc.filename}:" if getattr(exc, "filename", None) else ""
        print(f"btfsm {args.command}: error:{where} {exc.strerror or exc}", file=sys.stderr)
        return 2


def cli_run(args) -> int:
    from .files import load_model
    from .oracles import RandomOracle
    from .runtime import Runtime

    model = load_model(args.model)
    if args.ticks < 0:
        raise UsageError("--ticks must be >= 0")
    rt = Runtime(model, fallback=RandomOracle(args.seed, args.p_env), trace=args.trace)
    env_rng = RandomOracle(args.seed + 1, args.p_env)
    rt_oracle_events = _random_events(model, env_rng)
    counts = {"RUNNING": 0, "SUCCESS": 0, "FAILURE": 0}
    for _ in range(args.ticks):
        step = rt.tick(rt_oracle_events(rt))
        counts[step.status.name] += 1
    rt.close()
    print(f"{model.name}: {args.ticks} ticks ({args.ticks / model.tick_rate:g} s), root "
          + ", ".join(f"{k} {v}" for k, v in counts.items()))
    print("final: " + ", ".join(f"{k}={v}" for k, v in rt.vars.items()))
    for f in model.fsms:
        st, goal = rt.fsm_state(f.name)
        print(f"fsm {f.name}: state '{st}', goal {goal}")
    if args.trace:
        print(f"trace: {args.trace}")
    return 0


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


def cli_replay(args) -> int:
    from .files import load_model
    from .trace import replay

    model = load_model(args.model)
    if str(args.trace).endswith(".json"):
        from btfsm.verify.counterexample import replay_counterexample

        try:
            ok, text = replay_counterexample(args.trace, model)
        except (OSError, ValueError, KeyError) as exc:
            raise UsageError(f"{args.trace}: not a counterexample of this model ({exc})") from None
        print(text)
        if args.cell:
            from btfsm.sim.binding import CellBinding
            from btfsm.sim.replay import replay_in_cell

            why = CellBinding.unsupported(model)
            if why:
                raise UsageError(f"{model.name}: the kitting cell cannot run this model ({why})")
            print(replay_in_cell(model, args.trace, time_limit=args.time, render=args.render, gif=args.gif).text())
        return 0 if ok else 1
    if args.cell:
        raise UsageError("--cell replays counterexamples (.json), not traces")
    try:
        result = replay(args.trace, model)
    except (OSError, ValueError) as exc:
        raise UsageError(f"{args.trace}: {exc}") from None
    if result is None:
        print(f"replay: {args.trace} reproduces exactly on {model.name}")
        return 0
    tick, why = result
    print(f"replay: differs at tick {tick}: {why}")
    return 1


if __name__ == "__main__":
    sys.exit(main())
