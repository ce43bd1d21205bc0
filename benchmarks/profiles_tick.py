#!/usr/bin/env python3
"""Tick rate per semantics profile, beside the real engines, on the same 25-node tree.

One tree (``SPEC``), built node for node in btfsm (a Model, run under each profile
``btfsm``, ``btcpp``, ``pytrees``), in real BehaviorTree.CPP 4 through its Python
bindings (``behaviortreepy``: XML written here, every leaf registered as a Python
callback) and in real py_trees 2.6::

    root            ReactiveSequence              ReactiveSequence   Sequence(memory=False)
      alive         condition
      tasks         ReactiveFallback              ReactiveFallback   Selector(memory=False)
        emergency   ReactiveSequence: battery_low, dock (async)
        avoid       ReactiveSequence: obstacle, stop (async)
        mission     MemorySequence                Sequence           Sequence(memory=True)
          approach  MemorySequence: localized, plan, move_to
          grasp     MemoryFallback: pick, pick_again                 Fallback / Selector(memory=True)
          not_blocked  Inverter(blocked)
          transport MemorySequence: move_to_bin, place
          report    ForceSuccess(notify)          ForceSuccess       FailureIsSuccess
        idle        async action

Every leaf's answer is a function of the global tick number only (conditions: a window of
``T % period``; actions: SUCCESS when ``(T + offset) % period == 0``, FAILURE at a
declared phase, RUNNING otherwise), so halting a leaf cannot change what it answers and
the engines can be compared callback by callback. The wheels (``dock``, ``stop``,
``move_to``, ``move_to_bin``, ``idle``) are declared one resource, ``base``: the
preemptions of ``emergency`` and ``avoid`` are BehaviorTree.CPP issue #1031's pattern.

One run:

1. **agreement**: ``--check-ticks`` ticks in every engine, logging per tick each leaf
   callback in order (``start``/``running``/``halt`` of actions, ``tick`` of conditions) and
   the root status; the btcpp profile is compared with real BT.CPP, the pytrees profile
   with real py_trees, and the btfsm profile with both (it differs where halt-before-start
   reorders a preemption: counted, not an error). Exclusive-resource violations per
   profile are counted too (``Step.violations``).
2. **timing**: median of ``--repeats`` runs of ``--ticks`` ticks after a warm-up (the
   modes take turns, round robin):
   btfsm ``Runtime.tick`` (leaves as Python implementations) and bare ``Program.step``
   (an oracle computing the same answers) under each profile, real BT.CPP
   ``tree.tick_exactly_once()``, real py_trees ``BehaviourTree.tick()``; ticks/s and
   ratios. Each mode's time is its loop of ticks alone (the tree and the model are built
   before the clock starts), by the wall clock or, with ``--clock cpu``, by this process's
   CPU time (steadier on a machine that other jobs share).

Usage: ``python benchmarks/profiles_tick.py [--ticks 20000] [--repeats 5] [--check-ticks 2000] [--clock wall|cpu] [--json]``
(behaviortreepy and py_trees come with ``pip install -e .[test]`` or ``.[bench]``).
Exit 0 when every profile agrees with its engine, 1 otherwise, 2 when an engine is missing.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import os
import platform
import statistics
import sys
import time

from btfsm import (Action, Condition, EnvEvent, ForceSuccess, Int, Inverter, MemoryFallback,
                   MemorySequence, Model, ReactiveFallback, ReactiveSequence, failure, running, success)
from btfsm.profiles import SEMANTICS
from btfsm.runtime import Runtime

__all__ = ["SPEC", "RESOURCES", "build_model", "btcpp_xml", "leaf_status", "run_btfsm", "run_btcpp",
           "run_pytrees", "compare", "measure", "main"]

# (kind, name, payload): composites and decorators hold children; "cond" holds
# (period, lo, hi): SUCCESS iff lo <= T % period < hi; "act" holds (period, offset, fail phase or None)
SPEC = ("rseq", "root", [
    ("cond", "alive", (97, 0, 96)),
    ("rfb", "tasks", [
        ("rseq", "emergency", [("cond", "battery_low", (50, 40, 45)), ("act", "dock", (4, 0, None))]),
        ("rseq", "avoid", [("cond", "obstacle", (31, 10, 12)), ("act", "stop", (2, 0, None))]),
        ("mseq", "mission", [
            ("mseq", "approach", [("cond", "localized", (13, 0, 12)), ("act", "plan", (3, 1, None)),
                                  ("act", "move_to", (7, 2, 5))]),
            ("mfb", "grasp", [("act", "pick", (3, 0, 2)), ("act", "pick_again", (4, 1, 3))]),
            ("inv", "not_blocked", [("cond", "blocked", (23, 0, 1))]),
            ("mseq", "transport", [("act", "move_to_bin", (6, 3, None)), ("act", "place", (2, 1, None))]),
            ("fs", "report", [("cond", "notify", (2, 0, 1))]),
        ]),
        ("act", "idle", (5, 0, None)),
    ]),
])
RESOURCES = {"base": ["dock", "stop", "move_to", "move_to_bin", "idle"]}
RUNNING, SUCCESS, FAILURE = "RUNNING", "SUCCESS", "FAILURE"
#: ``--clock``: wall time, or the CPU time of this process (every engine runs its ticks in
#: this thread; on a shared machine the CPU time leaves out the spells spent waiting for a core)
CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}
_now = CLOCKS["wall"]


def _walk(spec):
    yield spec
    if spec[0] not in ("cond", "act"):
        for kid in spec[2]:
            yield from _walk(kid)


LEAVES = {s[1]: s for s in _walk(SPEC) if s[0] in ("cond", "act")}


def leaf_status(name: str, t: int) -> str:
    """What leaf ``name`` answers at global tick ``t`` (the same in every engine).

    >>> [leaf_status("stop", t) for t in (1, 2)], leaf_status("blocked", 23)
    (['RUNNING', 'SUCCESS'], 'SUCCESS')
    """
    kind, _, p = LEAVES[name]
    if kind == "cond":
        period, lo, hi = p
        return SUCCESS if lo <= t % period < hi else FAILURE
    period, offset, fail = p
    x = (t + offset) % period
    return SUCCESS if x == 0 else FAILURE if x == fail else RUNNING


# --------------------------------------------------------------------------- btfsm


def build_model(horizon: int, semantics: str = "btfsm", resources=True) -> Model:
    """The tree as a btfsm model: world variable ``t`` is the global tick (event ``clock``).

    >>> m = build_model(100, "btcpp")
    >>> len(m.program.nodes), m.semantics, m.warnings
    (25, 'btcpp', ())
    """
    def node(s):
        kind, name, p = s
        if kind == "cond":
            period, lo, hi = p
            return Condition(name, f"{lo} <= t % {period} and t % {period} < {hi}")
        if kind == "act":
            return Action(name, outcomes=[running(), success(), failure()])
        kids = [node(k) for k in p]
        if kind in ("inv", "fs"):
            return (Inverter if kind == "inv" else ForceSuccess)(name, kids[0])
        cls = {"rseq": ReactiveSequence, "rfb": ReactiveFallback, "mseq": MemorySequence, "mfb": MemoryFallback}[kind]
        return cls(name, kids)
    return Model("profiles_tick", variables=[Int("t", 0, horizon)], tree=node(SPEC),
                 environment=[EnvEvent("clock", f"t < {horizon}", {"t": "t + 1"})], semantics=semantics,
                 resources=RESOURCES if resources else (), description="benchmarks/profiles_tick.py")


class _Clock:
    __slots__ = ("t",)

    def __init__(self):
        self.t = 0


def _btfsm_impls(clock, log):
    """Runtime implementations: each action answers ``leaf_status`` of the global tick."""
    class Leaf:
        __slots__ = ("name",)

        def __init__(self, name):
            self.name = name

        def tick(self, call):
            if log is not None:
                log.append((self.name, "start" if call.first else "running"))
            return leaf_status(self.name, clock.t).lower()

        def halt(self, call):
            if log is not None:
                log.append((self.name, "halt"))
    return {n: Leaf(n) for n, s in LEAVES.items() if s[0] == "act"}


def run_btfsm(semantics: str, ticks: int, log: bool = True):
    """``(per-tick logs, root statuses, exclusive violations)`` of the Runtime."""
    clock, calls = _Clock(), ([] if log else None)
    rt = Runtime(build_model(ticks, semantics), _btfsm_impls(clock, calls), record=log)
    conds = {n for n, s in LEAVES.items() if s[0] == "cond"}
    acts = set(LEAVES) - conds
    out, roots, excl = [], [], 0
    events = ("clock",)
    for k in range(1, ticks + 1):
        clock.t = k
        if calls is not None:
            calls.clear()
        step = rt.tick(events)
        excl += sum(1 for v in step.violations if v[0] == "exclusive")
        if log:
            # conditions are expressions in btfsm: their ticks are the recorded status events,
            # merged with the action calls in tick order (an action's status event follows its call)
            merged, it = [], iter(calls)
            for ev in step.events:
                if ev[0] == "status" and ev[1] in conds:
                    merged.append((ev[1], "tick"))
                elif ev[0] in ("outcome", "halt") and ev[1] in acts:
                    merged.append(next(it))
            merged.extend(it)
            out.append(tuple(merged))
            roots.append(step.status.name)
    return out, roots, excl


class _StepOracle:
    """Answers ``Program.step`` like the implementations (no Runtime): the timing of the bare step.
    Per action, like a BT.CPP callback: ``leaf_status`` and one dict look-up of its answer
    (here to the index of the outcome of that name)."""

    __slots__ = ("clock", "index")

    def __init__(self, prog, clock):
        self.clock = clock
        self.index = {site.index: (site.node, {o[2].upper(): k for k, o in enumerate(site.outcomes)})
                      for site in prog.sites}

    def env(self, i):
        return True

    def outcome(self, site):
        name, idx = self.index[site.index]
        return idx[leaf_status(name, self.clock.t)]

    def halt(self, site):
        pass


def _time_btfsm_runtime(semantics, ticks, resources=True):
    clock = _Clock()
    rt = Runtime(build_model(ticks, semantics, resources), _btfsm_impls(clock, None))
    tick, events = rt.tick, ("clock",)
    t0 = _now()
    for k in range(1, ticks + 1):
        clock.t = k
        tick(events)
    return _now() - t0


def _time_btfsm_step(semantics, ticks, resources=True):
    prog, clock = build_model(ticks, semantics, resources).program, _Clock()
    oracle, s, step = _StepOracle(prog, clock), prog.initial, prog.step
    t0 = _now()
    for k in range(1, ticks + 1):
        clock.t = k
        s = step(s, oracle).state
    return _now() - t0


# --------------------------------------------------------------------------- BehaviorTree.CPP

_BTCPP_TAGS = {"rseq": "ReactiveSequence", "rfb": "ReactiveFallback", "mseq": "Sequence", "mfb": "Fallback",
               "inv": "Inverter", "fs": "ForceSuccess"}


def btcpp_xml() -> str:
    """The tree as BehaviorTree.CPP 4 XML; each leaf is its own node type, named like the node.

    >>> btcpp_xml().splitlines()[2].strip()
    '<ReactiveSequence name="root">'
    """
    lines = ['<root BTCPP_format="4" main_tree_to_execute="Main">', '  <BehaviorTree ID="Main">']

    def emit(s, depth):
        kind, name, p = s
        pad = "  " * depth
        if kind in ("cond", "act"):
            lines.append(f'{pad}<{name} name="{name}"/>')
            return
        lines.append(f'{pad}<{_BTCPP_TAGS[kind]} name="{name}">')
        for kid in p:
            emit(kid, depth + 1)
        lines.append(f"{pad}</{_BTCPP_TAGS[kind]}>")
    emit(SPEC, 2)
    lines += ["  </BehaviorTree>", "</root>"]
    return "\n".join(lines)


def _btcpp_tree(clock, log):
    import behaviortreepy as bt

    status = {RUNNING: bt.NodeStatus.RUNNING, SUCCESS: bt.NodeStatus.SUCCESS, FAILURE: bt.NodeStatus.FAILURE}
    f = bt.BehaviorTreeFactory()
    for name, s in LEAVES.items():
        if s[0] == "cond":
            if log is None:
                def cond(node, n=name):
                    return status[leaf_status(n, clock.t)]
            else:
                def cond(node, n=name):
                    log.append((n, "tick"))
                    return status[leaf_status(n, clock.t)]
            f.register_simple_condition(name, cond)
        else:
            if log is None:
                def go(node, n=name):
                    return status[leaf_status(n, clock.t)]
                f.register_simple_stateful_action(name, go, go, lambda node: None)
            else:
                def start(node, n=name):
                    log.append((n, "start"))
                    return status[leaf_status(n, clock.t)]

                def again(node, n=name):
                    log.append((n, "running"))
                    return status[leaf_status(n, clock.t)]

                def halted(node, n=name):
                    log.append((n, "halt"))
                f.register_simple_stateful_action(name, start, again, halted)
    return f.create_tree_from_text(btcpp_xml())


def run_btcpp(ticks: int):
    clock, log = _Clock(), []
    tree = _btcpp_tree(clock, log)
    out, roots = [], []
    for k in range(1, ticks + 1):
        clock.t = k
        log.clear()
        st = tree.tick_exactly_once()
        out.append(tuple(log))
        roots.append(st.name)
    return out, roots, None


def _time_btcpp(ticks):
    clock = _Clock()
    tick = _btcpp_tree(clock, None).tick_exactly_once
    t0 = _now()
    for k in range(1, ticks + 1):
        clock.t = k
        tick()
    return _now() - t0


# --------------------------------------------------------------------------- py_trees


def _pytrees_tree(clock, log):
    import py_trees
    from py_trees.common import Status

    status = {RUNNING: Status.RUNNING, SUCCESS: Status.SUCCESS, FAILURE: Status.FAILURE}

    class Cond(py_trees.behaviour.Behaviour):
        def update(self):
            if log is not None:
                log.append((self.name, "tick"))
            return status[leaf_status(self.name, clock.t)]

    class Act(py_trees.behaviour.Behaviour):
        def __init__(self, name):
            super().__init__(name)
            self.fresh = True

        def initialise(self):
            self.fresh = True

        def update(self):
            if log is not None:
                log.append((self.name, "start" if self.fresh else "running"))
            self.fresh = False
            return status[leaf_status(self.name, clock.t)]

        def terminate(self, new_status):
            if new_status == Status.INVALID and self.status == Status.RUNNING and log is not None:
                log.append((self.name, "halt"))

    seq, sel, dec = py_trees.composites.Sequence, py_trees.composites.Selector, py_trees.decorators

    def node(s):
        kind, name, p = s
        if kind == "cond":
            return Cond(name)
        if kind == "act":
            return Act(name)
        kids = [node(k) for k in p]
        if kind == "inv":
            return dec.Inverter(name, child=kids[0])
        if kind == "fs":
            return dec.FailureIsSuccess(name, child=kids[0])
        if kind in ("rseq", "mseq"):
            return seq(name, memory=kind == "mseq", children=kids)
        return sel(name, memory=kind == "mfb", children=kids)
    tree = py_trees.trees.BehaviourTree(node(SPEC))
    tree.setup(timeout=15)
    return tree


def run_pytrees(ticks: int):
    clock, log = _Clock(), []
    tree = _pytrees_tree(clock, log)
    out, roots = [], []
    for k in range(1, ticks + 1):
        clock.t = k
        log.clear()
        tree.tick()
        out.append(tuple(log))
        roots.append(tree.root.status.name)
    return out, roots, None


def _time_pytrees(ticks):
    clock = _Clock()
    tick = _pytrees_tree(clock, None).tick
    t0 = _now()
    for k in range(1, ticks + 1):
        clock.t = k
        tick()
    return _now() - t0


# --------------------------------------------------------------------------- the run


def compare(a, b) -> dict:
    """Ticks whose leaf-call sequence or root status differ, and the first such tick."""
    (la, ra, _), (lb, rb, _) = a, b
    bad = [k for k in range(len(la)) if la[k] != lb[k] or ra[k] != rb[k]]
    first = None
    if bad:
        k = bad[0]
        first = {"tick": k + 1, "a": [list(x) for x in la[k]], "a_root": ra[k], "b": [list(x) for x in lb[k]],
                 "b_root": rb[k]}
    return {"ticks": len(la), "differing_ticks": len(bad), "first": first}


def _timed(modes: dict, ticks, repeats) -> dict:
    """One warm-up run per mode, then ``repeats`` rounds that time every mode once each
    (round robin, so a busy spell of the machine hits every engine alike): the median."""
    for fn in modes.values():
        fn(ticks)
    secs: dict = {m: [] for m in modes}
    for _ in range(repeats):
        for m, fn in modes.items():
            secs[m].append(fn(ticks))
    out = {}
    for m, xs in secs.items():
        med = statistics.median(xs)
        out[m] = {"ticks_per_s": ticks / med, "us_per_tick": 1e6 * med / ticks, "min_s": min(xs), "max_s": max(xs)}
    return out


def measure(ticks: int, repeats: int, check_ticks: int, clock: str = "wall") -> dict:
    import behaviortreepy
    import py_trees

    global _now
    _now = CLOCKS[clock]

    runs = {f"btfsm[{s}]": run_btfsm(s, check_ticks) for s in SEMANTICS}
    runs["BT.CPP"] = run_btcpp(check_ticks)
    runs["py_trees"] = run_pytrees(check_ticks)
    agreement = {
        "btfsm[btcpp] vs BT.CPP": compare(runs["btfsm[btcpp]"], runs["BT.CPP"]),
        "btfsm[pytrees] vs py_trees": compare(runs["btfsm[pytrees]"], runs["py_trees"]),
        "btfsm[btfsm] vs BT.CPP": compare(runs["btfsm[btfsm]"], runs["BT.CPP"]),
        "btfsm[btfsm] vs py_trees": compare(runs["btfsm[btfsm]"], runs["py_trees"]),
        "BT.CPP vs py_trees": compare(runs["BT.CPP"], runs["py_trees"]),
    }
    claimed = ("btfsm[btcpp] vs BT.CPP", "btfsm[pytrees] vs py_trees")
    exclusive = {name: r[2] for name, r in runs.items() if r[2] is not None}
    modes = {}
    for s in SEMANTICS:
        modes[f"btfsm[{s}] runtime"] = lambda n, s=s: _time_btfsm_runtime(s, n)
        modes[f"btfsm[{s}] step"] = lambda n, s=s: _time_btfsm_step(s, n)
    modes["btfsm[btfsm] runtime, no resources"] = lambda n: _time_btfsm_runtime("btfsm", n, False)
    modes["btfsm[btfsm] step, no resources"] = lambda n: _time_btfsm_step("btfsm", n, False)
    modes["BT.CPP (behaviortreepy)"] = _time_btcpp
    modes["py_trees"] = _time_pytrees
    timings = _timed(modes, ticks, repeats)
    return {"python": platform.python_version(), "py_trees": py_trees.version.__version__,
            "behaviortreepy": getattr(behaviortreepy, "__version__", "?"), "machine": platform.machine(),
            "nproc": os.cpu_count(), "ticks": ticks, "repeats": repeats, "check_ticks": check_ticks, "clock": clock,
            "nodes": sum(1 for _ in _walk(SPEC)), "leaves": len(LEAVES),
            "agreement": agreement, "claimed_equal": {k: agreement[k]["differing_ticks"] == 0 for k in claimed},
            "exclusive_violations": exclusive, "timings": timings}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ticks", type=int, default=20000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--check-ticks", type=int, default=2000)
    ap.add_argument("--clock", choices=sorted(CLOCKS), default="wall",
                    help="time the ticks by the wall clock (default) or by this process's CPU time")
    ap.add_argument("--json", action="store_true", help="print one JSON object only")
    args = ap.parse_args(argv)
    if min(args.ticks, args.repeats, args.check_ticks) < 1:
        ap.error("--ticks, --repeats and --check-ticks must be positive")
    missing = [m for m in ("behaviortreepy", "py_trees") if importlib.util.find_spec(m) is None]
    if missing:
        print(f"profiles_tick: {', '.join(missing)} not installed (pip install -e .[test])", file=sys.stderr)
        return 2
    rep = measure(args.ticks, args.repeats, args.check_ticks, args.clock)
    ok = all(rep["claimed_equal"].values())
    if args.json:
        print(json.dumps(rep))
        return 0 if ok else 1
    print(f"python {rep['python']}  py_trees {rep['py_trees']}  behaviortreepy {rep['behaviortreepy']}  "
          f"{rep['machine']} x{rep['nproc']}  nodes={rep['nodes']} leaves={rep['leaves']}  "
          f"ticks={args.ticks} x{args.repeats}  clock={args.clock}")
    print(f"agreement over {args.check_ticks} ticks (leaf callbacks in order + root status):")
    for k, c in rep["agreement"].items():
        claim = "  (claimed equal)" if k in rep["claimed_equal"] else ""
        print(f"  {k:28s} {c['differing_ticks']:5d} differing tick(s){claim}")
        if c["first"] is not None and k in rep["claimed_equal"]:
            print(f"      first at tick {c['first']['tick']}: {c['first']['a']} {c['first']['a_root']} "
                  f"vs {c['first']['b']} {c['first']['b_root']}")
    print("exclusive-resource violations (resource base):",
          ", ".join(f"{k} {v}" for k, v in rep["exclusive_violations"].items()))
    t = rep["timings"]
    ref_cpp, ref_py = t["BT.CPP (behaviortreepy)"]["ticks_per_s"], t["py_trees"]["ticks_per_s"]
    print(f"{'engine':36s} {'ticks/s':>9s} {'us/tick':>8s} {'vs BT.CPP':>9s} {'vs py_trees':>11s}")
    for mode, r in t.items():
        print(f"{mode:36s} {r['ticks_per_s']:9.0f} {r['us_per_tick']:8.2f} {r['ticks_per_s'] / ref_cpp:8.2f}x "
              f"{r['ticks_per_s'] / ref_py:10.2f}x")
    if not ok:
        print("profiles_tick: a profile did not agree with its engine (see above)", file=sys.stderr)
    return 0 if ok else 1


if __name__ == "__main__":
    raise SystemExit(main())
