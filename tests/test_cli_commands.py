"""The command registry: each command's flags (``args_NAME``) sit beside its handler
(``cli_NAME``) in the module ``btfsm.cli.COMMANDS`` names, declared when the command is used."""
from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

from btfsm.cli import COMMANDS, build_parser


@pytest.mark.parametrize("name", list(COMMANDS))
def test_each_command_has_its_flags_beside_its_handler(name):
    module = importlib.import_module(COMMANDS[name][0])
    assert callable(getattr(module, f"cli_{name}")) and callable(getattr(module, f"args_{name}"))
    sub = next(a for a in build_parser()._actions if a.dest == "command").choices[name]
    assert "--debug" in sub.format_help()
    assert len(sub._actions) > 2  # the command's own flags were declared on first use


def test_the_top_level_help_imports_no_command_module():
    code = ("import sys, contextlib, io\nfrom btfsm.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            "    try: main(['--help'])\n    except SystemExit: pass\n"
            "print(sorted(m for m in sys.modules if m in ('btfsm.commands', 'btfsm.verify.cli', 'btfsm.sim.cli',"
            " 'btfsm.show', 'btfsm.verify.skills')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
