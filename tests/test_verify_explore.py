"""The explorer: transition-system contract, BFS order, budgets, FSM-level slicing."""
from __future__ import annotations

import numpy as np
import pytest

from btfsm import (FSM, Action, Bool, Condition, Edge, Enum, EnvChoice, EnvEvent, Int, Marker, Model,
                   ReactiveSequence, SkillRequest, State, failure, running, success)
from btfsm.verify import TransitionSystem, explore_fsm, open_fsm
from btfsm.verify.explore import explore
from btfsm.verify.explore import script_of, successor_scripts
from btfsm.verify.system import forward_reach, reverse_reach, shortest_path


def _counter(hi=3, expr=None):
    return Model("cnt", [Int("n", 0, hi)], tree=Action("inc", outcomes=[success(n=expr or f"min(n + 1, {hi})")]))


def test_contract_fields():
    ts = explore(_counter())
    assert isinstance(ts, TransitionSystem) and ts.kind == "model" and ts.fsm is None
    assert ts.slots == (0,) and ts.states.shape == (4, 1) and ts.states.dtype == np.int8
    assert ts.states[:, 0].tolist() == [0, 1, 2, 3]  # row 0 initial, BFS order
    assert ts.src.dtype == ts.dst.dtype == ts.label.dtype == np.int64
    assert ts.src.tolist() == [0, 1, 2, 3] and ts.dst.tolist() == [1, 2, 3, 3]
    assert ts.parent.tolist() == [-1, 0, 1, 2]
    assert ts.complete and ts.expanded == 4 and ts.seconds >= 0
    assert ts.full_state(2) == (2,) and ts.decode(3) == {"n": 3}
    assert ts.successors(3).tolist() == [3] and ts.out_transitions(1).tolist() == [1]
    assert ts.labels[int(ts.label[0])] == (("outcome", "inc", "success", "SUCCESS"),)


def test_bfs_parents_give_shortest_paths():
    # a ring 0 -> 1 -> ... -> 5 -> 0 plus a shortcut 0 -> 4 chosen by the environment
    m = Model("ring", [Int("n", 0, 5)], environment=[
        EnvChoice("c", [EnvEvent("step", None, {"n": "(n + 1) % 6"}), EnvEvent("jump", "n == 0", {"n": 4})])])
    ts = explore(m)
    depth = ts.depth()
    assert [len(ts.path_to(i)) for i in range(ts.n_states)] == depth.tolist()
    j = int(np.flatnonzero(ts.states[:, 0] == 5)[0])
    assert len(ts.path_to(j)) == 2  # 0 -> 4 -> 5, not five steps round the ring
    assert (np.diff(depth) >= 0).all()


def test_nondeterminism_is_enumerated_once_per_answer():
    m = Model("two", [Bool("a"), Bool("b")], environment=[EnvEvent("ea", None, {"a": "not a"}), EnvEvent("eb", None, {"b": "not b"})])
    ts = explore(m)
    assert ts.n_states == 4 and ts.n_transitions == 16
    assert len(set(zip(ts.src.tolist(), ts.dst.tolist(), ts.label.tolist()))) == 16
    assert len(ts.labels) == 4


def test_outcomes_and_scripts_round_trip():
    m = Model("o", [Int("n", 0, 2)], tree=Action("a", outcomes=[success(n="min(n + 1, 2)"), failure(), running()]))
    ts = explore(m)
    for t in range(ts.n_transitions):
        script = script_of(ts, t)
        step = ts.model.program.step(ts.full_state(int(ts.src[t])), __import__("btfsm.oracles").oracles.ScriptOracle(script))
        assert step.state == ts.full_state(int(ts.dst[t]))
    assert len(successor_scripts(ts, ts.full_state(0))) == 3


def test_blocked_choice_gives_no_transition():
    m = Model("blk", [Int("n", 0, 1)], environment=[EnvChoice("c", [EnvEvent("up", "n == 0", {"n": 1})])])
    ts = explore(m)
    assert ts.n_states == 2 and ts.dead.tolist() == [1]


def test_domain_errors_are_recorded_not_raised():
    ts = explore(_counter(2, "n + 1"))
    assert ts.n_states == 3 and len(ts.errors) == 1
    e = ts.errors[0]
    assert e.state == 2 and e.var == "n" and e.value == 3 and "outside its domain" in e.message


def test_budget_marks_incomplete_and_keeps_a_consistent_prefix():
    ts = explore(_counter(50), max_states=10)
    assert not ts.complete and ts.n_states == 10 and ts.expanded == 9
    assert ts.dead.tolist() == []  # the unexpanded state is not reported dead
    assert int(ts.dst.max()) < ts.n_states


def test_progress_is_called():
    calls = []
    explore(_counter(20000), progress=lambda *a: calls.append(a))
    assert calls and calls[-1][0] == 20001


def test_start_state():
    ts = explore(_counter(), start=(2,))
    assert ts.n_states == 2 and ts.full_state(0) == (2,)


