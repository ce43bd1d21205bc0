"""``response``: bounded response, decided exactly on the model's transition system.

A model declares requirements ``Response(name, trigger, response, within)`` (the file's
``responses:`` key; ``btfsm.timing``): every time ``trigger`` occurs, ``response`` must
hold within ``within`` seconds, for every behaviour the model allows. The trigger occurs
in every reachable state where an expression trigger holds, or, for ``event:NAME``, in the
state a tick reaches in which environment event NAME happened. The response time from
such a state is the number of ticks to the first state where ``response`` holds (0 when
it holds there), divided by the model's tick rate.

Exactly, on the explicit system (docs/verification.md section 2.1):

* ``worst[u]``: the longest response-free path from ``u`` to a response state: 0 on a
  response state; infinite when a response-free cycle or a state with no successor is
  reachable without passing a response state (that behaviour never responds); else
  ``1 + max`` over the successors. Computed by a reverse topological sweep (Kahn's
  algorithm, one numpy step per path length), linear in the transitions.
* ``best[u]``: the shortest path to a response state (reverse breadth-first search).

The worst case of a requirement is the maximum of ``worst`` over the trigger states, its
best case the minimum of ``best``. A violation gives the shortest counterexample: the
trigger state nearest the initial state whose worst case exceeds the bound, reached by a
shortest path, then ``bound`` ticks along a longest response-free path (or, when no
response ever comes, the lasso into the response-free cycle). ``btfsm replay`` confirms
both.

>>> import numpy as np
>>> stop = np.array([False, False, False, True])
>>> worst_until(4, np.array([0, 0, 1, 2]), np.array([1, 3, 2, 3]), stop).tolist()
[3, 2, 1, 0]
>>> best_until(4, np.array([0, 0, 1, 2]), np.array([1, 3, 2, 3]), stop).tolist()
[1, 2, 1, 0]
"""
from __future__ import annotations

from typing import Any

import numpy as np

from btfsm.errors import ModelError
from btfsm.timing import Response

from ..counterexample import path_counterexample
from ..system import cyclic_states, shortest_cycle, shortest_path
from .base import Result, budget_hit, evaluate

__all__ = ["check", "NAME", "INF", "worst_until", "best_until", "free_run", "reverse_csr", "analyse", "ResponseBound"]

NAME = "response"
INF = np.iinfo(np.int64).max  # no response on some behaviour


def _ints(a) -> np.ndarray:
    """``a`` as an integer array, without a copy when it is one (a system's ``src`` and
    ``dst`` are int32: no int64 copies of them)."""
    a = np.asarray(a)
    return a if a.dtype.kind in "iu" else a.astype(np.int64)


def reverse_csr(n: int, src, dst) -> tuple:
    """``(offs, pred)``: the sources of the edges into node ``v`` are
    ``pred[offs[v]:offs[v + 1]]``, in edge order (``pred`` in the type of ``src``)."""
    src, dst = _ints(src), _ints(dst)
    order = np.argsort(dst, kind="stable")
    offs = np.zeros(n + 1, np.int64)
    np.cumsum(np.bincount(dst, minlength=n), out=offs[1:])
    return offs, src[order]


def _preds(offs, pred, nodes) -> np.ndarray:
    """The sources of the edges into ``nodes`` (with repeats), one gather."""
    starts = offs[nodes]
    counts = offs[nodes + 1] - starts
    total = int(counts.sum())
    if not total:
        return np.zeros(0, np.int64)
    first = np.repeat(starts - (np.cumsum(counts) - counts), counts)
    return pred[first + np.arange(total)]


def _once(u, mark) -> np.ndarray:
    """``u`` with each node once (one of its occurrences, no sort: the order does not
    matter to the sweeps); ``mark``: a scratch array of -1 over the nodes, left as it
    was found."""
    pos = np.arange(len(u))
    mark[u] = pos
    keep = mark[u] == pos
    mark[u] = -1
    return u[keep]


def worst_until(n: int, src, dst, stop, rev=None) -> np.ndarray:
    """Per node, the longest path (in edges) to a ``stop`` node that visits no other stop
    node before; ``INF`` when a path from it avoids stop nodes for ever (a cycle, or a
    node without successors, reachable outside the stop nodes). ``rev``: the
    ``reverse_csr`` of the edges, if already built.

    Kahn's algorithm backwards from the stop nodes, one numpy step per round: a node
    leaves ``pending`` in round k when the last of its successors left it in round k - 1,
    so its longest path is k (stop nodes: round 0). Edges out of stop nodes do not count."""
    src, dst = _ints(src), _ints(dst)
    stop = np.asarray(stop, bool)
    pending = np.bincount(src[~stop[src]], minlength=n).astype(np.int64, copy=False)
    offs, pred = reverse_csr(n, src, dst) if rev is None else rev
    worst = np.full(n, INF, np.int64)
    worst[stop] = 0
    mark = np.full(n, -1, np.int64)
    frontier, k = np.flatnonzero(stop), 0
    while frontier.size:
        k += 1
        u = _preds(offs, pred, frontier)
        u = u[~stop[u]]
        if not u.size:
            break
        np.subtract.at(pending, u, 1)
        frontier = _once(u[pending[u] == 0], mark)
        worst[frontier] = k
    return worst


