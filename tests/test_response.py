"""Property ``response`` and ``btfsm bound`` (docs/verification.md 2.1).

The two sweeps (worst case: longest response-free path, infinite when a response-free
cycle or a dead end can be reached; best case: shortest path) are compared with
brute-force path enumeration on random graphs; the property's figures with a brute-force
walk over the explored system of random timed models; the CLI end to end: verdicts, JSON
figures, exit codes, counterexamples that replay.
"""
from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from memo_strategies import st

from btfsm import ModelError
from btfsm.cli import main
from btfsm.timing import Response
from btfsm.verify.explore import explore
from btfsm.verify.properties.response import INF, ResponseBound, best_until, worst_until

from strategies import timed_models


@st.composite
def graphs(draw):
    n = draw(st.integers(1, 7))
    edges = draw(st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1)), max_size=14))
    stop = draw(st.lists(st.booleans(), min_size=n, max_size=n))
    src = np.array([e[0] for e in edges], np.int64)
    dst = np.array([e[1] for e in edges], np.int64)
    return n, src, dst, np.array(stop, bool)


def brute_worst(n, src, dst, stop, u, seen=()):
    """Longest path from u to a stop node avoiding other stop nodes; INF on a cycle or dead end."""
    if stop[u]:
        return 0
    if u in seen:
        return INF
    succ = dst[src == u]
    if succ.size == 0:
        return INF
    best = 0
    for v in succ.tolist():
        w = brute_worst(n, src, dst, stop, v, seen + (u,))
        if w == INF:
            return INF
        best = max(best, w + 1)
    return best


def brute_best(n, src, dst, stop, u):
    dist = {u: 0}
    frontier = [u]
    while frontier:
        nxt = []
        for x in frontier:
            if stop[x]:
                return dist[x]
            for v in dst[src == x].tolist():
                if v not in dist:
                    dist[v] = dist[x] + 1
                    nxt.append(v)
        frontier = nxt
    return INF


@settings(max_examples=400, deadline=None, derandomize=True, database=None)
@given(graphs())
def test_sweeps_equal_brute_force(g):
    n, src, dst, stop = g
    worst = worst_until(n, src, dst, stop)
    best = best_until(n, src, dst, stop)
    for u in range(n):
        assert worst[u] == brute_worst(n, src, dst, stop, u), u
        assert best[u] == brute_best(n, src, dst, stop, u), u


def brute_model_worst(ts, stop, triggers, limit=60):
    """The same figure by walking the explored system from each trigger state."""
    offs = ts.offsets
    out = 0
    for t in triggers.tolist():
        memo = {}

        def walk(u, depth, path):
            if stop[u]:
                return 0
            if u in path or depth > limit:
                return INF
            lo, hi = int(offs[u]), int(offs[u + 1])
            if lo == hi:
                return INF
            best = 0
            for v in ts.dst[lo:hi].tolist():
                key = v
                w = memo[key] if key in memo and key not in path else walk(v, depth + 1, path | {u})
                if w == INF:
                    return INF
                best = max(best, w + 1)
            memo[u] = best
            return best
        out = max(out, walk(t, 0, frozenset()))
        if out == INF:
            break
    return out


@settings(max_examples=60, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much])
@given(timed_models(), st.data())
def test_model_figures_equal_a_brute_force_walk(model, data):
    try:
        prog = model.program
    except ModelError:
        return
    ts = explore(model, max_states=400)
    if not ts.complete or ts.n_states < 2:
        return
    vars_ = [v for v in model.variables if v.kind == "bool"]
    if not vars_:
        return
    v = data.draw(st.sampled_from(vars_))
    events = [e.name for e in model.environment if not hasattr(e, "options")]
    trig = data.draw(st.sampled_from([f"not {v.name}"] + [f"event:{e}" for e in events]))
    rb = ResponseBound(ts, Response("r", trig, v.name))
    if not rb.occurs:
        return
    assert rb.worst == brute_model_worst(ts, rb.stop, rb.triggers)
    assert prog is model.program
    if rb.trigger_edges is not None and rb.worst != INF:  # the worst run from one trigger source
        src = int(ts.src[rb.trigger_edges[data.draw(st.integers(0, len(rb.trigger_edges) - 1))]])
        edges = rb.trigger_edges[ts.src[rb.trigger_edges] == src]
        path, k, loop = rb.witness_from(edges)
        assert loop is None and path[k - 1] in edges.tolist() and ts.src[path[0]] == 0
        assert all(ts.dst[a] == ts.src[b] for a, b in zip(path, path[1:])) and rb.stop[ts.dst[path[-1]]]
        assert len(path) - k == brute_model_worst(ts, rb.stop, np.unique(ts.dst[edges]))


