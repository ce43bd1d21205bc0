#!/usr/bin/env python3
"""btfsm vs py_trees: tick rate on the same 30-node tree, doing identical work.

The tree (14 internal nodes, 16 leaves) is the one of the py_trees anchor
(docs: /work/shared/research/bt-library-anchors.md, section 4), built node for node in
both libraries::

    Root            Parallel (all must succeed)   py_trees Parallel(SuccessOnAll(synchronise=False))
      Monitors      ReactiveSequence              Sequence(memory=False)
        BatteryMonitor, ObstacleMonitor, GoalMonitor   instant actions updating the world
      Tasks         ReactiveFallback              Selector(memory=False)
        Emergency   ReactiveSequence: IsBatteryLow, Dock (6 ticks, recharges)
        Avoid       ReactiveSequence: IsObstacle, Halt (2 ticks)
        GoalGuard   Guard (goal == latched mission goal)    EternalGuard
          RecordOutcome  Effects (latch / clear the goal, record the status)
                                                  StatusToBlackboard (+ the guard's latch)
            Mission      MemorySequence           Sequence(memory=True)
              Approach   MemorySequence: IsLocalized, PlanPath (1 tick), MoveTo (8 ticks)
              Grasp      ReactiveFallback: Inverter(IsHandEmpty), Retry(Pick (3 ticks), 3)
              Transport  MemorySequence: MoveToBin (8 ticks), Place (2 ticks)
              Report     ForceSuccess(Notify)     FailureIsSuccess
        Idle        instant action (1 tick)

World: the battery drains 1 per tick, the obstacle flag is on while ``t % 50`` is in
10..12, the goal id is ``t // 97`` (a goal change preempts the mission through the guard).

One run prints, for both libraries, the visited nodes per tick, the halts of running
actions and the root SUCCESS ticks, and checks they are identical; then times btfsm
(``Runtime.tick`` and bare ``Program.step`` with a light oracle) against py_trees'
``BehaviourTree.tick()`` (median of ``--repeats`` runs of ``--ticks`` ticks after a
warm-up) and the cost of tracing.

Usage: ``python3 benchmarks/bt_tick.py [--ticks 20000] [--repeats 5] [--json]``
(py_trees comes with ``pip install -e .[bench]``).
"""
from __future__ import annotations

import argparse
import io
import json
import os
import platform
import statistics
import sys
import time

from btfsm import (Action, Bool, Condition, Effects, Enum, ForceSuccess, Guard, Int, Inverter,
                   MemorySequence, Model, Parallel, ReactiveFallback, ReactiveSequence, Retry,
                   running, success, walk)
from btfsm.runtime import Runtime

__all__ = ["DURATIONS", "build_model", "Duration", "implementations", "LightOracle",
           "btfsm_counters", "btfsm_visit_log", "step_counters", "build_pytrees",
           "pytrees_counters", "pytrees_visit_log", "time_runs", "measure", "main"]

# ticks each action needs (RUNNING for ticks - 1 ticks, then SUCCESS); 1 = instant
DURATIONS = {"Dock": 6, "Halt": 2, "PlanPath": 1, "MoveTo": 8, "Pick": 3,
             "MoveToBin": 8, "Place": 2, "Idle": 1}
GOAL_PERIOD = 97  # the goal id changes every 97 ticks


# --------------------------------------------------------------------------- btfsm model