def best_until(n: int, src, dst, stop, rev=None) -> np.ndarray:
    """Per node, the shortest path (in edges) to a ``stop`` node; ``INF`` when none
    (breadth-first backwards from the stop nodes; ``rev`` as for ``worst_until``)."""
    stop = np.asarray(stop, bool)
    best = np.full(n, INF, np.int64)
    best[stop] = 0
    offs, pred = reverse_csr(n, src, dst) if rev is None else rev
    mark = np.full(n, -1, np.int64)
    frontier, k = np.flatnonzero(stop), 0
    while frontier.size:
        k += 1
        u = _preds(offs, pred, frontier)
        frontier = _once(u[best[u] == INF], mark)
        best[frontier] = k
    return best


def free_run(n: int, src, dst, stop, cap: int) -> np.ndarray:
    """For every state, the most transitions a walk from it can take through states where
    the response does not hold (``~stop``, the start and every state reached), capped at
    ``cap``; -1 where the response holds. One round per transition of the walk.

    >>> free_run(4, np.array([0, 1, 2, 2]), np.array([1, 2, 0, 3]), np.array([False, False, False, True]), 5).tolist()
    [5, 5, 5, -1]
    >>> free_run(3, np.array([0, 1]), np.array([1, 2]), np.array([False, False, False]), 5).tolist()
    [2, 1, 0]
    """
    src, dst = np.asarray(src, np.int64), np.asarray(dst, np.int64)
    keep = ~stop[src] & ~stop[dst]
    s, d = src[keep], dst[keep]
    L = np.where(stop[:n], -1, 0).astype(np.int64)
    for _ in range(cap):
        nxt = L.copy()
        np.maximum.at(nxt, s, L[d] + 1)
        np.minimum(nxt, cap, out=nxt)
        if np.array_equal(nxt, L):
            break
        L = nxt
    return L


