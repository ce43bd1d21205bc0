"""Past one machine, in miniature: a breadth-first search whose states are partitioned by
hash across Dask workers (issue 13, point 5; docs/verification.md, "Past one machine").

Every state code belongs to one partition, ``owner(code) = hash(code) mod P``; partition
``j`` lives on worker ``j`` and keeps its visited codes (a sorted int64 array: 8 bytes per
state) and its current frontier. A level is two kinds of task, each pinned to the worker
of its partition (Dask futures with ``workers=``; no data passes through the client):

1. ``expand`` on worker ``i``: the frontier of partition ``i`` through the traced engine's
   batch expansion (``btfsm.verify.traced.BatchSuccessors``: the same trie over the same
   ``Program.step`` as the one-process search, batches of ``CHUNK`` states), giving the
   level's transitions from those states and their targets cut into ``P`` buckets by owner
   (deduplicated locally). One bucket is one message: all of a level's states from ``i``
   to ``j`` travel together (at least 10^4 states per message once levels are that wide).
2. ``merge`` on worker ``j``: the ``P`` buckets addressed to ``j`` (Dask moves them worker
   to worker), minus the visited codes, are the new frontier of ``j``.

Termination detection is the level barrier: the client gathers two small ints per
partition per level (transitions found, new states) and stops when a level finds no new
state anywhere; every state is expanded exactly once (it is new in exactly one level), so
the sums are the exact state and transition counts of the one-process search. Only
counts come back: no transition arrays, no parent pointers (docs/verification.md says what
the properties would need).

Needs ``dask[distributed]`` (the ``dist`` extra) and a model the traced engine can follow.

>>> from btfsm.verify.distributed import owner
>>> import numpy as np
>>> owner(np.arange(6), 2).tolist()
[0, 1, 1, 1, 0, 0]
"""
from __future__ import annotations

import operator
import threading
import time
from dataclasses import dataclass, field

import numpy as np

from .traced import CHUNK, BatchSuccessors

__all__ = ["owner", "DistributedCounts", "explore_distributed", "MESSAGE_MIN"]

MESSAGE_MIN = 10_000  # states per message the design aims at (a level's bucket, see above)
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_ENGINES: dict = {}
_LOCK = threading.Lock()


def owner(codes: np.ndarray, parts: int) -> np.ndarray:
    """Partition of each state code: a multiplicative hash (Fibonacci hashing) mod ``parts``."""
    h = (np.asarray(codes, np.int64).astype(np.uint64) * _GOLDEN) >> np.uint64(40)
    return (h % np.uint64(parts)).astype(np.int64)


@dataclass
class DistributedCounts:
    """What a distributed search returns: exact counts, and how the work was spread."""

    states: int
    transitions: int
    levels: int
    seconds: float
    per_partition: list = field(default_factory=list)  # states owned by each partition
    messages: int = 0  # non-empty buckets sent
    largest_message: int = 0  # states in the largest bucket
    states_sent: int = 0  # states in all buckets (after local deduplication)


def _engine(spec) -> BatchSuccessors:
    """One engine per (model, thread): the trie is built lazily and is not thread-safe."""
    key = (spec, threading.get_ident())
    with _LOCK:
        eng = _ENGINES.get(key)
    if eng is None:
        factory, args, kwargs = spec
        eng = BatchSuccessors(factory(*args, **dict(kwargs)))
        with _LOCK:
            _ENGINES[key] = eng
    return eng


def _initial(spec) -> int:
    return int(_engine(spec).initial)


def _merge(visited: np.ndarray, incoming: np.ndarray):
    """(visited with the new codes, the new codes): ``incoming`` sorted and unique."""
    pos = np.searchsorted(visited, incoming)
    seen = np.zeros(len(incoming), bool)
    inside = pos < len(visited)
    seen[inside] = visited[pos[inside]] == incoming[inside]
    new = incoming[~seen]
    return np.insert(visited, pos[~seen], new), new


