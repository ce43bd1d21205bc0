"""Oracles answer the step function's questions (environment events, primitive outcomes).

``Oracle`` is the interface (a ``typing.Protocol``: what ``Program.step`` asks); every
oracle of the library and of the tests is declared against it (tests/test_oracles_shared.py
runs one suite over them all).

* ``FirstOracle``: no event happens, every primitive has its first declared outcome.
* ``ScriptOracle``: answers from a list of choices and records every choice point; the
  model checker enumerates choice lists with it, replay feeds it a trace.
* ``RandomOracle``: seeded random answers, for simulating a model without implementations.

Only real choices (two or more options) consume a script entry.

>>> o = ScriptOracle([1])
>>> o.env(0), o.env(1), o.arities
(True, False, [2, 2])
"""
from __future__ import annotations

import random
from typing import TYPE_CHECKING, Any, Protocol, Sequence

if TYPE_CHECKING:
    from .semantics import Site

__all__ = ["Oracle", "FirstOracle", "SucceedOracle", "ScriptOracle", "RandomOracle", "all_choices"]


class Oracle(Protocol):
    """What the step function asks (``Program.step``, docs/semantics.md). Answers must be
    deterministic functions of the oracle's own state: the checker re-runs a tick with the
    same oracle to rebuild a transition.

    An oracle may also have ``request(fsm_index, goal_index)``: the step function then tells
    it the goal an FSM is driven toward, before the FSM's state runs (``btfsm.runtime``
    uses it; it is looked up with ``getattr``, so it is not part of this Protocol)."""

    __slots__ = ()

    def env(self, i: int) -> bool:
        """Does enabled environment event ``i`` (an index into ``Program.env``) happen this tick?"""
        ...

    def choose(self, i: int | tuple[Any, ...], enabled: Sequence[Any]) -> int:
        """An index into ``enabled`` (the enabled options of choice point ``i``: the index of
        an environment choice in ``Program.env``, or at FSM level, ``OpenFSM.run`` in
        ``btfsm.verify.explore``, ``("goal",)``, ``("param", slot)`` or ``("input", slot)``)."""
        ...

    def outcome(self, site: Site) -> int:
        """Which of ``site.outcomes`` the primitive running at ``site`` had this tick."""
        ...

    def halt(self, site: Site) -> None:
        """The running primitive at ``site`` was abandoned (preempted, halted by its parent)."""
        ...


class FirstOracle(Oracle):
    def env(self, i: int) -> bool:
        return False

    def choose(self, i: int | tuple[Any, ...], enabled: Sequence[Any]) -> int:
        """Index into ``enabled`` (the enabled options of choice ``i``)."""
        return 0

    def outcome(self, site: Site) -> int:
        return 0

    def halt(self, site: Site) -> None:
        pass


class SucceedOracle(FirstOracle):
    """No event happens and every primitive has its first SUCCESS outcome (the first
    outcome when it declares none): the authors' stub primitives, which succeed at once."""

    def outcome(self, site: Site) -> int:
        for k, o in enumerate(site.outcomes):
            if o[0] == 1:  # Status.SUCCESS
                return k
        return 0


class ScriptOracle(Oracle):
    """Answers choice point k with ``script[k]`` (0 past its end) and records arities.

    ``labels[k]`` says what point k was: ``("env", i)`` or the primitive's Site."""

    __slots__ = ("script", "pos", "arities", "labels", "taken")

    def __init__(self, script=()):
        self.script, self.pos = tuple(script), 0
        self.arities: list = []
        self.labels: list = []
        self.taken: list = []

    def _choose(self, n: int, label) -> int:
        k = self.pos
        self.pos = k + 1
        self.arities.append(n)
        self.labels.append(label)
        c = self.script[k] if k < len(self.script) else 0
        if not 0 <= c < n:
            raise ValueError(f"choice {c} at point {k} is out of range 0..{n - 1}")
        self.taken.append(c)
        return c

    def env(self, i: int) -> bool:
        return self._choose(2, ("env", i)) == 1

    def choose(self, i: int | tuple[Any, ...], enabled: Sequence[Any]) -> int:
        return 0 if len(enabled) == 1 else self._choose(len(enabled), ("choice", i))

    def outcome(self, site: Site) -> int:
        n = len(site.outcomes)
        return 0 if n == 1 else self._choose(n, site)

    def halt(self, site: Site) -> None:
        pass


class RandomOracle(FirstOracle):
    """Each enabled event happens with probability ``p_env``; outcomes are uniform."""

    def __init__(self, seed: int = 0, p_env: float = 0.5):
        self.rng, self.p_env = random.Random(seed), p_env

    def env(self, i: int) -> bool:
        return self.rng.random() < self.p_env

    def choose(self, i: int | tuple[Any, ...], enabled: Sequence[Any]) -> int:
        return self.rng.randrange(len(enabled)) if len(enabled) > 1 else 0

    def outcome(self, site: Site) -> int:
        return self.rng.randrange(len(site.outcomes))


def all_choices(run, state, oracle_class=ScriptOracle, errors=()):
    """Every way one tick can go from ``state``: yields ``(script, result, oracle)`` for
    each complete choice script (DFS over the choice tree; ``run(state, oracle)`` is
    ``Program.step`` or another step function). An exception of a type in ``errors`` is
    yielded as the result instead of a Step.

    >>> from btfsm import Model, Bool, EnvEvent
    >>> m = Model("m", [Bool("a"), Bool("b")], environment=[EnvEvent("x", None, {"a": True}),
    ...                                                     EnvEvent("y", None, {"b": True})])
    >>> sorted(r.state for _, r, _ in all_choices(m.program.step, m.program.initial))
    [(0, 0), (0, 1), (1, 0), (1, 1)]
    """
    stack = [()]
    while stack:
        prefix = stack.pop()
        oracle = oracle_class(prefix)
        try:
            result = run(state, oracle)
        except errors as exc:
            result = exc
        taken = tuple(oracle.taken)
        for k in range(len(prefix), len(oracle.arities)):
            for alt in range(oracle.arities[k] - 1, 0, -1):
                stack.append(taken[:k] + (alt,))
        yield taken, result, oracle
