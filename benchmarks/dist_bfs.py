"""The partitioned search on Dask against the one-process search, 1 and 2 workers in the
same run (issue 13, point 5; issue 24, point 2; docs/verification.md, section 6).

Usage: ``python3 benchmarks/dist_bfs.py [--size N] [--workers 1 2] [--scheduler ADDRESS]
[--check] [--simulate 2 16 64] [--free-cores 2] [--capacity]``

Explores ``btfsm.models.pickplace.pickplace(N)`` (default 12: 1,305,694 states):

* once with ``btfsm.verify.explore.explore`` (one process, the traced engine, the whole
  system stored) in a child process, for its wall time, CPU time and peak memory;
* once with the partitions' own search with one partition (``simulate(model, 1)``: the
  same engine's batches and seen set, counts only, no Dask) in a child process: the
  like-for-like one-process figure;
* then with ``btfsm.verify.distributed.explore_distributed`` on a fresh ``LocalCluster``
  of W worker processes (one thread each) for each W of ``--workers`` (default 1 and 2),
  or on the running cluster at ``--scheduler``: the counts, whether they equal the
  one-process ones, the wall time (from the client's call to the counts; the cluster's
  start-up and the workers' imports not included, the partition key's pilot and the
  workers' model building included), the speed-up over both one-process runs, the CPU
  seconds of each worker process during the search (all its threads: a measure of the
  overheads that the machine's load hardly changes, unlike the wall time), and each
  worker's peak RSS; the load average beside each line;
* ``--check``: also ``check_distributed`` (transitions kept, no-dead-states at model
  level and workable-reachability over the partitions) next to the one-process verdicts;
* ``--capacity`` (first): one single-partition search alone, then two at once, in child
  processes: on a shared machine, how much work a second core does now (x2.00 when it
  is free), the ceiling of any 2-worker speed-up in the same run;
* ``--simulate P...``: the same partitions run one after the other in this process
  (``btfsm.verify.distributed.simulate``, no Dask) for P partitions: rounds, messages,
  states sent and states per partition (the message volume for 16 and 64 workers);
* ``--free-cores P...``: the search without rounds of P partitions in this process, each
  step on a clock of its CPU seconds (``simulate(rounds=False)``): the partitions' work on
  P free cores (the makespan), next to one partition's CPU seconds in the same process
  (the lesser of a run before and a run after them), a figure that a loaded machine does
  not ruin.

Needs the ``dist`` extra (``dask[distributed]``). Exit 1 when a count differs.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

_ONE = """
import json, resource, sys, time
from btfsm.models.pickplace import pickplace
from btfsm.verify.explore import explore
t, cpu = time.perf_counter(), time.process_time()
ts = explore(pickplace({n}))
s = time.perf_counter() - t
out = {{"states": ts.n_states, "transitions": ts.n_transitions, "seconds": s, "cpu": time.process_time() - cpu,
        "rss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024}}
if {check}:
    from btfsm.verify.properties import dead, workable
    m = ts.model
    out["traps"] = int(workable.traps(ts).size)
    out["dead"] = int(dead.dead_states(ts).size)
    out["sinks"] = sorted(f.name for f in m.fsms if dead.reachable_sinks(ts, f) is not None)
    out["check_seconds"] = time.perf_counter() - t
    out["check_rss"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
print(json.dumps(out))
"""

# the same search as the partitions' (``Partition``: the traced engine's batches, a seen
# bitmap, counts only) with one partition, in one process and without Dask: like for like
_COUNT = """
import json, resource, sys, time
from btfsm.models.pickplace import pickplace
from btfsm.verify.distributed import simulate
t, cpu = time.perf_counter(), time.process_time()
r = simulate(pickplace({n}), 1, key=())
print(json.dumps({{"states": r.states, "transitions": r.transitions, "seconds": time.perf_counter() - t,
                  "cpu": time.process_time() - cpu, "rss": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024}}))
"""


def _peak() -> int:
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def _cpu() -> float:
    """This process's CPU seconds (a worker's, through ``client.run``): all its threads."""
    import resource

    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


def _warm() -> None:
    """A worker imports the modules of the search (as after a first job): their import is
    not part of the search, as it is not of the one-process runs' times."""
    import btfsm.models.pickplace  # noqa: F401
    import btfsm.verify.distributed  # noqa: F401


def _load() -> str:
    return "load " + " ".join(f"{x:.2f}" for x in os.getloadavg())


def _child(code, root) -> dict:
    return json.loads(subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True,
                                     cwd=root).stdout)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=12)
    ap.add_argument("--workers", type=int, nargs="*", default=[1, 2], help="local clusters to run (none: only --simulate)")
    ap.add_argument("--round-states", type=int, default=None, metavar="N",
                    help="with --simulate: states a partition expands per round at most (default ROUND_STATES)")
    ap.add_argument("--scheduler", default=None, metavar="ADDRESS",
                    help="a running Dask scheduler (tcp://HOST:PORT) instead of local clusters")
    ap.add_argument("--message-min", type=int, default=None, help="states bound elsewhere that end a round")
    ap.add_argument("--check", action="store_true", help="also the partitioned checks")
    ap.add_argument("--simulate", type=int, nargs="*", default=[], metavar="P",
                    help="simulate P partitions in this process (message volume)")
    ap.add_argument("--free-cores", type=int, nargs="*", default=[], metavar="P",
                    help="the search without rounds of P partitions on a clock of CPU seconds, in this process: "
                         "their work on P free cores, against one partition's CPU seconds")
    ap.add_argument("--capacity", action="store_true",
                    help="first measure what a second core gives now: one single-partition search alone, then two at once")
    a = ap.parse_args()
    from btfsm.models.pickplace import pickplace
    from btfsm.verify import distributed as dist

    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
    if a.capacity:  # a shared machine: how much a second process gets done beside a first
        solo = f"from btfsm.models.pickplace import pickplace; from btfsm.verify.distributed import simulate; simulate(pickplace({a.size}), 1)"
        t = time.perf_counter()
        subprocess.run([sys.executable, "-c", solo], check=True, cwd=root)
        alone = time.perf_counter() - t
        t = time.perf_counter()
        pair = [subprocess.Popen([sys.executable, "-c", solo], cwd=root) for _ in range(2)]
        for p in pair:
            p.wait()
        both = time.perf_counter() - t
        print(f"capacity    : one single-partition search alone {alone:.2f} s, two at once {both:.2f} s: "
              f"the machine gives x{2 * alone / both:.2f} the work of one process now")
    print(_load())
    one = _child(_ONE.format(n=a.size, check=a.check), root)
    print(f"one process : {one['states']:,} states, {one['transitions']:,} transitions, {one['seconds']:.2f} s "
          f"({one['cpu']:.2f} CPU s), peak RSS {one['rss'] / 2**20:,.0f} MB (explore: the whole system stored); "
          f"{_load()}")
    if a.check:
        print(f"{'':12}  with the traps, dead and sink states: {one['check_seconds']:.2f} s, peak RSS "
              f"{one['check_rss'] / 2**20:,.0f} MB")
    count = _child(_COUNT.format(n=a.size), root)
    print(f"one process : {count['states']:,} states, {count['transitions']:,} transitions, {count['seconds']:.2f} s "
          f"({count['cpu']:.2f} CPU s), peak RSS {count['rss'] / 2**20:,.0f} MB (the partitions' search, 1 partition, "
          f"no Dask: counts only, like for like); {_load()}")
    want = (one["states"], one["transitions"])
    ok = (count["states"], count["transitions"]) == want
    kw = {} if a.message_min is None else {"message_min": a.message_min}
    runs = [None] if a.scheduler else a.workers
    for w in runs:
        with dist.cluster(a.scheduler, w or 2) as client:
            client.run(_warm)
            cpu0 = client.run(_cpu)
            r = dist.explore_distributed(client, pickplace, (a.size,), **kw)
            cpu1 = client.run(_cpu)
            peaks = sorted(client.run(_peak).values())
            c = dist.check_distributed(client, pickplace, (a.size,), **kw) if a.check else None
            check_peaks = sorted(client.run(_peak).values()) if a.check else None
        label = f"{len(r.per_partition)} worker{'s' if len(r.per_partition) > 1 else ' '}"
        same = (r.states, r.transitions) == want
        ok &= same
        spent = sorted(cpu1[k] - cpu0[k] for k in cpu1)  # each worker process's CPU seconds, all its threads
        steps = f"{r.levels} round{'s' if r.levels > 1 else ''}" if len(r.per_partition) == 1 else \
            f"no rounds: {r.levels} steps in the busiest partition"
        print(f"{label:12}: {r.states:,} states, {r.transitions:,} transitions, {r.seconds:.2f} s "
              f"(x{one['seconds'] / r.seconds:.2f} explore, x{count['seconds'] / r.seconds:.2f} the one-process "
              f"count; {steps}; states per partition {r.per_partition}; {r.messages} messages, largest "
              f"{r.largest_message:,} states, {r.states_sent:,} states sent; the busiest partition's work "
              f"{r.work_seconds:.2f} s, the rest {r.seconds - r.work_seconds:.2f} s (start-up, waits, messages); "
              f"CPU of the worker processes {' + '.join(f'{x:.2f}' for x in spent)} = {sum(spent):.2f} s "
              f"(x{sum(spent) / count['cpu']:.2f} the one-process count's {count['cpu']:.2f}), of the partitions' "
              f"steps {r.cpu_seconds:.2f} s, the busiest {r.cpu_path:.2f} s; peak RSS per worker "
              f"{', '.join(f'{p / 2**20:,.0f}' for p in peaks)} MB); counts {'equal' if same else 'DIFFERENT'}; "
              f"{_load()}")
        if c is not None:
            mine = {"traps": c.traps, "dead": c.dead, "sinks": sorted(k for k, v in c.sinks.items() if v)}
            theirs = {k: one[k] for k in mine}
            ok &= mine == theirs
            print(f"{'':12}  checks in {c.seconds:.2f} s: {mine} (one process {theirs}); verdicts {c.verdicts}; "
                  f"{c.back_rounds} rounds backwards; peak RSS per worker "
                  f"{', '.join(f'{p / 2**20:,.0f}' for p in check_peaks)} MB")
    if a.simulate:
        model = pickplace(a.size)
        for p in a.simulate:
            t = time.perf_counter()
            r = dist.simulate(model, p, **kw, **({} if a.round_states is None else {"round_states": a.round_states}))
            same = (r.states, r.transitions) == want
            ok &= same
            sizes = r.per_partition
            print(f"simulated {p:3} partitions: {r.levels} rounds, {r.messages} messages, {r.states_sent:,} states sent "
                  f"({r.states_sent / r.states:.1%} of the states), largest {r.largest_message:,}; critical path "
                  f"{r.critical_path:,} states (ideal speed-up {r.ideal_speedup:.2f}); states per partition "
                  f"min {min(sizes):,} max {max(sizes):,} (mean {r.states / p:,.0f}); counts {'equal' if same else 'DIFFERENT'}; "
                  f"{time.perf_counter() - t:.1f} s in one process")
    if a.free_cores:
        model = pickplace(a.size)
        solo = dist.simulate(model, 1, key=())
        ok &= (solo.states, solo.transitions) == want
        print(f"one partition in this process: {solo.cpu_seconds:.2f} CPU s; {_load()}")
        runs = [(p, dist.simulate(model, p, **kw, rounds=False)) for p in a.free_cores]
        again = dist.simulate(model, 1, key=()).cpu_seconds  # CPU seconds move with the load: the lesser of two
        base = min(solo.cpu_seconds, again)
        print(f"one partition again, after them: {again:.2f} CPU s (the ratios below: against {base:.2f}); {_load()}")
        for p, r in runs:
            same = (r.states, r.transitions) == want
            ok &= same
            print(f"{p} partitions without rounds on {p} free cores: {r.makespan:.2f} s of the partitions' work "
                  f"(x{base / r.makespan:.2f} one partition; Dask and its messages aside), CPU "
                  f"{r.cpu_seconds:.2f} s in all (x{r.cpu_seconds / base:.2f} one partition's), the busiest "
                  f"{r.cpu_path:.2f} s; {r.levels} steps in the busiest partition, {r.messages} messages, {r.states_sent:,} states "
                  f"sent; counts "
                  f"{'equal' if same else 'DIFFERENT'}; {_load()}")
    print("exact counts: " + ("equal" if ok else "DIFFERENT"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
