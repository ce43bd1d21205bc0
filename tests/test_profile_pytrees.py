"""The ``pytrees`` profile, table by table: the node-semantics scenarios of py_trees' own
test suite (tests/test_sequences.py, test_selectors.py, test_parallels.py,
test_decorators.py, test_eternal_guard.py at splintered-reality/py_trees 0d5b39f), each
run in btfsm under ``semantics="pytrees"`` AND in real py_trees 2.6 (the same leaf
lifecycle log and root statuses), plus the section-8 rules of docs/semantics.md and the
``btfsm.interop.pytrees`` round trips.

A scenario's leaves answer from a table (one letter per tick: R, S, F); a stateful
py_trees leaf of the original test (``StatusQueue``, ``SuccessEveryN``) is replaced by
the table of answers it gives in that test.
"""
from __future__ import annotations

import subprocess
import sys
import warnings

import pytest
from hypothesis import HealthCheck, given, settings

py_trees = pytest.importorskip("py_trees")

from btfsm import (Action, ForceFailure, ForceSuccess, Guard, Inverter, KeepRunningUntilFailure, MemoryFallback,  # noqa: E402
                   MemorySequence, ModelError, Parallel, ReactiveFallback, ReactiveSequence,
                   Repeat, Retry, Status)
from btfsm.expr import Const, to_text  # noqa: E402
from btfsm.interop.pytrees import PytreesImportWarning, from_pytrees, to_pytrees  # noqa: E402
from pytrees_peer import build_model, leaf, run_btfsm, run_pytrees  # noqa: E402
from test_peer_pytrees import peer_trees  # noqa: E402


def _tree(table, make):
    """``make(L)`` builds the tree; ``L(name)`` is the leaf answering ``table[name]``."""
    return make(lambda name: leaf(name, table[name]))


def _par(name, kids, policy):
    if policy == "one":
        return Parallel(name, kids, success_threshold=1)
    if policy == "all":
        return Parallel(name, kids)
    if policy == "all_sync":
        return Parallel(name, kids, synchronise=True)
    sync, chosen = policy
    return Parallel(name, kids, synchronise=sync, selected=chosen)


