"""The scalar exploration engine: breadth-first, the step run once per transition.

A state's successors are enumerated by a depth-first search over choice scripts: run the
step with a script prefix (``EnumOracle`` answers 0 past its end), then push every other
answer at every choice point after the prefix. Each script is a distinct leaf of the
choice tree, so every successor is produced exactly once per distinct set of answers.

States are stored as one int64 each (``btfsm.verify.codec``); the visited set is a dict
of those codes. Transitions are kept in flat arrays in source order. Called through
``btfsm.verify.explore.explore``/``explore_fsm`` (``engine="scalar"``, or ``"auto"`` when the
traced engine cannot follow the model).
"""
from __future__ import annotations

import time
from array import array
from collections import deque
from operator import mul
from typing import Any

import numpy as np

from btfsm.errors import DomainError

from .codec import codec, decode, rows
from .labels import readable
from .search import DEFAULT_MAX_STATES, Budget, EnumOracle, Search, SearchTask, run_environment
from .system import DomainViolation, TransitionSystem

__all__ = ["search", "TreeCache", "OutOfTime"]

_PROGRESS_EVERY = 4096
_CLOCK_EVERY = 256  # step runs between two reads of the clock (with a time budget)


class OutOfTime(Exception):
    """The time budget ran out inside ``TreeCache.results``."""


class TreeCache:
    """The tree's results per state reached after the environment.

    ``Program.step`` applies the environment to the tick's state list and then ticks the
    root on the same context; nothing but the state passes from one phase to the other
    (the per-tick FSM records start empty, the environment adds no violation). So the
    results of a tick are the environment's results followed by the results of a tick
    of the same model without environment from the state the environment left, and those
    can be computed once per such state. The choice script of a tick is the environment's
    answers followed by the tree's, as ``Program.step`` asks them."""

    # entries per generation, at most two generations kept: BFS revisits recent states, and
    # the measured hit rates at 10,000 equal those of an unbounded cache
    LIMIT = 20_000

    def __init__(self, model, limit: "int | None" = None):
        self.env = model.program  # the environment phase runs on the full program
        self.tree = model.program.without_environment()
        self.limit = limit or self.LIMIT
        self.cache: dict = {}  # this generation
        self.old: dict = {}  # the previous one: entries used again move up
        self.tree_ids: dict = {}
        self.tree_keys: list = []
        self.hits = self.misses = 0

    def results(self, post, mults, small, kept, budget=None):
        """``[(tree key id, code, state, status, violations, taken, error)]`` of ``post``.
        Raises ``OutOfTime`` when ``budget``'s time runs out while enumerating."""
        res = self.cache.get(post)
        if res is not None:
            self.hits += 1
            return res
        res = self.old.pop(post, None)
        if res is not None:
            self.hits += 1
            self._keep(post, res)
            return res
        self.misses += 1
        res = []
        stack = [()]
        step = self.tree.step
        timed = budget is not None and budget.max_seconds is not None
        seen = {} if self.tree.merge_points else None  # in-tick retries merged (EnumOracle.merge)
        while stack:
            if timed and len(res) % _CLOCK_EVERY == _CLOCK_EVERY - 1 and budget.out_of_time():
                raise OutOfTime()
            script = stack.pop()
            o = EnumOracle(script, seen)
            err = st = None
            try:
                st = step(post, o)
            except DomainError as exc:
                err = exc
            ar = o.arities
            k0 = len(script)
            if len(ar) > k0:
                taken = o.taken
                for k in range(k0, len(ar) if o.cut is None else max(o.cut, k0)):
                    base = tuple(taken[:k])
                    for c in range(1, ar[k]):
                        stack.append(base + (c,))
            key = tuple(o.picks)
            tid = self.tree_ids.get(key)
            if tid is None:
                tid = self.tree_ids[key] = len(self.tree_keys)
                self.tree_keys.append(key)
            if err is not None:
                res.append((tid, None, None, None, None, tuple(o.taken), err))
                continue
            ns = st.state
            if ns is None:  # an answer the declared timing does not allow (a duration)
                continue
            code = sum(map(mul, ns, mults)) if small else tuple(ns[k] for k in kept)
            res.append((tid, code, ns, st.status, tuple(st.violations) if st.violations else None, None, None))
        self._keep(post, res)
        return res

    def _keep(self, post, res):
        if len(self.cache) >= self.limit:
            self.old, self.cache = self.cache, {}
        self.cache[post] = res


