"""The ``btfsm`` command line.

Exit codes
    0    success
    1    a property, conformance or replay check failed (or ``validate --strict`` found warnings)
    2    bad input: a malformed model, trace or flag value, an unreadable input or an
         unwritable output path
    3    incomplete: a budget (``--max-states``) was hit, or memory ran out, before an answer
    70   internal error: a bug in btfsm (please report it with the command line at the
         btfsm issue tracker)
    130  interrupted (Ctrl-C)
    143  terminated (SIGTERM; the handler raises ``btfsm.errors.Terminated``, a
         ``KeyboardInterrupt``, so clean-up runs exactly as for Ctrl-C)

Errors
    Every error is one line on stderr, ``btfsm COMMAND: error: FILE: ELEMENT: PROBLEM``
    (the parts that apply; a model with several problems found in one pass, such as the
    untyped blackboard entries of an XML tree, gets one such line each and a last line
    ``btfsm COMMAND: N errors``, ``--json``: an ``errors`` list of ``file``, ``element``,
    ``problem``; ``violation:`` for a violation met while running, exit 1, and
    ``incomplete:`` when memory ran out, exit 3), never a Python traceback. An internal error says that it is
    a bug, names the exception and where to report it; the global ``--debug`` flag (before
    or after the command) adds the traceback. Under ``--json`` the error is instead one JSON
    object on stdout, so stdout always holds exactly one JSON document::

        {"error": {"kind": "model", "type": "ModelError", "command": "validate", "file": "m.yaml",
                   "element": "fsms.arm", "problem": "...", "message": "...", "exit_code": 2}}

    ``kind`` is one of ``model``, ``usage``, ``file`` (an OSError on a user path),
    ``violation``, ``budget``, ``internal``, ``interrupted``, ``terminated``.

Flag values
    Every flag is checked when parsed (``btfsm.validators``): numbers must be finite and in
    range, output paths must be writable names that are not folders, devices or the input
    model. Output files are written to a temporary name and renamed (``btfsm.outputs``), so
    an interrupted or failed command leaves no half-written file.
"""
from __future__ import annotations

import argparse
import importlib
import json
import os
import sys
from typing import Any, cast

from .errors import ConformanceError, DomainError, ModelError, ModelErrors, Terminated, UsageError
from . import reserve, signals
from .profiles import SEMANTICS, TICKS
from .validators import (finite_float, input_file, input_text, int_range, output_dir, output_file, probability,
                         seed_int)

__all__ = ["main", "build_parser", "UsageError", "EXIT_OK", "EXIT_FAILED", "EXIT_INPUT", "EXIT_BUDGET",
           "EXIT_INTERNAL", "EXIT_INTERRUPTED", "EXIT_TERMINATED", "REPORT_HINT"]

EXIT_OK, EXIT_FAILED, EXIT_INPUT, EXIT_BUDGET = 0, 1, 2, 3
EXIT_INTERNAL, EXIT_INTERRUPTED, EXIT_TERMINATED = 70, 130, 143
REPORT_HINT = "please report it with the command line at the btfsm issue tracker"

#: Upper bounds for flag values: far above any sensible run, low enough to stay well defined.
MAX_STATES_LIMIT = 10 ** 10
MAX_TICKS = 10 ** 7
MAX_SIM_TIME = 100_000.0  # simulated seconds
MAX_WORKERS = 256
MAX_SCENARIOS = 100_000
MAX_FRAMES = 100_000

#: Third-party modules that only some commands need (``pip install 'btfsm[sim]'``).
OPTIONAL_MODULES = {"matplotlib", "PIL", "dask", "distributed", "pyarrow", "numpy", "tqdm", "pymunk"}


