"""``btfsm validate``: load, summarise, list warnings and lints."""
from __future__ import annotations

from .loading import load_cli_model
from .text import printable


def cli_validate(args) -> int:
    """``btfsm validate FILE [--strict]``: load, summarise, list warnings and lints."""
    model = load_cli_model(args)
    states = sum(len(f.states) for f in model.fsms)
    nodes = len(model.nodes())
    print(f"{args.model}: ok ({_count(len(model.variables), 'variable')}, {_count(len(model.fsms), 'FSM')} "
          f"with {_count(states, 'state')}, {_count(nodes, 'tree node')})")
    warnings = list(model.warnings) + list(model.program.lints)
    for element, text in warnings:
        print(printable(f"warning: {element}: {text}"))
    return 1 if warnings and args.strict else 0


def _count(n: int, word: str) -> str:
    return f"{n} {word}{'' if n == 1 else 's'}"
