"""``btfsm check`` and ``btfsm export`` (handlers named in ``btfsm.cli.COMMANDS``).

``btfsm check MODEL [--property NAME]... [--json] [--max-states N] [--counterexample-dir DIR]``
(flag values are checked by the parser in ``btfsm.cli``; files are written atomically by
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

__all__ = ["cli_check", "cli_export"]


def cli_check(args) -> int:
    from btfsm.errors import UsageError

    from .search import DEFAULT_MAX_STATES, DEFAULT_MAX_TRANSITIONS, describe_hit
    from .properties import PROPERTIES
    from .report import check

    props = list(args.property or [])
    unknown = [p for p in props if p not in PROPERTIES]
    if unknown:
        raise UsageError(f"unknown property {', '.join(repr(p) for p in unknown)}; known properties: {', '.join(PROPERTIES)}")
    max_states = DEFAULT_MAX_STATES if args.max_states is None else args.max_states
    max_transitions, max_seconds = _budgets(args, DEFAULT_MAX_TRANSITIONS)
    from btfsm.progress import ExplorationProgress

    model = _load(args)
    progress = ExplorationProgress()
    try:
        report = check(model, props or None, max_states=max_states, max_transitions=max_transitions,
                       max_seconds=max_seconds, progress=progress, engine=args.engine,
                       goal_level=getattr(args, "goal_level", "open"))
    except MemoryError:
        progress.done()
        print(f"btfsm check: out of memory while exploring {model.name}; lower --max-states", file=sys.stderr)
        return 3
    progress.done()
    written = _write_counterexamples(report, args.counterexample_dir) if args.counterexample_dir else []
    if args.json:
        print(json.dumps(report.to_json(), default=_plain))
    else:
        print(report.format_text(quiet=getattr(args, "quiet", False), verbose=getattr(args, "verbose", False)))
        if not report.complete:
            hit = sorted({describe_hit(s.get("budget"), max_states, max_transitions, max_seconds) or "budget"
                          for s in report.systems if not s["complete"]})
            print(f"({' and '.join(hit)} hit: explored {report.states:,} states, {report.transitions:,} transitions "
                  f"in {report.seconds:.2f} s; raise it to decide the rest)")
        for path in written:
            print(f"counterexample written: {path}")
    return report.exit_code


def _budgets(args, default_transitions=None):
    """(max_transitions, max_seconds) from ``--max-transitions`` and ``--max-seconds``
    (their ranges are checked by the parser in ``btfsm.cli``)."""
    max_transitions = getattr(args, "max_transitions", None)
    max_seconds = getattr(args, "max_seconds", None)
    return (default_transitions if max_transitions is None else max_transitions), max_seconds


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


def cli_export(args) -> int:
    from btfsm.errors import UsageError

    model = _load(args)
    if args.fsm is not None and args.fsm not in [f.name for f in model.fsms]:
        raise UsageError(f"{args.model}: --fsm: no FSM named '{args.fsm}' in {model.name} (have: {', '.join(f.name for f in model.fsms) or 'none'})")
    from .export import export  # written separately (verify/export.py)
    from .search import BudgetExceeded

    max_transitions, max_seconds = _budgets(args)
    try:
        out = export(model, args.format, args.fsm, max_states=getattr(args, "max_states", None),
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
