"""Speed of the explicit checker (``verify``): exploration, AG EF, determinism, full checks.

Usage: ``python3 benchmarks/check_speed.py [--big] [--full18] [--repeats N] [--json]``

Measures, with both wall time and CPU time of this process (the CPU figure is the one to
compare on a shared machine):

* ``explore`` (the generic path, ``btfsm.verify.explore.explore``: its default engine is
  ``btfsm.verify.traced``; each row is followed by the same exploration with the scalar
  engine, one step per transition) on the SPIN pick/place replica ``btfsm.models.pickplace``
  (state counts identical to SPIN's ``-o2`` run), Q=D=B=3 and 6 (12 with ``--big``:
  1.3 M states), on a synthetic mid-size tree model (two FSMs, counters, an
  environment: about 10^5 states) and on the paper's ARIAC kitting models;
* AG EF workable (backward reachability over the CSR) on the explored pick/place systems;
* determinism of a synthetic 200-state x 4-goal x 10-edge skill (36 k guard pairs);
* the full ``btfsm check`` (all properties) of the paper-sized models, and with
  ``--full18`` of pick/place Q=D=B=18 (6 M states and 47 M transitions at the model level
  and again at the FSM level; about 15 s), with the process's peak RSS.

Timing is read only here and in the ``seconds`` fields of the checker's results.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from btfsm import (FSM, Bool, Condition, Edge, Enum, EnvEvent, Int, Marker, Model, ReactiveFallback,  # noqa: E402
                   ReactiveSequence, SkillRequest, State, failure, running, success)
from btfsm.verify.determinism import analyse  # noqa: E402
from btfsm.verify.explore import explore  # noqa: E402
from btfsm.verify.properties.workable import traps  # noqa: E402
from btfsm.verify.report import check  # noqa: E402


ENGINE = {"auto": "(generic path: traced)", "scalar": "(scalar engine)"}


def timed(fn, repeats=1):
    """(result, best wall seconds, best cpu seconds)."""
    best_w = best_c = float("inf")
    out = None
    for _ in range(repeats):
        w, c = time.perf_counter(), time.process_time()
        out = fn()
        best_w, best_c = min(best_w, time.perf_counter() - w), min(best_c, time.process_time() - c)
    return out, best_w, best_c


def cell(q: int = 8, d: int = 40) -> Model:
    """A synthetic kitting cell: an arm (pick/place, preemptible) and a conveyor FSM, a part
    queue, a delivered counter, a belt mode and a drifting temperature; about 10^5 states
    at the defaults."""
    arm = FSM("arm", [State("home"), State("reach", outcomes=[running(), success(), failure()]),
                      State("grip", outcomes=[success(holding=True), failure()]),
                      State("carry", outcomes=[running(), success()]),
                      State("drop", outcomes=[success(holding=False, done=f"(done + 1) % {d + 1}")])],
              "home", ["pick", "place"],
              [Edge("home", "reach", ["pick"]), Edge("reach", "grip", ["pick"]), Edge("reach", "home", ["pick"], on="failure"),
               Edge("grip", "home", ["pick"], guard="holding"), Edge("grip", "reach", ["pick"], on="failure"),
               Edge("reach", "home", ["place"], direct=True), Edge("home", "carry", ["place"], guard="holding"),
               Edge("carry", "drop", ["place"]), Edge("drop", "home", ["place"]), Edge("grip", "home", ["place"], direct=True)],
              [Marker("grip", ["pick"]), Marker("drop", ["place"]),
               Marker("home", ["place"], direct=True, outcome="failure", guard="not holding")])
    belt = FSM("belt", [State("stopped"), State("moving", outcomes=[running(), success(queue=f"min(queue + 1, {q})")])],
               "stopped", ["feed", "stop"],
               [Edge("stopped", "moving", ["feed"]), Edge("moving", "stopped", ["feed"]),
                Edge("moving", "stopped", ["stop"], direct=True)],
               [Marker("stopped", ["stop"], direct=True), Marker("stopped", ["feed"], direct=True, guard=f"queue == {q}")])
    tree = ReactiveFallback("root", [
        ReactiveSequence("deliver", [Condition("has", "holding"), SkillRequest("place", fsm="arm", goal="place")]),
        ReactiveSequence("fetch", [Condition("parts", "queue > 0 and mode != 'jammed'"),
                                   SkillRequest("pick", fsm="arm", goal="pick", post="holding")]),
        SkillRequest("feed", fsm="belt", goal="feed"),
    ])
    env = [EnvEvent("jam", "mode == 'ok' and heat > 6", {"mode": "'jammed'"}),
           EnvEvent("clear", "mode == 'jammed'", {"mode": "'ok'"}),
           EnvEvent("take", "holding and queue > 0", {"queue": "queue - 1"}),
           EnvEvent("arrive", f"queue < {q}", {"queue": "queue + 1"}),
           EnvEvent("warm", "heat < 9", {"heat": "heat + 1"}), EnvEvent("cool", "heat > 0", {"heat": "heat - 1"})]
    return Model("cell", [Bool("holding"), Int("queue", 0, q), Int("done", 0, d), Enum("mode", ("ok", "jammed")),
                          Int("heat", 0, 9)],
                 fsms=[arm, belt], tree=tree, environment=env, invariants={"queue": f"queue <= {q}"})


def skill(n_states: int = 200, goals: int = 4, edges: int = 10) -> Model:
    """A synthetic skill for determinism: ``edges`` guarded edges per (state, goal), guards
    are conjunctions of 2 atoms over enums and ints (about 36 k pairs)."""
    ids = [f"s{i}" for i in range(n_states)]
    gs = [f"g{k}" for k in range(goals)]
    es = []
    for i in range(n_states):
        for k, g in enumerate(gs):
            for e in range(edges):
                guard = f"mode == '{('a', 'b', 'c')[(i + e) % 3]}' and q {('<', '>=', '==')[(e + k) % 3]} {(e * 7 + i) % 5}"
                es.append(Edge(ids[i], ids[(i + e + 1) % n_states], [g], guard=guard, id=f"e{i}_{k}_{e}"))
    f = FSM("big", [State(s) for s in ids], ids[0], gs, es)
    return Model("skill", [Enum("mode", ("a", "b", "c")), Int("q", 0, 4), Bool("flag")], fsms=[f])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--big", action="store_true", help="also pick/place Q=D=B=12 (1.3 M states, about a minute)")
    ap.add_argument("--full18", action="store_true", help="also the full check of pick/place Q=D=B=18 (about 15 s)")
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    from btfsm.models.ariac import baseline, preemptive
    from btfsm.models.pickplace import SPIN_STATES, pickplace

    rows = []

    def row(name, **kw):
        rows.append(dict(name=name, **kw))
        if not args.json:
            print(name.ljust(34), "  ".join(f"{k}={v}" for k, v in kw.items()), flush=True)

    sizes = (3, 6, 12) if args.big else (3, 6)
    for n in sizes:
        m = pickplace(n)
        m.program
        for engine in ("auto", "scalar"):
            ts, w, c = timed(lambda: explore(m, engine=engine), args.repeats)
            assert ts.n_states == SPIN_STATES[n], (ts.n_states, SPIN_STATES[n])
            row(f"explore pickplace Q=D=B={n} {ENGINE[engine]}", states=ts.n_states, transitions=ts.n_transitions,
                wall_s=round(w, 2), cpu_s=round(c, 2), states_per_s_cpu=int(ts.n_states / c),
                transitions_per_s_cpu=int(ts.n_transitions / c),
                maxrss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024)
        bad, w, c = timed(lambda: traps(ts), args.repeats)
        row(f"AG EF workable pickplace {n}", traps=int(bad.size), wall_s=round(w, 3), cpu_s=round(c, 3))
    dead = pickplace(3, dead=True)
    ts, w, c = timed(lambda: explore(dead), args.repeats)
    row("explore pickplace 3 DEAD", states=ts.n_states, dead=len(ts.dead), traps=int(traps(ts).size), cpu_s=round(c, 2))
    for name, m in (("cell (synthetic)", cell()), ("ariac preemptive q=8", preemptive(n_tray=40, queue_max=8))):
        m.program
        for engine in ("auto", "scalar"):
            ts, w, c = timed(lambda: explore(m, engine=engine), args.repeats)
            row(f"explore {name} {ENGINE[engine]}", states=ts.n_states, transitions=ts.n_transitions, wall_s=round(w, 2),
                cpu_s=round(c, 2), states_per_s_cpu=int(ts.n_states / c), transitions_per_s_cpu=int(ts.n_transitions / c))
    big = skill()
    big.program
    (ov, gaps), w, c = timed(lambda: analyse(big, gaps=False), args.repeats)
    pairs = sum(len(big.fsms[0].edges_from(s.id, g)) * (len(big.fsms[0].edges_from(s.id, g)) - 1) // 2
                for s in big.fsms[0].states for g in big.fsms[0].goals)
    row("determinism 200x4x10 skill", pairs=pairs, overlaps=len(ov), wall_s=round(w, 2), cpu_s=round(c, 2),
        us_per_pair_cpu=round(c / pairs * 1e6, 1))
    for name, m in (("ariac preemptive", preemptive()), ("ariac baseline", baseline()), ("pickplace 3", pickplace(3))):
        m.program
        r, w, c = timed(lambda: check(m), args.repeats)
        row(f"full check {name}", states=r.states, verdicts="".join("+" if x.holds else ("-" if x.holds is False else "?")
                                                                   for x in r.results), wall_s=round(w, 2), cpu_s=round(c, 2))
    if args.full18:
        m = pickplace(18)
        m.program
        r, w, c = timed(lambda: check(m, max_states=7_000_000, max_transitions=60_000_000), args.repeats)
        row("full check pickplace 18", states=r.states, verdicts="".join(
            "+" if x.holds else ("-" if x.holds is False else "?") for x in r.results), wall_s=round(w, 2),
            cpu_s=round(c, 2), maxrss_mb=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024)
    if args.json:
        print(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
