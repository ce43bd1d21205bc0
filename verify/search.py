"""The pieces every exploration engine shares: the enumerating oracle (``EnumOracle``),
the environment step (``run_environment``) and the default budget.
"""
from __future__ import annotations

from btfsm.oracles import ScriptOracle

__all__ = ["EnumOracle", "run_environment", "DEFAULT_MAX_STATES"]

DEFAULT_MAX_STATES = 5_000_000


class EnumOracle(ScriptOracle):
    """A ``ScriptOracle`` that also keeps ``picks``: every answer in a state-independent
    form (``("env", i, 0|1)``, ``("choice", i, option)``, ``(site, outcome)`` for every
    primitive that ran, single-outcome ones included). ``picks`` name a transition.

    Same answers and records as ``ScriptOracle`` (script entry k answers choice point k, 0
    past the end; ``arities``, ``labels``, ``taken``); the bookkeeping is inlined because
    this is the innermost loop of exploration. Scripts are assumed valid (they are made
    from the arities recorded on the same prefix)."""

    __slots__ = ("picks",)

    def __init__(self, script=()):
        self.script, self.pos = script, 0
        self.arities, self.labels, self.taken, self.picks = [], [], [], []

    def env(self, i):
        k = self.pos
        self.pos = k + 1
        s = self.script
        c = s[k] if k < len(s) else 0
        self.arities.append(2)
        self.labels.append(("env", i))
        self.taken.append(c)
        self.picks.append(("env", i, c))
        return c == 1

    def choose(self, i, enabled):
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

    def outcome(self, site):
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


def run_environment(env, s, oracle, indices=None, rec=None) -> bool:
    """Apply the environment entries ``env`` (``Program.env``; only those at ``indices``
    when given) to the state list ``s`` in place, asking ``oracle`` like ``Program.step``
    does (docs/semantics.md, tick step 1); ``rec`` collects env and write events.
    Returns False when a choice has no enabled option (the tick cannot happen)."""
    for i in (range(len(env)) if indices is None else indices):
        name, guard, eff, options = env[i]
        if options is not None:
            enabled = [k for k, o in enumerate(options) if o[1] is None or o[1](s)]
            if not enabled:
                return False
            name, _, eff, _ = options[enabled[oracle.choose(i, enabled)] if len(enabled) > 1 else enabled[0]]
        elif not ((guard is None or guard(s)) and oracle.env(i)):
            continue
        if eff is not None:
            eff(s)
        if rec is not None:
            rec.append(("env", name))
            if eff is not None:
                rec.extend(("write", k, s[k]) for k in eff.targets)
    return True
