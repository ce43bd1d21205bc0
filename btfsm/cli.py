"""The ``btfsm`` command line: the dispatcher, the exit codes and the error handler.

Commands
    ``COMMANDS`` lists each command's module and one-line help. The module holds the
    command's handler ``cli_NAME(args)`` and, beside it, its flags ``args_NAME(parser)``
    (the flags several commands share: ``btfsm.cliargs``); both are imported only when that
    command runs or shows its help. Adding a command is those two functions and a line in
    ``COMMANDS``.

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

from .cliargs import MAX_FRAMES, MAX_SCENARIOS, MAX_SIM_TIME, MAX_STATES_LIMIT, MAX_TICKS, MAX_WORKERS
from .errors import ConformanceError, DomainError, ModelError, ModelErrors, Terminated, UsageError
from . import reserve, signals

__all__ = ["main", "build_parser", "UsageError", "EXIT_OK", "EXIT_FAILED", "EXIT_INPUT", "EXIT_BUDGET",
           "EXIT_INTERNAL", "EXIT_INTERRUPTED", "EXIT_TERMINATED", "REPORT_HINT", "COMMANDS", "MAX_STATES_LIMIT",
           "MAX_TICKS", "MAX_SIM_TIME", "MAX_WORKERS", "MAX_SCENARIOS", "MAX_FRAMES"]

EXIT_OK, EXIT_FAILED, EXIT_INPUT, EXIT_BUDGET = 0, 1, 2, 3
EXIT_INTERNAL, EXIT_INTERRUPTED, EXIT_TERMINATED = 70, 130, 143
REPORT_HINT = "please report it with the command line at the btfsm issue tracker"

#: Third-party modules that only some commands need (``pip install 'btfsm[sim]'``).
OPTIONAL_MODULES = {"matplotlib", "PIL", "dask", "distributed", "pyarrow", "numpy", "tqdm", "pymunk"}


class CliParser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors are ``UsageError``s (one line, exit 2), not usage dumps.

    A command's parser gets its flags on first use (``arguments``: the command module's
    ``args_NAME``, imported then), so a command imports only its own module."""

    arguments: str | None = None  # "module:function" that adds this parser's flags, not yet called

    def error(self, message):
        raise UsageError(message.replace("\n", " "))

    def _declare(self) -> None:
        if self.arguments is not None:
            spec, self.arguments = self.arguments, None
            _handler(spec)(self)

    def parse_known_args(self, args=None, namespace=None):  # type: ignore[override]
        self._declare()
        return super().parse_known_args(args, namespace)

    def format_help(self) -> str:
        self._declare()
        return super().format_help()

    def format_usage(self) -> str:
        self._declare()
        return super().format_usage()


def _handler(spec: str):
    """Import ``module:function`` lazily so each command loads only what it needs."""
    module, func = spec.split(":")
    return getattr(importlib.import_module(module), func)


#: The commands, in the order of ``btfsm --help``: name -> (module, help). The module holds
#: the command's handler ``cli_NAME(args)`` and, beside it, its flags ``args_NAME(parser)``
#: (shared flag groups: ``btfsm.cliargs``). A new command is its two functions and a line here.
COMMANDS = {
    "validate": ("btfsm.commands", "check that a model file loads; print its warnings"),
    "show": ("btfsm.show", "draw the tree and each FSM (dot, svg, png)"),
    "run": ("btfsm.commands", "run a model in the runtime with seeded random outcomes; write a trace"),
    "replay": ("btfsm.commands", "re-run a trace or counterexample and confirm it reproduces"),
    "check": ("btfsm.verify.cli", "model-check a model; print verdicts and counterexamples"),
    "bound": ("btfsm.verify.cli", "the exact best and worst response time from a trigger to a response"),
    "export": ("btfsm.verify.cli", "export a model to Promela, SMV or dot"),
    "skills": ("btfsm.verify.skills", "derive the skill transitions a tree can request"),
    "sim": ("btfsm.sim.cli", "run a model in a simulated cell (its scene; the ARIAC cell for the paper's models)"),
    "experiment": ("btfsm.sim.cli", "reproduce the paper's ARIAC experiment"),
    "sweep": ("btfsm.sim.cli", "run the experiment over a grid of cell parameters (on Dask)"),
    "conform": ("btfsm.commands", "run scenarios and check runtime conformance, or (--log) check a run recorded "
                                  "by BehaviorTree.CPP or py_trees against the model"),
    "import": ("btfsm.commands", "read a BehaviorTree.CPP XML v4 tree (+ side file); write a btfsm model file"),
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
    for name, (module, help_text) in COMMANDS.items():
        sp = sub.add_parser(name, help=help_text, description=help_text)
        sp.set_defaults(_spec=f"{module}:cli_{name}")
        sp.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                        help="print the traceback of an internal error")
        sp.arguments = f"{module}:args_{name}"
    return p


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
            info["errors_stopped"] = exc.stopped  # the search stopped at its cap: more may follow
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
        more = " (the first ones: the search stopped there, more may follow)" if info.get("errors_stopped") else ""
        return "\n".join(lines + [f"{head}{len(lines)} errors{more}"])
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


if __name__ == "__main__":
    sys.exit(main())