# (scenario, table, tree, expected root statuses); the name says which upstream test
SCENARIOS = [
    ("sequences: running_with_no_memory_children_do_not_reset", {"rs": "RS", "ok": "SS"},
     lambda L: ReactiveSequence("root", [L("rs"), L("ok")]), "RS"),
    ("sequences: running_with_no_memory_invalidate_dangling_runners", {"sr": "SR", "run": "RR"},
     lambda L: ReactiveSequence("root", [L("sr"), L("run")]), "RR"),
    ("sequences: running_with_memory_proceeds", {"ok": "SS", "rs": "RS", "run": "RR"},
     lambda L: MemorySequence("root", [L("ok"), L("rs"), L("run")]), "RR"),
    ("sequences: static_sequence_successes", {"s1": "S", "s2": "S", "s3": "S", "s4": "S"},
     lambda L: MemorySequence("root", [L("s1"), L("s2"), L("s3"), L("s4")]), "S"),
    ("sequences: static_sequence_with_failure", {"s1": "S", "s2": "S", "f": "F", "s3": "S"},
     lambda L: MemorySequence("root", [L("s1"), L("s2"), L("f"), L("s3")]), "F"),
    ("selectors: tick_running_with_no_memory", {"fail_fast": "FS", "run": "RR"},
     lambda L: ReactiveFallback("root", [L("fail_fast"), L("run")]), "RS"),
    ("selectors: with_memory_priority_handling", {"f": "FF", "rf": "RF", "ok": "SS"},
     lambda L: MemoryFallback("root", [L("f"), L("rf"), L("ok")]), "RS"),
    *[(f"parallels: parallel_failure ({p})", {"f": "F", "s": "S"},
       (lambda p: lambda L: _par("root", [L("f"), L("s")], p))(p), "F")
      for p in ("one", "all_sync", "all", (True, ("s",)), (False, ("s",)), (True, ("f",)), (False, ("f",)))],
    ("parallels: parallel_success", {"s1": "S", "s2": "S"},
     lambda L: _par("root", [L("s1"), L("s2")], "all_sync"), "S"),
    ("parallels: parallel_running", {"after1": "RS", "run": "RR", "every2": "FS"},
     lambda L: _par("root", [L("after1"), L("run"), L("every2")], "all_sync"), "FR"),
    ("parallels: parallel_success_on_one", {"r1": "R", "s": "S", "r2": "R"},
     lambda L: _par("root", [L("r1"), L("s"), L("r2")], "one"), "S"),
    ("parallels: parallel_success_on_selected", {"r1": "RR", "s1": "RS", "s2": "RS", "r2": "RR"},
     lambda L: _par("root", [L("r1"), L("s1"), L("s2"), L("r2")], (False, ("s1", "s2"))), "RS"),
    ("parallels: parallel_synchronisation", {"ok": "SSS", "flip": "RSR"},
     lambda L: _par("root", [L("ok"), L("flip")], "all_sync"), "RSR"),
    ("parallels: parallel_no_synchronisation", {"two": "RSRSRS", "three": "RRSRRS"},
     lambda L: _par("root", [L("two"), L("three")], "all"), "RRRRRS"),
    ("decorators: repeat_until_success", {"rss": "RSS"},
     lambda L: Repeat("root", L("rss"), 2), "RRS"),
    ("decorators: repeat_interrupting_failure", {"rsf": "RSF"},
     lambda L: Repeat("root", L("rsf"), 2), "RRF"),
    ("decorators: retry_until_success", {"rfs": "RFS"},
     lambda L: Retry("root", L("rfs"), 2), "RRS"),
    ("decorators: retry_eventual_failure", {"rff": "RFF"},
     lambda L: Retry("root", L("rff"), 2), "RRF"),
    ("decorators: failure_is_success_tree", {"f1": "F", "f2": "F"},
     lambda L: ReactiveFallback("root", [L("f1"), ForceSuccess("fis", L("f2"))]), "S"),
    ("decorators: success_is_failure_tree", {"s1": "S", "s2": "S"},
     lambda L: ReactiveFallback("root", [ForceFailure("sif", L("s1")), L("s2")]), "S"),
    ("decorators: inverter", {"s": "S", "f": "F"},
     lambda L: ReactiveSequence("root", [Inverter("i1", L("f")), Inverter("i2", L("s"))]), "F"),
    # test_eternal_guard: the guard closes while the task sequence runs: its task is halted
    ("eternal_guard: sequence", {"g": "FSSSF", "t1": "RSSSS", "t2": "RRRRR"},
     lambda L: Guard("g", MemorySequence("tasks", [L("t1"), L("t2")]), "g_open"), "FRRRF"),
    # issue 10: ReactiveFallback[A, MemorySequence[B, C]], A fails at once while C runs
    ("issue 10: halt after the new child returned", {"a": "FFF", "b": "SSS", "c": "RRR"},
     lambda L: ReactiveFallback("root", [L("a"), MemorySequence("mem", [L("b"), L("c")])]), "RRR"),
]


@pytest.mark.parametrize("label,table,make,roots", SCENARIOS, ids=[s[0] for s in SCENARIOS])
def test_py_trees_scenarios(label, table, make, roots):
    tree = _tree(table, make)
    ticks = len(roots)
    log = run_btfsm(tree, table, ticks)
    assert [x[1][0] for x in log if x[0] == "root"] == list(roots)
    assert log == run_pytrees(tree, table, ticks)


def _roots(log):
    return "".join(x[1][0] for x in log if x[0] == "root")


def test_profile_parallel_failure_first():
    """A Parallel whose success and failure rules both hold in one tick fails under
    pytrees (py_trees checks for a failed child first), succeeds under btfsm."""
    table = {"s": "S", "f": "F"}
    tree = Parallel("root", [leaf("s", "S"), leaf("f", "F")], success_threshold=1)
    assert _roots(run_btfsm(tree, table, 1, "btfsm")) == "S"
    assert _roots(run_btfsm(tree, table, 1, "pytrees")) == "F" == _roots(run_pytrees(tree, table, 1))


def test_profile_parallel_synchronise():
    """synchronise: a child that succeeded is not ticked again until the parallel
    returns (it counts as a success); without it, every child is ticked every tick."""
    table = {"ok": "SFS", "run": "RSR"}
    for sync, roots, ok_ticks in ((True, "RSR", 2), (False, "RFR", 3)):
        tree = Parallel("root", [leaf("ok", table["ok"]), leaf("run", table["run"])], synchronise=sync)
        for sem in ("btfsm", "pytrees"):
            log = run_btfsm(tree, table, 3, sem)
            assert _roots(log) == roots
            assert sum(1 for x in log if x[:2] == ("tick", "ok")) == ok_ticks
        assert run_btfsm(tree, table, 3) == run_pytrees(tree, table, 3)