def search(task: SearchTask, budget: "Budget | None", split: "TreeCache | None" = None) -> TransitionSystem:
    """Explore the system of ``task`` breadth-first from ``task.initial``: ``run(state,
    oracle)`` is one transition (``Program.step``, or ``OpenFSM.run`` with ``op`` at FSM
    level), states are coded over the ``kept`` slots; ``split``: a ``TreeCache`` (model
    level with an environment). ``budget``: a ``btfsm.verify.search.Budget`` (None:
    unbounded); the search stops at the first bound hit and records which in ``budget.hit``."""
    t0 = time.perf_counter()
    model, kind, fsm, kept, run = task.model, task.kind, task.fsm, task.kept, task.run
    initial, progress, op = task.initial, task.progress, task.op
    prog = model.program
    mults, offset, total = codec(prog, kept)
    small = total < (1 << 62)
    if budget is None:
        budget = Budget()
    smax = DEFAULT_MAX_STATES * 1000 if budget.max_states is None else budget.max_states
    tmax = (1 << 62) if budget.max_transitions is None else budget.max_transitions
    timed = budget.max_seconds is not None
    runs, check_at = 0, _CLOCK_EVERY  # step runs, and when to read the clock next
    visited: dict = {}
    codes: Any = array("q") if small else []
    tuples: Any = None if small else []
    parent = array("q", [-1])
    src, dst, lab, stat = array("q"), array("q"), array("q"), array("b")
    label_ids: dict = {}
    readable_ids: dict = {}
    labels: list = []
    label_goal: list = []
    errors, violations = [], []
    s0 = tuple(initial)
    c: Any  # a state code: an int, or the kept values when the codes would not fit one
    c0 = sum(map(mul, s0, mults)) if small else tuple(s0[k] for k in kept)
    visited[c0] = 0
    if small:
        codes.append(c0)
    else:
        tuples.append(c0)
    queue = deque([s0])
    n, i, complete, nt = 1, -1, True, 0
    Oracle = EnumOracle
    loops = kind == "model" and bool(prog.merge_points)
    last = 0

    def label_of(key):
        name, g = readable(prog, key, op)
        li = readable_ids.get(name)
        if li is None:
            li = readable_ids[name] = len(labels)
            labels.append(name)
            label_goal.append(g)
        return li

    # bound methods as locals: these loops run once per transition
    src_add, dst_add, lab_add, stat_add = src.append, dst.append, lab.append, stat.append
    code_add = codes.append if small else tuples.append
    parent_add, queue_add, pop = parent.append, queue.append, queue.popleft
    vget, lget = visited.get, label_ids.get
    env_ids: dict = {}
    while queue:
        s = pop()
        i += 1
        if progress is not None and i - last >= _PROGRESS_EVERY:
            last = i
            progress(n, nt, time.perf_counter() - t0)
        stack = [()]
        seen: "dict | None" = {} if loops else None  # in-tick retries merged per state (EnumOracle.merge)
        if split is not None:  # environment answers here, tree results from the cache
            env = split.env
            while stack:
                if timed:
                    runs += 1
                    if runs >= check_at:
                        check_at = runs + _CLOCK_EVERY
                        if budget.out_of_time():
                            complete, budget.hit = False, "seconds"
                            break
                script = stack.pop()
                o = Oracle(script)
                post = list(s)
                try:
                    ok = run_environment(env, post, o)
                except DomainError as exc:
                    errors.append(DomainViolation(i, tuple(o.taken), readable(prog, tuple(o.picks), op)[0],
                                                  exc.var, exc.value, exc.where, str(exc)))
                    ok = False
                ar = o.arities
                k0 = len(script)
                if len(ar) > k0:
                    taken = o.taken
                    for k in range(k0, len(ar)):
                        base = tuple(taken[:k])
                        for c in range(1, ar[k]):
                            stack.append(base + (c,))
                if not ok:
                    continue
                ekey = tuple(o.picks)
                row = env_ids.get(ekey)
                if row is None:
                    row = env_ids[ekey] = {}
                try:
                    results = split.results(tuple(post), mults, small, kept, budget)
                except OutOfTime:
                    complete, budget.hit = False, "seconds"
                    break
                for tid, c, ns, status, viol, ttaken, err in results:
                    if err is not None:
                        full = ekey + split.tree_keys[tid]
                        errors.append(DomainViolation(i, tuple(o.taken) + ttaken, readable(prog, full, op)[0],
                                                      err.var, err.value, err.where, str(err)))
                        continue
                    li = row.get(tid)
                    if li is None:
                        li = row[tid] = label_of(ekey + split.tree_keys[tid])
                    if nt >= tmax:
                        complete, budget.hit = False, "transitions"
                        break
                    j = vget(c)
                    if j is None:
                        if n >= smax:
                            complete, budget.hit = False, "states"
                            break
                        j = n
                        n += 1
                        visited[c] = j
                        code_add(c)
                        parent_add(nt)
                        queue_add(ns)
                    src_add(i)
                    dst_add(j)
                    lab_add(li)
                    stat_add(status)
                    if viol is not None:
                        violations.append((nt, viol))
                    nt += 1
                if not complete:
                    break
        else:
            while stack:
                if timed:
                    runs += 1
                    if runs >= check_at:
                        check_at = runs + _CLOCK_EVERY
                        if budget.out_of_time():
                            complete, budget.hit = False, "seconds"
                            break
                script = stack.pop()
                o = Oracle(script, seen)
                try:
                    st = run(s, o)
                except DomainError as exc:
                    errors.append(DomainViolation(i, tuple(o.taken), readable(prog, tuple(o.picks), op)[0],
                                                  exc.var, exc.value, exc.where, str(exc)))
                    st = None
                ar = o.arities
                k0 = len(script)
                if len(ar) > k0:
                    taken = o.taken
                    for k in range(k0, len(ar) if o.cut is None else max(o.cut, k0)):
                        base = tuple(taken[:k])
                        for c in range(1, ar[k]):
                            stack.append(base + (c,))
                if st is None:
                    continue
                ns = st.state
                if ns is None:
                    continue
                key = tuple(o.picks)
                li = lget(key)
                if li is None:
                    li = label_ids[key] = label_of(key)
                c = sum(map(mul, ns, mults)) if small else tuple(ns[k] for k in kept)
                if nt >= tmax:
                    complete, budget.hit = False, "transitions"
                    break
                j = vget(c)
                if j is None:
                    if n >= smax:
                        complete, budget.hit = False, "states"
                        break
                    j = n
                    n += 1
                    visited[c] = j
                    code_add(c)
                    parent_add(nt)
                    queue_add(ns)
                src_add(i)
                dst_add(j)
                lab_add(li)
                stat_add(st.status)
                if st.violations:
                    violations.append((nt, tuple(st.violations)))
                nt += 1
        if not complete:
            break
    expanded = i + 1 if complete else i
    del visited
    states = decode(prog, kept, codes, offset, mults) if small else rows(prog, kept, tuples)
    # numpy views of the arrays' buffers (no copy: peak memory stays one copy of the edges)
    src_a = np.frombuffer(src, dtype=np.int64) if nt else np.zeros(0, np.int64)
    dst_a = np.frombuffer(dst, dtype=np.int64) if nt else np.zeros(0, np.int64)
    lab_a = np.frombuffer(lab, dtype=np.int64) if nt else np.zeros(0, np.int64)
    stat_a = np.frombuffer(stat, dtype=np.int8) if nt else np.zeros(0, np.int8)
    goal_a = np.asarray(label_goal, dtype=np.int64)[lab_a] if kind == "fsm" else None
    seconds = time.perf_counter() - t0
    if progress is not None:
        progress(n, nt, seconds)
    return TransitionSystem(model=model, kind=kind, fsm=fsm, slots=tuple(kept), states=states, src=src_a, dst=dst_a,
                            label=lab_a, labels=tuple(labels), parent=np.frombuffer(parent, dtype=np.int64),
                            complete=complete, seconds=seconds, status=stat_a, goal=goal_a, expanded=expanded,
                            errors=tuple(errors), violations=tuple(violations), open=op,
                            stopped=None if complete else budget.hit)


_declared: Search = search  # an engine of the shared interface (btfsm.verify.search.Search; mypy holds it to it)