def build_model(horizon: int = 1_000_000, durations=None) -> Model:
    """The 30-node tree as a btfsm model; ``t`` may count up to ``horizon`` ticks.
    ``durations`` overrides DURATIONS (action name -> ticks; 1 is an instant action).

    >>> m = build_model(100)
    >>> sum(1 for _ in walk(m.tree)), m.warnings, m.program.lints
    (30, (), [])
    """
    durations = {**DURATIONS, **(durations or {})}

    def act(name: str, **on_success) -> Action:  # instant actions declare only success
        done = success(**on_success)
        return Action(name, outcomes=[done] if durations[name] == 1 else [running(), done])

    goals = horizon // GOAL_PERIOD
    variables = [
        Int("t", 0, horizon), Int("battery", 0, 100, 100), Bool("obstacle"),
        Int("goal", 0, goals), Int("mission_goal", -1, goals, -1),  # -1: no mission
        Enum("mission_status", ("none", "running", "success", "failure")),
    ]
    monitors = ReactiveSequence("Monitors", [
        Action("BatteryMonitor", outcomes=[success(t="t + 1", battery="max(0, battery - 1)")]),
        Action("ObstacleMonitor", outcomes=[success(obstacle="10 <= t % 50 <= 12")]),
        Action("GoalMonitor", outcomes=[success(goal=f"t // {GOAL_PERIOD}")]),
    ])
    mission = MemorySequence("Mission", [
        MemorySequence("Approach", [Condition("IsLocalized", "true"), act("PlanPath"), act("MoveTo")]),
        ReactiveFallback("Grasp", [Inverter("AlreadyHolding", Condition("IsHandEmpty", "true")),
                                   Retry("RetryPick", act("Pick"), 3)]),
        MemorySequence("Transport", [act("MoveToBin"), act("Place")]),
        ForceSuccess("Report", Condition("Notify", "false")),
    ])
    # EternalGuard + StatusToBlackboard: the goal is latched when the mission starts and
    # cleared when it ends or is halted; the guard fails (halting it) once the goal moves on
    record = Effects("RecordOutcome", mission,
                     on_start={"mission_goal": "goal", "mission_status": "'running'"},
                     on_success={"mission_goal": "-1", "mission_status": "'success'"},
                     on_failure={"mission_goal": "-1", "mission_status": "'failure'"},
                     on_halt={"mission_goal": "-1"})
    tasks = ReactiveFallback("Tasks", [
        ReactiveSequence("Emergency", [Condition("IsBatteryLow", "battery < 20"), act("Dock", battery="100")]),
        ReactiveSequence("Avoid", [Condition("IsObstacle", "obstacle"), act("Halt")]),
        Guard("GoalGuard", record, condition="mission_goal < 0 or goal == mission_goal"),
        act("Idle"),
    ])
    return Model("bt_tick", variables=variables, tree=Parallel("Root", [monitors, tasks]),
                 description="py_trees anchor tree (bench_pytrees.py), node for node")


class Duration:
    """Runtime implementation of a timed action: RUNNING until its ``ticks``-th tick."""

    __slots__ = ("ticks", "count", "halts")

    def __init__(self, ticks: int):
        self.ticks, self.count, self.halts = ticks, 0, 0

    def tick(self, call) -> str:
        count = 1 if call.first else self.count + 1
        self.count = count
        return "success" if count >= self.ticks else "running"

    def halt(self, call) -> None:
        self.halts += 1


def implementations(durations=None) -> dict:
    """Fresh implementations of every timed action, by primitive name."""
    return {name: Duration(ticks) for name, ticks in {**DURATIONS, **(durations or {})}.items()}


class LightOracle:
    """The cheapest oracle that still does the actions' work: a tick counter per site.

    Answers ``Program.step`` directly (no Runtime): outcome 0 is ``running`` and 1
    ``success`` for timed actions; ``halts`` counts abandoned runs."""

    __slots__ = ("left", "ticks", "halts")

    def __init__(self, program, durations=None):
        n = len(program.sites)
        durations = {**DURATIONS, **(durations or {})}
        self.ticks = [durations.get(site.primitive, 1) for site in program.sites]
        self.left = [0] * n  # ticks still to run, 0 when idle
        self.halts = 0

    def env(self, i):
        return False

    def choose(self, i, enabled):
        return 0

    def outcome(self, site):
        i = site.index
        left = self.left[i] or self.ticks[i]
        if left == 1:  # last tick: success (index 0 for an instant action)
            self.left[i] = 0
            return len(site.outcomes) - 1
        self.left[i] = left - 1
        return 0

    def halt(self, site):
        self.left[site.index] = 0
        self.halts += 1


def _count_visits(events) -> int:
    return sum(1 for ev in events if ev[0] == "status")


def btfsm_counters(ticks: int, durations=None) -> dict:
    """Work counters of ``Runtime.tick`` (recording on, to count node ticks)."""
    impls = implementations(durations)
    rt = Runtime(build_model(ticks, durations), impls, record=True)
    visits = ok = 0
    for _ in range(ticks):
        step = rt.tick()
        visits += _count_visits(step.events)
        ok += step.status == 1
    return _counters(ticks, visits, sum(d.halts for d in impls.values()), ok)


