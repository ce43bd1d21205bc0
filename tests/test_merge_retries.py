"""Merged in-tick retries (docs/semantics.md 8.3, "In-tick retries"): exploring a model whose
RecoveryNodes retry within one tick, the checker merges the runs of a tick that reach the
same context (``btfsm.verify.search.EnumOracle.merge``). Against the plain enumeration of
every answer (the brute force), for random trees: the same reachable states, from each the
same (target, status, violations) endings, the same answers (label items) and the same
recorded events, and every kept transition re-runs (``script_of``)."""
from __future__ import annotations

import os

from hypothesis import HealthCheck, given, reject, settings
from memo_strategies import st

from btfsm import Bool, Int, Model
from btfsm.bt import (Action, Condition, Inverter, MemoryFallback, MemorySequence, Parallel, PipelineSequence,
                      ReactiveFallback, ReactiveSequence, RecoveryNode, Retry, RoundRobin, SequenceWithMemory)
from btfsm.errors import DomainError
from btfsm.oracles import all_choices
from btfsm.primitives import failure, running, success
from btfsm.verify.explore import explore, script_of, successor_scripts
from btfsm.verify.labels import readable
from btfsm.verify.search import EnumOracle

LONG = bool(os.environ.get("BTFSM_LONG"))
# the default run draws the same 25 trees every time (derandomized: about 2 s of CPU, where new
# draws took 0.2 s in one run of the suite and 21 s in the next); BTFSM_LONG=1 draws 400 new
# ones each run
EXAMPLES = 400 if LONG else 25
# The brute force enumerates every answer of a tick: nested in-tick retries multiply them,
# and a drawn tree may have millions (one took 9 GB and minutes in CI). Trees past this many
# runs from one state are rejected: the comparison is made on the trees it can afford.
MAX_RUNS = 20_000

OUTCOMES = [lambda: running(), lambda: success(), lambda: failure(), lambda: success("inc", n="min(n + 1, 2)"),
            lambda: failure("flip", b="not b")]


@st.composite
def trees(draw, depth=0, names=None):
    names = names if names is not None else iter(range(10_000))
    kinds = ["action", "condition"] if depth >= 3 else [
        "action", "action", "condition", "recovery", "recovery", "seq", "fb", "rseq", "rfb", "pipe", "robin", "inv",
        "par", "retry", "swm"]
    kind = draw(st.sampled_from(kinds))
    name = f"n{next(names)}"
    if kind == "action":
        outs = draw(st.lists(st.sampled_from(range(len(OUTCOMES))), min_size=1, max_size=3, unique=True))
        return Action(name, outcomes=tuple(OUTCOMES[k]() for k in outs))
    if kind == "condition":
        return Condition(name, draw(st.sampled_from(["b", "not b", "n > 0", "n < 2"])))
    if kind == "inv":
        return Inverter(name, draw(trees(depth + 1, names)))
    if kind == "retry":  # under btcpp: a tickOnce wake-up, the root re-ticked within the step
        return Retry(name, draw(trees(depth + 1, names)), attempts=2)
    count = 2 if kind == "recovery" else draw(st.integers(1, 3))
    kids = tuple(draw(trees(depth + 1, names)) for _ in range(count))
    if kind == "recovery":
        return RecoveryNode(name, kids, retries=draw(st.integers(0, 3)))
    if kind == "robin":
        return RoundRobin(name, kids, wrap_around=draw(st.booleans()))
    if kind == "par":
        return Parallel(name, kids, success_threshold=draw(st.integers(1, count)))
    return {"seq": MemorySequence, "fb": MemoryFallback, "rseq": ReactiveSequence, "rfb": ReactiveFallback,
            "pipe": PipelineSequence, "swm": SequenceWithMemory}[kind](name, kids)


@st.composite
def roots(draw):
    """Mostly a RecoveryNode that retries at the root, with random trees below."""
    names = iter(range(10_000))
    if draw(st.integers(0, 3)) == 0:
        return draw(trees(0, names))
    kids = (draw(trees(1, names)), draw(trees(1, names)))
    return RecoveryNode("root", kids, retries=draw(st.integers(1, 3)))