def test_huge_code_space_falls_back_to_tuples():
    variables = [Int(f"x{i}", 0, 100) for i in range(12)]  # 101**12 > 2**62
    m = Model("wide", variables, environment=[EnvEvent("e", "x0 < 3", {"x0": "x0 + 1"})])
    ts = explore(m)
    assert ts.n_states == 4 and ts.states.shape == (4, 12)
    assert ts.states[:, 0].tolist() == [0, 1, 2, 3]


def test_negative_int_domains_encode():
    m = Model("neg", [Int("t", -3, -1)], environment=[EnvEvent("up", "t < -1", {"t": "t + 1"})])
    ts = explore(m)
    assert ts.states[:, 0].tolist() == [-3, -2, -1]


def test_graph_helpers_and_networkx():
    ts = explore(_counter())
    back = reverse_reach(ts, ts.states[:, 0] == 3)
    assert back.all()
    assert forward_reach(ts, 2).tolist() == [False, False, True, True]
    assert shortest_path(ts, 0, 3) == [0, 1, 2]
    g = ts.to_networkx()
    assert g.number_of_nodes() == 4 and g.number_of_edges() == 4
    with pytest.raises(ValueError):
        ts.to_networkx(max_states=2)


# ---------------------------------------------------------------------- FSM level


def _arm(params=(), retarget="immediate"):
    return FSM("arm", [State("home"), State("go", outcomes=[running(), success(done=True)])], "home", ["fetch", "rest"],
               [Edge("home", "go", ["fetch"], guard="ready"), Edge("go", "home", ["rest"], direct=True)],
               [Marker("go", ["fetch"]), Marker("home", ["rest"], direct=True)], params, retarget,
               "rest" if retarget == "withdraw" else "")


def test_fsm_level_slices_and_free_inputs():
    m = Model("fl", [Bool("ready"), Bool("done"), Enum("noise", ("x", "y", "z"))], fsms=[_arm()],
              environment=[EnvEvent("buzz", None, {"noise": "'y'"})])
    op = open_fsm(m, "arm")
    prog = m.program
    names = [prog.slots[k].name for k in op.kept]
    assert names == ["done", "arm.state", "arm.goal"]  # noise is sliced away, ready is an input
    assert [prog.slots[k].name for k, _ in op.inputs] == ["ready"] and op.env == ()
    ts = explore_fsm(m, "arm")
    assert ts.kind == "fsm" and ts.fsm == "arm" and ts.slots == op.kept
    assert ts.goal is not None and set(ts.goal.tolist()) == {0, 1}
    assert {item[0] for lab in ts.labels for item in lab} >= {"goal", "input", "outcome"}
    full = ts.full_state(0)
    assert full == prog.initial


def test_fsm_level_environment_that_writes_a_read_variable_is_kept():
    m = Model("fl", [Bool("ready"), Bool("done")], fsms=[_arm()],
              environment=[EnvEvent("arrive", "not ready", {"ready": True})])
    op = open_fsm(m, "arm")
    assert op.env == (0,) and op.inputs == ()
    ts = explore_fsm(m, "arm")
    assert any(("env", "arrive") in lab for lab in ts.labels)


def test_fsm_level_goals_from_the_tree_and_pre():
    tree = ReactiveSequence("root", [Condition("c", "ready"), SkillRequest("f", fsm="arm", goal="fetch", pre="not done")])
    m = Model("t", [Bool("ready"), Bool("done")], fsms=[_arm()], tree=tree)
    op = open_fsm(m, "arm")
    assert op.goals == (0,) and set(op.pres) == {0}
    ts = explore_fsm(m, "arm")
    done = ts.slots.index(m.program.scope["done"].index)
    assert not any(ts.states[int(s), done] for s in ts.src.tolist())  # never requested once done
    assert explore_fsm(m, "arm", goals=["rest"]).goal.tolist() == [1] * explore_fsm(m, "arm", goals=["rest"]).n_transitions


def test_fsm_level_params_are_chosen():
    m = Model("p", [Bool("ready"), Bool("done")], fsms=[_arm(params=(Int("target", 0, 2),))])
    ts = explore_fsm(m, "arm")
    assert {it[2] for lab in ts.labels for it in lab if it[0] == "param"} == {0, 1, 2}


def test_unknown_fsm_and_goal():
    m = Model("p", [Bool("ready"), Bool("done")], fsms=[_arm()])
    with pytest.raises(KeyError):
        explore_fsm(m, "nope")
    with pytest.raises(KeyError):
        explore_fsm(m, "arm", goals=["nope"])


def test_pickplace_matches_spin_state_counts():
    pp = pytest.importorskip("btfsm.models.pickplace")
    ts = explore(pp.pickplace(3))
    assert ts.n_states == pp.SPIN_STATES[3] == 10_288
    dead = explore(pp.pickplace(3, dead=True))
    assert dead.n_states == 8_624 and len(dead.dead) == 1_024
