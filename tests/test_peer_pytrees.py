"""The ``pytrees`` profile against real py_trees 2.6, tick by tick, on random trees.

Hypothesis draws trees of every py_trees composite and decorator btfsm maps
(docs/semantics.md section 8.2): Sequence/Selector with memory True/False, Parallel with
SuccessOnAll (synchronise or not), SuccessOnOne and SuccessOnSelected (synchronise or
not), Inverter, FailureIsSuccess, SuccessIsFailure, Retry, Repeat and EternalGuard.
Each tree is built in py_trees by ``btfsm.interop.pytrees.to_pytrees`` and run as a btfsm
model under ``semantics="pytrees"``; the leaf lifecycles (start, tick, halt, in order)
and the root statuses must be identical (``tests/pytrees_peer.py``).
"""
from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings
from memo_strategies import st

pytest.importorskip("py_trees")

from btfsm import (FailureIsRunning, ForceFailure, ForceSuccess, Guard, Inverter, KeepRunningUntilFailure,  # noqa: E402
                   MemoryFallback, MemorySequence, Parallel, ReactiveFallback, ReactiveSequence, Repeat, Retry,
                   RunningIsFailure, RunningIsSuccess)
from pytrees_peer import (STATUS, KeyedBehaviour, build_pytrees, leaf, run_btfsm, run_imported,  # noqa: E402
                          run_pytrees, tick_pytrees)

TICKS = 8
TREES = 1200
IMPORTED_TREES = 300


@st.composite
def peer_trees(draw, max_depth=3):
    """(tree, table): a random tree and each leaf's / guard's answer on every tick."""
    table: dict = {}
    counter = [0]

    def answers(statuses):
        return "".join(draw(st.lists(st.sampled_from(statuses), min_size=TICKS, max_size=TICKS)))

    def name(prefix):
        counter[0] += 1
        return f"{prefix}{counter[0]}"

    def node(depth):
        kinds = ["leaf"] * 3
        if depth > 0:
            kinds += ["RSeq", "MSeq", "RFb", "MFb", "Par", "Par", "Inv", "FS", "FF", "Retry", "Repeat", "Guard", "Forever",
                      "FIR", "RIF", "RIS"]
        k = draw(st.sampled_from(kinds))
        if k == "leaf":
            n = name("a")
            table[n] = answers(draw(st.sampled_from(["RSF", "SF", "RS", "RF", "S", "F", "R"])))
            return leaf(n, table[n])
        if k in ("RSeq", "MSeq", "RFb", "MFb", "Par"):
            kids = [node(depth - 1) for _ in range(draw(st.integers(1, 3)))]
            n = name(k.lower())
            if k != "Par":
                return {"RSeq": ReactiveSequence, "MSeq": MemorySequence, "RFb": ReactiveFallback, "MFb": MemoryFallback}[k](n, kids)
            policy = draw(st.sampled_from(["all", "all_sync", "one", "selected", "selected_sync"]))
            sync = policy.endswith("sync")
            if policy.startswith("all"):
                return Parallel(n, kids, synchronise=sync)
            if policy == "one":
                return Parallel(n, kids, success_threshold=1)
            chosen = draw(st.lists(st.sampled_from([c.name for c in kids]), min_size=1, unique=True))
            return Parallel(n, kids, selected=tuple(c for c in (x.name for x in kids) if c in chosen), synchronise=sync)
        child = node(depth - 1)
        n = name(k.lower())
        if k == "Retry":
            return Retry(n, child, draw(st.integers(1, 3)))
        if k == "Repeat":
            return Repeat(n, child, draw(st.integers(1, 3)))
        if k == "Forever":
            return KeepRunningUntilFailure(n, child)
        if k in ("FIR", "RIF", "RIS"):
            return {"FIR": FailureIsRunning, "RIF": RunningIsFailure, "RIS": RunningIsSuccess}[k](n, child)
        if k == "Guard":
            table[n] = answers("SSF")
            return Guard(n, child, f"{n}_open")
        return {"Inv": Inverter, "FS": ForceSuccess, "FF": ForceFailure}[k](n, child)

    tree = node(draw(st.integers(1, max_depth)))
    return tree, table