class CliParser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors are ``UsageError``s (one line, exit 2), not usage dumps."""

    def error(self, message):
        raise UsageError(message.replace("\n", " "))


def _handler(spec: str):
    """Import ``module:function`` lazily so each command loads only what it needs."""
    module, func = spec.split(":")
    return getattr(importlib.import_module(module), func)


COMMANDS = {
    # name: (handler, help)
    "validate": ("btfsm.cli:cli_validate", "check that a model file loads; print its warnings"),
    "show": ("btfsm.show:cli_show", "draw the tree and each FSM (dot, svg, png)"),
    "run": ("btfsm.cli:cli_run", "run a model in the runtime with seeded random outcomes; write a trace"),
    "replay": ("btfsm.cli:cli_replay", "re-run a trace or counterexample and confirm it reproduces"),
    "check": ("btfsm.verify.cli:cli_check", "model-check a model; print verdicts and counterexamples"),
    "bound": ("btfsm.verify.cli:cli_bound", "the exact best and worst response time from a trigger to a response"),
    "export": ("btfsm.verify.cli:cli_export", "export a model to Promela, SMV or dot"),
    "skills": ("btfsm.verify.skills:cli_skills", "derive the skill transitions a tree can request"),
    "sim": ("btfsm.sim.cli:cli_sim", "run a model in a simulated cell (its scene; the ARIAC cell for the paper's models)"),
    "experiment": ("btfsm.sim.cli:cli_experiment", "reproduce the paper's ARIAC experiment"),
    "sweep": ("btfsm.sim.cli:cli_sweep", "run the experiment over a grid of cell parameters (on Dask)"),
    "conform": ("btfsm.cli:cli_conform", "run scenarios and check runtime conformance, or (--log) check a run recorded "
                                         "by BehaviorTree.CPP or py_trees against the model"),
    "import": ("btfsm.cli:cli_import", "read a BehaviorTree.CPP XML v4 tree (+ side file); write a btfsm model file"),
}

#: Per command: the argument names that are output paths (checked against the inputs).
OUTPUTS = {"show": ("output",), "run": ("trace",), "replay": ("render", "gif", "html"), "check": ("counterexample_dir", "html"),
           "bound": ("output",), "export": ("output",), "sim": ("render", "gif"), "experiment": ("out",), "sweep": ("out",),
           "import": ("output",), "conform": ("html",)}
INPUTS = {"replay": ("trace", "model"), "import": ("model", "leaves")}


def build_parser() -> argparse.ArgumentParser:
    from . import __version__

    p = CliParser(prog="btfsm", description="Preemptive robot skills: check BT-FSM models and run them.",
                  epilog="Exit codes: 0 ok, 1 a check failed, 2 bad input, 3 budget hit, 70 internal error "
                         "(a bug), 130 interrupted, 143 terminated.")
    p.add_argument("--version", action="version", version=f"btfsm {__version__}")
    p.add_argument("--debug", action="store_true", help="print the traceback of an internal error")
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=CliParser)
    for name, (spec, help_text) in COMMANDS.items():
        sp = sub.add_parser(name, help=help_text, description=help_text)
        sp.set_defaults(_spec=spec)
        sp.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                        help="print the traceback of an internal error")
        _ARGS.get(name, lambda sp: None)(sp)
    return p


def _args_model(sp):
    sp.add_argument("model", type=input_file, help="model file (.yaml/.json), FILE.py:FUNCTION or package.module:FUNCTION (a function "
                         "returning a Model), or a built-in model name")
    sp.add_argument("--semantics", choices=SEMANTICS, default=None,
                    help="tick rules of this engine instead of the model's own (btfsm, btcpp: BehaviorTree.CPP 4, "
                         "pytrees: py_trees 2.6; see docs/semantics.md section 8)")
    sp.add_argument("--tick", choices=TICKS, default=None,
                    help="how a BehaviorTree.CPP main loop ticks the tree under btcpp, instead of the model's own: "
                         "once (tickOnce(), the default: re-ticks while a wake-up signal is pending) or exactly-once "
                         "(tickExactlyOnce()); docs/semantics.md 8.1")
    _args_xml(sp)


def _args_xml(sp):
    g = sp.add_argument_group("BehaviorTree.CPP XML trees (docs/model-files.md)")
    g.add_argument("--node-library", metavar="NAME", default=None,
                   help="model the custom nodes of this family of trees (nav2: Nav2's controls, decorators and leaves)")
    g.add_argument("--nodes", metavar="FILE", type=input_file, action="append", default=None,
                   help="a Groot2 node model file (TreeNodesModel): port kinds and types of the tree's nodes (repeatable)")
    g.add_argument("--main-tree", metavar="ID", default=None, help="the BehaviorTree to check (default: the file's "
                   "main_tree_to_execute, or its only tree)")


def _args_scene(sp):
    sp.add_argument("--scene", metavar="FILE", type=input_file, default=None,
                    help="run in this scene file (docs/cell.md) instead of the kitting cell; default: the "
                         "model's own scene (MODEL.scene.yaml beside it, or a shipped scene named after it)")


def _args_html(sp, what):
    sp.add_argument("--html", metavar="HTML", type=output_file(".html", ".htm"), default=None,
                    help=f"also write one self-contained HTML page: {what}, stepped tick by tick over the tree "
                         "and the FSMs (needs Graphviz; btfsm/html.py)")


def _args_json(sp, what="the result"):
    sp.add_argument("--json", action="store_true", help=f"print {what} (or the error) as one JSON object on stdout")


def _args_max_states(sp, default=None):
    sp.add_argument("--max-states", type=int_range(1, MAX_STATES_LIMIT), default=default, metavar="N",
                    help=f"state budget, 1..{MAX_STATES_LIMIT:.0e}; hitting it exits 3")


def _args_validate(sp):
    _args_model(sp)
    sp.add_argument("--strict", action="store_true", help="exit 1 when there are warnings")
    _args_json(sp, "the summary and warnings")


def _args_show(sp):
    _args_model(sp)
    sp.add_argument("--format", choices=("dot", "svg", "png"), default="dot")
    sp.add_argument("--output", "-o", type=input_text,
                    help="a name ending in .dot, .svg or .png is a file (one picture, matching --format); "
                         "any other name is a folder, created if missing, with one file per picture "
                         "(default: stdout for dot)")
    sp.add_argument("--what", default="all", type=input_text, help="'tree', an FSM name, or 'all'")


def _args_run(sp):
    _args_model(sp)
    sp.add_argument("--ticks", type=int_range(0, MAX_TICKS), default=100, help=f"0..{MAX_TICKS:,}")
    sp.add_argument("--seed", type=seed_int, default=0)
    sp.add_argument("--p-env", type=probability, default=0.2,
                    help="probability (0..1) of each enabled environment event per tick")
    sp.add_argument("--trace", type=output_file(), help="write the JSON Lines trace here")


def _args_replay(sp):
    sp.add_argument("trace", type=input_file,
                    help="a trace (.jsonl) or a counterexample (.json from btfsm check --counterexample-dir)")
    _args_model(sp)
    sp.add_argument("--cell", action="store_true", help="also replay the counterexample's situation in the kitting cell "
                                                         "(or in a scene: --scene, or the model's own scene)")
    _args_scene(sp)
    sp.add_argument("--render", metavar="PNG", type=output_file(".png"), help="with --cell: draw the cell at the end")
    sp.add_argument("--gif", metavar="GIF", type=output_file(".gif"), help="with --cell: write an animation")
    sp.add_argument("--time", type=finite_float(0, MAX_SIM_TIME, lo_open=True), default=120.0,
                    help="with --cell: time limit (simulated s)")
    sp.add_argument("--pace", choices=("paced", "ticks", "phase"),
                    help="with --cell, the kitting cell: paced (the default for a response counterexample: each FSM "
                         "state lasts at least as long as there), ticks (the events at the counterexample's ticks, "
                         "the arm at its own speed), phase (each event when the cell's FSM is at the counterexample's "
                         "state and ticks into it, its failures forced, the arm at its own speed; prints where the "
                         "response time went)")
    _args_html(sp, "the counterexample or trace (with --cell: and the cell run, with pictures)")


def _args_check(sp):
    _args_model(sp)
    sp.add_argument("--property", action="append", default=[], metavar="NAME", type=input_text)
    _args_json(sp, "the report")
    _args_max_states(sp)
    _args_budgets(sp)
    sp.add_argument("--counterexample-dir", type=output_dir, help="write each counterexample as JSON into this folder")
    _args_html(sp, "the verdicts and each counterexample")
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
    _args_response(sp, required=False)
    sp.add_argument("--within", type=finite_float(0, None), metavar="S", default=None,
                    help="with --trigger/--response: the bound in seconds (property 'response')")
    _args_timed(sp)


def _args_timed(sp):
    sp.add_argument("--timed", action="store_true",
                    help="first give every primitive the bind table drives a duration derived from the scene "
                         "(--scene, else the model's own scene); docs/verification.md 2.1")
    sp.add_argument("--scene", metavar="FILE", type=input_file, default=None,
                    help="with --timed: the scene file (docs/cell.md) to derive the durations from")


def _args_response(sp, required):
    sp.add_argument("--trigger", type=input_text, required=required, metavar="EXPR",
                    help="an expression, or event:NAME (the tick in which environment event NAME happens)")
    sp.add_argument("--response", type=input_text, required=required, metavar="EXPR",
                    help="the expression that must come to hold after each trigger")


def _args_bound(sp):
    _args_model(sp)
    _args_response(sp, required=True)
    sp.add_argument("--output", "-o", type=output_file(".json"), default=None,
                    help="write the worst-case run as a counterexample file (replay it with btfsm replay)")
    sp.add_argument("--within", type=finite_float(0, None), default=None, metavar="S",
                    help="also the worst first late response: over runs that answered every earlier trigger within S "
                         "seconds (an event trigger whose minimum interval exceeds S); -o then writes that run")
    _args_timed(sp)
    _args_json(sp, "the figures")
    _args_max_states(sp)
    _args_budgets(sp)


def _args_export(sp):
    _args_model(sp)
    sp.add_argument("--format", choices=("promela", "smv", "dot", "btcpp"), required=True,
                    help="btcpp: the tree as BehaviorTree.CPP XML v4 (docs/semantics.md 8.1)")
    sp.add_argument("--fsm", type=input_text,
                    help="FSM to export at FSM level (default: the whole model when its tree is one "
                         "SkillRequest, the first FSM when there is no tree)")
    sp.add_argument("--output", "-o", type=output_file())
    _args_max_states(sp)
    _args_budgets(sp)


def _args_skills(sp):
    _args_model(sp)
    sp.add_argument("--format", choices=("text", "dot", "json"), default="text")
    sp.add_argument("--json", dest="format", action="store_const", const="json", help="same as --format json")
    _args_max_states(sp)
    _args_budgets(sp)


def _args_budgets(sp):
    sp.add_argument("--max-transitions", type=int_range(1, None), default=None, metavar="N",
                    help="stop exploring after this many transitions (exit 3)")
    sp.add_argument("--max-seconds", type=finite_float(0, None, lo_open=True), default=None, metavar="S",
                    help="stop exploring after this many seconds of checker time (exit 3)")


def _args_experiment(sp):
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
    _args_json(sp, "the summary")


def _args_sweep(sp):
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


def _args_sim(sp):
    _args_model(sp)
    sp.add_argument("--k", type=int_range(1, 40), default=1, help="belt parts every 30 + 0.2 k s (1..40, default 1)")
    sp.add_argument("--time", type=finite_float(0, MAX_SIM_TIME, lo_open=True), default=1500.0,
                    help="time limit in simulated seconds")
    sp.add_argument("--render", metavar="PNG", type=output_file(".png"), help="draw the cell at the end of the run")
    sp.add_argument("--gif", metavar="GIF", type=output_file(".gif"), help="write an animation of the run")
    sp.add_argument("--fps", type=finite_float(0.01, 100.0), default=2.0,
                    help="animation frames per simulated second (0.01..100)")
    sp.add_argument("--max-frames", type=int_range(1, MAX_FRAMES), default=600)
    _args_scene(sp)
    sp.add_argument("--seed", type=seed_int, default=0, help="with a scene: the seed of its random arrivals and faults")


def _args_conform(sp):
    _args_model(sp)
    sp.add_argument("--log", type=input_file, default=None, metavar="RUN",
                    help="check this recorded run instead of running scenarios: a BehaviorTree.CPP FileLogger2 file "
                         "(.btlog, checked under btcpp) or a py_trees run written by btfsm.interop.pytrees.RunRecorder "
                         "(under pytrees); --max-states bounds the configurations the search keeps at once (default "
                         "200,000); see docs/interop.md section 5")
    sp.add_argument("--scenarios", type=int_range(1, MAX_SCENARIOS), default=10)
    sp.add_argument("--seed", type=seed_int, default=0)
    sp.add_argument("--time", type=finite_float(0, MAX_SIM_TIME, lo_open=True), default=700.0,
                    help="time limit per scenario (simulated s)")
    sp.add_argument("--drops", action="store_true", help="add faulty-gripper drop regions to some scenarios")
    sp.add_argument("--no-path", action="store_true", help="skip the path check against the explored system")
    _args_scene(sp)
    _args_max_states(sp)
    _args_json(sp, "the scenarios and the verdict")
    _args_html(sp, "the scenarios, and the first nonconforming one (else the first) as a run with the cell's pictures")


def _args_import(sp):
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
    _args_xml(sp)


_ARGS = {"validate": _args_validate, "show": _args_show, "run": _args_run, "replay": _args_replay,
         "check": _args_check, "bound": _args_bound, "export": _args_export, "skills": _args_skills,
         "experiment": _args_experiment, "sweep": _args_sweep, "sim": _args_sim, "conform": _args_conform, "import": _args_import}


def _refuse_input_as_output(args) -> None:
    """An output path must not name the model or another input file (it would overwrite it)."""
    inputs = [getattr(args, name, None) for name in INPUTS.get(args.command, ("model",))]
    inputs = [p for p in inputs if isinstance(p, str) and os.path.isfile(p)]
    for name in OUTPUTS.get(args.command, ()):
        out = getattr(args, name, None)
        if not isinstance(out, str) or not os.path.exists(out):
            continue
        for inp in inputs:
            try:
                same = os.path.samefile(out, cast(str, inp))
            except OSError:
                same = False
            if same:
                raise UsageError(f"--{name.replace('_', '-')} {out}: is the input file {inp}; "
                                 f"refusing to overwrite it")


# ---------------------------------------------------------------- errors and signals

#: Characters that would break the one-line rule (what ``str.splitlines`` splits on).
_LINE_BREAKS = {c: repr(c)[1:-1] for c in "\n\r\v\f\x1c\x1d\x1e\x85\u2028\u2029"}


def _one_line(text) -> str:
    """``text`` with line breaks escaped (``\\n``), so a message stays one line.

    >>> _one_line("a\\nb")
    'a\\\\nb'
    """
    text = str(text)
    return text.translate(str.maketrans(_LINE_BREAKS)) if any(c in text for c in _LINE_BREAKS) else text


def _describe(exc: BaseException, command: str) -> dict:
    """kind, exit code and the parts of the one-line message for an exception."""
    info: dict[str, Any] = {"kind": "internal", "type": type(exc).__name__, "command": command, "file": None, "element": None,
            "problem": str(exc), "exit_code": EXIT_INTERNAL}
    if isinstance(exc, Terminated):
        info.update(kind="terminated", problem="terminated", exit_code=EXIT_TERMINATED)
    elif isinstance(exc, KeyboardInterrupt):
        info.update(kind="interrupted", problem="interrupted", exit_code=EXIT_INTERRUPTED)
    elif isinstance(exc, ModelError):
        info.update(kind="model", file=exc.file, element=exc.element or None, problem=str(exc.problem),
                    exit_code=EXIT_INPUT)
        if isinstance(exc, ModelErrors):  # every problem found in one pass: one line each, and the list
            info["errors"] = [{"file": e.file, "element": e.element or None, "problem": str(e.problem)}
                              for e in exc.errors]
    elif isinstance(exc, UsageError):
        info.update(kind="usage", exit_code=EXIT_INPUT)
    elif isinstance(exc, (DomainError, ConformanceError)):
        info.update(kind="violation", exit_code=EXIT_FAILED)
    elif isinstance(exc, MemoryError):
        info.update(kind="budget", problem="out of memory before an answer (lower --max-states)",
                    exit_code=EXIT_BUDGET)
    elif isinstance(exc, ImportError) and (getattr(exc, "name", None) or "").split(".")[0] in OPTIONAL_MODULES:
        info.update(kind="usage", exit_code=EXIT_INPUT,
                    problem=f"this command needs the Python package '{(exc.name or '').split('.')[0]}' "
                            f"(install it with: pip install 'btfsm[sim]')")
    elif isinstance(exc, OSError) and not isinstance(exc, (BlockingIOError, ChildProcessError)) and (
            getattr(exc, "filename", None) is not None):
        info.update(kind="file", file=os.fsdecode(exc.filename), problem=str(exc.strerror or exc),
                    exit_code=EXIT_INPUT)
    return info


def _message(info: dict) -> str:
    head = f"btfsm {info['command']}: " if info["command"] else "btfsm: "
    if info["kind"] in ("interrupted", "terminated"):
        return head + info["problem"]
    if info["kind"] == "internal":
        return _one_line(head + f"internal error (a bug in btfsm): {info['type']}: {info['problem']}; {REPORT_HINT} "
                       f"(run with --debug for the traceback)")
    label = {"violation": "violation: ", "budget": "incomplete: "}.get(info["kind"], "error: ")
    if info.get("errors"):
        lines = [_one_line(head + label + "".join(f"{part}: " for part in (e["file"], e["element"]) if part)
                           + e["problem"]) for e in info["errors"]]
        return "\n".join(lines + [f"{head}{len(lines)} errors"])
    where = "".join(f"{part}: " for part in (info["file"], info["element"]) if part)
    return _one_line(head + label + where + info["problem"])


def _emit(info: dict, as_json: bool) -> None:
    info = dict(info, message=_message(info))
    if as_json:
        _write(sys.stdout, json.dumps({"error": info}))
    else:
        _write(sys.stderr, info["message"])


def _write(stream, line: str) -> None:
    try:
        stream.write(line + "\n")
        stream.flush()
    except UnicodeEncodeError:
        enc = getattr(stream, "encoding", None) or "ascii"
        stream.write(line.encode(enc, "backslashreplace").decode(enc) + "\n")
        stream.flush()
    except (BrokenPipeError, ValueError):  # closed stream: nothing more to say
        pass


def _safe_streams() -> None:
    """Names from a model may hold characters the terminal cannot encode: escape them."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.reconfigure(errors="backslashreplace")  # type: ignore[union-attr]  # (AttributeError: not a text file)
        except (AttributeError, ValueError, OSError):
            pass


