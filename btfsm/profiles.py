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

from .bt import names_in

__all__ = ["Profile", "PROFILES", "SEMANTICS", "DEFAULT_SEMANTICS", "TICKS", "DEFAULT_TICK", "profile"]


@dataclass(frozen=True)
class Profile:
    """The rule switches of one engine. ``name`` is what model files and ``--semantics`` say."""

    name: str
    engine: str
    #: before an idle leaf that can run is ticked, halt the running branches it competes with
    #: (docs/semantics.md section 4); off: the engine halts only after a child returned
    halt_before_start: bool = True
    #: Parallel keeps which children finished (one memory slot per child), does not tick
    #: them again, and returns as soon as a threshold is reached (later children are not
    #: ticked in that tick; success is checked before failure after each child). Off: every
    #: child is ticked every tick and success wins (docs/semantics.md section 2)
    parallel_memory: bool = False
    #: Retry, Repeat and SequenceWithMemory: a child that was idle and finishes at once
    #: (with attempts/cycles/children left) makes the node return RUNNING (BehaviorTree.CPP's
    #: wake-up signal); a child that had been running and finishes is ticked again (or the
    #: next child is) in the same tick. Off: Retry/Repeat return RUNNING after every
    #: attempt, SequenceWithMemory moves on within the tick
    loop_wake_up: bool = False
    #: IfThenElse / WhileDoElse whose condition is a stateful leaf (an Action that can
    #: return RUNNING, a SkillRequest): once it finished, the leaf keeps its status and is
    #: not ticked again until the node resets it (BehaviorTree.CPP's StatefulActionNode
    #: returns its last status when ticked while SUCCESS/FAILURE). Off: ticked afresh
    stale_condition: bool = False
    #: a SkillRequest that finished and is ticked again in the same tick (a Retry/Repeat
    #: loop) steps its FSM again, as BehaviorTree.CPP calls a stateful action's onStart
    #: again. Off: it gets the reply of its first step (one step per request per tick)
    restart_in_tick: bool = False
    #: a Parallel that reaches its failure rule and its success rule in one tick fails
    #: (py_trees checks for a failed child first); off: success wins (docs/semantics.md 2)
    parallel_failure_first: bool = False
    #: whose names the engine's messages (lints) give btfsm's node types: the node classes'
    #: ``btcpp`` or ``pytrees`` names (``btfsm.bt.names_in``), or btfsm's own (None)
    naming: "str | None" = None

    def node_name(self, btfsm_type: str) -> str:
        """The engine's name of a btfsm node type (the btfsm name when it has no other).

        >>> PROFILES["btcpp"].node_name("MemorySequence"), PROFILES["btfsm"].node_name("MemorySequence")
        ('Sequence', 'MemorySequence')
        """
        return names_in(self.naming).get(btfsm_type, btfsm_type) if self.naming else btfsm_type


PROFILES = {
    "btfsm": Profile("btfsm", "btfsm (docs/semantics.md sections 1-7)"),
    "btcpp": Profile("btcpp", "BehaviorTree.CPP 4.x", halt_before_start=False, parallel_memory=True,
                     loop_wake_up=True, stale_condition=True, restart_in_tick=True, naming="btcpp"),
    "pytrees": Profile("pytrees", "py_trees 2.6", halt_before_start=False, parallel_failure_first=True,
                       naming="pytrees"),
}
SEMANTICS = tuple(PROFILES)
DEFAULT_SEMANTICS = "btfsm"
#: How the main loop ticks a BehaviorTree.CPP tree (``Model.tick``, the file's ``tick:``,
#: ``--tick``): ``once`` is ``Tree::tickOnce()``, which ticks the root again while it returns
#: RUNNING and a wake-up signal is pending (Retry/Repeat/SequenceWithMemory emit one);
#: ``exactly-once`` is ``tickExactlyOnce()``. Only ``btcpp`` has wake-ups (switch
#: ``loop_wake_up``): under the other profiles both are the same (docs/semantics.md 8.1)
TICKS = ("once", "exactly-once")
DEFAULT_TICK = "once"


def profile(name: str) -> Profile:
    """The profile called ``name``; ValueError naming the choices otherwise."""
    try:
        return PROFILES[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown semantics {name!r} (one of: {', '.join(SEMANTICS)})") from None
