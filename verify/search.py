"""The pieces every exploration engine shares: the enumerating oracle (``EnumOracle``),
the environment step (``run_environment``), the budgets (``Budget``) and the engines'
interfaces (``Search``: what ``btfsm.verify.scalar.search`` and
``btfsm.verify.traced.search`` are, each given a ``SearchTask``; ``Explorer``: a whole exploration with its budgets, what
``btfsm.verify.vector.explore`` is; tests/test_engines_shared.py runs one suite over them).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Protocol, Sequence

from btfsm.oracles import ScriptOracle

if TYPE_CHECKING:
    from btfsm.model import Model
    from btfsm.semantics import Site, Step

    from .explore import OpenFSM
    from .system import TransitionSystem

__all__ = ["EnumOracle", "run_environment", "DEFAULT_MAX_STATES", "DEFAULT_MAX_TRANSITIONS", "Budget", "BudgetExceeded",
           "describe_hit", "HIT_WORDS", "Search", "SearchTask", "Explorer", "Progress", "Run"]

DEFAULT_MAX_STATES = 5_000_000
DEFAULT_MAX_TRANSITIONS = 50_000_000  # the command line's default: about 1.3 GB of transition arrays


class EnumOracle(ScriptOracle):
    """A ``ScriptOracle`` that also keeps ``picks``: every answer in a state-independent
    form (``("env", i, 0|1)``, ``("choice", i, option)``, ``(site, outcome)`` for every
    primitive that ran, single-outcome ones included). ``picks`` name a transition.

    Same answers and records as ``ScriptOracle`` (script entry k answers choice point k, 0
    past the end; ``arities``, ``labels``, ``taken``); the bookkeeping is inlined because
    this is the innermost loop of exploration. Scripts are assumed valid (they are made
    from the arities recorded on the same prefix)."""

    __slots__ = ("picks", "seen", "cut", "outer", "ran", "seen_picks")

    def __init__(self, script=(), seen=None):
        self.script, self.pos = script, 0
        self.arities, self.labels, self.taken, self.picks = [], [], [], []
        self.seen, self.cut, self.ran = seen, None, None

    def merge(self, node, s, violations, fsm_done, reticks=()):
        """Merging in-tick retries (``seen``: a dict shared by every run of one enumeration of
        a state's successors; None: off). ``Program.step`` calls this where a loop node
        (a RecoveryNode, ``Program.merge_points``) starts a retry within the tick; from there
        the rest of the tick depends only on ``s``, the violations, FSM records and tickOnce
        re-ticks so far (the tick's whole context there). The first run to reach that
        context (with the answers before it: the same environment, and whether a leaf
        answered RUNNING) keeps it; a run reaching it after other answers sets ``cut``:
        it finishes with its default answers, but its choice points from here on are not
        branched (the first run's branches give every ending from here). So every
        (target, status, violations) and every answer and event of a tick is still
        found, each ending once per context (docs/semantics.md 8.3)."""
        if self.seen is None or self.cut is not None:
            return
        picks = self.picks
        if self.ran is None:  # the answers before the tree (environment, request), asked once
            self.outer = tuple(p for p in picks if p[0] == "env" or p[0] == "choice")
            self.ran, self.seen_picks = False, 0
        if not self.ran:  # has a leaf answered RUNNING so far?
            for k in range(self.seen_picks, len(picks)):
                p = picks[k]
                if len(p) == 2 and p[0].outcomes[p[1]][0] == 0:
                    self.ran = True
                    break
            self.seen_picks = len(picks)
        key = (node, tuple(s), tuple(violations), frozenset(fsm_done.items()) if fsm_done else None, reticks,
               self.outer, self.ran)
        prefix = tuple(self.taken)
        if self.seen.setdefault(key, prefix) != prefix:
            self.cut = self.pos

    def env(self, i: int) -> bool:
        k = self.pos
        self.pos = k + 1
        s = self.script
        c = s[k] if k < len(s) else 0
        self.arities.append(2)
        self.labels.append(("env", i))
        self.taken.append(c)
        self.picks.append(("env", i, c))
        return c == 1

    def choose(self, i: int | tuple[Any, ...], enabled: Sequence[Any]) -> int:
        if len(enabled) == 1:
            return 0  # a lone option is no choice (as in ScriptOracle)
        k = self.pos
        self.pos = k + 1
        s = self.script
        c = s[k] if k < len(s) else 0
        self.arities.append(len(enabled))
        self.labels.append(("choice", i))
        self.taken.append(c)
        self.picks.append(("choice", i, enabled[c]))
        return c

    def outcome(self, site: Site) -> int:
        n = len(site.outcomes)
        if n == 1:
            self.picks.append((site, 0))
            return 0
        k = self.pos
        self.pos = k + 1
        s = self.script
        c = s[k] if k < len(s) else 0
        self.arities.append(n)
        self.labels.append(site)
        self.taken.append(c)
        self.picks.append((site, c))
        return c


def run_environment(program, s, oracle, indices=None, rec=None) -> bool:
    """Apply the environment of ``program`` (only the entries at ``indices`` when given)
    to the state list ``s`` in place, asking ``oracle``: ``Program.environment_phase``, the
    same code ``Program.step`` runs (docs/semantics.md, tick step 1); ``rec`` collects env
    and write events. Returns False when a choice has no enabled option."""
    return program.environment_phase(s, oracle, rec, indices) is None


clock = time.monotonic  # the budgets' clock (module-level so that tests can drive it: tests/test_budgets.py)


class Budget:
    """The bounds of one exploration: ``max_states`` (states numbered), ``max_transitions``
    (transitions kept), ``max_seconds`` (wall time, read from a monotonic clock here in the
    checker only, never in the model or the simulator). None: no bound. The clock starts
    when the Budget is made, so a fallback from one engine to another shares it.

    An engine that hits a bound stops, keeps what it explored and sets ``hit`` to
    ``"states"``, ``"transitions"``, ``"seconds"`` (or ``"paths"``: the traced engine's
    decision trie grew past what it may trace, see ``btfsm.verify.traced``; ``"rows"``: a
    state of the vectorised engine may split into more rows than it holds). Without a time
    bound, what is explored does not depend on the clock.

    >>> b = Budget(max_states=10)
    >>> b.states_left(7), b.transitions_left(7), b.out_of_time()
    (3, None, False)
    """

    __slots__ = ("max_states", "max_transitions", "max_seconds", "start", "hit")

    def __init__(self, max_states: "int | None" = None, max_transitions: "int | None" = None,
                 max_seconds: "float | None" = None) -> None:
        self.max_states = None if max_states is None else max(int(max_states), 1)
        self.max_transitions = None if max_transitions is None else max(int(max_transitions), 0)
        self.max_seconds = None if max_seconds is None else float(max_seconds)
        self.start = clock()
        self.hit: "str | None" = None

    def states_left(self, n: int):
        return None if self.max_states is None else self.max_states - n

    def transitions_left(self, nt: int):
        return None if self.max_transitions is None else self.max_transitions - nt

    def out_of_time(self) -> bool:
        return self.max_seconds is not None and clock() - self.start >= self.max_seconds

    def elapsed(self) -> float:
        return clock() - self.start

    def describe(self) -> str:
        """``"state budget (--max-states 1000)"`` for the bound that was hit ("" if none)."""
        return describe_hit(self.hit, self.max_states, self.max_transitions, self.max_seconds)


HIT_WORDS = {"states": "state", "transitions": "transition", "seconds": "time", "paths": "path", "rows": "row"}


def describe_hit(hit, max_states=None, max_transitions=None, max_seconds=None) -> str:
    """Words for a budget that was hit (``Budget.hit``)."""
    if hit == "states":
        return f"state budget (--max-states {max_states:,})" if max_states is not None else "state budget"
    if hit == "transitions":
        return (f"transition budget (--max-transitions {max_transitions:,})" if max_transitions is not None
                else "transition budget")
    if hit == "seconds":
        return f"time budget (--max-seconds {max_seconds:g})" if max_seconds is not None else "time budget"
    if hit == "rows":
        return "row budget of the vectorised engine (one state splits into too many rows)"
    if hit == "paths":
        return "path budget of the traced engine (use --engine scalar)"
    return ""


class BudgetExceeded(Exception):
    """Raised by searches that cannot return a partial result (``skills`` support checks);
    ``hit`` names the bound as ``Budget.hit`` does."""

    def __init__(self, hit: str, message: str):
        super().__init__(message)
        self.hit = hit


# ---------------------------------------------------------------------- the engines' interfaces

#: ``progress(states, transitions, seconds)``, called by an engine as it goes
Progress = Callable[[int, int, float], Any]
#: one transition: ``run(state, oracle, record=False) -> Step`` (``Program.step``, or
#: ``OpenFSM.run`` at FSM level)
Run = Callable[..., "Step"]


@dataclass(frozen=True)
class SearchTask:
    """One system for an engine to explore (``Search``): breadth-first from ``initial`` by
    ``run``, states coded over the ``kept`` slots; ``kind`` is ``"model"``, or ``"fsm"``
    with the FSM's name ``fsm`` and its ``OpenFSM`` ``op``; ``progress(states, transitions,
    seconds)`` is called as the engine goes (None: not)."""

    model: Model
    kind: str
    fsm: str | None
    kept: tuple[int, ...]
    run: Run
    initial: tuple[int, ...]
    progress: Progress | None = None
    op: OpenFSM | None = None


class Search(Protocol):
    """An exploration engine of ``btfsm.verify.explore`` (``scalar.search``,
    ``traced.search``; ``explore._explore_with`` picks one): the system of a
    ``SearchTask``; the search stops at the first bound of ``budget`` (mutable: it records
    which bound was hit in ``budget.hit``; None: unbounded). Engines give the same system,
    numbering included. (An engine may take more arguments after these, with defaults: the
    scalar engine's ``split``, the traced engine's ``fallback``.)"""

    def __call__(self, task: SearchTask, budget: Budget | None, /) -> TransitionSystem: ...


class Explorer(Protocol):
    """A whole exploration: the model (``fsm`` None) or its FSM ``fsm`` as an open system
    (requests for ``goals``, all when None) to its ``TransitionSystem``, under the budgets
    (None: unbounded; see ``Budget``): ``btfsm.verify.vector.explore``; and the scalar,
    traced and auto engines as ``btfsm.verify.explore.explore`` (``fsm`` None) or
    ``explore_fsm`` with ``engine=`` their name (tests/test_engines_shared.py)."""

    def __call__(self, model: Model, *, fsm: str | None = None, goals: Sequence[str] | None = None,
                 max_states: int | None = None, max_transitions: int | None = None,
                 max_seconds: float | None = None, progress: Progress | None = None) -> TransitionSystem: ...