def _prescan(argv) -> tuple:
    """(command, --json, --debug) found in argv before parsing (parsing itself may fail)."""
    words = [a for a in argv if isinstance(a, str)]
    words = words[: words.index("--")] if "--" in words else words
    command = next((a for a in words if a in COMMANDS), "")
    return command, "--json" in words, "--debug" in words


def main(argv=None) -> int:
    """Run the command line; return the exit code (``--help``/``--version`` raise SystemExit(0))."""
    argv = sys.argv[1:] if argv is None else list(argv)
    command, as_json, debug = _prescan(argv)
    _safe_streams()
    reserve.hold()  # released on a MemoryError, so that the report has memory to be written
    with signals.handling():
        try:
            code = _main(argv)
            signals.check()  # an interrupt that was swallowed on its way (e.g. in a destructor)
            return code
        except SystemExit:
            raise
        except BrokenPipeError:
            _silence_stdout()
            return EXIT_OK
        except BaseException as exc:  # noqa: BLE001 - the one place that turns everything into one line
            if isinstance(exc, MemoryError):
                return _out_of_memory(exc, command, as_json)
            info = _describe(exc, command)
            _emit(info, as_json)
            if debug and info["kind"] == "internal":
                import traceback

                traceback.print_exception(type(exc), exc, exc.__traceback__, file=sys.stderr)
            return info["exit_code"]