class ResponseBound:
    """The exact response times of one requirement on one explored system."""

    def __init__(self, ts, req: Response):
        self.ts, self.req = ts, req
        model = ts.model
        rate = model.tick_rate
        self.rate = rate
        try:
            self.stop = evaluate(ts, req.response)
        except ModelError as exc:
            raise ModelError(f"responses.{req.name}.response", exc.problem) from None
        ev = req.trigger_event
        if ev is not None:
            names = {e.name for e in model.environment} | {o.name for e in model.environment
                                                           for o in (getattr(e, "options", None) or ())}
            if ev not in names:
                raise ModelError(f"responses.{req.name}.trigger", f"no environment event or option '{ev}'")
            hit = np.array([("env", ev) in lab for lab in ts.labels] or [False], bool)
            self.trigger_edges = np.flatnonzero(hit[ts.label]) if ts.n_transitions else np.zeros(0, np.int64)
            tstates = np.unique(ts.dst[self.trigger_edges])
        else:
            try:
                tmask = evaluate(ts, req.trigger)
            except ModelError as exc:
                raise ModelError(f"responses.{req.name}.trigger", exc.problem) from None
            self.trigger_edges = None  # type: ignore[assignment]  # (no trigger edges: trigger states only)
            tstates = np.flatnonzero(tmask)
        self.triggers = tstates
        n = ts.n_states
        rev = reverse_csr(n, ts.src, ts.dst)
        self.worst_at = worst_until(n, ts.src, ts.dst, self.stop, rev)
        self.best_at = best_until(n, ts.src, ts.dst, self.stop, rev)

    @property
    def occurs(self) -> bool:
        return self.triggers.size > 0

    @property
    def worst(self) -> "int | None":
        """Worst case in ticks (INF: unbounded), None when the trigger never occurs."""
        return int(self.worst_at[self.triggers].max()) if self.occurs else None

    @property
    def best(self) -> "int | None":
        return int(self.best_at[self.triggers].min()) if self.occurs else None

    def seconds(self, ticks):
        return None if ticks is None else (float("inf") if ticks == INF else ticks / self.rate)

    def bound_ticks(self) -> "int | None":
        w = self.req.within
        return None if w is None else int(np.floor(w * self.rate + 1e-9))

    # ---------------------------------------------------------------- witnesses
    def _entry(self, states) -> tuple:
        """(prefix transitions, trigger state) reaching the nearest of ``states`` (BFS
        order), ending with the trigger tick for an event trigger."""
        ts = self.ts
        states = np.asarray(states, np.int64)
        if self.trigger_edges is None:
            t = int(states.min())
            return ts.path_to(t), t
        mask = np.zeros(ts.n_states, bool)
        mask[states] = True
        return self._through(self.trigger_edges[mask[ts.dst[self.trigger_edges]]])

    def _through(self, edges) -> tuple:
        """(prefix transitions, trigger state) through the trigger transition of ``edges``
        with the nearest source (BFS order), then the first tick."""
        ts = self.ts
        e = int(edges[np.lexsort((edges, ts.src[edges]))[0]])
        return ts.path_to(int(ts.src[e])) + [e], int(ts.dst[e])

    def _worst_from(self, prefix: list, t: int) -> "tuple | None":
        """(transitions, trigger step index, loop or None): ``prefix`` then a longest
        response-free path from trigger state ``t`` (the lasso when it is unbounded)."""
        worst = int(self.worst_at[t])
        if worst != INF:
            return prefix + self._longest_walk(t, worst), len(prefix), None
        return self._lasso(prefix, t)

    def _longest_walk(self, u: int, steps: int) -> list:
        """``steps`` transitions from ``u`` along a longest response-free path (fewer if a
        state without successors is reached)."""
        ts, worst, stop = self.ts, self.worst_at, self.stop
        offs = ts.offsets
        out = []
        for _ in range(steps):
            if stop[u]:
                break
            lo, hi = int(offs[u]), int(offs[u + 1])
            if lo == hi:
                break
            w = worst[ts.dst[lo:hi]]
            t = lo + int(np.argmax(w))  # INF first, else the longest; the first such transition
            out.append(t)
            u = int(ts.dst[t])
        return out

    def worst_witness(self) -> "tuple | None":
        """(transitions, trigger step index, loop or None): a run reaching a trigger state with
        the worst case and following a longest response-free path; for an unbounded worst
        case, the lasso into a response-free cycle (or the path to a state without successors)."""
        worst: Any = self.worst
        return self._worst_from(*self._entry(self.triggers[self.worst_at[self.triggers] == worst]))

    def witness_from(self, edges) -> "tuple | None":
        """(transitions, trigger step index, loop or None): the worst run among those whose
        trigger is one of ``edges`` (trigger transitions, e.g. the arrivals from one state),
        as ``worst_witness`` (the nearest source on a tie)."""
        edges = np.asarray(edges, np.int64)
        w = self.worst_at[self.ts.dst[edges]]
        return self._worst_from(*self._through(edges[w == w.max()]))

    def violation_witness(self, bound: int) -> "tuple | None":
        """(transitions, trigger step index, loop or None) of the shortest run whose response
        takes more than ``bound`` ticks: the lasso when the response never comes. None on a
        budget-cut system whose explored part holds no such run (the unbounded figure then
        comes from states left unexpanded)."""
        bad = self.triggers[self.worst_at[self.triggers] > bound]
        prefix, t = self._entry(bad)
        if self.worst_at[t] == INF:
            return self._lasso(prefix, t)
        return prefix + self._longest_walk(t, bound), len(prefix), None

    def bounded_witness(self, bound: int) -> "tuple | None":
        """(transitions, trigger step index, None): the run from the nearest trigger state
        that goes ``bound`` ticks without the response inside the explored part, or None.
        For a budget-cut system, where unexpanded states make the sweep's figures unbounded:
        such a run is a real violation whatever lies past the budget. ``L[u]``, the most
        response-free transitions a walk from ``u`` can take (capped at ``bound``), grows by
        one transition per round."""
        ts, stop = self.ts, self.stop
        L = free_run(ts.n_states, ts.src, ts.dst, stop, bound)
        good = self.triggers[L[self.triggers] >= bound]
        if not good.size:
            return None
        prefix, u = self._entry(good)
        walk, offs = [], ts.offsets
        for r in range(bound, 0, -1):
            lo, hi = int(offs[u]), int(offs[u + 1])
            succ = ts.dst[lo:hi]
            e = lo + int(np.flatnonzero(~stop[succ] & (L[succ] >= r - 1))[0])
            walk.append(e)
            u = int(ts.dst[e])
        return prefix + walk, len(prefix), None

    # ---------------------------------------------------------------- the first late response
    def first_late(self, bound: int) -> "tuple | None":
        """``(worst ticks, transitions, trigger step)`` over the trigger occurrences whose
        run so far answered every earlier occurrence within ``bound`` ticks (a "clean"
        prefix), or None when this cannot be computed: the trigger is not an event whose
        minimum interval exceeds ``bound`` (then at most one occurrence is pending, and the
        event's interval timer says how long it has waited). When this worst case is at
        most ``bound``, no occurrence is ever late (the first late one would have a clean
        prefix), so the requirement holds; when it exceeds ``bound``, its run is a first
        violation: every earlier occurrence was answered in time. The plain worst case can
        be larger: it also counts occurrences after a late one, in runs that a deadline
        (a part lost at the end of its window) would have cut."""
        ts, ev = self.ts, self.req.trigger_event
        if ev is None or self.trigger_edges is None or not ts.complete:
            return None
        prog = ts.model.program
        slot = next((k for k, sl in enumerate(prog.slots) if sl.name == f"{ev}:since" and sl.kind == "timer"), None)
        if slot is None or prog.slots[slot].size - 1 <= bound:
            return None
        since = ts.column(slot).astype(np.int64)
        n, stop, offs = ts.n_states, self.stop, ts.offsets
        trig = np.zeros(ts.n_transitions, bool)
        trig[self.trigger_edges] = True
        parent = np.full((2, n), -2, np.int64)  # the transition into (pending, state), -1 at the start
        parent[0, 0] = -1
        mode = np.zeros((2, n), np.int8)  # the pending flag before that transition
        frontier = [np.array([0], np.int64), np.zeros(0, np.int64)]
        while frontier[0].size or frontier[1].size:
            nxt: list = [[], []]
            for p in (0, 1):
                u = frontier[p]
                if not u.size:
                    continue
                lo, hi = offs[u], offs[u + 1]
                cnt = hi - lo
                if not cnt.sum():
                    continue
                t = np.repeat(lo - np.cumsum(np.r_[0, cnt[:-1]]), cnt) + np.arange(int(cnt.sum()))
                d = ts.dst[t]
                q = np.where(trig[t], 1, p)
                q[stop[d]] = 0
                ok = ~((q == 1) & (since[d] > bound))  # a late occurrence: the run is cut here
                t, d, q = t[ok], d[ok], q[ok]
                for r in (0, 1):
                    sel = q == r
                    dd, tt = d[sel], t[sel]
                    new = parent[r, dd] == -2
                    dd, tt = dd[new], tt[new]
                    dd, first = np.unique(dd, return_index=True)
                    parent[r, dd] = tt[first]
                    mode[r, dd] = p
                    nxt[r].append(dd)
            frontier = [np.concatenate(x) if x else np.zeros(0, np.int64) for x in nxt]
        src = ts.src[self.trigger_edges]
        clean = (parent[0, src] != -2) | (parent[1, src] != -2)
        edges = self.trigger_edges[clean]
        if not edges.size:
            return None
        w = self.worst_at[ts.dst[edges]]
        e = int(edges[int(np.argmax(w))])
        worst = int(w.max())
        # the clean prefix to the trigger, then a longest response-free walk
        path, node = [e], int(ts.src[e])
        r = 0 if parent[0, node] != -2 else 1
        while parent[r, node] >= 0:
            tr = int(parent[r, node])
            path.append(tr)
            r, node = int(mode[r, node]), int(ts.src[tr])
        path.reverse()
        if worst == INF:
            lasso = self._lasso(path, int(ts.dst[e]))
            return (worst,) + (lasso[0], lasso[1]) if lasso else None
        return worst, path + self._longest_walk(int(ts.dst[e]), worst), len(path)

    def _lasso(self, prefix, t) -> "tuple | None":
        ts, stop = self.ts, self.stop
        free = ~stop[ts.src]
        idx = np.flatnonzero(free)
        on_cycle = cyclic_states(ts.n_states, ts.src[idx], ts.dst[idx])
        on_cycle = on_cycle[~stop[on_cycle]]
        has_out = np.diff(ts.offsets) > 0
        dead = np.flatnonzero(~stop & ~has_out[: ts.n_states]) if ts.complete else np.zeros(0, np.int64)
        goal = np.zeros(ts.n_states, bool)
        goal[on_cycle] = True
        goal[dead] = True
        walk = shortest_path(ts, t, goal, free)
        if walk is None:  # only on a budget-cut system: the run goes on past the explored part
            assert not ts.complete, "an unbounded response with no response-free cycle or dead end reachable"
            return None
        end = int(ts.dst[walk[-1]]) if walk else t
        if end in set(dead.tolist()):
            return prefix + walk, len(prefix), None
        sub = np.flatnonzero(free)
        cyc = shortest_cycle(ts.n_states, ts.src[sub], ts.dst[sub], end)
        path = prefix + walk
        return path + sub[np.asarray(cyc, np.int64)].tolist(), len(prefix), len(path)