def _round(spec, me: int, parts: int, message_min: int, part, *incoming):
    """One round of partition ``me``: ``part`` is (visited, pending frontier); the
    ``incoming`` buckets are the codes other partitions sent it last round. Expands its
    frontier level by level, keeping its own targets, until the buckets for the others
    hold ``message_min`` states (or nothing is left to expand). Returns ((visited,
    pending), buckets by owner, (transitions, states sent, pending))."""
    visited, frontier = part
    eng = _engine(spec)
    got = [b for b in incoming if len(b)]
    if got:
        visited, new = _merge(visited, np.unique(np.concatenate(got)))
        frontier = np.union1d(frontier, new)
    out: list = [[] for _ in range(parts)]
    nt = sent = 0
    while len(frontier):
        targets = []
        for a in range(0, len(frontier), CHUNK):
            _rows, dst = eng(frontier[a:a + CHUNK])
            nt += len(dst)
            targets.append(np.unique(dst))
        dst = np.unique(np.concatenate(targets))
        own = owner(dst, parts)
        for j in range(parts):
            if j != me:
                out[j].append(dst[own == j])
                sent += int(np.count_nonzero(own == j))
        visited, frontier = _merge(visited, dst[own == me])
        if sent >= message_min:
            break
    buckets = tuple(np.unique(np.concatenate(b)) if b else np.zeros(0, np.int64) for b in out)
    return (visited, frontier), buckets, (nt, [len(b) for b in buckets], len(frontier))


def _bucket(result, j):
    return result[1][j]


def explore_distributed(client, factory, args=(), kwargs=None, *, workers=None,
                        message_min: int = MESSAGE_MIN) -> DistributedCounts:
    """Explore ``factory(*args, **kwargs)`` (a function returning a Model, importable on
    the workers) breadth-first, one partition per worker of ``client`` (or per address in
    ``workers``); returns exact state and transition counts. ``message_min``: a partition
    goes on expanding its own states within a round until it has this many states to
    send (0: one BFS level per round, a level-synchronous search)."""
    t0 = time.perf_counter()
    spec = (factory, tuple(args), tuple(sorted((kwargs or {}).items())))
    addrs = list(workers) if workers is not None else sorted(client.scheduler_info()["workers"])
    parts = len(addrs)

    def on(j, fn, *a):
        return client.submit(fn, *a, workers=[addrs[j]], allow_other_workers=False, pure=False)

    c0 = client.submit(_initial, spec, workers=[addrs[0]], pure=False).result()
    home = int(owner(np.array([c0]), parts)[0])
    start = np.array([c0], np.int64)
    empty = np.zeros(0, np.int64)
    part = [client.scatter((start, start) if j == home else (empty, empty), workers=[addrs[j]], hash=False)
            for j in range(parts)]
    inbox: list = [[] for _ in range(parts)]
    counts = DistributedCounts(states=0, transitions=0, levels=0, seconds=0.0)
    while True:
        res = [on(j, _round, spec, j, parts, message_min, part[j], *inbox[j]) for j in range(parts)]
        part = [on(j, operator.getitem, res[j], 0) for j in range(parts)]
        inbox = [[on(i, _bucket, res[i], j) for i in range(parts) if i != j] for j in range(parts)]
        stats = client.gather([on(j, operator.getitem, res[j], 2) for j in range(parts)])  # the round barrier
        counts.levels += 1
        counts.transitions += sum(nt for nt, _, _ in stats)
        flat = [k for _, sizes, _ in stats for k in sizes]
        counts.messages += sum(1 for k in flat if k)
        counts.states_sent += sum(flat)
        counts.largest_message = max([counts.largest_message, *flat])
        del res
        if sum(flat) == 0 and all(left == 0 for _, _, left in stats):
            break
    counts.per_partition = client.gather([on(j, _count, part[j]) for j in range(parts)])
    counts.states = sum(counts.per_partition)
    counts.seconds = time.perf_counter() - t0
    return counts


def _count(part) -> int:
    return len(part[0])