def _out_of_memory(exc: MemoryError, command: str, as_json: bool) -> int:
    """The budget exit (3) of a MemoryError, in one line: the reserve and what the failed
    computation held are freed first; should the message still not fit, a fixed line is
    written straight to the file descriptor."""
    reserve.release(exc)
    try:
        _emit(_describe(exc, command), as_json)
    except MemoryError:
        try:
            os.write(2, _OOM_LINE)
        except OSError:
            pass
    return EXIT_BUDGET


_OOM_LINE = b"btfsm: incomplete: out of memory before an answer (lower --max-states)\n"


def _silence_stdout() -> None:
    """After a closed pipe (``btfsm ... | head``), send further output nowhere."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):
        pass


def _main(argv) -> int:
    parser = build_parser()
    # commands may accept extra options (``accepts_extra``); parse known args first to find the command
    args, rest = parser.parse_known_args(argv)
    if args.command is None:
        extra = f"unrecognized arguments: {' '.join(rest)}; " if rest else ""
        raise UsageError(f"{extra}no command given (commands: {', '.join(COMMANDS)}; see btfsm --help)")
    handler = _handler(args._spec)
    if rest and not getattr(handler, "accepts_extra", False):
        parser.parse_args(argv)  # reports the unknown option (UsageError)
    _refuse_input_as_output(args)
    try:
        result = handler(args, rest) if getattr(handler, "accepts_extra", False) else handler(args)
    except ModelError as exc:  # name the model file when the error does not (e.g. export errors)
        model = getattr(args, "model", None)
        if exc.file or not isinstance(model, str) or not os.path.isfile(model):
            raise
        raise exc.at(file=model) from None
    return int(result or 0)


def cli_conform(args) -> int:
    """``btfsm conform``: ``--log RUN`` checks a recorded run (``btfsm.verify.runlog``, no
    simulator needed); otherwise the simulated scenarios of ``btfsm.sim.cli``."""
    if args.log is not None:
        return _handler("btfsm.verify.runlog:cli_conform_log")(args)
    if args.max_states is None:
        args.max_states = 2_000_000
    return _handler("btfsm.sim.cli:cli_conform")(args)


def cli_validate(args) -> int:
    """``btfsm validate MODEL [--strict] [--json]``: the text report is ``btfsm.files.cli_validate``."""
    from .files import cli_validate as validate_text
    from .files import load_cli_model

    if _is_scene_file(args.model):
        return _validate_scene(args)
    if not getattr(args, "json", False):
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
    if getattr(args, "json", False):
        print(json.dumps(summary))
    else:
        print(f"{args.model}: ok (scene {sc.name}: {len(sc.areas)} areas, {len(sc.belts)} belts, {len(sc.walls)} walls, "
              f"{len(sc.sensors)} sensors, {len(sc.robots)} robots, {parts} parts)")
    return 0


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
    html = getattr(args, "html", None)
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


if __name__ == "__main__":
    sys.exit(main())
