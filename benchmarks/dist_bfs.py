"""The hash-partitioned BFS on a local two-worker Dask cluster against the one-process
search (issue 13, point 5; docs/verification.md, "Past one machine").

Usage: ``python3 benchmarks/dist_bfs.py [--size N] [--workers W] [--message-min M] [--threads]``

Explores ``btfsm.models.pickplace.pickplace(N)`` (default 12: 1,305,694 states) once with
``btfsm.verify.explore.explore`` (one process, the traced engine) and once with
``btfsm.verify.distributed.explore_distributed`` on a ``LocalCluster`` of W worker
processes (``--threads``: worker threads in this process), prints both counts, whether
they are equal, and the wall time of each (the cluster's start-up not included).
Needs the ``dist`` extra (``dask[distributed]``).
"""
from __future__ import annotations

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=12)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--message-min", type=int, default=10_000, help="states per message (0: level-synchronous)")
    ap.add_argument("--threads", action="store_true", help="workers as threads of this process")
    a = ap.parse_args()
    from dask.distributed import Client, LocalCluster

    from btfsm.models.pickplace import pickplace
    from btfsm.verify.distributed import explore_distributed
    from btfsm.verify.explore import explore

    t = time.perf_counter()
    ts = explore(pickplace(a.size))
    one = time.perf_counter() - t
    print(f"one process : {ts.n_states:,} states, {ts.n_transitions:,} transitions, {one:.1f} s")
    want = (ts.n_states, ts.n_transitions)
    del ts
    with LocalCluster(n_workers=a.workers, threads_per_worker=1, processes=not a.threads,
                      dashboard_address=None) as cluster, Client(cluster) as client:
        r = explore_distributed(client, pickplace, (a.size,), message_min=a.message_min)
    print(f"{a.workers} workers   : {r.states:,} states, {r.transitions:,} transitions, {r.seconds:.1f} s "
          f"({r.levels} rounds; states per partition {r.per_partition}; {r.messages} messages, "
          f"largest {r.largest_message:,} states, {r.states_sent:,} states sent)")
    same = (r.states, r.transitions) == want
    print("exact counts: " + ("equal" if same else "DIFFERENT"))
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