@settings(max_examples=TREES, derandomize=True, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(peer_trees())
def test_random_trees_match_real_py_trees(case):
    tree, table = case
    assert run_btfsm(tree, table, TICKS) == run_pytrees(tree, table, TICKS)


# Names py_trees accepts and btfsm's first importer refused or mangled: collisions with the
# "_2" suffix, unicode, spaces, guards whose derived variables collide, names btfsm cannot
# carry as they are (empty, a line break, a template placeholder, 300 characters), keywords.
HOSTILE_NAMES = ["a", "a_2", "a_3", "a", "Tür offen", "g 1", "g_1", "g-1", "", " ", "x\ny", "${x}",
                 "é" * 300, "if", "true", "1", "ok", "ok_2", "\u200b"]


def _blackboard_behaviour(data, name):
    import operator

    import py_trees
    key, value = data.draw(st.sampled_from(["x", "y"])), data.draw(st.integers(0, 2))
    if data.draw(st.booleans()):
        return py_trees.behaviours.SetBlackboardVariable(name, key, value, overwrite=True)
    op = data.draw(st.sampled_from([operator.eq, operator.ne, operator.lt, operator.ge]))
    return py_trees.behaviours.CheckBlackboardVariableValue(name, py_trees.common.ComparisonExpression(key, value, op))


def _swap(old, new):
    """Put behaviour ``new`` where ``old`` is in its tree (py_trees has no call for it)."""
    new.peer_key = getattr(old, "peer_key", None)
    parent = old.parent
    new.parent = parent
    if parent is not None:
        parent.children[parent.children.index(old)] = new
        if getattr(parent, "decorated", None) is old:
            parent.decorated = new
        chosen = getattr(getattr(parent, "policy", None), "children", None)  # SuccessOnSelected
        if chosen and any(c is old for c in chosen):
            chosen[[id(c) for c in chosen].index(id(old))] = new


@settings(max_examples=IMPORTED_TREES, derandomize=True, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(peer_trees(), st.data())
def test_imported_trees_with_hostile_names_match_real_py_trees(case, data):
    """The user's path: a tree built in py_trees (renamed with names drawn from
    HOSTILE_NAMES; Retry(num_failures=1) also written 0 or -2; Repeat forever written -1, 0,
    2.5 or as SuccessIsRunning; some leaves replaced by CheckBlackboardVariableValue and
    SetBlackboardVariable on keys x and y; sometimes a BehaviourTree instead of its root) is imported with from_pytrees
    and ticked by btfsm; it must do what real py_trees does with it."""
    import py_trees
    tree, table = case
    log: list = []
    clock = [0]
    root = build_pytrees(tree, table, log, clock)
    leaves: dict = {}
    py_trees.blackboard.Blackboard.clear()
    for i, b in enumerate(list(root.iterate())):
        if not isinstance(b, KeyedBehaviour):
            b.peer_key = b.name
        elif data.draw(st.integers(0, 3)) == 0:  # py_trees' blackboard behaviours, on keys x and y
            new = _blackboard_behaviour(data, f"bb{i}")
            _swap(b, new)
            new.peer_key = "blackboard"  # not a table row: the oracle is not asked, nothing is logged
            root = new if b is root else root
            continue
        if data.draw(st.booleans()):
            b.name = data.draw(st.sampled_from(HOSTILE_NAMES))
        if isinstance(b, py_trees.decorators.Retry) and b.num_failures == 1:
            b.num_failures = data.draw(st.sampled_from([1, 0, -2]))
        if isinstance(b, py_trees.decorators.Repeat) and b.num_success == -1:
            b.num_success = data.draw(st.sampled_from([-1, 0, 2.5, "SuccessIsRunning"]))
            if b.num_success == "SuccessIsRunning":  # the same rule, py_trees' other spelling
                new = py_trees.decorators.SuccessIsRunning(name=b.name, child=b.decorated)
                _swap(b, new)
                root = new if b is root else root
    for b in root.iterate():
        if isinstance(b, KeyedBehaviour):
            leaves.setdefault(b.name, set()).update(STATUS[a].name.lower() for a in table[b.key])
    subject = py_trees.trees.BehaviourTree(root) if data.draw(st.booleans()) else root
    ours = run_imported(subject, table, TICKS, {k: sorted(v) for k, v in leaves.items()})
    assert ours == tick_pytrees(root, log, clock, TICKS)
