"""``btfsm check`` and ``btfsm export`` (handlers named in ``btfsm.cli.COMMANDS``).

``btfsm check MODEL [--property NAME]... [--json] [--max-states N] [--counterexample-dir DIR]``
exits 0 when every property holds, 1 when one is violated (its counterexample is printed),
2 on bad input or usage (an unknown property name lists the known ones), 3 when the state
budget was hit and some property is undecided. A ``\\r``-updated progress line (states and
states/s) goes to stderr for explorations longer than a second.
"""
from __future__ import annotations

import json
import os
import sys

__all__ = ["cli_check", "cli_export"]


class _Progress:
    """Prints ``what: N states, M states/s`` on stderr once an exploration runs > 1 s."""

    def __init__(self, stream=None, after: float = 1.0):
        self.stream = stream or sys.stderr
        self.after = after
        self.shown = False

    def __call__(self, what, states, transitions, seconds):
        if seconds < self.after:
            return
        rate = states / seconds if seconds > 0 else 0.0
        self.stream.write(f"\r{what}: {states:,} states, {transitions:,} transitions, {rate:,.0f} states/s   ")
        self.stream.flush()
        self.shown = True

    def done(self):
        if self.shown:
            self.stream.write("\n")
            self.stream.flush()
            self.shown = False


def cli_check(args) -> int:
    from btfsm.cli import UsageError

    from .search import DEFAULT_MAX_STATES, DEFAULT_MAX_TRANSITIONS, describe_hit
    from .properties import PROPERTIES
    from .report import check

    props = list(args.property or [])
    unknown = [p for p in props if p not in PROPERTIES]
    if unknown:
        raise UsageError(f"unknown property {', '.join(repr(p) for p in unknown)}; known properties: {', '.join(PROPERTIES)}")
    max_states = DEFAULT_MAX_STATES if args.max_states is None else args.max_states
    if max_states < 1:
        raise UsageError("--max-states must be at least 1")
    max_transitions, max_seconds = _budgets(args, DEFAULT_MAX_TRANSITIONS)
    model = _load(args.model)
    progress = _Progress()
    try:
        report = check(model, props or None, max_states=max_states, max_transitions=max_transitions,
                       max_seconds=max_seconds, progress=progress, engine=args.engine)
    except MemoryError:
        progress.done()
        print(f"btfsm check: out of memory while exploring {model.name}; lower --max-states", file=sys.stderr)
        return 3
    progress.done()
    if args.counterexample_dir:
        _write_counterexamples(report, args.counterexample_dir)
    if args.json:
        print(json.dumps(report.to_json(), default=_plain))
    else:
        print(report.format_text())
        if not report.complete:
            hit = sorted({describe_hit(s.get("budget"), max_states, max_transitions, max_seconds) or "budget"
                          for s in report.systems if not s["complete"]})
            print(f"({' and '.join(hit)} hit: explored {report.states:,} states, {report.transitions:,} transitions "
                  f"in {report.seconds:.2f} s; raise it to decide the rest)")
    return report.exit_code


def _budgets(args, default_transitions=None):
    """(max_transitions, max_seconds) from ``--max-transitions`` and ``--max-seconds``."""
    from btfsm.cli import UsageError

    max_transitions = getattr(args, "max_transitions", None)
    max_seconds = getattr(args, "max_seconds", None)
    if max_transitions is not None and max_transitions < 1:
        raise UsageError("--max-transitions must be at least 1")
    if max_seconds is not None and not (max_seconds > 0 and max_seconds != float("inf")):
        raise UsageError("--max-seconds must be a positive finite number")
    return (default_transitions if max_transitions is None else max_transitions), max_seconds


def _plain(x):
    if hasattr(x, "item"):
        return x.item()
    if isinstance(x, (set, frozenset, tuple)):
        return list(x)
    return str(x)


def _load(ref):
    from btfsm.cli import UsageError
    from btfsm.files import load_model

    try:
        return load_model(ref)
    except OSError as exc:
        raise UsageError(f"{ref}: {exc.strerror or exc}") from None


def _write_counterexamples(report, folder):
    from btfsm.cli import UsageError

    try:
        os.makedirs(folder, exist_ok=True)
        for r in report.results:
            if r.counterexample is not None:
                path = os.path.join(folder, f"{report.model}.{r.name}.json")
                with open(path, "w", encoding="utf-8") as fh:
                    json.dump(r.counterexample.to_json(), fh, indent=1, default=_plain)
                    fh.write("\n")
    except OSError as exc:
        raise UsageError(f"--counterexample-dir {folder}: {exc.strerror or exc}") from None


def cli_export(args) -> int:
    from btfsm.cli import UsageError

    model = _load(args.model)
    if args.fsm is not None and args.fsm not in [f.name for f in model.fsms]:
        raise UsageError(f"no FSM named '{args.fsm}' in {model.name} (have: {', '.join(f.name for f in model.fsms) or 'none'})")
    from .export import export  # written separately (verify/export.py)
    from .search import BudgetExceeded

    max_transitions, max_seconds = _budgets(args)
    max_states = getattr(args, "max_states", None)
    if max_states is not None and max_states < 1:
        raise UsageError("--max-states must be at least 1")
    try:
        out = export(model, args.format, args.fsm, args.output, max_states=max_states,
                     max_transitions=max_transitions, max_seconds=max_seconds)
    except BudgetExceeded as exc:
        print(f"btfsm export: {exc}", file=sys.stderr)
        return 3
    if isinstance(out, str) and not args.output:
        sys.stdout.write(out if out.endswith("\n") else out + "\n")
    return out if isinstance(out, int) and not isinstance(out, bool) else 0