TIMED = """
name: timed
tick_rate: 10
variables: {q: {int: [0, 1]}}
primitives:
  work: {outcomes: [running, {success: {q: 0}}], duration: [0.2, 0.4]}
tree:
  ReactiveFallback: root
  children:
    - {Condition: empty, expr: q == 0}
    - {Action: w, primitive: work}
environment:
  - {event: arrive, guard: q < 1, effects: {q: q + 1}, min_interval: 1.0}
responses:
  serve: {trigger: "event:arrive", response: q == 0, within: 0.4}
"""


@pytest.fixture
def timed_file(tmp_path):
    p = tmp_path / "timed.yaml"
    p.write_text(TIMED, encoding="utf-8")
    return p


def test_check_holds_at_the_exact_bound_and_fails_one_tick_below(timed_file, tmp_path, capsys):
    assert main(["check", str(timed_file), "--property", "response", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)["properties"][0]["info"]["responses"]["serve"]
    assert (info["worst_ticks"], info["best_ticks"], info["worst_seconds"]) == (4, 2, 0.4)
    # the same requirement from the command line, 0.1 s tighter: violated, the counterexample replays
    ce_dir = tmp_path / "ce"
    assert main(["check", str(timed_file), "--trigger", "event:arrive", "--response", "q == 0", "--within", "0.3",
                 "--property", "response", "--counterexample-dir", str(ce_dir)]) == 1
    out = capsys.readouterr().out
    assert "the response can take 0.4 s > 0.3 s" in out
    (ce,) = list(ce_dir.iterdir())
    assert main(["replay", str(ce), str(timed_file)]) == 0
    assert "confirmed: 'q == 0' still does not hold 3 tick(s)" in capsys.readouterr().out


def test_bound_prints_best_and_worst_and_writes_a_replayable_witness(timed_file, tmp_path, capsys):
    w = tmp_path / "worst.json"
    assert main(["bound", str(timed_file), "--trigger", "event:arrive", "--response", "q == 0", "-o", str(w), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert (out["worst_ticks"], out["best_ticks"], out["unbounded"]) == (4, 2, False)
    assert main(["replay", str(w), str(timed_file)]) == 0
    assert "first holds 4 tick(s) (0.4 s)" in capsys.readouterr().out


def test_unbounded_response_gives_a_lasso(tmp_path, capsys):
    p = tmp_path / "never.yaml"
    p.write_text(TIMED.replace("{success: {q: 0}}", "success"), encoding="utf-8")
    w = tmp_path / "lasso.json"
    assert main(["bound", str(p), "--trigger", "event:arrive", "--response", "q == 0", "-o", str(w)]) == 1
    assert "unbounded" in capsys.readouterr().out
    data = json.loads(w.read_text())
    assert data["loop"] is not None
    assert main(["replay", str(w), str(p)]) == 0
    assert "never holds" in capsys.readouterr().out


@pytest.mark.parametrize("argv,msg", [
    (["bound", "{f}", "--trigger", "event:nope", "--response", "q == 0"], "no environment event or option 'nope'"),
    (["bound", "{f}", "--trigger", "q ==", "--response", "q == 0"], "--trigger/--response"),
    (["bound", "{f}", "--trigger", "zz > 1", "--response", "q == 0"], "zz"),
    (["check", "{f}", "--within", "3"], "--within needs --trigger and --response"),
    (["check", "{f}", "--trigger", "q == 1"], "--trigger and --response go together"),
])
def test_bad_requirements_exit_2(timed_file, capsys, argv, msg):
    assert main([a.format(f=timed_file) for a in argv]) == 2
    err = capsys.readouterr().err
    assert msg in err and "Traceback" not in err


def test_a_model_without_requirements_holds_trivially():
    from btfsm.models.registry import load_builtin
    from btfsm.verify.report import check

    res = check(load_builtin("two-area"), ["response"]).results[0]
    assert res.holds is True and res.not_applicable == "no 'responses:' declared"


def test_both_engines_explore_a_model_with_an_event_requirement(timed_file):
    """The scalar engine ticks the tree without the environment (its TreeCache): a
    requirement triggered by an environment event must not stop it from building that."""
    from btfsm.files import load_model
    from test_verify_traced import assert_same

    m = load_model(str(timed_file))
    assert_same(explore(m, engine="scalar"), explore(m, engine="traced"))


def test_a_budget_cut_system_leaves_the_response_undecided_without_a_crash():
    """A state budget that cuts the timed baseline: the unexpanded states give an unbounded
    figure, no run of the explored part shows it, so the property is undecided (exit 3)
    instead of an internal error (it raised AssertionError in _lasso before)."""
    from btfsm.models import ariac
    from btfsm.verify.report import check

    r = check(ariac.baseline_timed(), ["response"], max_states=2000)
    (res,) = r.results
    assert r.exit_code == 3 and res.holds is None and res.counterexample is None
    assert any("left unexpanded" in n for n in res.notes)


@settings(max_examples=300, deadline=None, derandomize=True, database=None)
@given(st.integers(1, 8).flatmap(lambda n: st.tuples(
    st.just(n), st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1)), max_size=3 * n),
    st.lists(st.booleans(), min_size=n, max_size=n), st.integers(0, 6))))