def _full(prog, state):
    """Every answer of one tick from ``state``, nothing merged (an EnumOracle without ``seen``)."""
    out = []
    for k, (taken, step, o) in enumerate(all_choices(lambda s, o: prog.step(s, o, True), state, EnumOracle,
                                                     (DomainError,))):
        if k >= MAX_RUNS:
            reject()  # too many runs in one tick for the brute force (see MAX_RUNS)
        if isinstance(step, DomainError) or step.state is None:
            continue
        out.append((step, o))
    return out


def _summary(prog, runs):
    ends = {(st.state, st.status, tuple(st.violations)) for st, _ in runs}
    items = {it for _, o in runs for it in readable(prog, tuple(o.picks), None)[0]}
    events = {ev for st, _ in runs for ev in st.events or ()}
    return ends, items, events


@settings(max_examples=EXAMPLES, deadline=None, derandomize=not LONG, suppress_health_check=list(HealthCheck))
@given(tree=roots(), semantics=st.sampled_from(["btcpp", "btfsm"]))
def test_merged_retries_keep_every_ending_answer_and_event(tree, semantics):
    m = Model("m", variables=[Int("n", 0, 2), Bool("b")], tree=tree, semantics=semantics)
    prog = m.program
    ts = explore(m, engine="scalar")
    assert ts.complete
    # the brute force: breadth-first over every answer
    seen, todo = {prog.initial}, [prog.initial]
    while todo:
        s = todo.pop()
        for step, _o in _full(prog, s):
            if step.state not in seen:
                seen.add(step.state)
                todo.append(step.state)
    states = {ts.full_state(i) for i in range(ts.n_states)}
    assert states == seen
    for i in range(ts.n_states):
        s = ts.full_state(i)
        full = _summary(prog, _full(prog, s))
        merged_runs = [(st_, o) for _script, st_, o in successor_scripts(ts, s) if st_ is not None]
        merged = _summary(prog, merged_runs)
        assert merged == full, (i, tree)
        kept = {(ts.full_state(int(ts.dst[t])), int(ts.status[t])) for t in ts.out_transitions(i).tolist()}
        assert kept == {(e[0], e[1]) for e in full[0]}
        if prog.merge_points:
            assert len(merged_runs) <= len(_full(prog, s))
    for t in range(0, ts.n_transitions, max(1, ts.n_transitions // 20)):
        script_of(ts, t)  # every kept transition is found again by re-enumerating its source


def _same_as_brute_force(m):
    prog = m.program
    ts = explore(m)
    full = _full(prog, prog.initial)
    merged = [(st_, o) for _s, st_, o in successor_scripts(ts, prog.initial) if st_ is not None]
    assert _summary(prog, merged) == _summary(prog, full)
    return full, merged


def test_nav2_recovery_merges_the_retries_of_one_tick():
    """In-tick retries over a pipeline of instant answers: the plain enumeration multiplies
    the answers of each retry, the merged one keeps a few runs per context; same endings."""
    leaf = (success(), failure())
    tree = RecoveryNode("r", (PipelineSequence("p", (Action("a", outcomes=leaf), Action("b", outcomes=leaf),
                                                     Action("c", outcomes=(running(), success(), failure())))),
                              ReactiveFallback("f", (Action("d", outcomes=leaf), Action("e", outcomes=leaf)))),
                        retries=4)
    m = Model("m", tree=tree, semantics="btcpp")
    assert {"r", "p", "f"} <= m.program.merge_points
    full, merged = _same_as_brute_force(m)
    assert len(full) > 5_000 and len(merged) * 20 < len(full)


def test_no_merge_under_a_parallel():
    """A Parallel counts its children's results in the tick (btfsm's profile keeps no memory
    of them): a RecoveryNode under it is no merge point, and the endings are all found."""
    leaf = (success(), failure())
    rec = RecoveryNode("r", (Action("a", outcomes=(running(), success(), failure())), Action("b", outcomes=leaf)),
                       retries=2)
    m = Model("m", tree=Parallel("p", (Action("x", outcomes=leaf), rec), success_threshold=1, failure_threshold=2),
              semantics="btfsm")
    assert not m.program.merge_points
    _same_as_brute_force(m)
