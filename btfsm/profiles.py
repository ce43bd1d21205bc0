"""Semantics profiles: which engine's tick rules the one step function follows.

A model names its profile (``Model.semantics``, the file's ``semantics:`` key; the CLI's
``--semantics`` overrides it). ``btfsm.semantics.Program`` reads the profile's rule
switches while it compiles the tree: there is one step function, not one per engine.
Every switch is a row of docs/semantics.md section 8, with its test.

* ``btfsm``: the rules of docs/semantics.md sections 1-7 (halt before start).
* ``btcpp``: BehaviorTree.CPP 4.x, proven tick by tick against the real library
  (``behaviortreepy``) in ``tests/test_peer_btcpp.py``.
* ``pytrees``: py_trees 2.6, proven against the real library in
  ``tests/test_peer_pytrees.py``.

>>> PROFILES["btcpp"].halt_before_start
False
>>> profile("nope")
Traceback (most recent call last):
...
ValueError: unknown semantics 'nope' (one of: btfsm, btcpp, pytrees)
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Profile", "PROFILES", "SEMANTICS", "DEFAULT_SEMANTICS", "profile"]


@dataclass(frozen=True)
class Profile:
    """The rule switches of one engine. ``name`` is what model files and ``--semantics`` say."""

    name: str
    engine: str
    #: before an idle leaf that can run is ticked, halt the running branches it competes with
    #: (docs/semantics.md section 4); off: the engine halts only after a child returned
    halt_before_start: bool = True
    #: a Parallel that reaches its failure rule and its success rule in one tick fails
    #: (py_trees checks for a failed child first); off: success wins (docs/semantics.md 2)
    parallel_failure_first: bool = False


PROFILES = {
    "btfsm": Profile("btfsm", "btfsm (docs/semantics.md sections 1-7)"),
    "btcpp": Profile("btcpp", "BehaviorTree.CPP 4.x", halt_before_start=False),
    "pytrees": Profile("pytrees", "py_trees 2.6", halt_before_start=False, parallel_failure_first=True),
}
SEMANTICS = tuple(PROFILES)
DEFAULT_SEMANTICS = "btfsm"


def profile(name: str) -> Profile:
    """The profile called ``name``; ValueError naming the choices otherwise."""
    try:
        return PROFILES[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown semantics {name!r} (one of: {', '.join(SEMANTICS)})") from None