def test_free_run_equals_a_brute_force_walk_count(case):
    """free_run against enumerating every walk of up to cap transitions."""
    from btfsm.verify.properties.response import free_run

    n, edges, stop, cap = case
    stop = np.array(stop, bool)
    src = np.array([a for a, _ in edges], np.int64)
    dst = np.array([b for _, b in edges], np.int64)

    def longest(u, left):
        if stop[u]:
            return -1
        best = 0
        if left:
            for a, b in edges:
                if a == u and not stop[b]:
                    best = max(best, 1 + longest(b, left - 1))
        return best

    assert free_run(n, src, dst, stop, cap).tolist() == [longest(u, cap) for u in range(n)]


def test_a_violation_inside_a_budget_cut_system_is_reported_and_replays(tmp_path, capsys):
    """Cut at 500,000 of its 1.0 M states, the timed baseline's explored part already holds
    a run of 16 s without the response: a real violation (exit 1) whose counterexample
    replays, although the unexpanded states make the worst case look unbounded (one
    exploration: the command's --json report carries the verdict and the notes)."""
    from btfsm.cli import main

    assert main(["check", "ariac-baseline-timed", "--property", "response", "--max-states", "500000",
                 "--counterexample-dir", str(tmp_path), "--json"]) == 1
    report = json.loads(capsys.readouterr().out)
    (res,) = report["properties"]
    assert report["complete"] is False and res["holds"] is False and res["counterexample"] is not None
    assert any("the violation's run lies inside it" in n for n in res["notes"])
    (ce,) = tmp_path.glob("*.json")
    assert main(["replay", str(ce), "ariac-baseline-timed"]) == 0


def test_bound_output_on_a_budget_cut_system_without_a_witness(timed_file, tmp_path, capsys):
    # 3 states explored: the worst case is unbounded only through the unexpanded states, and
    # the explored part holds no run that never responds: nothing to write, exit 3
    w = tmp_path / "worst.json"
    assert main(["bound", str(timed_file), "--trigger", "event:arrive", "--response", "q == 0",
                 "--max-states", "3", "-o", str(w), "--json"]) == 3
    captured = capsys.readouterr()
    out = json.loads(captured.out)
    assert (out["unbounded"], out["complete"], out["counterexample"]) == (True, False, None)
    assert "no worst-case run written" in captured.err and "budget" in captured.err
    assert not w.exists()
