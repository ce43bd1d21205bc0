"""One test suite for every oracle (``btfsm.oracles.Oracle``, what ``Program.step`` asks),
parametrized over the implementations (the pattern of dd's ``tests/common.py``): the
library's (``FirstOracle``, ``SucceedOracle``, ``ScriptOracle``, ``RandomOracle``,
the checker's ``EnumOracle``, replay's ``ReplayOracle`` and ``AnswerOracle``, the
runtime's oracle over implementations) and the tests' own (``ModOracle``,
``TableOracle``, ``_Watch``).

What every oracle must do: be declared against the Protocol, answer within range (an
environment event happens or not, an index into the enabled options, an index into the
primitive's outcomes), give only ticks the model allows (the step is one of those
``all_choices`` enumerates, the brute force), and answer alike when built alike.
"""
from __future__ import annotations

import pytest

from btfsm.clock import Clock
from btfsm.oracles import FirstOracle, Oracle, RandomOracle, ScriptOracle, SucceedOracle, all_choices
from btfsm.runtime import Runtime
from btfsm.semantics import Site
from btfsm.trace import AnswerOracle, ReplayOracle, tick_record
from btfsm.verify.search import EnumOracle

from core_strategies import ModOracle, TableOracle, every_question_model
from oracle_bruteforce import _Watch


MODEL = every_question_model()
PROG = MODEL.program


def _reachable(limit: int = 40) -> list:
    seen, todo = [PROG.initial], [PROG.initial]
    while todo and len(seen) < limit:
        s = todo.pop(0)
        for _, st, _ in all_choices(PROG.step, s):
            if st.state is not None and st.state not in seen:
                seen.append(st.state)
                todo.append(st.state)
    return seen


STATES = _reachable()


class _Ref:
    """One tick from ``state`` as the brute force takes it: its script, its Step (events
    recorded) and its answers (``EnumOracle.picks``)."""

    def __init__(self, state, script):
        self.state, self.script = state, script
        o = EnumOracle(script)
        self.step = PROG.step(state, o, True)
        self.picks = list(o.picks)

    def event_names(self) -> set:
        names = set()
        for p in self.picks:
            if p[0] == "env" and p[2] == 1:
                names.add(PROG.env[p[1]][0])
            elif p[0] == "choice":
                names.add(PROG.env[p[1]][3][p[2]][0])
        return names

    def outcome_indices(self) -> list:
        return [k for p, k in ((p[0], p[1]) for p in self.picks) if isinstance(p, Site)]

    def table_script(self) -> str:
        return " ".join(f"{site.label}:{site.outcomes[k][2]}" for site, k in
                        ((p[0], p[1]) for p in self.picks) if isinstance(site, Site))


def _runtime(ref):
    rt = Runtime(MODEL, {}, fallback=ScriptOracle([k for k in ref.outcome_indices()]))
    o = rt._oracle  # the runtime's oracle (over implementations; here none: the fallback answers)
    o.reset(ref.event_names())
    return o


#: name -> oracle made for one reference tick (same arguments, same oracle)
IMPLEMENTATIONS = {
    "FirstOracle": lambda ref: FirstOracle(),
    "SucceedOracle": lambda ref: SucceedOracle(),
    "ScriptOracle": lambda ref: ScriptOracle(ref.script),
    "RandomOracle": lambda ref: RandomOracle(seed=len(ref.script) * 7 + sum(ref.script)),
    "EnumOracle": lambda ref: EnumOracle(ref.script),
    "ReplayOracle": lambda ref: ReplayOracle(PROG, tick_record(PROG, Clock(MODEL.tick_rate), ref.step, {})),
    "AnswerOracle": lambda ref: AnswerOracle(PROG, ref.event_names(), ref.outcome_indices()),
    "Runtime": _runtime,
    "tests.ModOracle": lambda ref: ModOracle(ref.script),
    "tests.TableOracle": lambda ref: TableOracle(PROG, ref.table_script(), " ".join(sorted(ref.event_names()))),
    "tests._Watch": lambda ref: _Watch(ref.script),
}
#: the oracles that answer what they were given: they take the reference tick itself
REPLAYING = {"ScriptOracle", "EnumOracle", "ReplayOracle", "AnswerOracle", "Runtime", "tests.TableOracle",
             "tests._Watch"}


