"""Explicit transition systems: the result of exploring a model (``btfsm.verify.explore``).

A ``TransitionSystem`` stores states as rows of small ints (one column per kept slot of
``model.program.slots``) and transitions as flat int64 arrays (``src``, ``dst``,
``label``), sorted by source. State 0 is the initial state and states are numbered in
breadth-first order, so following ``parent`` back from any state gives a shortest path.

Two kinds exist: ``"model"`` (one transition = one BT tick of the whole model) and
``"fsm"`` (one FSM as an open system: one transition = one request of one goal, with the
environment, the goal, its parameters and free inputs chosen every possible way).

>>> from btfsm import Model, Int, Action, success
>>> from btfsm.verify.explore import explore
>>> m = Model("c", variables=[Int("n", 0, 2)], tree=Action("inc", outcomes=[success(n="min(n + 1, 2)")]))
>>> ts = explore(m)
>>> ts.n_states, ts.n_transitions, ts.successors(2).tolist()
(3, 3, [2])
>>> ts.path_to(2)
[0, 1]
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import cast

import numpy as np

from .codec import codec, decode_codes, dtype

_SLICE = 1 << 22  # states or transitions per slice where a whole-system temporary would be large

__all__ = ["TransitionSystem", "DomainViolation", "shortest_path", "reverse_reach", "forward_reach",
           "strong_components", "bottom_sccs", "cyclic_states", "shortest_cycle", "forward_csr", "components",
           "bottom_components", "cyclic_states_of"]


@dataclass(frozen=True)
class DomainViolation:
    """An effect wrote outside its domain during the tick taken from ``state`` with ``script``."""

    state: int
    script: tuple
    label: tuple
    var: str
    value: int
    where: str
    message: str


class TransitionSystem:
    """An explored model or FSM. Fields beyond the contract: ``status`` (root status or FSM
    reply per transition), ``goal`` (requested goal index per transition, FSM level),
    ``expanded`` (states ``0..expanded-1`` have all their successors), ``errors``
    (``DomainViolation``s), ``violations`` (``(transition, violations)`` contract breaches),
    ``open`` (FSM level: the open system's description, see ``btfsm.verify.explore.OpenFSM``),
    ``stopped`` (an incomplete system: the budget that was hit, ``"states"``,
    ``"transitions"``, ``"seconds"`` or ``"paths"``; see ``btfsm.verify.search.Budget``).

    Compact storage (the traced engine's): instead of ``states``, ``src``, ``label``,
    ``status`` (and ``goal``) an engine may give ``codes`` (one int code per state,
    ``btfsm.verify.codec``), ``offsets`` (the CSR row pointer: the transitions of state i
    are ``offsets[i]:offsets[i+1]``), ``edge`` (a small code per transition) with
    ``edge_label``/``edge_status`` (the label index and status of each edge code) and
    ``label_goal`` (the requested goal of each label, FSM level). The other arrays are then
    derived on first use and kept (``states`` decoded from the codes, ``src`` repeated from
    the offsets, ``label``/``status``/``goal`` looked up from the edge codes): the same values
    as an engine that stores them, in the smallest integer types that hold them."""

    def __init__(self, model, kind, fsm, slots, states=None, src=None, dst=None, label=None, labels=(), parent=None,
                 complete=True, seconds=0.0, status=None, goal=None, expanded=0, errors=(), violations=(), open=None,
                 stopped=None, *, codes=None, offsets=None, edge=None, edge_label=None, edge_status=None,
                 label_goal=None):
        self.model, self.kind, self.fsm, self.slots = model, kind, fsm, slots
        self.dst, self.labels, self.parent = dst, labels, parent
        self.complete, self.seconds, self.expanded = complete, seconds, expanded
        self.errors, self.violations, self.open, self.stopped = errors, violations, open, stopped
        self.codes, self.edge, self.edge_label, self.edge_status = codes, edge, edge_label, edge_status
        self.label_goal = label_goal
        given = {"states": states, "src": src, "label": label, "offsets": offsets}
        if edge is None:
            given["status"] = np.zeros(0, np.int8) if status is None else status
            given["goal"] = goal
        for name, value in given.items():
            if value is not None or name == "goal":
                self.__dict__[name] = value  # a derived attribute (below) given by the engine
        if states is None and codes is None:
            raise ValueError("a TransitionSystem needs states or codes")
        if src is None and offsets is None:
            raise ValueError("a TransitionSystem needs src or offsets")

    # ------------------------------------------------------------------ derived arrays
    @cached_property
    def states(self) -> np.ndarray:
        """Rows of small ints, one column per kept slot (decoded from ``codes``)."""
        prog = self.model.program
        mults = codec(prog, tuple(self.slots))[0]
        return decode_codes(prog, tuple(self.slots), self.codes, mults)

    @cached_property
    def src(self) -> np.ndarray:
        """Source state of every transition (repeated from ``offsets``)."""
        n = self.n_states
        dt = np.int32 if n < 1 << 31 else np.int64
        return np.repeat(np.arange(n, dtype=dt), np.diff(self.offsets))

    @cached_property
    def label(self) -> np.ndarray:
        """Label index (into ``labels``) of every transition."""
        return self.edge_label[self.edge]

    @cached_property
    def status(self) -> np.ndarray:
        """Root status (FSM level: the FSM's reply) of every transition, int8."""
        return self.edge_status[self.edge]

    @cached_property
    def goal(self) -> "np.ndarray | None":
        """Requested goal index of every transition (FSM level), else None."""
        if self.kind != "fsm" or self.label_goal is None:
            return None
        return self.label_goal[self.label]

    # ------------------------------------------------------------------ sizes
    @property
    def n_states(self) -> int:
        if self.codes is not None:
            return int(self.codes.shape[0])
        return int(self.states.shape[0])

    @property
    def n_transitions(self) -> int:
        return int(self.dst.shape[0])

    @property
    def nbytes(self) -> int:
        """Bytes held by the arrays stored or derived so far."""
        names = ("codes", "states", "src", "dst", "label", "status", "goal", "edge", "offsets", "parent", "reverse")
        total = 0
        for name in names:
            value = self.__dict__.get(name)
            for a in (value if isinstance(value, tuple) else (value,)):
                total += a.nbytes if isinstance(a, np.ndarray) else 0
        return total

    def __repr__(self) -> str:
        what = self.kind if self.fsm is None else f"fsm {self.fsm}"
        done = "" if self.complete else f", incomplete: {self.stopped or 'budget'} budget hit"
        return f"TransitionSystem({self.model.name}, {what}: {self.n_states} states, {self.n_transitions} transitions{done})"

    # ------------------------------------------------------------------ adjacency
    @cached_property
    def offsets(self) -> np.ndarray:
        """CSR offsets: the transitions of state i are ``offsets[i]:offsets[i+1]``."""
        return np.searchsorted(self.src, np.arange(self.n_states + 1, dtype=np.int64)).astype(np.int64)

    @cached_property
    def reverse(self) -> tuple:
        """``(offsets, transitions)``: a CSR of incoming transitions, by destination."""
        order = np.argsort(self.dst, kind="stable").astype(np.int64)
        offs = np.searchsorted(self.dst[order], np.arange(self.n_states + 1, dtype=np.int64)).astype(np.int64)
        return offs, order

    def out_transitions(self, i: int) -> np.ndarray:
        """Indices of the transitions leaving state ``i``."""
        o = self.offsets
        return np.arange(o[i], o[i + 1], dtype=np.int64)

    def successors(self, i: int) -> np.ndarray:
        """Destination states of the transitions leaving ``i`` (with repeats for
        transitions that differ only by label)."""
        o = self.offsets
        return self.dst[o[i]:o[i + 1]]

    @cached_property
    def dead(self) -> np.ndarray:
        """Expanded states without any successor."""
        counts = np.diff(self.offsets)[: self.expanded]
        return np.flatnonzero(counts == 0)

    # ------------------------------------------------------------------ states
    def _row(self, i: int) -> np.ndarray:
        """The kept slots' values of state ``i``: from ``states`` when it is held, else
        decoded from its code alone (a counterexample decodes only its path)."""
        if "states" in self.__dict__ or self.codes is None:
            return self.states[i]
        prog = self.model.program
        return decode_codes(prog, tuple(self.slots), self.codes[i:i + 1], codec(prog, tuple(self.slots))[0])[0]

    def full_state(self, i: int) -> tuple:
        """The program state tuple of state ``i`` (slots sliced away hold their initial value)."""
        row = self._row(i)
        if self.kind == "model":
            return tuple(int(x) for x in row)
        base = list(self.model.program.initial)
        for k, slot in enumerate(self.slots):
            base[slot] = int(row[k])
        return tuple(base)

    def decode(self, i: int) -> dict:
        """Readable values of the kept slots of state ``i``."""
        prog = self.model.program
        row = self._row(i)
        return {prog.slots[s].name: prog.decode_slot(s, int(row[k])) for k, s in enumerate(self.slots)}

    def column(self, slot: int) -> np.ndarray:
        """The values of program slot ``slot`` in every state (its initial value if sliced away).
        A compact system decodes the one column from ``codes`` (in slices, kept for the next
        call) and never builds ``states``."""
        prog = self.model.program
        dt = dtype(prog, tuple(self.slots))
        if slot not in self.slots:
            return np.full(self.n_states, prog.initial[slot], dtype=dt)
        if "states" in self.__dict__ or self.codes is None:
            return self.states[:, self.slots.index(slot)]
        cols = self.__dict__.setdefault("_columns", {})
        col = cols.get(slot)
        if col is None:
            info, mult = prog.slots[slot], codec(prog, tuple(self.slots))[0][slot]
            col = np.empty(self.n_states, dt)
            for a in range(0, self.n_states, _SLICE):
                part = self.codes[a:a + _SLICE].astype(np.int64)
                part //= mult
                part %= max(info.size, 1)
                part += info.lo
                col[a:a + _SLICE] = part
            cols[slot] = col
        return col

    def columns(self) -> list:
        """One array per program slot (for vectorised predicates)."""
        return [self.column(k) for k in range(len(self.model.program.slots))]

    def source(self, t: int) -> int:
        """The source state of transition ``t`` (from ``offsets`` unless ``src`` is held)."""
        if "src" in self.__dict__:
            return int(self.src[t])
        return int(np.searchsorted(self.offsets, t, side="right")) - 1

    def label_of(self, t: int) -> int:
        """The label index of transition ``t`` (without building ``label``)."""
        if "label" in self.__dict__:
            return int(self.label[t])
        return int(self.edge_label[self.edge[t]])

    def goal_of(self, t: int) -> int:
        """The requested goal of transition ``t`` (FSM level), without building ``goal``."""
        if "goal" in self.__dict__ or self.edge is None:
            return int(cast(np.ndarray, self.goal)[t])
        return int(cast(np.ndarray, self.label_goal)[self.label_of(t)])

    def pick(self, tmask: np.ndarray) -> tuple:
        """``(positions, src, dst)`` of the transitions selected by ``tmask`` (int64
        positions; sources made a slice at a time)."""
        parts, srcs = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
        for a, b, src in self.slices():
            sel = np.flatnonzero(tmask[a:b])
            parts.append(sel + a)
            srcs.append(src[sel])
        pos = np.concatenate(parts)
        return pos, np.concatenate(srcs), self.dst[pos]

    def where(self, fn) -> np.ndarray:
        """A boolean per transition: ``fn(label, status, goal)`` over index arrays (``goal``:
        the requested goal, FSM level, else None). A compact system evaluates ``fn`` once per
        edge code and looks the answers up in ``edge``, so neither ``label``, ``status`` nor
        ``goal`` is built (1 byte per transition for the answer)."""
        if self.edge is not None and "label" not in self.__dict__:
            lab = np.asarray(self.edge_label)
            goal = self.label_goal[lab] if self.kind == "fsm" and self.label_goal is not None else None
            table = np.broadcast_to(np.asarray(fn(lab, np.asarray(self.edge_status), goal), bool), lab.shape)
            return table[self.edge]
        return np.broadcast_to(np.asarray(fn(self.label, self.status, self.goal), bool), (self.n_transitions,)).copy()

    def slices(self, size: int = 1 << 23):
        """``(a, b, src)`` over the transitions in slices of about ``size``: the source of
        each transition ``a..b-1`` (int32 below 2^31 states), made from ``offsets`` a slice
        at a time (``src`` itself is never built)."""
        m = self.n_transitions
        if "src" in self.__dict__:
            for a in range(0, m, size):
                yield a, min(a + size, m), self.src[a:a + size]
            return
        dt = np.int32 if self.n_states < 1 << 31 else np.int64
        offs = self.offsets
        for a in range(0, m, size):
            b = min(a + size, m)
            s0, s1 = self.source(a), self.source(b - 1)
            o = np.clip(offs[s0:s1 + 2].astype(np.int64), a, b)
            yield a, b, np.repeat(np.arange(s0, s1 + 1, dtype=dt), np.diff(o))

    def any_out(self, tmask: np.ndarray) -> np.ndarray:
        """A boolean per state: does some transition selected by ``tmask`` leave it?"""
        out = np.zeros(self.n_states, bool)
        for a, b, src in self.slices():
            out[src[tmask[a:b]]] = True
        return out

    def path_to(self, i: int) -> list:
        """Transition indices of the shortest path from the initial state to ``i``."""
        path = []
        t = int(self.parent[i])
        while t >= 0:
            path.append(t)
            t = int(self.parent[self.source(t)])
        path.reverse()
        return path

    def depth(self) -> np.ndarray:
        """BFS depth of every state."""
        d = np.zeros(self.n_states, np.int64)
        par = self.parent
        for i in range(1, self.n_states):  # parents have smaller indices (BFS order)
            d[i] = d[int(self.src[par[i]])] + 1
        return d

    def to_networkx(self, max_states: int = 100_000):
        """A ``networkx.MultiDiGraph`` (for small systems only: reporting, SCC views)."""
        if self.n_states > max_states:
            raise ValueError(f"{self.n_states} states: too many for networkx (max_states={max_states})")
        import networkx as nx

        g: nx.MultiDiGraph = nx.MultiDiGraph(model=self.model.name, kind=self.kind, fsm=self.fsm)
        for i in range(self.n_states):
            g.add_node(i, **self.decode(i))
        for t in range(self.n_transitions):
            g.add_edge(int(self.src[t]), int(self.dst[t]), key=t, label=self.labels[int(self.label[t])],
                       status=int(self.status[t]) if len(self.status) else None)
        return g


# ---------------------------------------------------------------------- graph helpers


def _expand(frontier: np.ndarray, offs: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """All ``targets[offs[i]:offs[i+1]]`` for i in frontier, concatenated (vectorised)."""
    starts, ends = offs[frontier], offs[frontier + 1]
    lens = ends - starts
    total = int(lens.sum())
    if total == 0:
        return np.zeros(0, np.int64)
    # positions = starts repeated, plus 0..len-1 within each run
    run_starts = np.repeat(starts - np.concatenate(([0], np.cumsum(lens)[:-1])), lens)
    return targets[run_starts + np.arange(total, dtype=np.int64)]


def _closure(seen: np.ndarray, offs: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """Grow the mask ``seen`` along the CSR ``(offs, targets)`` to a fixed point, level by
    level. Duplicates in a level are dropped in linear time with a stamp array (the last
    position that wrote a node keeps it)."""
    stamp = np.empty(seen.shape[0], np.int64)
    frontier = np.flatnonzero(seen)
    while frontier.size:
        cand = _expand(frontier, offs, targets)
        cand = cand[~seen[cand]]
        if not cand.size:
            break
        pos = np.arange(cand.size, dtype=np.int64)
        stamp[cand] = pos
        cand = cand[stamp[cand] == pos]
        seen[cand] = True
        frontier = cand
    return seen


def forward_csr(ts: TransitionSystem, mask: "np.ndarray | None" = None) -> tuple:
    """``(offsets, targets)``: the CSR of the transitions selected by ``mask`` (all when
    None: the system's own ``offsets`` and ``dst``, no copy). A selection is built a slice
    of transitions at a time: 4 bytes per selected transition (int32 below 2^31 states)."""
    if mask is None:
        return ts.offsets, ts.dst
    n = ts.n_states
    counts = np.zeros(n + 1, np.int64)
    parts = [np.zeros(0, ts.dst.dtype)]
    for a, b, src in ts.slices():
        sel = mask[a:b]
        s = src[sel]
        if s.size:
            s0 = int(s[0])
            counts[s0 + 1:int(s[-1]) + 2] += np.bincount(s - s0)
            parts.append(ts.dst[a:b][sel])
    np.cumsum(counts, out=counts)
    return counts.astype(np.int32) if counts[-1] < 1 << 31 else counts, np.concatenate(parts)


def _matrix(n: int, offs, targets):
    """The CSR ``(offs, targets)`` as a scipy matrix for ``scipy.sparse.csgraph``, without
    copying it: int32 indices stay int32, and the weights (csgraph converts them to float64)
    are one broadcast 1.0, not an array."""
    from scipy.sparse import csr_matrix

    it = np.int32 if max(n, targets.size) < 1 << 31 else np.int64
    ones = np.broadcast_to(np.float64(1.0), targets.shape)
    return csr_matrix((ones, targets.astype(it, copy=False), offs.astype(it, copy=False)), shape=(n, n), copy=False)


def components(ts: TransitionSystem, mask: "np.ndarray | None" = None) -> tuple:
    """``(count, label)``: the strongly connected components of the transitions selected
    by ``mask`` (all when None), scipy's linear-time algorithm straight on the system's CSR
    (int32 label per state; no copy of the transitions)."""
    from scipy.sparse.csgraph import connected_components

    from scipy.sparse import csr_matrix

    n = ts.n_states
    offs, targets = forward_csr(ts, mask)
    # scipy's strong components never return on a matrix with a repeated entry (two
    # transitions between the same states, e.g. differing by label): when there is one,
    # sort each row and merge repeats first, in C, on a copy of the targets (4 bytes and 1
    # byte per transition)
    it = np.int32 if max(n, targets.size) < 1 << 31 else np.int64
    if mask is None and not _repeats(ts):  # the stored CSR as it is: no copy
        return connected_components(_matrix(n, offs, targets), directed=True, connection="strong")
    g = csr_matrix((np.ones(targets.size, bool), targets.astype(it, copy=mask is None),
                    offs.astype(it, copy=mask is None)), shape=(n, n), copy=False)
    del offs, targets
    g.sum_duplicates()
    return connected_components(_matrix(n, g.indptr, g.indices), directed=True, connection="strong")


_MAX_LAGS = 16


def _repeats(ts: TransitionSystem) -> bool:
    """Whether some state has two transitions to one state (True, without looking, when a
    state has more than ``_MAX_LAGS`` transitions). A pass over the transitions a slice
    at a time, comparing each with the few before it in its row."""
    offs = ts.offsets
    widest = max((int(np.diff(offs[a:a + _SLICE + 1]).max(initial=0)) for a in range(0, ts.n_states, _SLICE)),
                 default=0)
    if widest > _MAX_LAGS:
        return True
    if widest < 2:
        return False
    prev_s = prev_d = None
    for a, b, src in ts.slices():
        s, d = src, ts.dst[a:b]
        if prev_s is not None:
            s, d = np.concatenate([prev_s, s]), np.concatenate([prev_d, d])
        for lag in range(1, widest):
            if ((s[lag:] == s[:-lag]) & (d[lag:] == d[:-lag])).any():
                return True
        prev_s, prev_d = s[-widest:], d[-widest:]
    return False


def bottom_components(ts: TransitionSystem, count: int, label: np.ndarray) -> np.ndarray:
    """A boolean per component: no transition leaves it (one pass over the transitions,
    a slice at a time)."""
    left = np.zeros(count, bool)
    if count > 1:
        for a, b, src in ts.slices():
            ls, ld = label[src], label[ts.dst[a:b]]
            left[ls[ls != ld]] = True
    return ~left


def reverse_reach(ts: TransitionSystem, targets: np.ndarray, mask: "np.ndarray | None" = None) -> np.ndarray:
    """Boolean mask of states that can reach a ``targets`` state (a mask) using only the
    transitions selected by ``mask`` (all when None). Linear in the transitions: the
    reversed CSR is scipy's transpose of ``forward_csr`` (int32 indices, 5 bytes per
    selected transition), dropped on return."""
    seen = targets.astype(bool).copy()
    offs, targets_ = forward_csr(ts, mask)
    if targets_.size == 0:
        return seen
    from scipy.sparse import csr_matrix

    n = ts.n_states
    it = np.int32 if max(n, targets_.size) < 1 << 31 else np.int64
    rev = csr_matrix((np.ones(targets_.size, bool), targets_.astype(it, copy=False), offs.astype(it, copy=False)),
                     shape=(n, n), copy=False).tocsc()
    del offs, targets_
    return _closure(seen, rev.indptr, rev.indices)


def forward_reach(ts: TransitionSystem, start, mask: "np.ndarray | None" = None) -> np.ndarray:
    """Boolean mask of states reachable from ``start`` (an index or a mask) along the
    transitions selected by ``mask`` (all when None)."""
    n = ts.n_states
    seen = np.zeros(n, bool)
    if isinstance(start, np.ndarray) and start.dtype == bool:
        seen |= start
    else:
        seen[np.asarray(start, dtype=np.int64)] = True
    offs, dsts = forward_csr(ts, mask)
    return _closure(seen, offs, dsts)


def shortest_path(ts: TransitionSystem, start: int, goal, mask: "np.ndarray | None" = None) -> "list | None":
    """Transition indices of a shortest path from ``start`` to a state in ``goal`` (a set,
    mask or index) along transitions selected by ``mask``; ``[]`` when start is a goal,
    None when there is none. Plain BFS (for short paths inside small regions)."""
    if isinstance(goal, np.ndarray):
        is_goal = (lambda i: bool(goal[i])) if goal.dtype == bool else (lambda i: i in set(goal.tolist()))
    elif isinstance(goal, (set, frozenset)):
        is_goal = goal.__contains__
    else:
        is_goal = (lambda i, g=int(goal): i == g)  # type: ignore[misc]  # (mypy cannot type a lambda default)
    if is_goal(start):
        return []
    offs = ts.offsets
    via = {start: -1}
    frontier = [start]
    while frontier:
        nxt = []
        for i in frontier:
            for t in range(int(offs[i]), int(offs[i + 1])):
                if mask is not None and not mask[t]:
                    continue
                j = int(ts.dst[t])
                if j in via:
                    continue
                via[j] = t
                if is_goal(j):
                    path = []
                    while t >= 0:
                        path.append(t)
                        t = via[int(ts.src[t])]
                    return path[::-1]
                nxt.append(j)
        frontier = nxt
    return None


def strong_components(n: int, src, dst) -> np.ndarray:
    """SCC label of each of the ``n`` nodes of the graph with edges ``src[k] -> dst[k]``
    (scipy's linear-time algorithm over a CSR matrix; exact at any size)."""
    from scipy.sparse.csgraph import connected_components

    src, dst = np.asarray(src, np.int64), np.asarray(dst, np.int64)
    return connected_components(_csr(n, src, dst), directed=True, connection="strong")[1]


def _csr(n: int, src: np.ndarray, dst: np.ndarray):
    """The ``n`` x ``n`` boolean adjacency matrix (repeated edges summed to True, so any
    number of parallel transitions stays one structural edge)."""
    from scipy.sparse import csr_matrix

    return csr_matrix((np.ones(src.size, bool), (src, dst)), shape=(n, n))


def bottom_sccs(n: int, src, dst, nodes) -> list:
    """Bottom SCCs of the sub-graph induced by ``nodes`` (edges ``src -> dst`` with both ends
    in ``nodes``): sorted lists of node indices, ordered by their lowest node."""
    nodes = np.unique(np.asarray(nodes, np.int64))
    if nodes.size == 0:
        return []
    src, dst = np.asarray(src, np.int64), np.asarray(dst, np.int64)
    inside = np.zeros(n, bool)
    inside[nodes] = True
    keep = inside[src] & inside[dst]
    pos = np.full(n, -1, np.int64)
    pos[nodes] = np.arange(nodes.size)
    s, d = pos[src[keep]], pos[dst[keep]]
    lab = strong_components(nodes.size, s, d)
    leaves = np.ones(int(lab.max()) + 1, bool)
    leaves[lab[s][lab[s] != lab[d]]] = False
    order = np.argsort(lab, kind="stable")  # nodes ascending within each label
    groups = np.split(nodes[order], np.flatnonzero(np.diff(lab[order])) + 1)
    out = [g.tolist() for g in groups if leaves[lab[pos[g[0]]]]]
    return sorted(out, key=lambda scc: scc[0])


def cyclic_states(n: int, src, dst) -> np.ndarray:
    """Sorted nodes lying on a cycle of the graph with edges ``src -> dst``: members of an
    SCC with more than one node, or with a self-loop."""
    src, dst = np.asarray(src, np.int64), np.asarray(dst, np.int64)
    if src.size == 0:
        return np.zeros(0, np.int64)
    lab = strong_components(n, src, dst)
    size = np.bincount(lab)
    on = size[lab] > 1
    on[src[src == dst]] = True
    return np.flatnonzero(on)


def cyclic_states_of(ts: TransitionSystem, mask: np.ndarray) -> np.ndarray:
    """``cyclic_states`` of the transitions of ``ts`` selected by ``mask``, on their CSR
    (no per-transition copies beyond the selection's targets)."""
    if not mask.any():
        return np.zeros(0, np.int64)
    count, lab = components(ts, mask)
    on = np.bincount(lab, minlength=count)[lab] > 1
    for a, b, src in ts.slices():
        sel = mask[a:b]
        s = src[sel]
        on[s[s == ts.dst[a:b][sel]]] = True
    return np.flatnonzero(on)


def shortest_cycle(n: int, src, dst, c: int) -> "list | None":
    """Positions ``k`` (into ``src``/``dst``) of the edges of a shortest cycle through node
    ``c`` of the graph with edges ``src[k] -> dst[k]``, starting with an edge out of ``c``;
    None when ``c`` lies on no cycle. Exact at any size and linear in the edges: one
    breadth-first search from ``c`` (scipy, in C), then the edge back into ``c`` whose
    source the search reached first (so nearest: BFS order is by distance), then the BFS
    tree path to that source. Each step of the path is the lowest-positioned edge between
    its two nodes (parallel edges differ only by label).

    >>> shortest_cycle(4, [0, 1, 2, 1, 3], [1, 2, 0, 3, 1], 1)
    [3, 4]
    >>> shortest_cycle(3, [0, 1], [1, 2], 0) is None
    True
    """
    from scipy.sparse.csgraph import breadth_first_order

    src, dst = np.asarray(src, np.int64), np.asarray(dst, np.int64)
    back = np.flatnonzero(dst == c)
    if back.size == 0:
        return None
    order, pred = breadth_first_order(_csr(n, src, dst), c, directed=True, return_predecessors=True)
    rank = np.full(n, np.iinfo(np.int64).max, np.int64)
    rank[order] = np.arange(order.size, dtype=np.int64)
    r = rank[src[back]]
    if int(r.min()) == np.iinfo(np.int64).max:
        return None
    closing = int(back[np.flatnonzero(r == r.min())[0]])  # lowest position among the nearest
    nodes = [int(src[closing])]
    while nodes[-1] != c:
        nodes.append(int(pred[nodes[-1]]))
    nodes.reverse()  # c, ..., src[closing]
    # the lowest-positioned edge for each tree step: one pass over the edges
    first = {}
    steps = set(zip(nodes[:-1], nodes[1:]))
    if steps:
        hit = np.flatnonzero(np.isin(src, np.array(nodes[:-1], np.int64)))
        for k in hit.tolist():
            key = (int(src[k]), int(dst[k]))
            if key in steps and key not in first:
                first[key] = k
    return [first[a, b] for a, b in zip(nodes[:-1], nodes[1:])] + [closing]