def btfsm_visit_log(ticks: int, durations=None) -> list:
    """Per tick, the ``(node, status name)`` of every node ticked, in tick order."""
    rt = Runtime(build_model(ticks, durations), implementations(durations), record=True)
    names = ("RUNNING", "SUCCESS", "FAILURE")
    return [tuple((ev[1], names[ev[2]]) for ev in rt.tick().events if ev[0] == "status")
            for _ in range(ticks)]


def step_counters(ticks: int, durations=None) -> dict:
    """The same counters from ``Program.step(record=True)`` with the light oracle."""
    prog = build_model(ticks, durations).program
    oracle, s, visits, ok = LightOracle(prog, durations), prog.initial, 0, 0
    for _ in range(ticks):
        step = prog.step(s, oracle, True)
        s = step.state
        visits += _count_visits(step.events)
        ok += step.status == 1
    return _counters(ticks, visits, oracle.halts, ok)


def _counters(ticks, visits, halts, ok) -> dict:
    return {"ticks": ticks, "visits": visits, "visited_per_tick": round(visits / ticks, 4),
            "halts": halts, "root_success_ticks": ok}


# --------------------------------------------------------------------------- py_trees


def build_pytrees(durations=None):
    """The same tree in py_trees 2.x: ``(root, halt_counter)``; the world lives on the
    blackboard plus a small dict, as in the anchor script."""
    import py_trees
    from py_trees.common import Access, ParallelPolicy, Status

    py_trees.blackboard.Blackboard.clear()
    d = {**DURATIONS, **(durations or {})}
    world = {"t": 0, "battery": 100}
    halts = [0]

    class Timed(py_trees.behaviour.Behaviour):
        def __init__(self, name, ticks, done=None):
            super().__init__(name)
            self.ticks, self.done, self.count = ticks, done, 0

        def initialise(self):
            self.count = 0

        def update(self):
            self.count += 1
            if self.count < self.ticks:
                return Status.RUNNING
            if self.done is not None:
                self.done()
            return Status.SUCCESS

        def terminate(self, new_status):
            if new_status == Status.INVALID and self.status == Status.RUNNING:
                halts[0] += 1

    class Const(py_trees.behaviour.Behaviour):
        def __init__(self, name, value):
            super().__init__(name)
            self.value = Status.SUCCESS if value else Status.FAILURE

        def update(self):
            return self.value

    class Check(py_trees.behaviour.Behaviour):  # reads one blackboard key
        def __init__(self, name, key, test):
            super().__init__(name)
            self.key, self.test = key, test
            self.bb = self.attach_blackboard_client(name=name)
            self.bb.register_key(key=key, access=Access.READ)

        def update(self):
            return Status.SUCCESS if self.test(self.bb.get(self.key)) else Status.FAILURE

    class Monitor(py_trees.behaviour.Behaviour):  # writes one blackboard key
        def __init__(self, name, key, compute):
            super().__init__(name)
            self.key, self.compute = key, compute
            self.bb = self.attach_blackboard_client(name=name)
            self.bb.register_key(key=key, access=Access.WRITE)

        def update(self):
            self.bb.set(self.key, self.compute())
            return Status.SUCCESS

    def drain():
        world["t"] += 1
        world["battery"] = max(0, world["battery"] - 1)
        return world["battery"]

    def recharge():
        world["battery"] = 100

    seq = py_trees.composites.Sequence
    sel = py_trees.composites.Selector
    dec = py_trees.decorators
    mission = seq("Mission", memory=True, children=[
        seq("Approach", memory=True, children=[Const("IsLocalized", True), Timed("PlanPath", d["PlanPath"]), Timed("MoveTo", d["MoveTo"])]),
        sel("Grasp", memory=False, children=[
            dec.Inverter("AlreadyHolding", child=Const("IsHandEmpty", True)),
            dec.Retry("RetryPick", child=Timed("Pick", d["Pick"]), num_failures=3)]),
        seq("Transport", memory=True, children=[Timed("MoveToBin", d["MoveToBin"]), Timed("Place", d["Place"])]),
        dec.FailureIsSuccess("Report", child=Const("Notify", False)),
    ])
    latched = {"goal": None}

    def goal_unchanged(blackboard):
        if mission.status != Status.RUNNING:  # the mission (re)starts: latch its goal
            latched["goal"] = blackboard.goal
            return True
        return blackboard.goal == latched["goal"]

    tasks = sel("Tasks", memory=False, children=[
        seq("Emergency", memory=False, children=[Check("IsBatteryLow", "battery", lambda b: b < 20),
                                                 Timed("Dock", d["Dock"], recharge)]),
        seq("Avoid", memory=False, children=[Check("IsObstacle", "obstacle", bool), Timed("Halt", d["Halt"])]),
        dec.EternalGuard("GoalGuard", condition=goal_unchanged, blackboard_keys={"goal"},
                         child=dec.StatusToBlackboard("RecordOutcome", child=mission,
                                                      variable_name="mission_status")),
        Timed("Idle", d["Idle"]),
    ])
    monitors = seq("Monitors", memory=False, children=[
        Monitor("BatteryMonitor", "battery", drain),
        Monitor("ObstacleMonitor", "obstacle", lambda: world["t"] % 50 in (10, 11, 12)),
        Monitor("GoalMonitor", "goal", lambda: world["t"] // GOAL_PERIOD),
    ])
    root = py_trees.composites.Parallel(
        "Root", policy=ParallelPolicy.SuccessOnAll(synchronise=False), children=[monitors, tasks])
    return root, halts


def _pytrees_tree(visitors=(), durations=None):
    import py_trees

    root, halts = build_pytrees(durations)
    tree = py_trees.trees.BehaviourTree(root)
    tree.visitors.extend(visitors)
    tree.setup(timeout=15)
    return tree, root, halts


def _visitor(on_visit):
    import py_trees

    class Visits(py_trees.visitors.VisitorBase):
        def __init__(self):
            super().__init__(full=False)  # only nodes ticked this tick (not INVALID)

        def run(self, behaviour):
            on_visit(behaviour)
    return Visits()


def pytrees_counters(ticks: int, durations=None) -> dict:
    """Work counters of py_trees: nodes yielded with a status, halts, root SUCCESS ticks."""
    from py_trees.common import Status

    visits = [0]

    def count(_):
        visits[0] += 1
    tree, root, halts = _pytrees_tree([_visitor(count)], durations)
    ok = 0
    for _ in range(ticks):
        tree.tick()
        ok += root.status == Status.SUCCESS
    return _counters(ticks, visits[0], halts[0], ok)


def pytrees_visit_log(ticks: int, durations=None) -> list:
    """Per tick, the ``(node, status name)`` of every node py_trees ticked, in order."""
    log: list = []
    tree, _, _ = _pytrees_tree([_visitor(lambda b: log.append((b.name, b.status.name)))], durations)
    out = []
    for _ in range(ticks):
        log.clear()
        tree.tick()
        out.append(tuple(log))
    return out


# --------------------------------------------------------------------------- timing


def _time_runtime(ticks, trace=None):
    """trace: None, "live" (records built and written during each tick), "deferred"
    (answers logged during the ticks, records written by re-running the step; the time
    includes writing the whole file) or "loop" (deferred, timing the control loop only)."""
    stream = io.StringIO() if trace else None
    mode = "live" if trace == "live" else "deferred"
    rt = Runtime(build_model(ticks), implementations(), trace=stream, trace_mode=mode)
    if trace == "loop":
        rt.FLUSH_EVERY = ticks + 1
    tick = rt.tick
    t0 = time.perf_counter()
    for _ in range(ticks):
        tick()
    if trace in ("live", "deferred"):
        rt.close()
    t1 = time.perf_counter()
    if trace == "loop":
        rt.close()
    return t1 - t0


def _time_step(ticks, record=False):
    prog = build_model(ticks).program
    oracle, s, step = LightOracle(prog), prog.initial, prog.step
    t0 = time.perf_counter()
    for _ in range(ticks):
        s = step(s, oracle, record).state
    return time.perf_counter() - t0


def _time_pytrees(ticks, snapshot=False):
    import py_trees

    tree, _, _ = _pytrees_tree([py_trees.visitors.SnapshotVisitor()] if snapshot else [])
    tick = tree.tick
    t0 = time.perf_counter()
    for _ in range(ticks):
        tick()
    return time.perf_counter() - t0


def time_runs(fn, ticks: int, repeats: int) -> dict:
    """One warm-up, then ``repeats`` timed runs: median ticks/s and the spread."""
    fn(ticks)
    secs = [fn(ticks) for _ in range(repeats)]
    med = statistics.median(secs)
    return {"ticks_per_s": ticks / med, "us_per_tick": 1e6 * med / ticks,
            "min_s": min(secs), "max_s": max(secs), "median_s": med}


MODES = {
    "py_trees": _time_pytrees,
    "py_trees+snapshot": lambda n: _time_pytrees(n, snapshot=True),
    "runtime": _time_runtime,
    "runtime+trace": lambda n: _time_runtime(n, trace="deferred"),
    "runtime+trace-loop": lambda n: _time_runtime(n, trace="loop"),
    "runtime+trace-live": lambda n: _time_runtime(n, trace="live"),
    "step": _time_step,
    "step+record": lambda n: _time_step(n, record=True),
}


def measure(ticks: int, repeats: int, modes=tuple(MODES)) -> dict:
    """Counters (checked equal) and timings; returns the report as a dict."""
    import py_trees

    counters = {"py_trees": pytrees_counters(ticks), "runtime": btfsm_counters(ticks),
                "step": step_counters(ticks)}
    same = counters["runtime"] == counters["py_trees"] == counters["step"]
    timings = {m: time_runs(MODES[m], ticks, repeats) for m in modes}
    rate = {m: r["ticks_per_s"] for m, r in timings.items()}
    derived = {}
    if "py_trees" in rate:
        for m in ("runtime", "step"):
            if m in rate:
                derived[f"{m}_vs_py_trees"] = rate[m] / rate["py_trees"]
    for m, traced in (("runtime", "runtime+trace"), ("runtime", "runtime+trace-loop"), ("runtime", "runtime+trace-live"),
                      ("step", "step+record"), ("py_trees", "py_trees+snapshot")):
        if m in timings and traced in timings:
            a, b = timings[m], timings[traced]
            derived[f"{traced}_overhead_pct"] = 100 * (b["median_s"] / a["median_s"] - 1)
            derived[f"{traced}_overhead_us"] = b["us_per_tick"] - a["us_per_tick"]
    nodes = list(walk(build_model(ticks).tree))
    return {"python": platform.python_version(), "py_trees": py_trees.version.__version__,
            "machine": platform.machine(), "nproc": os.cpu_count(), "ticks": ticks, "repeats": repeats,
            "nodes": len(nodes), "leaves": sum(1 for n in nodes if not n.children_of()),
            "counters": counters, "identical": same, "timings": timings, **derived}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ticks", type=int, default=20000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--json", action="store_true", help="print one JSON object only")
    args = ap.parse_args(argv)
    if args.ticks < 1 or args.repeats < 1:
        ap.error("--ticks and --repeats must be positive")
    try:
        import py_trees  # noqa: F401
    except ImportError:
        print("bt_tick: py_trees is not installed (pip install -e .[bench])", file=sys.stderr)
        return 2
    rep = measure(args.ticks, args.repeats)
    if args.json:
        print(json.dumps(rep))
        return 0 if rep["identical"] else 1
    print(f"python {rep['python']}  py_trees {rep['py_trees']}  {rep['machine']} x{rep['nproc']}  "
          f"nodes={rep['nodes']} leaves={rep['leaves']}  ticks={args.ticks} x{args.repeats}")
    for lib, c in rep["counters"].items():
        print(f"{lib:10s} visited/tick={c['visited_per_tick']:.4f}  halts={c['halts']}  "
              f"root SUCCESS ticks={c['root_success_ticks']}")
    print("work identical:", "yes" if rep["identical"] else "NO")
    for mode, r in rep["timings"].items():
        print(f"{mode:18s} {r['ticks_per_s']:9.0f} ticks/s  {r['us_per_tick']:7.2f} us/tick  "
              f"(min {r['min_s']:.3f}s max {r['max_s']:.3f}s)")
    for key in ("runtime_vs_py_trees", "step_vs_py_trees"):
        print(f"{key:28s} {rep[key]:6.2f}x   target >= 3x: {'met' if rep[key] >= 3 else 'NOT met'}")
    for mode in ("runtime+trace", "runtime+trace-loop", "runtime+trace-live", "step+record", "py_trees+snapshot"):
        pct, us = rep[f"{mode}_overhead_pct"], rep[f"{mode}_overhead_us"]
        verdict = "" if mode.startswith("py_trees") else f"target < 25 %: {'met' if pct < 25 else 'NOT met'}"
        print(f"{mode + ' overhead':28s} {pct:6.1f} %  ({us:+.2f} us/tick)  {verdict}")
    if not rep["identical"]:
        print("bt_tick: the two libraries did different work; timings are not comparable", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