class _Checked(Oracle):
    """Passes every question on and checks that the answer is in range."""

    def __init__(self, inner: Oracle):
        self.inner, self.asked = inner, []

    def env(self, i: int) -> bool:
        assert 0 <= i < len(PROG.env)
        a = self.inner.env(i)
        assert a is True or a is False, f"env({i}) answered {a!r}"
        self.asked.append(("env", i, a))
        return a

    def choose(self, i, enabled) -> int:
        k = self.inner.choose(i, enabled)
        assert type(k) is int and 0 <= k < len(enabled), f"choose({i}, {enabled}) answered {k!r}"
        self.asked.append(("choose", i, k))
        return k

    def outcome(self, site: Site) -> int:
        k = self.inner.outcome(site)
        assert type(k) is int and 0 <= k < len(site.outcomes), f"outcome({site.label}) answered {k!r}"
        self.asked.append(("outcome", site.label, k))
        return k

    def halt(self, site: Site) -> None:
        assert self.inner.halt(site) is None
        self.asked.append(("halt", site.label))

    def __getattr__(self, name):  # request(...) and the like, when the oracle has them
        return getattr(self.inner, name)


def _refs() -> list:
    out = []
    for s in STATES:
        out.extend(_Ref(s, script) for script, st, _ in all_choices(PROG.step, s) if st.state is not None)
    return out


REFS = _refs()


def test_the_model_asks_every_question():
    kinds = {a[0] for ref in REFS for a in _asked(ScriptOracle(ref.script), ref.state)}
    assert kinds == {"env", "choose", "outcome", "halt"}
    assert len(STATES) > 5 and len(REFS) > 50


def _asked(oracle, state) -> list:
    c = _Checked(oracle)
    PROG.step(state, c, True)
    return c.asked


@pytest.mark.parametrize("name", sorted(IMPLEMENTATIONS))
def test_declared_against_the_protocol(name):
    cls = type(IMPLEMENTATIONS[name](REFS[0]))
    assert Oracle in cls.__mro__, f"{cls.__name__} does not derive from btfsm.oracles.Oracle"
    for method in ("env", "choose", "outcome", "halt"):  # the Protocol's own bodies answer None
        owner = next(c for c in cls.__mro__ if method in vars(c))
        assert owner is not Oracle, f"{cls.__name__}.{method} is the Protocol's stub"


@pytest.mark.parametrize("name", sorted(IMPLEMENTATIONS))
def test_answers_are_ticks_the_model_allows(name):
    """Every answer in range, and the tick is one the brute force enumerates; the
    replaying oracles give exactly the reference tick."""
    make = IMPLEMENTATIONS[name]
    allowed = {s: {(st.state, st.status) for _, st, _ in all_choices(PROG.step, s)} for s in STATES}
    for ref in REFS:
        step = PROG.step(ref.state, _Checked(make(ref)), True)
        assert (step.state, step.status) in allowed[ref.state], f"{name} from {ref.state}: a tick the model does not allow"
        if name in REPLAYING:
            assert (step.state, step.status, step.events) == (ref.step.state, ref.step.status, ref.step.events)


@pytest.mark.parametrize("name", sorted(IMPLEMENTATIONS))
def test_same_oracle_same_tick(name):
    make = IMPLEMENTATIONS[name]
    for ref in REFS[::5]:
        a, b = _Checked(make(ref)), _Checked(make(ref))
        sa, sb = PROG.step(ref.state, a, True), PROG.step(ref.state, b, True)
        assert (sa.state, sa.status, sa.events, a.asked) == (sb.state, sb.status, sb.events, b.asked)