def analyse(ts, req: Response) -> ResponseBound:
    return ResponseBound(ts, req)


def _fmt(rb, ticks) -> str:
    if ticks is None:
        return "-"
    if ticks == INF:
        return "unbounded"
    return f"{ticks} ticks ({rb.seconds(ticks):g} s)"


def _requirements(ctx) -> tuple:
    return tuple(ctx.model.responses)  # --trigger/--response/--within are added to the model (verify.cli)


def counterexample(rb, transitions, trigger_step, loop, summary, bound):
    req = rb.req
    viol = {"kind": "response", "name": req.name,
            "trigger": req.trigger_text, "response": req.response_text, "trigger_step": trigger_step, "bound_ticks": bound,
            "worst_ticks": None if rb.worst == INF else rb.worst, "tick_rate": rb.rate}
    if loop is not None:
        viol["text"] = (f"'{req.name}': after the trigger at step {trigger_step} the run enters a cycle "
                        f"(from step {loop + 1}) on which '{req.response_text}' never holds")
    elif bound is not None:
        viol["text"] = (f"'{req.name}': '{req.response_text}' still does not hold {bound} tick(s) ({req.within:g} s, the "
                        f"bound) after the trigger at step {trigger_step}")
    else:
        viol["text"] = (f"'{req.name}': the worst case: {len(transitions) - trigger_step} tick(s) from the trigger "
                        f"at step {trigger_step} to '{req.response_text}'")
    return path_counterexample(rb.ts, transitions, NAME, summary, viol, loop=loop)