def test_profile_parallel_selected():
    """selected (SuccessOnSelected): SUCCESS once every selected child succeeded; the
    others are halted; a failure of any child fails the parallel."""
    table = {"r": "RRR", "s": "RSS", "x": "RRF"}
    tree = Parallel("root", [leaf("r", "RRR"), leaf("s", "RSS"), leaf("x", "RRF")], selected=("s",))
    log = run_btfsm(tree, table, 2)
    assert _roots(log) == "RS" and ("halt", "r") in log and ("halt", "x") in log
    assert log == run_pytrees(tree, table, 2)
    with pytest.raises(ModelError, match="selected"):
        build_model(Parallel("p", [leaf("a", "S")], selected=("nope",))).program
    with pytest.raises(ModelError, match="not both"):
        build_model(Parallel("p", [leaf("a", "S")], success_threshold=1, selected=("a",))).program


# ------------------------------------------------------------------ interop round trips

@settings(max_examples=200, derandomize=True, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(peer_trees())
def test_round_trip_btfsm_to_pytrees_and_back(case):
    """from_pytrees(to_pytrees(model)) gives the model's tree back (leaves' outcomes
    from the mapping, guards as the same '<guard>_open' variables)."""
    tree, table = case
    model = build_model(tree)
    outcomes = {n.name: n.outcomes for n in _leaves(tree)}
    back = from_pytrees(to_pytrees(model, answer=lambda name: "success"), leaves=outcomes)
    assert _normal(back.tree) == _normal(model.tree)
    assert back.semantics == "pytrees"
    assert {v.name for v in back.variables} == {v.name for v in model.variables}


def _normal(n):
    """The same tree with ``Parallel(success_threshold=len(children))`` spelled as the
    default (all children), the one form py_trees cannot tell apart."""
    import dataclasses
    if isinstance(n, Parallel) and n.success_threshold == len(n.children):
        n = dataclasses.replace(n, success_threshold=None)
    if hasattr(n, "children"):
        return dataclasses.replace(n, children=tuple(_normal(c) for c in n.children))
    if getattr(n, "child", None) is not None:
        return dataclasses.replace(n, child=_normal(n.child))
    return n


def _leaves(tree):
    from btfsm import walk
    return [n for n in walk(tree) if isinstance(n, Action)]


def test_from_pytrees_upstream_tree_and_builtin_leaves():
    """A tree written with py_trees' own classes (test_parallels' running scenario)."""
    B, C, D, P = py_trees.behaviours, py_trees.composites, py_trees.decorators, py_trees.common.ParallelPolicy
    S = py_trees.common.Status
    after1 = B.StatusQueue(name="after1", queue=[S.RUNNING], eventually=S.SUCCESS)
    root = C.Selector("root", memory=True, children=[
        C.Parallel("par", policy=P.SuccessOnAll(), children=[after1, B.Running("run"), B.SuccessEveryN("every2", 2)]),
        D.Inverter("inv", C.Sequence("seq", memory=False, children=[B.Success("ok"), B.Failure("ok")])),
        D.PassThrough("pass", B.Dummy("dummy")),
    ])
    m = from_pytrees(root)
    par, inv, dummy = m.tree.children
    assert isinstance(m.tree, MemoryFallback) and m.semantics == "pytrees"
    assert isinstance(par, Parallel) and par.synchronise and par.success_threshold is None
    assert [sorted(o.status.name for o in k.outcomes) for k in par.children] == [
        ["RUNNING", "SUCCESS"], ["RUNNING"], ["FAILURE", "SUCCESS"]]
    assert [k.name for k in inv.child.children] == ["ok", "ok_2"]  # duplicate names made unique
    assert dummy.name == "dummy" and [o.status for o in dummy.outcomes] == [Status.RUNNING]
    selected = C.Parallel("sel", policy=P.SuccessOnSelected([after1 := B.Success("a")], synchronise=False),
                          children=[after1, B.Running("b")])
    assert from_pytrees(selected).tree.selected == ("a",)


def test_from_pytrees_unknown_leaf_warns_and_refuses_what_it_cannot_model():
    class Custom(py_trees.behaviour.Behaviour):
        def update(self):
            return py_trees.common.Status.SUCCESS
    with pytest.warns(PytreesImportWarning, match="tree.mine"):
        m = from_pytrees(py_trees.composites.Sequence("root", memory=True, children=[Custom("mine")]))
    assert {o.status for o in m.tree.children[0].outcomes} == set(Status)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a mapped leaf: no warning
        mapped = from_pytrees(Custom("mine"), leaves={"mine": ["success", "running"]})
    assert [o.status for o in mapped.tree.outcomes] == [Status.SUCCESS, Status.RUNNING]
    timeout = py_trees.decorators.Timeout("slow", py_trees.behaviours.Running("r"), duration=1.0)
    with pytest.raises(ModelError, match=r"tree\.slow: py_trees decorator Timeout has no btfsm counterpart"):
        from_pytrees(py_trees.composites.Selector("root", memory=False, children=[timeout]))
    with pytest.raises(ModelError, match=r"tree\.slow"):  # a BehaviourTree is read as its root
        from_pytrees(py_trees.trees.BehaviourTree(timeout))
    with pytest.raises(ModelError, match=r"tree: expected a py_trees behaviour or BehaviourTree, got int"):
        from_pytrees(3)


def test_from_pytrees_counts_as_py_trees_compares_them():
    """py_trees' Retry fails when its failure count reaches num_failures ("<"): any count
    <= 1 is Retry(1). Its Repeat succeeds when the count *equals* num_success: -1, 0 or a
    count that is not a whole number is never reached (repeat for ever, KeepRunningUntilFailure).
    Peer-tested in tests/test_peer_pytrees.py."""
    D, B = py_trees.decorators, py_trees.behaviours
    for k, attempts in ((0, 1), (-3, 1), (1, 1), (3, 3), (2.5, 3)):
        assert from_pytrees(D.Retry("r", B.Failure("f"), num_failures=k)).tree.attempts == attempts
    for k in (-1, 0, 2.5):
        assert type(from_pytrees(D.Repeat("r", B.Success("s"), num_success=k)).tree) is KeepRunningUntilFailure
    assert from_pytrees(D.Repeat("r", B.Success("s"), num_success=2)).tree.times == 2
    assert from_pytrees(D.Repeat("r", B.Success("s"), num_success=True)).tree.times == 1  # True == 1 in py_trees
    assert type(from_pytrees(D.SuccessIsRunning("r", B.Success("s"))).tree) is KeepRunningUntilFailure
    with pytest.raises(ModelError, match=r"^leaves: expected a mapping of behaviour names, got int"):
        from_pytrees(B.Success("s"), leaves=3)
    with pytest.raises(ModelError, match=r"tree\.r: Retry num_failures inf"):
        from_pytrees(D.Retry("r", B.Failure("f"), num_failures=float("inf")))
    with pytest.raises(ModelError, match=r"tree\.r: Retry num_failures 'x' is not a number"):
        from_pytrees(D.Retry("r", B.Failure("f"), num_failures="x"))


def test_from_pytrees_blackboard_behaviours():
    """CheckBlackboardVariableValue is a Condition, SetBlackboardVariable an Action writing
    the value, over a variable per key and a flag that it exists (peer-tested in
    tests/test_peer_pytrees.py). What depends on Python code or on existence is refused."""
    import operator
    B, CE = py_trees.behaviours, py_trees.common.ComparisonExpression
    root = py_trees.composites.Sequence("root", memory=False, children=[
        B.SetBlackboardVariable("set", "mode", "a b", overwrite=True),
        B.CheckBlackboardVariableValue("is c", CE("mode", "c", operator.ne)),
        B.CheckBlackboardVariableValue("n big", CE("n", 4, operator.ge))])
    m = from_pytrees(root, blackboard={"n": 5})
    assert [(v.name, v.kind, v.init) for v in m.variables] == [
        ("mode", "enum", "a b"), ("mode_exists", "bool", False), ("n", "int", 5), ("n_exists", "bool", True)]
    assert dict(m.tree.children[0].outcomes[0].effects) == {"mode": Const("a b"), "mode_exists": Const(True)}
    assert [to_text(c.expr) for c in m.tree.children[1:]] == ["mode_exists and mode != 'c'", "n_exists and n >= 4"]
    refused = [
        (B.SetBlackboardVariable("s", "k", 1, overwrite=False), "overwrite=False"),
        (B.SetBlackboardVariable("s", "k", lambda: 1, overwrite=True), "computed by Python code"),
        (B.CheckBlackboardVariableValue("s", CE("k.a", 1, operator.eq)), "no nested attributes"),
        (B.CheckBlackboardVariableValue("s", CE("k", 1, operator.contains)), "btfsm models ==, !="),
        (py_trees.composites.Sequence("r", memory=False, children=[
            B.SetBlackboardVariable("s", "k", 1, overwrite=True), B.SetBlackboardVariable("t", "k", "x", True)]),
         "several kinds")]
    for b, why in refused:
        with pytest.raises(ModelError, match=why):
            from_pytrees(b)


def test_from_pytrees_keeps_names_and_resolves_collisions():
    B, C, D = py_trees.behaviours, py_trees.composites, py_trees.decorators
    root = C.Sequence("root", memory=False, children=[
        B.Success("a"), B.Success("a_2"), B.Success("a"),
        D.EternalGuard("Tür offen", B.Running("Tür offen"), condition=lambda: True),
        D.EternalGuard("g 1", B.Running("x"), condition=lambda: True),
        D.EternalGuard("g_1", B.Running("y"), condition=lambda: True),
        B.Success(""), B.Success("line\nbreak"), B.Success("${x}")])
    m = from_pytrees(root, leaves={"Tür offen": ["running", "success"]})
    names = [n.name for n in m.tree.children]
    assert names == ["a", "a_2", "a_3", "Tür offen", "g 1", "g_1", "unnamed", "line_break", "$_{x}"]
    guard = m.tree.children[3]
    assert guard.child.name == "Tür offen_2" and {o.status.name for o in guard.child.outcomes} == {"RUNNING", "SUCCESS"}
    # the leaf's entry is not read as the guard's condition: the guard is a free variable
    assert [v.name for v in m.variables] == ["Tur_offen_open", "g_1_open", "g_1_open_2"]
    assert [str(g.condition.id) for g in m.tree.children[3:6]] == ["Tur_offen_open", "g_1_open", "g_1_open_2"]
    m2 = from_pytrees(root.children[3], guards={"Tür offen": "false"}, leaves={"Tür offen": "running"})
    assert not m2.variables and m2.tree.condition.value is False
    with pytest.raises(ModelError, match=r"tree\.Tür offen\.condition: syntax error"):
        from_pytrees(root.children[3], guards={"Tür offen": "x >"})


def test_from_pytrees_guard_becomes_a_free_variable():
    guard = py_trees.decorators.EternalGuard("door ok", py_trees.behaviours.Running("go"), condition=lambda: True)
    m = from_pytrees(guard)
    assert isinstance(m.tree, Guard) and [v.name for v in m.variables] == ["door_ok_open"]
    assert [e.name for e in m.environment] == ["door_ok_open"]
    m2 = from_pytrees(guard, leaves={"door ok": "false"})  # still read: no leaf has that name
    assert isinstance(m2.tree, Guard) and not m2.variables


def test_to_pytrees_refuses_nodes_without_counterpart():
    from btfsm import Effects
    with pytest.raises(ModelError, match=r"tree\.fx: Effects"):
        to_pytrees(build_model(Effects("fx", leaf("a", "S"))), answer=lambda n: "success")
    with pytest.raises(ModelError, match=r"tree\.p: .*failure_threshold 2"):
        to_pytrees(build_model(Parallel("p", [leaf("a", "S"), leaf("b", "S")], failure_threshold=2)), answer=lambda n: "success")
    with pytest.raises(ModelError, match=r"tree\.p: py_trees has no Parallel policy"):
        to_pytrees(build_model(Parallel("p", [leaf("a", "S"), leaf("b", "S"), leaf("c", "S")], success_threshold=2)),
                   answer=lambda n: "success")


def test_import_without_py_trees_is_a_clear_error():
    code = ("import sys; sys.modules['py_trees'] = None\n"
            "try:\n    import btfsm.interop.pytrees\nexcept ImportError as e:\n    print(e)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert "btfsm.interop.pytrees needs py_trees" in out
