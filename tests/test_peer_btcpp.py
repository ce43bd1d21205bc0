"""btfsm's ``btcpp`` profile against real BehaviorTree.CPP 4 (``behaviortreepy``), tick by tick.

Hypothesis draws random trees over every control and decorator node the exporter writes
(thresholds and counts included) with async actions (stateful: RUNNING possible), instant
actions and conditions whose answers are a pure function of (leaf, tick). Each tree goes
through ``btfsm.interop.btcpp_export.to_btcpp_xml`` into the real engine and through
``Program.step`` under ``semantics: btcpp``; the root status and the leaf callbacks (start,
run, halt, tick, cond, in order) must be identical on every tick. docs/semantics.md 8.1.
"""
from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

pytest.importorskip("behaviortreepy")

from btcpp_peer import compare  # noqa: E402

TICKS = 8
TREES = 1000

_COMPOSITES = ("ReactiveSequence", "MemorySequence", "SequenceWithMemory", "ReactiveFallback", "MemoryFallback",
               "Parallel", "ParallelAll", "IfThenElse", "WhileDoElse")
_DECORATORS = ("Inverter", "ForceSuccess", "ForceFailure", "Retry", "Repeat", "KeepRunningUntilFailure", "RunOnce")


@st.composite
def trees(draw, depth=4):
    counter = iter(range(1000))

    def node(d):
        if d == 0 or draw(st.integers(0, 3)) == 0:
            kind = draw(st.sampled_from(("async", "async", "sync", "cond")))
            alphabet = "SFR" if kind == "async" else "SF"
            table = "".join(draw(st.lists(st.sampled_from(alphabet), min_size=TICKS, max_size=TICKS)))
            return (kind, f"L{next(counter)}", table)
        name = f"n{next(counter)}"
        if draw(st.booleans()):
            t = draw(st.sampled_from(_COMPOSITES))
            lo, hi = (2, 3) if t in ("IfThenElse", "WhileDoElse") else (1, 4)
            kids = [node(d - 1) for _ in range(draw(st.integers(lo, hi)))]
            n = len(kids)
            params = {}
            if t == "Parallel":
                s = draw(st.integers(-n, n).filter(lambda x: x != 0))
                f = draw(st.integers(-n, n).filter(lambda x: x != 0))
                params = {"success_threshold": s, "failure_threshold": f}
            elif t == "ParallelAll":
                params = {"max_failures": draw(st.integers(1, n))}
            return (t, name, kids, params)
        t = draw(st.sampled_from(_DECORATORS))
        params = {}
        if t == "Retry":
            params = {"attempts": draw(st.integers(1, 3))}
        elif t == "Repeat":
            params = {"times": draw(st.integers(1, 3))}
        elif t == "RunOnce":
            params = {"then_skip": False}
        return (t, name, node(d - 1), params)
    return node(depth)


def _show(spec, a, b, xml):
    lines = [f"spec: {spec}", xml]
    for k, (x, y) in enumerate(zip(a, b)):
        mark = "  " if x == y else "!!"
        lines.append(f"{mark} tick {k}: btcpp {x}\n{mark}         btfsm {y}")
    return "\n".join(lines)


@settings(derandomize=True, max_examples=TREES, deadline=None, database=None,
          suppress_health_check=list(HealthCheck))
@given(trees())
def test_peer_btcpp_random_trees(spec):
    a, b, xml = compare(spec, TICKS)
    assert a == b, _show(spec, a, b, xml)