def check(ctx) -> Result:
    reqs = _requirements(ctx)
    if not reqs:
        return Result(NAME, True, None, [], not_applicable="no 'responses:' declared")
    ts = ctx.model_ts()
    info: dict
    verdict: "bool | None"
    notes, info, verdict, ce = [], {"responses": {}}, True, None
    for req in reqs:
        rb = ResponseBound(ts, req)
        bound = rb.bound_ticks()
        worst: Any = rb.worst
        best = rb.best
        entry = {"trigger": req.trigger_text, "response": req.response_text, "within_seconds": req.within, "bound_ticks": bound,
                 "triggers": int(rb.triggers.size),
                 "worst_ticks": None if worst in (None, INF) else worst,
                 "worst_seconds": None if worst in (None, INF) else rb.seconds(worst),
                 "best_ticks": None if best in (None, INF) else best,
                 "best_seconds": None if best in (None, INF) else rb.seconds(best),
                 "unbounded": worst == INF}
        info["responses"][req.name] = entry
        if not rb.occurs:
            notes.append(f"{req.name}: the trigger never occurs in a reachable state")
            continue
        text = f"{req.name}: worst case {_fmt(rb, worst)}, best case {_fmt(rb, best)}"
        if bound is not None:
            text += f"; bound {req.within:g} s = {bound} ticks"
        notes.append(text)
        if bound is not None and worst > bound:
            first = rb.first_late(bound)
            if first is not None:
                entry.update(first_late_ticks=None if first[0] == INF else first[0],
                             first_late_seconds=None if first[0] == INF else rb.seconds(first[0]))
                notes.append(f"{req.name}: the worst first late response (every earlier trigger answered "
                             f"within the bound) {_fmt(rb, first[0])}")
            witness: Any = rb.violation_witness(bound) if ce is None else None
            if ce is None and witness is None:  # a cut system: look for a run of `bound` ticks inside it
                witness = rb.bounded_witness(bound)
            if ce is None and witness is None:  # ... and there is none
                verdict = None if verdict is not False else False
                notes.append(f"{req.name}: no run of the explored part exceeds the bound; the worst case "
                             "comes from states the budget left unexpanded")
                continue
            verdict = False
            if ce is None:
                path, k, loop = witness
                summary = (f"'{req.name}': '{req.response_text}' may never come after the trigger" if worst == INF else
                           f"'{req.name}': the response can take {worst / rb.rate:g} s > {req.within:g} s")
                ce = counterexample(rb, path, k, loop, summary, bound)
    if not ts.complete:
        notes.append(f"{budget_hit(ts)}: the figures cover the explored part only; " +
                     ("the violation's run lies inside it" if verdict is False else "not decided"))
        if verdict:
            verdict = None
    return Result(NAME, verdict, ce, notes, info)
