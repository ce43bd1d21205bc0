"""Past one machine: a search whose states are partitioned across Dask workers, and the
checks that run on the partitions (issue 13, point 5; issue 24, point 2;
docs/verification.md, section 6 "Past one machine").

Every state code belongs to one partition, ``owner(code, P, key)``: a multiplicative hash
of the code's *key* mod ``P``. The key is the values of the few slots that transitions
change least (``partition_key``: measured on a short seeded pilot search, so the same key
every time), as in Lerda and Sisto's partitioning of SPIN's state space by one process's
local state: a transition that leaves the key alone stays in its partition, so on
pick/place about 6 % of the states travel instead of half of them with a hash of the whole
code. A partition is a ``Partition`` object living on one worker (a Dask actor): its seen
codes (a bitmap over the code space, or a sorted array past ``DENSE_LIMIT``), its owned
codes in discovery order (the queue of states still to expand is their tail) and, with
``keep=True``, the out-transitions of its states (target codes, by state).

The search goes in steps. In a step a partition (1) queues the codes the others sent it
that it has not seen, (2) expands its queue in batches of up to ``CHUNK`` states through
the traced engine's batch expansion (``btfsm.verify.traced.BatchSuccessors``: the trie
over ``Program.step`` that the one-process search runs), queueing the new targets it owns
at once and cutting the others' new targets into one bucket per owner (a code is sent
once: sent codes are marked seen too), (3) stops after ``ROUND_STATES`` expanded states
(so that no partition goes on alone while the others wait for its states), when the
buckets hold ``message_min`` states, or when its queue is empty. On Dask (``_Actor.run``)
a partition takes steps while it has work and sends each bucket (an int64 array) straight
to the owner's actor, worker to worker, without waiting, and sleeps when it has none; the
client detects the end by Mattern's counting of buckets sent and received
(``_remote_run``): no rounds, no barrier. ``simulate`` runs the steps in rounds (every
partition one step, then every delivery: the figures of the docs' tables) or, with
``rounds=False``, as on Dask on a clock of CPU seconds (``_free_cores``). Every state is
expanded exactly once (its owner queues it once), so the sums are the exact state and
transition counts of the one-process search, whatever ``P`` and the order of deliveries.

The checks that ``keep=True`` makes possible (``check_distributed``): *no-dead-states* at
model level (a state with no successor that is not terminal and not a domain error; an FSM
token on a sink state) is judged by each partition on its own states; *workable-
reachability* (AG EF workable) is a backward reachability over the partitions: each
partition ships its reversed transitions to the target's owner once, then rounds of steps
like the search's spread "can reach a workable state" backwards until nothing changes; the states
never reached are the traps. ``simulate`` runs the same partitions one after the other in
this process (no Dask): the same counts, rounds and message volume for any ``P`` (the 16-
and 64-worker figures of the docs).

Needs ``dask[distributed]`` (the ``dist`` extra) for ``explore_distributed``,
``check_distributed`` and ``cluster``, and a model the traced engine can follow.

>>> import numpy as np
>>> owner(np.arange(6), 2).tolist()
[0, 1, 1, 1, 0, 0]
>>> key = ((10, 10),)  # the tens digit alone decides
>>> owner(np.array([3, 7, 13, 17, 23]), 2, key).tolist()
[0, 0, 1, 1, 1]
"""
from __future__ import annotations

import asyncio
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np

from .traced import CHUNK, DENSE_LIMIT, STEP, BatchSuccessors
from .visited import FIBONACCI

__all__ = ["owner", "Partition", "DistributedCounts", "DistributedCheck", "explore_distributed",
           "check_distributed", "simulate", "cluster", "MESSAGE_MIN", "ROUND_STATES", "partition_key"]

MESSAGE_MIN = 1 << 17  # states bound elsewhere after which a partition ends its round
ROUND_STATES = 1 << 16  # states a partition expands in one round at most (with other partitions)
KEY_SPREAD = 32  # key values per partition (at least) the partition key aims at
# Dask starts its workers with MALLOC_TRIM_THRESHOLD_=65536, which freezes glibc's mmap
# threshold at 128 KiB: every batch's arrays are then fresh zero pages, and a partition
# expands at half speed (measured: 11.0 s instead of 5.6 s for pick/place at 14 in one
# process). A worker that takes a partition gets the thresholds glibc would grow to
# (``_malloc_thresholds``; mallopt's M_TRIM_THRESHOLD = -1, M_MMAP_THRESHOLD = -3).
WORKER_MALLOC = ((-3, 1 << 25), (-1, 1 << 26))
# The embedded cluster's workers without Dask's statistical profiler (it samples the
# working thread's stack every 10 ms, for a dashboard the embedded cluster does not have)
# and with the system monitor every 2 s instead of 0.5 s: an idle worker then takes about
# 1.6 % of a core instead of 3.2 % (measured), and the partition's thread is not interrupted.
QUIET_WORKERS = {"distributed.worker.profile.enabled": False, "distributed.admin.system-monitor.interval": "2s"}
CONNECT_SECONDS = 10  # to reach a running scheduler before giving up


