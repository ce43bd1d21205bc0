"""The flags that several ``btfsm`` commands share, and the upper bounds of flag values.

A command declares its own flags beside its handler (``args_NAME(parser)`` next to
``cli_NAME(args)``, listed in ``btfsm.cli.COMMANDS``) and adds the shared groups from
here: the model argument and its tick profile, the BehaviorTree.CPP XML options, the scene,
``--html``, ``--json``, the exploration budgets and ``--trigger``/``--response``. Every
value is checked when parsed (``btfsm.validators``).
"""
from __future__ import annotations

import argparse

from .profiles import SEMANTICS, TICKS
from .validators import finite_float, input_file, input_text, int_range, output_file

__all__ = ["MAX_STATES_LIMIT", "MAX_TICKS", "MAX_SIM_TIME", "MAX_WORKERS", "MAX_SCENARIOS", "MAX_FRAMES",
           "model", "xml", "scene", "html", "json", "max_states", "budgets", "response"]

#: Upper bounds for flag values: far above any sensible run, low enough to stay well defined.
MAX_STATES_LIMIT = 10 ** 10
MAX_TICKS = 10 ** 7
MAX_SIM_TIME = 100_000.0  # simulated seconds
MAX_WORKERS = 256
MAX_SCENARIOS = 100_000
MAX_FRAMES = 100_000

Parser = argparse.ArgumentParser


def model(sp: Parser) -> None:
    """The model argument, ``--semantics``, ``--tick`` and the XML options."""
    sp.add_argument("model", type=input_file, help="model file (.yaml/.json), FILE.py:FUNCTION or package.module:FUNCTION (a function "
                         "returning a Model), or a built-in model name")
    sp.add_argument("--semantics", choices=SEMANTICS, default=None,
                    help="tick rules of this engine instead of the model's own (btfsm, btcpp: BehaviorTree.CPP 4, "
                         "pytrees: py_trees 2.6; see docs/semantics.md section 8)")
    sp.add_argument("--tick", choices=TICKS, default=None,
                    help="how a BehaviorTree.CPP main loop ticks the tree under btcpp, instead of the model's own: "
                         "once (tickOnce(), the default: re-ticks while a wake-up signal is pending) or exactly-once "
                         "(tickExactlyOnce()); docs/semantics.md 8.1")
    xml(sp)


def xml(sp: Parser) -> None:
    g = sp.add_argument_group("BehaviorTree.CPP XML trees (docs/model-files.md)")
    g.add_argument("--node-library", metavar="NAME", default=None,
                   help="model the custom nodes of this family of trees (nav2: Nav2's controls, decorators and leaves)")
    g.add_argument("--nodes", metavar="FILE", type=input_file, action="append", default=None,
                   help="a Groot2 node model file (TreeNodesModel): port kinds and types of the tree's nodes (repeatable)")
    g.add_argument("--main-tree", metavar="ID", default=None, help="the BehaviorTree to check (default: the file's "
                   "main_tree_to_execute, or its only tree)")


def scene(sp: Parser) -> None:
    sp.add_argument("--scene", metavar="FILE", type=input_file, default=None,
                    help="run in this scene file (docs/cell.md) instead of the kitting cell; default: the "
                         "model's own scene (MODEL.scene.yaml beside it, or a shipped scene named after it)")


def html(sp: Parser, what: str) -> None:
    sp.add_argument("--html", metavar="HTML", type=output_file(".html", ".htm"), default=None,
                    help=f"also write one self-contained HTML page: {what}, stepped tick by tick over the tree "
                         "and the FSMs (needs Graphviz; btfsm/html.py)")


def json(sp: Parser, what: str = "the result") -> None:
    sp.add_argument("--json", action="store_true", help=f"print {what} (or the error) as one JSON object on stdout")


def max_states(sp: Parser, default: int | None = None) -> None:
    sp.add_argument("--max-states", type=int_range(1, MAX_STATES_LIMIT), default=default, metavar="N",
                    help=f"state budget, 1..{MAX_STATES_LIMIT:.0e}; hitting it exits 3")


def budgets(sp: Parser) -> None:
    sp.add_argument("--max-transitions", type=int_range(1, None), default=None, metavar="N",
                    help="stop exploring after this many transitions (exit 3)")
    sp.add_argument("--max-seconds", type=finite_float(0, None, lo_open=True), default=None, metavar="S",
                    help="stop exploring after this many seconds of checker time (exit 3)")


def response(sp: Parser, required: bool) -> None:
    sp.add_argument("--trigger", type=input_text, required=required, metavar="EXPR",
                    help="an expression, or event:NAME (the tick in which environment event NAME happens)")
    sp.add_argument("--response", type=input_text, required=required, metavar="EXPR",
                    help="the expression that must come to hold after each trigger")