def owner(codes: np.ndarray, parts: int, key: tuple = ()) -> np.ndarray:
    """Partition of each state code: Fibonacci hashing of its *key* (the digits of the
    slots in ``key``, pairs ``(mult, size)``; ``()``: the whole code) mod ``parts``."""
    c = np.asarray(codes, np.int64)
    if key:  # x - x // m * m, not x % m: numpy divides by a scalar fast, its remainder of int64 is slower
        d = np.zeros(len(c), np.int64)
        for mult, size in key:
            q = c // mult
            d = d * size + (q - q // size * size)
        c = d
    h = ((c.astype(np.uint64) * FIBONACCI) >> np.uint64(40)).astype(np.int64)  # 24 bits
    return h % parts


def partition_key(model, parts: int, beam: int = 64, steps: int = 32, seed: int = 0, succ=None) -> tuple:
    """The slots whose values decide the owner: those that transitions change least
    (a transition between states of equal key stays in its partition, no message), taken
    in that order until their values are at least ``KEY_SPREAD * parts`` (so the hash
    spreads states evenly). Measured on a pilot: a beam search of ``steps`` levels keeping
    ``beam`` states a level (seeded: the same key every time). Slots that never change in
    the pilot are left out (they may be constant). Returns pairs ``(mult, size)``."""
    succ = succ or BatchSuccessors(model)
    slots = model.program.slots
    mults = np.array(succ.mults, np.int64)
    sizes = np.array([max(int(s.size), 1) for s in slots], np.int64)
    rng = np.random.default_rng(seed)
    front = np.array([succ.initial], np.int64)
    changed = np.zeros(len(mults), np.int64)
    for _ in range(steps):
        rows, dst = succ(front)
        if not len(dst):
            break
        a, b = (front[rows][:, None] // mults) % sizes, (dst[:, None] // mults) % sizes
        changed += (a != b).sum(axis=0)
        u = np.unique(dst)
        front = rng.choice(u, min(beam, len(u)), replace=False) if len(u) > beam else u
    key, spread = [], 1
    for k in np.argsort(changed, kind="stable"):
        if spread >= KEY_SPREAD * parts:
            break
        if changed[k] and sizes[k] > 1:
            key.append((int(mults[k]), int(sizes[k])))
            spread *= int(sizes[k])
    return tuple(key)


# ------------------------------------------------------------------ one partition


_BYTE_BITS = np.array([bin(i).count("1") for i in range(256)], np.uint8)


def _popcount(words: np.ndarray) -> np.ndarray:
    """Set bits of each uint64 (numpy >= 2: ``bitwise_count``; else a byte table)."""
    count = getattr(np, "bitwise_count", None)
    if count is not None:
        return count(words)
    return _BYTE_BITS[words.view(np.uint8)].reshape(-1, 8).sum(axis=1, dtype=np.uint8)


def _bit(codes: np.ndarray) -> np.ndarray:
    """Each code's bit within its 64-bit word of a bitmap."""
    return np.left_shift(np.uint64(1), (codes & 63).astype(np.uint64))


def _distinct(codes: np.ndarray) -> np.ndarray:
    """The distinct values of ``codes``, sorted (one integer sort; ``np.unique`` hashes)."""
    c = np.sort(codes)
    return c[np.concatenate(([True], c[1:] != c[:-1]))] if len(c) else c


class _Seen:
    """The codes a partition has seen: its own states and the codes it has sent away
    (each is sent once). ``fresh(codes)`` gives the distinct codes not seen before, sorted,
    and marks them. A bitmap over the whole code space (``total / 8`` bytes; pages touched
    only where codes are) up to ``DENSE_LIMIT`` codes, else a sorted array (each insertion
    copies it: slower, for code spaces a bitmap cannot cover)."""

    def __init__(self, total: int):
        self.total = total
        self.bits = np.zeros((total + 7) // 8, np.uint8) if total <= DENSE_LIMIT else None  # bit c % 8 of byte c // 8
        self.sorted = np.zeros(0, np.int64)

    def fresh(self, codes: np.ndarray) -> np.ndarray:
        if not len(codes):
            return np.zeros(0, np.int64)
        if self.bits is None:
            codes = _distinct(codes)
            pos = np.searchsorted(self.sorted, codes)
            seen = np.zeros(len(codes), bool)
            inside = pos < len(self.sorted)
            seen[inside] = self.sorted[pos[inside]] == codes[inside]
            new = codes[~seen]
            self.sorted = np.insert(self.sorted, pos[~seen], new)
            return new
        bytes_ = self.bits  # a byte at a time: 3x faster than 64-bit words (fewer bytes moved)
        unseen = ((bytes_[codes >> 3] >> (codes & 7).astype(np.uint8)) & 1) == 0
        # fewer: the seen ones go first; sorted as uint32 (codes under DENSE_LIMIT fit): twice as fast
        new = _distinct(codes[unseen].astype(np.uint32)).astype(np.int64)
        if len(new):
            byte = new >> 3
            starts = np.flatnonzero(np.concatenate(([True], byte[1:] != byte[:-1])))
            bytes_[byte[starts]] |= np.bitwise_or.reduceat(np.left_shift(1, new & 7).astype(np.uint8), starts)
        return new


class Partition:
    """The states of partition ``me`` of ``parts`` and the work on them; the same object
    runs on a Dask worker (as an actor, ``_Actor``) or in this process (``simulate``).

    ``step(phase)`` is one round of ``phase`` ("explore", then with ``keep`` "reverse"
    and "back"): it takes what ``receive`` queued, works and returns one array per
    partition (what to send there; its own entry empty) and a dict of counts."""

    def __init__(self, model, me: int, parts: int, keep: bool = False, message_min: int = MESSAGE_MIN,
                 key: tuple = (), succ=None, round_states: int = ROUND_STATES):
        self.model, self.me, self.parts, self.keep, self.message_min = model, me, parts, keep, message_min
        self.round_states = round_states
        self.key = key
        self.succ = succ or BatchSuccessors(model)  # partitions in one thread may share one
        self.seen = _Seen(self.succ.total)
        self.codes = np.zeros(1024, np.int64)
        self.n = self.head = self.transitions = 0
        self.inbox: list = []
        self._lock = threading.Lock()
        self._order: "np.ndarray | None" = None  # checks: local ids in code order (``_local``)
        self._sorted: "np.ndarray | None" = None
        self._rank: tuple = ()
        self._mine: tuple = ()  # checks: this partition's own reversed transitions
        self._reversed = False
        self._early: list = []  # reversed transitions that came before this partition's first reverse round
        self.pred = np.zeros(0, np.int64)  # checks: predecessor codes, CSR by local id
        self.pptr = np.zeros(1, np.int64)
        self.degree: list = []  # keep: out-degree of each expanded state, by batch
        self.targets: list = []  # keep: target codes of each batch's transitions
        self.errors: list = []  # keep: queue positions of states with a domain error
        if owner(np.array([self.succ.initial]), parts, key)[0] == me:
            self._add(self.seen.fresh(np.array([self.succ.initial], np.int64)))

    def receive(self, codes) -> None:
        with self._lock:  # a peer's delivery may come while ``step`` runs in another thread
            self.inbox.append(codes)

    def _add(self, new):
        """Queue the new own states ``new`` (already marked seen)."""
        if self.n + len(new) > len(self.codes):
            grown = np.zeros(max(2 * len(self.codes), self.n + len(new)), np.int64)
            grown[:self.n] = self.codes[:self.n]
            self.codes = grown
        self.codes[self.n:self.n + len(new)] = new
        self.n += len(new)

    def _split(self, codes, out) -> int:
        """Own codes (sorted, distinct) queued or marked, the others appended to ``out`` by
        owner; how many went to ``out``."""
        if self.parts == 1:
            self._take(codes)
            return 0
        own = owner(codes, self.parts, self.key)
        order = np.argsort(own.astype(np.uint16) if self.parts <= 1 << 16 else own, kind="stable")  # a radix sort
        ends = np.cumsum(np.bincount(own, minlength=self.parts))
        starts = ends - np.bincount(own, minlength=self.parts)
        for j in range(self.parts):
            part = codes[order[starts[j]:ends[j]]]
            if j == self.me:
                self._take(part)
            elif len(part):
                out[j].append(part)
        return len(codes) - int(ends[self.me] - starts[self.me])

    def step(self, phase: str):
        cpu = time.thread_time()
        buckets, stats = self._step(phase)
        stats["cpu"] = time.thread_time() - cpu  # this thread's CPU seconds: the load of others aside
        return buckets, stats

    def _step(self, phase: str):
        with self._lock:
            got, self.inbox = [b for b in self.inbox if len(b)], []
        out: list = [[] for _ in range(self.parts)]
        if phase == "explore":
            self._take = self._add
            if got:
                self._add(self.seen.fresh(np.concatenate(got)))
            stats = self._explore(out)
        elif phase == "reverse":
            stats = self._reverse(got, out)
        else:
            stats = self._back(got, out)
        buckets = [np.concatenate(b) if b else np.zeros(0, np.int64) for b in out]  # each code once (fresh)
        stats["sent"] = [len(b) for b in buckets]
        return buckets, stats

    # ---------------------------------------------------------------- the search

    def _explore(self, out) -> dict:
        nt = sent = done = 0
        while self.head < self.n:
            if done >= self.round_states and self.parts > 1:
                break
            k = min(self.n - self.head, CHUNK)
            done += k
            batch = self.codes[self.head:self.head + k]
            rows, dst, bad = self.succ.expand(batch)
            if self.keep:  # the transitions by source state
                dst = dst[np.argsort(rows, kind="stable")]
                self.degree.append(np.bincount(rows, minlength=k).astype(np.int32))
                self.targets.append(dst)
                if len(bad):
                    self.errors.append(np.unique(bad) + self.head)
            self.head += k
            nt += len(dst)
            sent += self._split(self.seen.fresh(dst), out)
            if sent >= self.message_min:
                break
        self.transitions += nt
        return {"transitions": nt, "pending": self.n - self.head, "expanded": done}

    # ---------------------------------------------------------------- checks (keep=True)

    def system(self):
        """This partition's states as a TransitionSystem without transitions (for the
        properties' state predicates: ``workable_mask``, ``terminal_mask``, columns)."""
        from .system import TransitionSystem

        n = self.n
        return TransitionSystem(self.model, "model", None, tuple(range(len(self.model.program.slots))),
                                codes=self.codes[:n], offsets=np.zeros(n + 1, np.int64), dst=np.zeros(0, np.int64),
                                edge=np.zeros(0, np.int8), edge_label=np.zeros(0, np.int8),
                                edge_status=np.zeros(0, np.int8), labels=(), parent=np.full(n, -1), expanded=n)

    def _local(self, codes) -> np.ndarray:
        """Local ids (positions in ``codes``) of owned codes: a code's rank among the owned
        codes (a bitmap of them, a prefix count per 64-bit word and a popcount; binary
        search past ``DENSE_LIMIT``) indexes the ids in code order."""
        if self._order is None or len(self._order) != self.n:
            own = self.codes[:self.n]
            self._order = np.argsort(own, kind="stable")
            self._sorted = None
            if self.seen.bits is not None:
                bits = np.zeros((self.seen.total + 63) // 64, np.uint64)
                s = own[self._order]
                word = s >> 6
                starts = np.flatnonzero(np.concatenate(([True], word[1:] != word[:-1]))) if len(s) else s
                if len(s):
                    bits[word[starts]] |= np.bitwise_or.reduceat(_bit(s), starts)
                prefix = np.zeros(len(bits) + 1, np.int64)
                np.cumsum(_popcount(bits), out=prefix[1:])
                self._rank = (bits, prefix)
            else:
                self._sorted = own[self._order]
        order = self._order
        if self._sorted is not None:
            return order[np.searchsorted(self._sorted, codes)]
        bits, prefix = self._rank
        out = np.empty(len(codes), np.int64)
        for a in range(0, len(codes), STEP):  # in slices: few temporaries
            c = codes[a:a + STEP]
            word = c >> 6
            out[a:a + STEP] = order[prefix[word] + _popcount(bits[word] & (_bit(c) - np.uint64(1)))]
        return out

    def local_checks(self) -> dict:
        """No-dead-states at model level on this partition's states: dead states (no
        successor, not terminal, not a domain error) and, per FSM, states whose token is on
        a sink (not terminal); the states' workable mask is kept for ``back``."""
        from .properties.dead import sink_states, terminal_mask
        from .properties.workable import workable_mask

        ts = self.system()
        degree = np.concatenate(self.degree) if self.degree else np.zeros(0, np.int32)
        terminal = terminal_mask(ts)
        dead = (degree == 0) & ~terminal
        if self.errors:
            dead[np.concatenate(self.errors)] = False
        prog = self.model.program
        sinks = {}
        for f in self.model.fsms:
            ids_ = sink_states(f)
            _, ids, tok, _, _ = prog.fsm_info[prog.fsm_index[f.name]]
            if ids_ and self.model.tree is not None:
                sinks[f.name] = int(np.count_nonzero(np.isin(ts.column(tok), [ids.index(x) for x in ids_]) & ~terminal))
        self.reached = workable_mask(ts) if (self.model.fsms or self.model.workable is not None) else np.ones(self.n, bool)
        self.frontier = np.flatnonzero(self.reached)
        return {"states": self.n, "dead": int(np.count_nonzero(dead)), "sinks": sinks,
                "workable": int(len(self.frontier))}

    def _reverse(self, got, out) -> dict:
        """First call: ship every transition reversed to its target's owner, one array per
        owner (the targets' codes, then the sources'). Second call: the CSR of predecessor
        codes by local state id, from what came in and this partition's own part."""
        if not self._reversed:
            self._reversed = True
            # a peer's first call may run before this one and its reversed transitions be
            # here already (each actor's round starts when its thread gets to it): keep them
            self._early, got = got, []
            degree = np.concatenate(self.degree) if self.degree else np.zeros(0, np.int32)
            dst = np.concatenate(self.targets) if self.targets else np.zeros(0, np.int64)
            self.degree, self.targets = [], []  # the forward transitions go: the reverse ones replace them
            src = np.repeat(self.codes[:len(degree)], degree)
            del degree
            if self.parts > 1:
                own = owner(dst, self.parts, self.key)
                for j in range(self.parts):
                    if j != self.me:
                        pick = own == j
                        out[j].append(np.concatenate([dst[pick], src[pick]]))
                pick = own == self.me
                del own
                dst, src = dst[pick], src[pick]
            self._mine = (dst, src)
            if self.parts > 1:
                return {"pending": 0}
        got, self._early = self._early + got, []
        tgt = np.concatenate([self._mine[0]] + [p[:len(p) // 2] for p in got])
        src = np.concatenate([self._mine[1]] + [p[len(p) // 2:] for p in got])
        self._mine, got = (), []
        tgt = self._local(tgt)
        order = np.argsort(tgt, kind="stable")
        self.pred = src[order]
        del src, order
        self.pptr = np.concatenate(([0], np.cumsum(np.bincount(tgt, minlength=self.n))))
        return {"pending": 0}

    def _back(self, got, out) -> dict:
        """Backward reachability from the workable states: the predecessors of the
        frontier, own ones marked at once (and searched on), others sent to their owner."""
        def take(codes):
            ids = self._local(codes)
            ids = ids[~self.reached[ids]]
            self.reached[ids] = True
            self.frontier = np.concatenate([self.frontier, ids])

        self._take = take
        if got:
            take(_distinct(np.concatenate(got)))
        sent = 0
        while len(self.frontier):
            f, self.frontier = self.frontier, np.zeros(0, np.int64)
            starts, ends = self.pptr[f], self.pptr[f + 1]
            lens = ends - starts
            idx = np.repeat(ends - np.cumsum(lens), lens) + np.arange(int(lens.sum()))
            sent += self._split(_distinct(self.pred[idx]), out)
        return {"pending": 0, "traps": int(self.n - np.count_nonzero(self.reached))}


# ------------------------------------------------------------------ rounds


@dataclass
class DistributedCounts:
    """What a distributed search returns: exact counts, and how the work was spread."""

    states: int
    transitions: int
    levels: int  # rounds (simulate; 1 worker); on Dask with 2 or more: the steps of the busiest partition
    seconds: float
    per_partition: list = field(default_factory=list)  # states owned by each partition
    messages: int = 0  # non-empty buckets sent
    largest_message: int = 0  # states in the largest bucket
    states_sent: int = 0  # states in all buckets (each code sent once by a partition)
    critical_path: int = 0  # sum over rounds of the most states a partition expanded in it
    work_seconds: float = 0.0  # on Dask: sum over rounds of the longest partition's work
    cpu_seconds: float = 0.0  # CPU seconds of the partitions' rounds, all together
    cpu_path: float = 0.0  # sum over rounds of the most CPU seconds a partition took in it (no rounds: the most in all)
    makespan: float = 0.0  # ``simulate(rounds=False)``: the partitions' work on free cores, in CPU seconds

    @property
    def ideal_speedup(self) -> float:
        """States / critical path: the speed-up over one partition that P cores could
        reach with free rounds and messages (deterministic, unlike a time)."""
        return self.states / self.critical_path if self.critical_path else 1.0


@dataclass
class DistributedCheck:
    """The partitioned checks' figures (``check_distributed``): the search's counts, dead
    states and sink states (no-dead-states at model level) and traps (states from which no
    workable state is reachable: workable-reachability)."""

    counts: DistributedCounts
    dead: int
    sinks: dict
    traps: int
    workable: int
    back_rounds: int
    seconds: float

    @property
    def verdicts(self) -> dict:
        """Property name -> holds (model level; no-dead-states' FSM-level non-progress
        cycles are not part of it)."""
        return {"workable-reachability": self.traps == 0,
                "no-dead-states": self.dead == 0 and not any(self.sinks.values())}


def _tally(counts, res) -> None:
    flat = [k for s in res for k in s["sent"]]
    counts.transitions += sum(s.get("transitions", 0) for s in res)
    counts.messages += sum(1 for k in flat if k)
    counts.states_sent += sum(flat)
    counts.largest_message = max([counts.largest_message, *flat])
    counts.critical_path += max(s.get("expanded", 0) for s in res)
    counts.work_seconds += max(s.get("work", 0.0) for s in res)
    counts.cpu_path += max(s.get("cpu", 0.0) for s in res)
    counts.cpu_seconds += sum(s.get("cpu", 0.0) for s in res)


def _done(res) -> bool:
    """The round barrier's test: nothing sent (so nothing in flight) and nothing pending."""
    return all(sum(s["sent"]) == 0 and s["pending"] == 0 for s in res)


def _rounds(parts, phase, counts=None) -> tuple:
    """Rounds of ``phase`` over the ``Partition``s ``parts`` in this process, each round's
    buckets delivered after every partition has worked; (rounds, last round's stats)."""
    rounds = 0
    while True:
        out = [p.step(phase) for p in parts]
        for buckets, _ in out:
            for j, b in enumerate(buckets):
                if len(b):
                    parts[j].receive(b)
        res = [stats for _, stats in out]
        rounds += 1
        if counts is not None:
            _tally(counts, res)
        if _done(res):
            return rounds, res


def _free_cores(parts, phase, counts) -> int:
    """The search without rounds, as the actors run it on Dask, scheduled in this process
    on a clock of CPU seconds: each partition's clock advances by the CPU seconds of its
    steps (``time.thread_time``, which the machine's other jobs do not inflate much); a
    bucket arrives at its owner at the sender's clock after the step that made it; the
    next step is the one whose partition is ready first (its own queue, or its earliest
    bucket). The largest clock at the end (``counts.makespan``) is the time the
    partitions' work takes on ``len(parts)`` free cores, messages and Dask aside; returns
    the most steps a partition took."""
    clock = [0.0] * len(parts)
    mail: list = [[] for _ in parts]  # (arrival, codes)
    steps = [0] * len(parts)
    sizes: list = []  # states in each bucket
    res: list = [{"transitions": 0, "expanded": 0, "cpu": 0.0, "sent": [0] * len(parts)} for _ in parts]
    while True:
        ready = [(clock[j] if p.head < p.n else max(clock[j], min(t for t, _ in mail[j])), j)
                 for j, p in enumerate(parts) if p.head < p.n or mail[j]]
        if not ready:
            break
        t, j = min(ready)
        clock[j] = t
        for _, b in [m for m in mail[j] if m[0] <= t]:
            parts[j].receive(b)
        mail[j] = [m for m in mail[j] if m[0] > t]
        buckets, stats = parts[j].step(phase)
        clock[j] += stats["cpu"]
        steps[j] += 1
        for name in ("transitions", "expanded", "cpu"):
            res[j][name] += stats[name]
        for k, b in enumerate(buckets):
            if len(b):
                mail[k].append((clock[j], b))
                res[j]["sent"][k] += len(b)
                sizes.append(len(b))
    _tally(counts, res)
    counts.messages, counts.largest_message = len(sizes), max(sizes, default=0)
    counts.critical_path = max(r["expanded"] for r in res)
    counts.cpu_path = max(r["cpu"] for r in res)
    counts.makespan = max(clock)
    return max(steps)


def simulate(model, parts: int, keep: bool = False, message_min: int = MESSAGE_MIN, key=None,
             round_states: int = ROUND_STATES, rounds: bool = True):
    """The partitioned search (and with ``keep`` the checks) with ``parts`` partitions run
    one after the other in this process: the same ``Partition`` code and rounds as on
    Dask, so the same counts, rounds and message volume, without the cluster. Returns
    ``DistributedCounts`` (``keep``: ``DistributedCheck``). ``rounds=False``: the search
    without rounds, as on Dask, on a clock of CPU seconds (``_free_cores``: its makespan)."""
    t0 = time.perf_counter()
    succ = BatchSuccessors(model)  # one trie for all: the partitions run one after the other
    key = partition_key(model, parts, succ=succ) if key is None else key
    ps = [Partition(model, j, parts, keep, message_min, key, succ, round_states) for j in range(parts)]
    counts = DistributedCounts(0, 0, 0, 0.0)
    counts.levels = _rounds(ps, "explore", counts)[0] if rounds or parts == 1 else _free_cores(ps, "explore", counts)
    counts.per_partition = [p.n for p in ps]
    counts.states = sum(counts.per_partition)
    counts.seconds = time.perf_counter() - t0
    if not keep:
        return counts
    local = [p.local_checks() for p in ps]
    _rounds(ps, "reverse")
    back, res = _rounds(ps, "back")
    return _check(counts, local, [s["traps"] for s in res], back, t0)


def _check(counts, local, traps, back, t0) -> DistributedCheck:
    sinks: dict = {}
    for r in local:
        for k, v in r["sinks"].items():
            sinks[k] = sinks.get(k, 0) + v
    return DistributedCheck(counts, sum(r["dead"] for r in local), sinks, sum(traps),
                            sum(r["workable"] for r in local), back, time.perf_counter() - t0)


# ------------------------------------------------------------------ on Dask


def _malloc_thresholds() -> None:
    """glibc's malloc thresholds as they grow by default (see ``WORKER_MALLOC``); nothing
    where the C library is not glibc."""
    import ctypes
    import ctypes.util

    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
        for param, value in WORKER_MALLOC:
            libc.mallopt(param, value)
    except (OSError, AttributeError):
        pass


class _Actor:
    """A ``Partition`` on a Dask worker. Its peers' actor handles come with ``connect``.
    ``step`` is a coroutine on the worker's event loop: the round's work runs in a thread
    (the loop stays free to take the peers' ``receive`` calls meanwhile), then each bucket
    goes to its owner's ``receive``, and ``step`` returns once every delivery is done, so
    no message is in flight between rounds."""

    def __init__(self, spec, me, parts, keep, message_min, key):
        _malloc_thresholds()
        factory, args, kwargs = spec
        self.p = Partition(factory(*args, **dict(kwargs)), me, parts, keep, message_min, key)
        self.peers = None
        self.wake = asyncio.Event()  # ``run``: set by a delivery or ``stop``
        self.quiet = asyncio.Event()  # ``settled``: set by ``run`` when it goes idle
        self.busy = self.stopped = self.failed = False
        self.error: "BaseException | None" = None
        self.sent = self.received = 0  # buckets, for the client's termination test

    def connect(self, peers) -> None:
        self.peers = peers

    async def receive(self, codes) -> None:
        self.p.receive(codes)

    async def step(self, phase):
        t0 = time.perf_counter()
        buckets, stats = await asyncio.get_running_loop().run_in_executor(None, self.p.step, phase)
        work = time.perf_counter() - t0
        await asyncio.gather(*[self.peers[j].receive(b) for j, b in enumerate(buckets) if len(b)])
        return {**stats, "sent": [len(b) for b in buckets], "work": work}

    # ------------------------------------------------ the search without rounds

    async def receive_async(self, codes) -> None:
        """A peer's bucket during ``run``: queued, counted, and the partition woken."""
        self.p.receive(codes)
        self.received += 1
        self.wake.set()

    def _idle(self) -> bool:
        return not self.busy and not self.p.inbox and self.p.head >= self.p.n

    async def status(self) -> tuple:
        """(idle, buckets sent, buckets received): read on the worker's event loop, where
        ``run`` and ``receive_async`` change them, so the three agree with each other."""
        return self._idle(), self.sent, self.received

    async def settled(self) -> tuple:
        """``status`` once this partition is idle (at once if it is): the client waits
        here instead of reading the status of a busy partition again and again. Also
        returns when ``run`` failed (idle: None)."""
        while not self._idle() and not self.failed:
            self.quiet.clear()
            await self.quiet.wait()
        return (None if self.failed else True), self.sent, self.received

    async def run(self, phase) -> dict:
        """The search without rounds: steps (at most ``round_states`` states, then each
        bucket sent to its owner at once, without waiting for its delivery) while there is
        work, asleep while there is none, until ``stop``; the client decides when to stop
        by ``status`` (``_remote_run``). Returns the sums of the steps' stats. Called once
        per actor (a ``stop`` that comes before it ends it at once)."""
        loop = asyncio.get_running_loop()
        total: dict = {"transitions": 0, "expanded": 0, "cpu": 0.0, "work": 0.0, "steps": 0, "messages": 0,
                       "largest": 0, "sent": [0] * self.p.parts}
        deliveries: list = []
        try:
            while not self.stopped:
                if self.error is not None:  # a delivery failed (its peer's worker is gone)
                    raise self.error
                if self._idle():
                    self.quiet.set()
                    self.wake.clear()
                    await self.wake.wait()
                    continue
                self.busy = True
                t0 = time.perf_counter()
                try:
                    buckets, stats = await loop.run_in_executor(None, self.p.step, phase)
                finally:
                    self.busy = False
                total["work"] += time.perf_counter() - t0
                total["steps"] += 1
                for k in ("transitions", "expanded", "cpu"):
                    total[k] += stats.get(k, 0)
                for j, b in enumerate(buckets):
                    if len(b):
                        self.sent += 1  # counted before it can arrive
                        total["messages"] += 1
                        total["sent"][j] += len(b)
                        total["largest"] = max(total["largest"], len(b))
                        delivery = asyncio.ensure_future(self.peers[j].receive_async(b))
                        delivery.add_done_callback(self._delivered)
                        deliveries.append(delivery)
            await asyncio.gather(*deliveries)  # all delivered already (the client saw sent == received)
        except BaseException:
            self.failed = True  # ``run`` ends with the error, which the client raises (``_remote_run``)
            self.quiet.set()
            raise
        return {**total, "pending": 0}

    def _delivered(self, delivery) -> None:
        """A delivery's end: a failure ends ``run`` (the client would otherwise wait for
        a bucket that never arrives)."""
        if not delivery.cancelled() and delivery.exception() is not None:
            self.error = delivery.exception()
            self.wake.set()

    async def stop(self) -> None:
        self.stopped = True
        self.wake.set()

    def n(self) -> int:
        return self.p.n

    def local_checks(self) -> dict:
        return self.p.local_checks()


def _remote_rounds(handles, phase, counts=None) -> tuple:
    """``_rounds`` over actors: every partition works at once; the buckets went worker to
    worker before each ``step`` returned."""
    rounds = 0
    while True:
        res = [f.result() for f in [a.step(phase) for a in handles]]
        rounds += 1
        if counts is not None:
            _tally(counts, res)
        if _done(res):
            return rounds, res


POLL_SECONDS = 0.005  # the client's pause between two reads of the partitions' status


def _remote_run(handles, phase, counts) -> int:
    """``phase`` on the actors without rounds (``_Actor.run``), then the sums of their
    work in ``counts``; returns the most steps a partition took. Termination is detected
    by reading every partition's (idle, buckets sent, buckets received) twice, one wave
    of reads after the other (Mattern's counting method; the first wave waits for each
    partition to be idle, ``settled``): when every partition was idle at both reads, its
    counts did not change between them and all partitions together received as many
    buckets as they sent, then at the moment between the two waves no partition worked
    and no bucket was in flight, so none ever will: an idle partition works again only on
    a delivery. No timing is assumed: a slow worker only delays the test."""
    runs = [a.run(phase) for a in handles]
    while True:
        first = [f.result() for f in [a.settled() for a in handles]]  # each waits until its partition is idle
        for f, (idle, _, _) in zip(runs, first):
            if idle is None:  # ``run`` failed: the others stop, its error is raised
                for g in [a.stop() for a in handles]:
                    g.result()
                f.result()
        second = [f.result() for f in [a.status() for a in handles]]
        now = [(s, r) for _, s, r in second]
        if all(idle for idle, _, _ in second) and now == [(s, r) for _, s, r in first] and \
                sum(s for s, _ in now) == sum(r for _, r in now):
            break
        time.sleep(POLL_SECONDS)
    for f in [a.stop() for a in handles]:
        f.result()
    res = [f.result() for f in runs]
    _tally(counts, res)
    counts.messages = sum(s["messages"] for s in res)
    counts.largest_message = max(s["largest"] for s in res)
    counts.critical_path = max(s["expanded"] for s in res)
    counts.work_seconds = max(s["work"] for s in res)
    counts.cpu_path = max(s["cpu"] for s in res)
    return max(s["steps"] for s in res)


def _start(client, factory, args, kwargs, workers, keep, message_min, key):
    spec = (factory, tuple(args), tuple(sorted((kwargs or {}).items())))
    addrs = list(workers) if workers is not None else sorted(client.scheduler_info()["workers"])
    parts = len(addrs)
    if key is None:
        key = partition_key(factory(*args, **(kwargs or {})), parts)
    futures = [client.submit(_Actor, spec, j, parts, keep, message_min, key, workers=[addrs[j]], actor=True,
                             allow_other_workers=False, pure=False) for j in range(parts)]
    handles = [f.result() for f in futures]
    for f in [a.connect(handles) for a in handles]:
        f.result()
    return handles, futures


def _search(client, factory, args, kwargs, workers, keep, message_min, key):
    """The rounds of the search on the actors; (actor handles and futures, counts)."""
    t0 = time.perf_counter()
    started = _start(client, factory, args, kwargs, workers, keep, message_min, key)
    handles = started[0]
    counts = DistributedCounts(0, 0, 0, 0.0)
    counts.levels = _remote_run(handles, "explore", counts) if len(handles) > 1 else \
        _remote_rounds(handles, "explore", counts)[0]
    counts.per_partition = [f.result() for f in [a.n() for a in handles]]
    counts.states = sum(counts.per_partition)
    counts.seconds = time.perf_counter() - t0
    return started, counts


def explore_distributed(client, factory, args=(), kwargs=None, *, workers=None,
                        message_min: int = MESSAGE_MIN, key=None) -> DistributedCounts:
    """Explore ``factory(*args, **kwargs)`` (a function returning a Model, importable on
    the workers) with one partition per worker of ``client`` (or per address in
    ``workers``); returns exact state and transition counts. ``message_min``: states bound
    elsewhere after which a partition ends its round; ``key``: the partition key (default
    ``partition_key`` of the model)."""
    return _search(client, factory, args, kwargs, workers, False, message_min, key)[1]


def check_distributed(client, factory, args=(), kwargs=None, *, workers=None,
                      message_min: int = MESSAGE_MIN, key=None) -> DistributedCheck:
    """The partitioned search with each partition's transitions kept, then no-dead-states
    at model level and workable-reachability over the partitions (``DistributedCheck``)."""
    t0 = time.perf_counter()
    (handles, _futures), counts = _search(client, factory, args, kwargs, workers, True, message_min, key)
    local = [f.result() for f in [a.local_checks() for a in handles]]
    _remote_rounds(handles, "reverse")
    back, res = _remote_rounds(handles, "back")
    return _check(counts, local, [s["traps"] for s in res], back, t0)


@contextmanager
def cluster(scheduler: "str | None" = None, workers: int = 2):
    """A Dask client for the partitioned search, closed on exit: connected to the running
    scheduler at ``scheduler`` (``tcp://HOST:PORT``; its workers, as many as it has, hold
    the partitions), or to an embedded local cluster of ``workers`` processes of one
    thread each, made here and shut down on exit."""
    from dask.distributed import Client, LocalCluster

    if scheduler:
        with Client(scheduler, timeout=CONNECT_SECONDS) as client:
            yield client
        return
    import dask

    with dask.config.set(QUIET_WORKERS), \
            LocalCluster(n_workers=workers, threads_per_worker=1, dashboard_address=None) as local, \
            Client(local) as client:
        yield client
