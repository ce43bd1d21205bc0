"""Path-compiled exploration: the real step function, traced once per path, then run on
whole batches of states with numpy.

``Program.step`` is run on *symbolic* states: every slot holds a ``Sym`` (its expression
over the tick's input state and its value in one representative state). Arithmetic and
comparisons build expressions; whenever the step's Python code needs a concrete answer
(``if``, ``and``/``or``/``not``, indexing, ``int()``) the ``Sym`` answers with the
representative's value and the tracer records that *decision*. The oracle's choice
points are recorded the same way. One run yields a path: its decisions, in order, and
the tick's result as expressions (next state), constants (status, labels, contract
violations) or a domain error. FSM tokens, held goals, running flags, node memories
and parameters are decided as soon as they are read (a switch on the slot's value);
world variables stay symbolic, so one path covers every value of a counter it only
compares or increments.

Paths share prefixes and form a decision trie. A state's walk of the trie (a decision
goes the way of the expression's value, a choice point down every answer, a leaf makes a
transition: next-state code from one expression) is fixed by the values of the trie's
decisions on it. So a batch of states is expanded by key (``_Engine.successors``): each
row's key is those values (every expression evaluated once per batch with numpy), a key
met for the first time is walked once on one of its rows (a part of the trie not traced
yet is traced there, that row's state the representative) and kept as a group, and the
batch's transitions are gathered from its rows' groups, ordered by (source, choice
script in the order ``btfsm.verify.explore``'s depth-first search takes them), so states,
labels and transitions are numbered exactly as the generic engine numbers them (tests
compare the two systems field by field). ``_Engine.expand`` walks the trie with row sets
instead (keys past ``KEY_LIMIT``, the timed closure, the staged tries, the distributed
search). Domain errors are re-run with the real step on
concrete states to report them exactly.

Nothing here re-states the semantics: every decision, expression and constant comes from
a run of ``Program.step``.

Why one module of more than 1,000 lines: the tracer (``Sym``, the decision trie), the
engine that walks the trie over batches (``_Engine``), the two phases of timed models
(``_closure``, ``_number``) and the staged tries of wide environments (``_Staged``) all work
on the same private structures (the trie's nodes and leaves, the engine's columns, codes
and ordinals) inside the search's hot loop; split apart, each would become a public
interface that only this engine uses. The visited set, which has an interface of its own,
is ``btfsm.verify.visited``.

>>> from btfsm.models.pickplace import pickplace
>>> from btfsm.verify.explore import explore
>>> ts = explore(pickplace(3), engine="traced")
>>> ts.n_states, ts.n_transitions
(10288, 70336)
"""
from __future__ import annotations

import time
from array import array
from typing import TYPE_CHECKING, Any, Sequence

import numpy as np

from btfsm.errors import DomainError

from .codec import code_dtype, codec
from .labels import readable
from .search import DEFAULT_MAX_STATES, Budget, EnumOracle, Search, SearchTask
from .system import DomainViolation, TransitionSystem
from .visited import STEP, Bitmap, Hashed, Ids

if TYPE_CHECKING:
    from btfsm.semantics import Site

__all__ = ["search", "BatchSuccessors", "Untraceable", "TooManyPaths", "CHUNK", "DENSE_LIMIT", "PATHS_MIN", "ROWS_LIMIT"]

CHUNK = 1 << 15  # states expanded per batch
DENSE_LIMIT = 1 << 31  # code space up to which the visited set is a bitmap (256 MB at most), else a hash table
DENSE_IDS = 1 << 25  # ... and up to which it is a table of state ids (128 MB at most; no numbering at the end)
TERMS_LIMIT = 1 << 22  # values of (term tuple, state) sums a batch may hold, else leaf by leaf
PATHS_MIN = 1 << 13  # paths traced before the trie must pay off (see ``search``)
PATHS_RATIO = 4  # ... then at most one path per this many transitions found
ROWS_LIMIT = 1 << 21  # (state, path) rows of one batch before it is split
KEY_LIMIT = 1 << 62  # decision keys (``_Engine.successors``) up to this, else the trie walked row set by row set
NEW_KEYS = 64  # ... and so is a batch with more new keys than this and than a quarter of its rows
_CONTROL = ("token", "goal", "flag", "memory", "param")  # decided when first read
_LAST = 1 << 20  # choice answer c > 0 sorts as _LAST - c: answers 0, n-1, ..., 1 (DFS order)


class Untraceable(Exception):
    """The step did something the tracer does not follow; use the generic engine."""


class TooManyPaths(Untraceable):
    """The decision trie grew past its path limit: the model's paths multiply (many free
    inputs or environment events), so tracing does not pay off; use the scalar engine."""


class _Stop(Exception):
    """A budget was hit while a batch was walked (``hit``: ``"seconds"`` or ``"paths"``)."""

    def __init__(self, hit):
        super().__init__(hit)
        self.hit = hit


class _Wide(Exception):
    """A batch reaches more (state, path) rows than it may; split it."""


# ---------------------------------------------------------------------- expressions

_OPS = {
    "+": (lambda a, b: a + b), "-": (lambda a, b: a - b), "*": (lambda a, b: a * b),
    "//": (lambda a, b: a // b), "%": (lambda a, b: a % b),
    "<": (lambda a, b: a < b), "<=": (lambda a, b: a <= b), "==": (lambda a, b: a == b),
    "!=": (lambda a, b: a != b), ">": (lambda a, b: a > b), ">=": (lambda a, b: a >= b),
}


class Sym:
    """A value of the traced tick: expression ``n`` (a node id) and the representative's
    value ``v``. Needing a concrete answer records a decision with the tracer ``t``."""

    __slots__ = ("t", "n", "v")

    def __init__(self, t, n, v):
        self.t, self.n, self.v = t, n, v

    def _op(self, op, other, swap=False):
        return self.t.apply(op, other, self) if swap else self.t.apply(op, self, other)

    def __add__(self, o): return self._op("+", o)
    def __radd__(self, o): return self._op("+", o, True)
    def __sub__(self, o): return self._op("-", o)
    def __rsub__(self, o): return self._op("-", o, True)
    def __mul__(self, o): return self._op("*", o)
    def __rmul__(self, o): return self._op("*", o, True)
    def __floordiv__(self, o): return self._op("//", o)
    def __rfloordiv__(self, o): return self._op("//", o, True)
    def __mod__(self, o): return self._op("%", o)
    def __rmod__(self, o): return self._op("%", o, True)
    def __lt__(self, o): return self._op("<", o)
    def __le__(self, o): return self._op("<=", o)
    def __gt__(self, o): return self._op(">", o)
    def __ge__(self, o): return self._op(">=", o)
    def __eq__(self, o): return self._op("==", o) if isinstance(o, (int, Sym)) else NotImplemented
    def __ne__(self, o): return self._op("!=", o) if isinstance(o, (int, Sym)) else NotImplemented
    def __neg__(self): return self.t.apply("-", 0, self)
    def __pos__(self): return self
    def __abs__(self): return self.t.unary_abs(self)
    def __bool__(self): return bool(self.t.decide(self, "b"))
    def __index__(self): return int(self.t.decide(self, "s"))
    def __int__(self): return int(self.t.decide(self, "s"))
    def __hash__(self): return hash(self.t.decide(self, "s"))
    def __repr__(self): return f"Sym({self.v})"


class _Tracer:
    """One traced run: the decisions taken (``path``) and the values they fixed (``known``)."""

    __slots__ = ("g", "path", "known")

    def __init__(self, graph):
        self.g, self.path, self.known = graph, [], {}

    def resolve(self, x):
        """(True, value) for a constant or an already decided Sym, else (False, node)."""
        if not isinstance(x, Sym):
            return True, x
        n = x.n
        if n in self.known:
            return True, self.known[n]
        if n in self.g.control:
            self.path.append(("s", n, x.v))
            self.known[n] = x.v
            return True, x.v
        return False, n

    def apply(self, op, a, b):
        ka, xa = self.resolve(a)
        kb, xb = self.resolve(b)
        fn = _OPS[op]
        if ka and kb:
            return fn(xa, xb)
        va = xa if ka else a.v
        vb = xb if kb else b.v
        g = self.g
        return Sym(self, g.node((op, xa if not ka else g.const(xa), xb if not kb else g.const(xb))), fn(va, vb))

    def unary_abs(self, a):
        k, x = self.resolve(a)
        return abs(x) if k else Sym(self, self.g.node(("abs", x)), abs(a.v))

    def decide(self, x, kind):
        k, n = self.resolve(x)
        if k:
            return n
        v = bool(x.v) if kind == "b" else int(x.v)
        self.path.append((kind, n, v))
        self.known[n] = v
        return v


class _Graph:
    """Hash-consed expression nodes over the input state: ``("col", k)``, ``("code",)``,
    ``("k", value)``, ``(op, a, b)``, ``("abs", a)``."""

    def __init__(self, width, control):
        self.ids: dict = {}
        self.nodes: list = []
        self.cols = [self.node(("col", k)) for k in range(width)]
        self.code = self.node(("code",))
        self.control = frozenset(self.cols[k] for k in control)

    def node(self, key) -> int:
        i = self.ids.get(key)
        if i is None:
            i = self.ids[key] = len(self.nodes)
            self.nodes.append(key)
        return i

    def const(self, v) -> int:
        return self.node(("k", int(v)))


def _offset(nodes, new, old):
    """c when expression ``new`` is ``old + c``, ``c + old`` or ``old - c`` (c a constant), else None."""
    key = nodes[new]
    if key[0] == "+" and key[1] == old and nodes[key[2]][0] == "k":
        return nodes[key[2]][1]
    if key[0] == "+" and key[2] == old and nodes[key[1]][0] == "k":
        return nodes[key[1]][1]
    if key[0] == "-" and key[1] == old and nodes[key[2]][0] == "k":
        return -nodes[key[2]][1]
    return None


class _Leaf:
    """The end of a path: ``kind`` ok | blocked | error, the next state's code change,
    status, readable label, requested goal (FSM level), violations, the full choice
    script ``taken``."""

    __slots__ = ("id", "kind", "code", "status", "label", "goal", "violations", "taken", "key", "label_id")

    def __init__(self, id, kind, code, status, label, goal, violations, taken):
        self.id, self.kind, self.code, self.status = id, kind, code, status
        self.label, self.goal, self.violations, self.taken = label, goal, violations, tuple(taken)
        self.key = tuple(c and _LAST - c for c in taken)
        self.label_id = -1


class _Column:
    """A growing column of ints in an ``array`` buffer of the smallest signed type that
    holds every value so far (``b``, ``h``, ``i``, ``q``; widened in place when a larger
    value comes). Growing reallocates the buffer (no second copy stays).

    >>> c = _Column("b")
    >>> c.extend(np.array([1, -1]), 1); c.extend(np.array([300]), 300)
    >>> c.view().tolist(), c.view().dtype.name
    ([1, -1, 300], 'int16')
    """

    TYPES = ("b", "h", "i", "q")

    def __init__(self, first: str = "b"):
        self.k = self.TYPES.index(first)
        self.buf = array(first)

    def extend(self, values: np.ndarray, hi: int):
        """Append ``values`` (all in ``-1..hi``)."""
        while hi > (1 << (8 * self.buf.itemsize - 1)) - 1:
            self.k += 1
            wider = array(self.TYPES[self.k])
            wider.frombytes(self.view().astype(np.dtype(self.TYPES[self.k])).tobytes())
            self.buf = wider
        self.buf.frombytes(np.ascontiguousarray(values, dtype=np.dtype(self.buf.typecode)).view(np.uint8).data)

    def view(self) -> np.ndarray:
        dt = np.dtype(self.buf.typecode)
        return np.frombuffer(self.buf, dtype=dt) if len(self.buf) else np.zeros(0, dt)


class _Values:
    """The values of expression nodes over a batch of codes, each computed once (a class,
    not a recursive closure: a closure that calls itself is a reference cycle, and each
    batch's values would wait for the cyclic garbage collector)."""

    __slots__ = ("codes", "nodes", "mults", "sizes", "los", "memo")

    def __init__(self, codes, nodes, mults, sizes, los):
        self.codes, self.nodes, self.mults, self.sizes, self.los = codes, nodes, mults, sizes, los
        self.memo: dict = {}

    def __call__(self, n):
        v = self.memo.get(n)
        if v is not None:
            return v
        key = self.nodes[n]
        op = key[0]
        if op == "col":
            k, codes, sizes = key[1], self.codes, self.sizes
            v = ((codes // self.mults[k]) % sizes[k] + self.los[k] if sizes[k] > 1
                 else np.full(len(codes), self.los[k], np.int64))
        elif op == "code":
            v = self.codes
        elif op == "k":
            v = key[1]
        elif op == "abs":
            v = np.abs(self(key[1]))
        else:
            v = _OPS[op](self(key[1]), self(key[2]))
        self.memo[n] = v
        return v


class _TracingOracle(EnumOracle):
    """An ``EnumOracle`` that also appends every choice point to the traced ``path``."""

    __slots__ = ("path",)

    def __init__(self, script, path):
        super().__init__(script)
        self.path = path

    def _note(self, k):
        if len(self.arities) > k:
            self.path.append(("c", self.arities[k], self.taken[k]))

    def env(self, i: int) -> bool:
        k = len(self.arities)
        r = EnumOracle.env(self, i)
        self._note(k)
        return r

    def choose(self, i: int | tuple[Any, ...], enabled: Sequence[Any]) -> int:
        k = len(self.arities)
        r = EnumOracle.choose(self, i, enabled)
        self._note(k)
        return r

    def outcome(self, site: Site) -> int:
        k = len(self.arities)
        r = EnumOracle.outcome(self, site)
        self._note(k)
        return r


# ---------------------------------------------------------------------- the engine


class _Engine:
    """The trie of one system: ``run(state, oracle)`` is one transition (``Program.step``,
    or ``OpenFSM.run`` at FSM level); states are codes over the ``kept`` slots, the
    others hold their values in ``base``."""

    def __init__(self, model, run, kept, base, op):
        prog = model.program
        self.prog, self.run, self.op = prog, run, op
        self.width = len(prog.slots)
        self.kept, self.base = frozenset(kept), tuple(base)
        self.mults, self.offset, self.total = codec(prog, tuple(kept))
        if self.total >= 1 << 62:
            raise Untraceable("the state space does not fit one int64 code")
        self.sizes = [max(s.size, 1) for s in prog.slots]
        self.los = [s.lo for s in prog.slots]
        self.g = _Graph(self.width, [k for k, s in enumerate(prog.slots) if s.kind in _CONTROL])
        self.names: dict = {}
        self.root: dict = {None: None}  # the trie: [kind, key, children] nodes and _Leaf ends
        self.leaves: list = []
        self.order_dirty = False
        self.leaf_ord = np.zeros(0, np.int64)
        self.max_paths = PATHS_MIN
        self.budget = None
        # the decisions of the trie, for ``successors``: expression node -> [kind, lowest value,
        # number of values] (a switch's range grows as values come), in order of first use
        self.decisions: dict = {}
        self.leaf_shift = np.zeros(0, np.int64)  # per leaf: its code change's constant ...
        self.leaf_terms = np.zeros(0, np.int64)  # ... and its term tuple (0: none, else index + 1)
        self.term_ids: dict = {}
        self.term_list: list = []
        self._forget()

    # ---- tracing
    def state_of(self, code: int) -> tuple:
        c = code
        return tuple((c // m) % z + lo if m else b for m, z, lo, b in zip(self.mults, self.sizes, self.los, self.base))

    def readable(self, picks) -> tuple:
        """(label, requested goal index or -1) of a transition's picks."""
        got = self.names.get(picks)
        if got is None:
            got = self.names[picks] = readable(self.prog, picks, self.op)
        return got

    def trace(self, state, script):
        """Run the step from ``state`` (as Syms) answering ``script``; insert the path.
        Raises ``_Stop`` past the path limit or the time budget."""
        if len(self.leaves) >= self.max_paths:
            raise _Stop("paths")
        if self.budget is not None and self.budget.out_of_time():
            raise _Stop("seconds")
        t = _Tracer(self.g)
        path = t.path
        o = _TracingOracle(script, path)
        kept = self.kept
        sym = [Sym(t, n, v) if k in kept else v for k, (n, v) in enumerate(zip(self.g.cols, state))]
        try:
            st = self.run(sym, o)
        except DomainError:
            return self.insert(path, "error", None, None, o, ())
        except (TypeError, AttributeError) as exc:  # something a Sym cannot stand for
            raise Untraceable(f"{type(exc).__name__}: {exc}") from exc
        if st is None or st.state is None:  # no option enabled (OpenFSM.run: None)
            return self.insert(path, "blocked", None, None, o, ())
        status = int(st.status)
        viol = tuple(st.violations) if st.violations else None
        if viol is not None and any(isinstance(x, Sym) for v in viol for x in v):
            raise Untraceable("a contract violation carries a traced value")
        return self.insert(path, "ok", self.code_change(t, st.state), status, o, viol)

    def code_change(self, t, entries) -> tuple:
        """The next state's code as ``(shift, terms)``: input code + ``shift`` (changes of
        slots whose old and new values the path fixed, and of counters: new = old + c)
        + the sum of the ``terms``, one expression ``mult * (new - old)`` per other
        changed slot."""
        g, mults = self.g, self.mults
        shift, terms = 0, []
        for k, e in enumerate(entries):
            col = g.cols[k]
            if not mults[k] or isinstance(e, Sym) and e.n == col:
                continue
            new_known, new = t.resolve(e)
            old_known, old = (True, t.known[col]) if col in t.known else (False, col)
            if new_known and old_known:
                shift += mults[k] * (new - old)
                continue
            step = None if new_known or old_known else _offset(g.nodes, new, old)
            if step is not None:  # new = old + constant (a counter): a constant change
                shift += mults[k] * step
                continue
            if new_known:  # set to a constant from an unread value: mult * new - mult * old
                shift += mults[k] * new
                terms.append(g.node(("*", old, g.const(-mults[k]))))  # one term per slot, whatever the constant
                continue
            diff = g.node(("-", g.const(new) if new_known else new, g.const(old) if old_known else old))
            terms.append(g.node(("*", diff, g.const(mults[k]))))
        return shift, tuple(terms)

    def insert(self, path, kind, code, status, o, viol):
        holder, key = self.root, None
        for d in path:
            node = holder.get(key)
            if node is None:
                node = holder[key] = [d[0], d[1], {}]
            elif node[0] != d[0] or node[1] != d[1]:
                raise Untraceable(f"step is not a function of its decisions at {d[:2]}")
            holder, key = node[2], d[2]
        if holder.get(key) is not None:
            raise Untraceable("a traced path ends where another goes on")
        for d in path:
            if d[0] != "c" and d[1] not in self.decisions:
                expr = self.g.nodes[d[1]]
                k = expr[1] if expr[0] == "col" else None
                self.decisions[d[1]] = [d[0], 0, 2, False] if d[0] == "b" else (
                    [d[0], self.los[k], self.sizes[k], False] if k is not None else [d[0], int(d[2]), 1, True])
                self._forget()  # the keys change
        label, goal = self.readable(tuple(o.picks))
        leaf = _Leaf(len(self.leaves), kind, code, status, label, goal, viol, o.taken)
        holder[key] = leaf
        self.leaves.append(leaf)
        self.order_dirty = True
        return leaf

    def ordinals(self) -> np.ndarray:
        if self.order_dirty:
            order = sorted(range(len(self.leaves)), key=lambda i: self.leaves[i].key)
            self.leaf_ord = np.empty(len(self.leaves), np.int64)
            self.leaf_ord[order] = np.arange(len(order))
            self.order_dirty = False
        return self.leaf_ord

    # ---- one batch
    def expand(self, codes: np.ndarray, cap: int = ROWS_LIMIT):
        """Walk the trie with the batch ``codes``: ``[(leaf, rows)]``. Raises ``_Wide`` when
        a batch of more than one state reaches more than ``cap`` rows of ok leaves."""
        ev = _Values(codes, self.g.nodes, self.mults, self.sizes, self.los)
        out = []
        emitted, wide = 0, len(codes) > 1
        every = len(codes)
        stack: list = [(self.root, None, np.arange(every), ())]
        pop, push = stack.pop, stack.append
        while stack:
            holder, key, rows, script = pop()
            node = holder[key]
            if node is None:
                self.trace(self.state_of(int(codes[rows[0]])), script)
                node = holder[key]
            if node.__class__ is _Leaf:
                out.append((node, rows))
                if node.kind == "ok":
                    emitted += len(rows)
                    if wide and emitted > cap:
                        raise _Wide()
                continue
            kind, what, kids = node
            if kind == "c":
                for c in range(what):
                    if c not in kids:
                        kids[c] = None
                    push((kids, c, rows, script + (c,)))
                continue
            vals = ev(what)
            groups: Any
            if not isinstance(vals, np.ndarray):  # a constant: every row goes one way
                groups = ((bool(vals) if kind == "b" else int(vals), rows),)
            elif kind == "b":
                if len(rows) != every:  # (all rows: ``rows`` is 0..len-1)
                    vals = vals[rows]
                if vals.dtype != np.bool_:
                    vals = vals != 0
                hits = int(np.count_nonzero(vals))
                if hits == len(rows) or hits == 0:
                    groups = ((hits > 0, rows),)
                else:
                    groups = ((True, rows[vals]), (False, rows[~vals]))
            else:
                if len(rows) != every:
                    vals = vals[rows]
                first = int(vals[0])
                if len(rows) == 1 or not (vals != first).any():
                    groups = ((first, rows),)
                else:
                    order = np.argsort(vals, kind="stable")
                    sv = vals[order]
                    cuts = [0, *(np.flatnonzero(sv[1:] != sv[:-1]) + 1).tolist(), len(sv)]
                    ro = rows[order]
                    groups = [(int(sv[a]), ro[a:b]) for a, b in zip(cuts, cuts[1:])]
            for val, sub in groups:
                if val not in kids:
                    kids[val] = None
                push((kids, val, sub, script))
        return out, ev


    # ---- one batch, grouped by decisions
    def successors(self, codes: np.ndarray, cap: int = ROWS_LIMIT):
        """The batch's transitions in the scalar engine's order (by source row, then choice
        script): ``(rows, leaf ids, target codes, counts, error leaves [(leaf, rows)], leaf
        ids)``, ``counts`` the transitions of each row, the last a superset of the leaves
        of the batch. The same transitions as ``expand`` (then sorted), found another way:
        a row's walk of the trie is fixed by the values of the trie's decisions on it, so
        each row gets a key (those values, mixed radix over ``decisions``), each key new
        to the engine is walked once (``_walk_row`` on one of its rows; a walk that meets a
        part not traced yet traces it from that row) and kept as a group, and the batch's
        transitions are gathered from its rows' groups. Raises ``_Wide`` as ``expand``
        does. None (then ``expand``) when the keys would pass ``KEY_LIMIT``, or the batch
        brings more new keys than ``NEW_KEYS`` and than a quarter of its rows (states
        that share few keys: one walk per key would cost more than the row-set walk)."""
        ev = _Values(codes, self.g.nodes, self.mults, self.sizes, self.los)
        b = len(codes)
        key = None
        while True:
            if key is None:
                key = self._keys(ev, b)
                if key is None:
                    return None
                keyed = len(self.decisions)
            if len(self.known):
                at = np.searchsorted(self.known, key)
                np.minimum(at, len(self.known) - 1, out=at)
                miss = self.known[at] != key
            else:
                at, miss = None, np.ones(b, bool)
            if not miss.any():
                gid = self.known_gid[at]
                break
            rows = np.flatnonzero(miss)
            uniq, first = np.unique(key[rows], return_index=True)
            if len(uniq) > max(NEW_KEYS, b // 4):  # the rows share few keys: a walk per key would not pay
                return None
            new = []
            for u, r in zip(uniq.tolist(), rows[first].tolist()):
                w = self._walk_row(codes, r, keyed)
                if w is None:  # a decision traced on the way is not in the keys: key again
                    key = None
                    break
                new.append((u, *w))
            if key is not None:
                self._add_groups(new)
        counts = self.g_nok[gid]
        total = int(counts.sum())
        if b > 1 and total > cap:
            raise _Wide()
        present = np.flatnonzero(np.bincount(gid, minlength=len(self.g_nok)))
        bad: list = []
        if self.g_has_bad[present].any():
            for g in present[self.g_has_bad[present]].tolist():
                rows_g = np.flatnonzero(gid == g)
                bad.extend((leaf, rows_g) for leaf in self.g_bad[g])
        rows = np.repeat(np.arange(b), counts)
        if not total:
            return rows, rows, rows, counts, bad, self.g_flat
        start = np.cumsum(counts) - counts
        at = np.repeat(self.g_off[gid] - start, counts)
        at += np.arange(total)
        lid = self.g_flat[at]
        dst = self.f_shift[at]
        used = sorted(set().union(*(self.g_terms[g] for g in present.tolist())))
        if used == [0]:
            dst += codes[rows]
        elif len(used) * b <= TERMS_LIMIT:  # each term tuple's sum over the batch, one gather
            sums = np.empty((len(used), b), np.int64)
            local = np.zeros(len(self.term_list) + 1, np.int64)
            for i, t in enumerate(used):
                local[t] = i * b
                sums[i] = codes
                for term in (self.term_list[t - 1] if t else ()):
                    sums[i] += ev(term)
            idx = local[self.f_term][at]
            idx += rows
            dst += sums.reshape(-1)[idx]
        else:
            dst += codes[rows]
            terms = self.f_term[at]
            for t in used:  # tuple by tuple, on its transitions only
                if t:
                    sel = np.flatnonzero(terms == t)
                    v = np.zeros(b, np.int64)
                    for term in self.term_list[t - 1]:
                        v += ev(term)
                    dst[sel] += v[rows[sel]]
        return rows, lid, dst, counts, bad, self.g_flat

    def _keys(self, ev, b):
        """Each row's decision key: the values of ``decisions``, mixed radix (a switch
        whose values leave its range widens it, and the kept groups go). None past ``KEY_LIMIT``."""
        while True:
            key = np.zeros(b, np.int64)
            mult, again = 1, False
            for n, d in self.decisions.items():
                kind, lo, size, check = d
                v = ev(n)
                if mult * (2 if kind == "b" else size) > KEY_LIMIT:
                    return None
                if kind == "b":
                    if isinstance(v, np.ndarray):
                        key += (v if v.dtype == np.bool_ else v != 0) * mult
                    elif v:
                        key += mult
                    mult *= 2
                    continue
                if check:  # (a column's values stay in its domain)
                    if isinstance(v, np.ndarray):
                        vmin, vmax = int(v.min()), int(v.max())
                    else:
                        vmin = vmax = int(v)
                    if vmin < lo or vmax >= lo + size:
                        new_lo = min(lo, vmin)
                        d[1], d[2] = new_lo, max(max(lo + size, vmax + 1) - new_lo, 2 * size)  # (grown in steps)
                        again = True
                        break
                if size > 1:
                    key += (v - lo) * mult
                mult *= size
            if not again:
                return key
            self._forget()

    def _forget(self):
        """No group kept (the keys change): ``known`` (the groups' keys, sorted) and
        ``known_gid`` (their group ids), and per group its ok leaves (``g_flat[g_off:g_off + g_nok]``,
        in script order, with their code changes ``f_shift`` and term tuples ``f_term``),
        its error leaves and the term tuples it uses."""
        self.known = self.known_gid = self.g_nok = self.g_off = self.g_flat = np.zeros(0, np.int64)
        self.f_shift = self.f_term = self.g_flat
        self.g_has_bad = np.zeros(0, bool)
        self.g_bad: list = []
        self.g_terms: list = []

    def _add_groups(self, new):
        """Keep the groups ``[(key, ok leaf ids, error leaves)]``."""
        if not new:
            return
        first = len(self.g_nok)
        keys = np.array([k for k, _, _ in new], np.int64)
        nok = np.array([len(ok) for _, ok, _ in new], np.int64)
        self.g_off = np.concatenate([self.g_off, len(self.g_flat) + np.cumsum(nok) - nok])
        self.g_nok = np.concatenate([self.g_nok, nok])
        self.g_flat = np.concatenate([self.g_flat, *(ok for _, ok, _ in new)])
        self.g_bad.extend(bad for _, _, bad in new)
        self.g_has_bad = np.concatenate([self.g_has_bad, np.array([bool(bad) for _, _, bad in new], bool)])
        keys = np.concatenate([self.known, keys])
        gids = np.concatenate([self.known_gid, np.arange(first, first + len(new), dtype=np.int64)])
        order = np.argsort(keys)
        self.known, self.known_gid = keys[order], gids[order]
        if len(self.leaf_shift) < len(self.leaves):
            self._leaf_tables()
        self.f_shift = self.leaf_shift[self.g_flat]
        self.f_term = self.leaf_terms[self.g_flat]
        self.g_terms.extend(set(self.leaf_terms[ok].tolist()) for _, ok, _ in new)

    def _walk_row(self, codes, r, keyed):
        """Row ``r``'s walk of the trie (``expand`` on it alone): ``(ok leaf ids in script
        order, error leaves)``; None when paths traced on the way brought decisions past
        the first ``keyed`` of ``decisions`` (the row's group may split on them)."""
        out, _ = self.expand(codes[r:r + 1], 1 << 62)
        if len(self.decisions) != keyed:
            return None
        ords = self.ordinals()
        ok = sorted((leaf for leaf, _ in out if leaf.kind == "ok"), key=lambda leaf: ords[leaf.id])
        return np.array([leaf.id for leaf in ok], np.int64), [leaf for leaf, _ in out if leaf.kind == "error"]

    def _leaf_tables(self):
        shift, terms = [], []
        for leaf in self.leaves[len(self.leaf_shift):]:
            code = leaf.code if leaf.kind == "ok" else (0, ())
            shift.append(code[0])
            if code[1]:
                t = self.term_ids.get(code[1])
                if t is None:
                    t = self.term_ids[code[1]] = len(self.term_ids) + 1
                terms.append(t)
            else:
                terms.append(0)
        self.leaf_shift = np.concatenate([self.leaf_shift, np.array(shift, np.int64)])
        self.leaf_terms = np.concatenate([self.leaf_terms, np.array(terms, np.int64)])
        self.term_list = list(self.term_ids)


# ---------------------------------------------------------------------- timed models: closure, then numbering

#: ``search`` explores a model with timers (docs/semantics.md 6.1) in two phases when no
#: time or transition budget is set: the reachable code graph first, in large batches that
#: include the timers' runs guessed ahead, then the breadth-first numbering.
CLOSURE_BATCH = CHUNK  # states per batch of the first phase
RUN_GUESS = 16  # ticks guessed ahead of a timer's run


def _timer_slots(prog, kept, mults) -> tuple:
    return tuple(k for k in kept if prog.slots[k].kind == "timer" and mults[k] and prog.slots[k].size > 1)


def _timer_runs(eng, timers, src, dst) -> np.ndarray:
    """Codes guessed ahead of the transitions ``src -> dst`` that change timers only, each
    by 0 or 1 (a tick of time): ``dst + j * (dst - src)`` for every ``j >= 1`` that keeps
    the counting timers in their domains. Guesses may be unreachable: they are expanded,
    never numbered unless reached."""
    step = dst - src
    timed = np.zeros(len(src), np.int64)
    room = np.full(len(src), np.iinfo(np.int64).max, np.int64)
    counts = np.zeros(len(src), bool)
    ok = np.ones(len(src), bool)
    for k in timers:
        m, size = eng.mults[k], eng.sizes[k]
        a, b = (src // m) % size, (dst // m) % size
        d = b - a
        ok &= (d == 0) | (d == 1)
        timed += d * m
        up = d == 1
        counts |= up
        room = np.where(up, np.minimum(room, size - 1 - b), room)
    room = np.minimum(room, RUN_GUESS)
    keep = ok & counts & (timed == step) & (room > 0)
    if not keep.any():
        return np.zeros(0, np.int64)
    base, step, room = dst[keep], step[keep], room[keep]
    j = np.arange(int(room.sum())) - np.repeat(np.cumsum(room) - room, room) + 1
    return np.repeat(base, room) + j * np.repeat(step, room)


def _closure(eng, c0, timers, smax, tmax, progress=None, t0=0.0):
    """Phase one: every code reachable from ``c0`` expanded once (with guessed timer runs):
    ``(codes, src, lid, dst, errors)``: the code of each entry, the transitions as
    (source entry, leaf id, target entry), ``errors`` as (entry, leaf) pairs. Entries are
    numbered in the order their codes are first met (the visited set of the ordinary
    search: ``visited.Bitmap`` or ``visited.Hashed``; targets become entries once, at the end). None
    when it does not pay off (far past a budget, more paths than ``PATHS_MIN``) or the
    tracer cannot follow: the caller then runs the ordinary search."""
    seen = (Bitmap if eng.total <= DENSE_LIMIT else Hashed)(eng.total, c0)
    srcs, lids, dsts, errs = [], [], [], []
    # past 1.5 times a budget (the guesses included) the ordinary search takes over
    limit, nt = smax + smax // 2 + CLOSURE_BATCH, 0
    eng.max_paths = PATHS_MIN  # more paths than the ordinary search may trace: give up
    head = 0  # entries are expanded in the order they are numbered
    while head < seen.n:
        batch = seen.batch(head, min(CLOSURE_BATCH, seen.n - head))
        try:
            out, ev = eng.expand(batch, ROWS_LIMIT)
        except (_Wide, _Stop):
            return None
        except MemoryError:
            raise
        except Exception:  # e.g. Untraceable, maybe on a guessed state no run reaches
            return None
        ok = [(leaf, rows) for leaf, rows in out if leaf.kind == "ok"]
        rows, lid, dst = _transitions(ok, batch, ev)
        errs.extend((head + r, leaf) for leaf, rs in out if leaf.kind == "error" for r in rs.tolist())
        fresh = np.flatnonzero(~seen.seen(dst))
        nt += len(dst)
        new = dst[_first_positions(dst, fresh, eng.total)]
        seen.add(new)
        if timers and len(new):
            guess = _timer_runs(eng, timers, batch[rows[fresh]], dst[fresh])
            if len(guess):
                seen.add(guess[_first_positions(guess, np.flatnonzero(~seen.seen(guess)), eng.total)])
        if seen.n > limit or nt > tmax + tmax // 2 + ROWS_LIMIT:
            return None  # far past a budget: the ordinary search cuts there
        srcs.append(rows + head)
        lids.append(lid)
        dsts.append(dst)
        head += len(batch)
        if progress is not None:  # codes expanded so far (guesses included), then the exact figures
            progress(head, nt, time.perf_counter() - t0)
    cat = (lambda xs: np.concatenate(xs) if xs else np.zeros(0, np.int64))
    return (seen.codes[:seen.n].astype(np.int64), cat(srcs), cat(lids),
            seen.number(cat(dsts)).astype(np.int64), errs)


def _number(n_entries, e0, t_src, t_dst, order_key):
    """Phase two: the breadth-first numbering of the entries reachable from ``e0``, states
    numbered in order of first discovery, each state's transitions in ``order_key`` order:
    ``(entry of each state id, id of each entry (-1: unreached), positions of the
    transitions in the system's order, parent transition of each state)``."""
    span = int(order_key.max()) + 1 if len(order_key) else 1
    if n_entries * span < 1 << 62:  # one int64 key: a stable sort of a nearly sorted array
        order = np.argsort(t_src * span + order_key, kind="stable")
    else:
        order = np.lexsort((order_key, t_src))
    offs = np.zeros(n_entries + 1, np.int64)
    np.cumsum(np.bincount(t_src, minlength=n_entries), out=offs[1:])
    tgt_sorted = t_dst[order]
    id_of = np.full(n_entries, -1, np.int64)
    id_of[e0] = 0
    level, n, states, picks = np.array([e0], np.int64), 1, [np.array([e0], np.int64)], []
    parents, done = [np.array([-1], np.int64)], 0  # parents: the transition that discovered each state
    while len(level):
        starts = offs[level]
        counts = offs[level + 1] - starts
        total = int(counts.sum())
        if not total:
            break
        idx = np.repeat(starts - (np.cumsum(counts) - counts), counts) + np.arange(total)
        picks.append(idx)
        tgt = tgt_sorted[idx]
        at = np.flatnonzero(id_of[tgt] < 0)
        cand = tgt[at]
        key = np.arange(-len(cand) - 1, -1)  # the positions in ``cand``, shifted below -1 (unreached)
        np.minimum.at(id_of, cand, key)  # ``id_of`` as the scratch: each candidate's first position
        win = np.flatnonzero(id_of[cand] == key)  # each new entry once, in order of first discovery
        new = cand[win]
        id_of[new] = np.arange(n, n + len(new))
        parents.append(done + at[win])
        n += len(new)
        done += total
        states.append(new)
        level = new
    pos = order[np.concatenate(picks)] if picks else np.zeros(0, np.int64)
    return np.concatenate(states), id_of, pos, np.concatenate(parents)


def _search_closure(task, eng, c0, smax, tmax, t0):
    """The system of a ``SearchTask`` (a model with timers) by ``_closure`` then ``_number``: the same system
    as the ordinary search (states, numbering, transitions, labels, parents, violations,
    domain errors), or None when the first phase gives up or the state budget is hit."""
    model, kind, fsm, kept, progress, op = task.model, task.kind, task.fsm, task.kept, task.progress, task.op
    prog = model.program
    timers = _timer_slots(prog, kept, eng.mults)
    got = _closure(eng, c0, timers, smax, tmax, progress, t0)
    if got is None:
        return None
    codes, t_src, t_lid, t_dst, errs = got
    ords = eng.ordinals()
    entries, id_of, pos, parent = _number(len(codes), 0, t_src, t_dst, ords[t_lid])
    n, nt = len(entries), len(pos)
    if n > smax or nt > tmax:
        return None  # a budget cuts the system: the ordinary search cuts it exactly
    lid = t_lid[pos]
    dst = id_of[t_dst[pos]]
    # each state's transitions are its entry's, all of them in a row (``_number`` takes every
    # transition of a state it reaches): the offsets from the entries' out-degrees, no source array
    degree = np.bincount(t_src, minlength=len(codes))[entries]
    del t_src, t_dst, t_lid, pos, got  # the code graph: its memory back before the system's arrays
    # labels and edge codes (label, status) numbered in order of first use, as the ordinary search does
    labels, label_goal, label_ids, kinds = [], [], {}, {}
    leaf_edge = np.zeros(len(eng.leaves), np.int64)
    first = np.full(len(eng.leaves), nt, np.int64)
    np.minimum.at(first, lid, np.arange(nt, dtype=np.int64))  # each leaf's first transition (nt: unused)
    u = np.flatnonzero(first < nt)  # the leaves used
    for li in u[np.argsort(first[u])].tolist():
        name = eng.leaves[li].label
        lab = label_ids.get(name)
        if lab is None:
            lab = label_ids[name] = len(labels)
            labels.append(name)
            label_goal.append(eng.leaves[li].goal)
        leaf_edge[li] = kinds.setdefault((lab, eng.leaves[li].status or 0), len(kinds))
    leaf_viol = np.array([leaf.violations is not None for leaf in eng.leaves], bool)
    violations = [(t, eng.leaves[int(lid[t])].violations) for t in np.flatnonzero(leaf_viol[lid]).tolist()]
    state_codes = codes[entries]
    errors = []
    if errs:
        by_id = {}
        for e, leaf in errs:
            i = int(id_of[e])
            if i >= 0:
                by_id.setdefault(leaf, []).append(i)
        bad = [(leaf, np.array(sorted(rows), np.int64)) for leaf, rows in by_id.items()]
        errors = _errors(eng, prog, bad, state_codes, 0, ords, None)
    seconds = time.perf_counter() - t0
    if progress is not None:
        progress(n, nt, seconds)
    # the compact layout of the ordinary search (src is ascending: each state's transitions in a row)
    offsets = np.zeros(n + 1, _small(nt))
    np.cumsum(degree, out=offsets[1:])
    edge_label = np.zeros(len(kinds), _small(len(labels)))
    edge_status = np.zeros(len(kinds), np.int8)
    for (lab, st), e in kinds.items():
        edge_label[e], edge_status[e] = lab, st
    ids = _small(n)
    return TransitionSystem(model=model, kind=kind, fsm=fsm, slots=tuple(kept),
                            codes=state_codes.astype(code_dtype(eng.total)), offsets=offsets, dst=dst.astype(ids),
                            edge=leaf_edge[lid].astype(_small(len(kinds))), edge_label=edge_label,
                            edge_status=edge_status, label_goal=np.asarray(label_goal, dtype=np.int64) if kind == "fsm"
                            else None, labels=tuple(labels), parent=parent.astype(offsets.dtype), complete=True,
                            seconds=seconds, expanded=n, errors=tuple(errors), violations=tuple(violations), open=op,
                            stopped=None)


def search(task: SearchTask, budget: "Budget | None", fallback: bool = True) -> TransitionSystem:
    """Explore the system of ``task`` breadth-first from ``task.initial`` with
    path-compiled batches: ``run(state, oracle)`` is one transition (``Program.step``, or
    ``OpenFSM.run`` with ``op`` at FSM level) and states are coded over the ``kept`` slots.
    Called by ``btfsm.verify.explore.explore``/``explore_fsm``, whose scalar engine takes
    the same task and gives the same system. Raises ``Untraceable`` when the tracer cannot
    follow ``run``.

    ``budget`` (a ``btfsm.verify.search.Budget``, None: unbounded) holds in time even when
    paths multiply: a batch whose rows would pass ``ROWS_LIMIT`` or the transitions left
    is split (down to one state: transitions stay in the scalar engine's order); the trie
    may hold ``PATHS_MIN`` paths, then one per ``PATHS_RATIO`` transitions found, and
    past that the search raises ``TooManyPaths`` (``fallback``: the caller goes on with the
    scalar engine) or stops with ``budget.hit = "paths"``; the clock is read before every
    path traced and after every batch."""
    t0 = time.perf_counter()
    model, kind, fsm, kept, run = task.model, task.kind, task.fsm, task.kept, task.run
    s0, progress, op = task.initial, task.progress, task.op
    prog = model.program
    if kind == "model" and prog.merge_points:
        raise Untraceable("in-tick retries (RecoveryNode) are merged by the scalar engine only")
    eng = _Engine(model, run, kept, s0, op)
    mults, offset, total = eng.mults, eng.offset, eng.total
    if budget is None:
        budget = Budget()
    eng.budget = budget if budget.max_seconds is not None else None
    smax = DEFAULT_MAX_STATES * 1000 if budget.max_states is None else budget.max_states
    tmax = (1 << 62) if budget.max_transitions is None else budget.max_transitions
    chunk = CHUNK
    c0 = sum(v * m for v, m in zip(s0, mults)) - offset
    staged = None
    if kind == "model" and env_width(prog) >= ENV_WIDE:  # one trie per environment entry, then the tree
        staged = _Staged(model, kept, s0)
        staged.budget = eng.budget
    elif budget.max_seconds is None and _timer_slots(prog, kept, mults):
        ts = _search_closure(task, eng, c0, smax, tmax, t0)
        if ts is not None:
            return ts
        eng = _Engine(model, run, kept, s0, op)  # the ordinary search, with a trie of its own

    visited = (Ids if total <= DENSE_IDS else Bitmap if total <= DENSE_LIMIT else Hashed)(total, c0)
    n, head, nt, complete, expanded = 1, 0, 0, True, None
    # the system in compact columns (see TransitionSystem): CSR row pointer, targets (their
    # codes until the end, then ids; ids at once when ``visited.direct``), edge codes (one per distinct label and status), BFS parents
    offsets, edge_c, parent = _Column("i"), _Column("b"), _Column("i")
    targets = array("i" if visited.direct else "I" if visited.codes.dtype == np.uint32 else "q")
    offsets.extend(np.array([0]), 0)
    parent.extend(np.array([-1]), 0)
    labels: list = []
    label_goal: list = []
    label_ids: dict = {}
    kinds: dict = {}  # (label index, status) -> edge code
    errors, violations = [], []
    leaf_kind = np.zeros(0, np.int64)
    leaf_viol = np.zeros(0, bool)
    while head < n:
        if budget.out_of_time():
            complete, budget.hit, expanded = False, "seconds", head
            break
        k = min(n - head, chunk)
        batch = visited.batch(head, k)
        got = counts = used = None
        try:
            if staged is not None:  # one state's successors may stop early, once a budget is hit among them
                rows, dst = staged.expand(batch, min(ROWS_LIMIT, tmax - nt + 1), lambda d: len(d) > tmax - nt or len(
                    np.unique(d[~visited.seen(d)])) > smax - n)
            else:
                got = eng.successors(batch, min(ROWS_LIMIT, tmax - nt + 1))
                if got is None:
                    out, ev = eng.expand(batch, min(ROWS_LIMIT, tmax - nt + 1))
        except _Wide:  # split the batch: transitions are ordered by source state first
            chunk = max(1, k // 4)
            continue
        except _Stop as stop_:
            if stop_.hit == "paths" and fallback:
                raise TooManyPaths(f"more than {(staged or eng).max_paths} paths traced after {nt} transitions") from None
            complete, budget.hit, expanded = False, stop_.hit, head
            break
        chunk = min(CHUNK, chunk * 2)
        if staged is None:
            ords = eng.ordinals()
            if got is not None:  # transitions of the batch, ordered as the generic engine makes them
                rows, lid, dst, counts, bad, used = got
            else:
                ok = sorted(((leaf, rows) for leaf, rows in out if leaf.kind == "ok"), key=lambda x: ords[x[0].id])
                rows, lid, dst = _transitions(ok, batch, ev)
                # each leaf's rows are ascending and the leaves are in order: a stable sort by row
                # (a radix sort on 16 bits) gives the (source, script) order
                order = np.argsort(rows.astype(np.uint16) if k <= 1 << 16 else rows, kind="stable")
                rows, lid, dst = rows[order], lid[order], dst[order]
                bad = [(leaf, r) for leaf, r in out if leaf.kind == "error"]
                counts = used = None
        leaves = eng.leaves if staged is None else staged.leaves
        # new targets, numbered in order of first discovery
        cut = len(dst)
        if cut > tmax - nt:  # the transition budget ends within this batch
            cut = tmax - nt
            complete, budget.hit = False, "transitions"
        fresh = np.flatnonzero(~visited.seen(dst[:cut]))
        if len(fresh):
            firstpos = _first_positions(dst, fresh, total)
            newcodes = dst[firstpos]
            room = smax - n
            if len(newcodes) > room:
                complete, budget.hit = False, "states"
                cut = int(firstpos[room])  # the targets kept are all among the first ``room``
                firstpos, newcodes = firstpos[:room], newcodes[:room]
            visited.add(newcodes)
            parent.extend(firstpos + nt, nt + cut)
            n += len(newcodes)
        cut_row: Any = None if complete else int(rows[cut])
        if staged is not None:
            lid = staged.kinds(cut + 1)
        stop = None if complete or staged is not None else (cut_row, int(ords[lid[cut]]))
        named = lid[:cut + 1]  # the generic engine names the cut transition's label too
        rows, lid = rows[:cut], lid[:cut]
        # labels numbered in order of first use, as the generic engine does
        if len(leaf_kind) < len(leaves):
            grow = len(leaves) - len(leaf_kind)
            leaf_kind = np.concatenate([leaf_kind, np.full(grow, -1, np.int64)])
            leaf_viol = np.array([leaf.violations is not None for leaf in leaves], bool)
        if len(named) and (leaf_kind[named if used is None else used] < 0).any():  # (used: the batch's leaves)
            u, first = np.unique(named, return_index=True)
            for li in u[np.argsort(first)]:
                if leaf_kind[li] < 0:
                    leaf = leaves[li]
                    lab = label_ids.get(leaf.label)
                    if lab is None:
                        lab = label_ids[leaf.label] = len(labels)
                        labels.append(leaf.label)
                        label_goal.append(leaf.goal)
                    leaf_kind[li] = kinds.setdefault((lab, leaf.status or 0), len(kinds))
        offsets.extend(np.cumsum(counts if complete and counts is not None else np.bincount(rows, minlength=k)) + nt,
                       nt + cut)
        ends = visited.ids(dst[:cut]) if visited.direct else dst[:cut].astype(visited.codes.dtype)
        targets.frombytes(ends.view(np.uint8).data)  # (its buffer: no bytes copy)
        edge_c.extend(leaf_kind[lid], len(kinds))
        if leaf_viol[lid if used is None else used].any():
            for t in np.flatnonzero(leaf_viol[lid]).tolist():
                violations.append((nt + t, leaves[int(lid[t])].violations))
        # domain errors, re-run on concrete states (reported exactly as the generic engine does)
        if staged is not None:
            errors.extend(staged.errors(batch, head, None if complete else cut))
        elif bad:
            errors.extend(_errors(eng, prog, bad, batch, head, ords, stop))
        nt += cut
        if not complete:
            expanded = head + cut_row
            break
        head += k
        (staged or eng).max_paths = max(PATHS_MIN, nt // PATHS_RATIO)
        if progress is not None:
            progress(n, nt, time.perf_counter() - t0)
    if expanded is None:
        expanded = head
    codes = visited.codes[:n]
    if visited.direct:
        dst = _view(targets, np.int32)
    else:
        dst = visited.number(np.frombuffer(targets, visited.codes.dtype) if nt else np.zeros(0, np.int64))
    del visited  # the index goes; the codes stay
    if len(offsets.buf) < n + 1:  # states not expanded have no transitions
        offsets.extend(np.full(n + 1 - len(offsets.buf), nt, np.int64), nt)
    seconds = time.perf_counter() - t0
    if progress is not None:
        progress(n, nt, seconds)
    edge_label = np.zeros(len(kinds), _small(len(labels)))
    edge_status = np.zeros(len(kinds), np.int8)
    for (lab, st), e in kinds.items():
        edge_label[e], edge_status[e] = lab, st
    goals = np.asarray(label_goal, dtype=np.int64) if kind == "fsm" else None
    return TransitionSystem(model=model, kind=kind, fsm=fsm, slots=tuple(kept), codes=codes,
                            offsets=offsets.view(), dst=dst, edge=edge_c.view(),
                            edge_label=edge_label, edge_status=edge_status, label_goal=goals, labels=tuple(labels),
                            parent=parent.view(), complete=complete, seconds=seconds,
                            expanded=expanded, errors=tuple(errors), violations=tuple(violations), open=op,
                            stopped=None if complete else budget.hit)


def _first_positions(dst: np.ndarray, at: np.ndarray, total: int) -> np.ndarray:
    """The positions in ``at`` (ascending) where a code of ``dst`` occurs for the first
    time, ascending: one sort of (code, position) keys (numpy's fast integer sort) when they
    fit 63 bits, else ``np.unique``.

    >>> d, at = np.array([5, 3, 5, 7, 3, 9]), np.array([0, 2, 3, 4, 5])
    >>> _first_positions(d, at, 10).tolist(), _first_positions(d, at, 1 << 62).tolist()
    ([0, 3, 4, 5], [0, 3, 4, 5])
    """
    if not len(at):
        return at
    if total * len(dst) < 1 << 62:
        key = dst[at] * len(dst) + at
        key.sort()
        code = key // len(dst)
        first = np.concatenate(([True], code[1:] != code[:-1]))
        return np.sort(key[first] - code[first] * len(dst))
    _, first = np.unique(dst[at], return_index=True)
    return np.sort(at[first])


def _small(n: int):
    """The smallest signed numpy type holding ``0..n``."""
    for dt in (np.int8, np.int16, np.int32):
        if n <= np.iinfo(dt).max:
            return dt
    return np.int64


class BatchSuccessors:
    """The traced engine's batch expansion on its own, for searches that keep their own
    visited set (``btfsm.verify.distributed``): ``succ(codes)`` gives ``(rows, targets)``,
    one entry per transition (the ``ok`` leaves, as ``search`` counts them), for a batch of
    state codes of the whole model (``initial`` is the initial state's code). The same
    trie and the same step function as ``search``; no budgets."""

    def __init__(self, model):
        prog = model.program
        kept = tuple(range(len(prog.slots)))
        self.engine = _Engine(model, prog.step, kept, prog.initial, None)
        self.engine.max_paths = 1 << 62
        mults, offset = self.engine.mults, self.engine.offset
        self.initial = sum(v * m for v, m in zip(prog.initial, mults)) - offset
        self.total = self.engine.total  # codes lie in 0..total-1
        self.mults = tuple(int(m) for m in mults)  # slot k's value is (code // mults[k]) % size + lo

    def __call__(self, codes: np.ndarray):
        return self.expand(codes)[:2]

    def expand(self, codes: np.ndarray):
        """``(rows, targets, error rows)``: the last, the batch rows (with repeats) of
        ticks that raised a domain error."""
        codes = np.asarray(codes, np.int64)
        out, ev = self.engine.expand(codes, 1 << 62)
        rows, _lid, dst = _transitions([(leaf, r) for leaf, r in out if leaf.kind == "ok"], codes, ev)
        bad = [np.asarray(r, np.int64) for leaf, r in out if leaf.kind == "error"]
        return rows, dst, np.concatenate(bad) if bad else np.zeros(0, np.int64)


def _view(buf, dtype) -> np.ndarray:
    return np.frombuffer(buf, dtype=dtype) if len(buf) else np.zeros(0, dtype)


def _transitions(ok, codes, ev):
    """(source rows, leaf ids, target codes) of the leaves ``ok`` reached by a batch: the
    input code plus the leaf's constant shift plus the sum of its terms' values, summed
    once per distinct tuple of terms over the batch and gathered at once (leaf by leaf,
    on each leaf's rows, when those sums would pass ``TERMS_LIMIT`` values)."""
    if not ok:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.int64)
    rows = np.concatenate([r for _, r in ok])
    sizes = [len(r) for _, r in ok]
    lid = np.repeat(np.array([leaf.id for leaf, _ in ok], np.int64), sizes)
    dst = codes[rows] + np.repeat(np.array([leaf.code[0] for leaf, _ in ok], np.int64), sizes)
    groups: dict = {}  # the distinct term tuples of the leaves (1, 2, ...; 0: no terms)
    which = [groups.setdefault(leaf.code[1], len(groups) + 1) if leaf.code[1] else 0 for leaf, _ in ok]
    if not groups:
        return rows, lid, dst
    if len(groups) * len(codes) <= TERMS_LIMIT:  # each tuple's sum over the batch, one gather
        sums = np.zeros((len(groups) + 1, len(codes)), np.int64)
        for terms, g in groups.items():
            for term in terms:
                sums[g] += ev(term)
        dst += sums[np.repeat(np.array(which, np.int64), sizes), rows]
        return rows, lid, dst
    a = 0
    for (leaf, r), m in zip(ok, sizes):  # each leaf's terms, on its rows only
        for term in leaf.code[1]:
            v = ev(term)
            dst[a:a + m] += v[r] if isinstance(v, np.ndarray) else v
        a += m
    return rows, lid, dst


def _errors(eng, prog, bad, codes, head, ords, cut_at):
    """DomainViolations of the error leaves' rows, in the generic engine's order."""
    items = []
    for leaf, rows in bad:
        for r in rows.tolist():
            if cut_at is None or (r, int(ords[leaf.id])) < cut_at:
                items.append((r, int(ords[leaf.id]), leaf))
    return _rerun_errors(eng, prog, [(r, leaf.taken) for r, _, leaf in sorted(items, key=lambda x: x[:2])], codes, head)


def _rerun_errors(eng, prog, items, codes, head):
    """The DomainViolations of ``(row, choice script)`` items, re-run on concrete states."""
    out = []
    for r, taken in items:
        o = EnumOracle(taken)
        try:
            eng.run(eng.state_of(int(codes[r])), o)
        except DomainError as exc:
            out.append(DomainViolation(head + r, tuple(o.taken), readable(prog, tuple(o.picks), eng.op)[0],
                                       exc.var, exc.value, exc.where, str(exc)))
        else:
            raise Untraceable("a traced domain error did not happen again")
    return out


# ---------------------------------------------------------------------- wide environments: staged tries

#: The environment multiplies the paths of one trie: every entry's answers times every other
#: entry's (6 choices of 3 options: 729 paths per state, 7**6 in all with the guards'
#: decisions). Past this many combined answers (the product over the entries of their
#: options, 2 for an event) the traced engine walks one trie per environment entry, then
#: one for the tree, each on the rows the previous one left (``_Staged``).
ENV_WIDE = 64
SLICE = 1 << 12  # rows of the first slice of one state's successors (then doubled up to ROWS_LIMIT)


def env_width(prog) -> int:
    """The product over the environment entries of their possible answers (options of a
    choice, 2 for an event): an upper bound of the environment's answers per state."""
    w = 1
    for _, _, _, options in prog.env:
        w *= max(2, len(options)) if options is not None else 2
    return w


class _EnvStep:
    """What one environment entry leaves: the state; no status, no violation."""

    __slots__ = ("state",)
    status = 0
    violations = None

    def __init__(self, state):
        self.state = state


class _Combo:
    """One transition kind of a staged search: the environment's answers (their readable
    picks) and the tree's path; what ``search`` reads of a leaf."""

    __slots__ = ("id", "label", "status", "violations")
    kind = "ok"
    goal = -1

    def __init__(self, id, label, status, violations):
        self.id, self.label, self.status, self.violations = id, label, status, violations


class _Staged:
    """The traced engine for a model whose environment answers multiply (``ENV_WIDE``).

    ``Program.step`` is the environment entries in order (``Program.environment_phase``),
    then the tree on the state they leave (the same split as the scalar engine's
    ``TreeCache``: nothing but the state passes between the phases). So a tick is traced as
    a sequence of tries: one per environment entry (``environment_phase`` of that entry
    alone) and one for the tree (``Program.step`` of the model without environment). A
    batch walks them in turn: each trie's leaves turn every row into its successors (rows
    multiply, paths only add up: 6 choices of 3 options make 7 paths each, not 7**6). Rows
    stay ordered by (source, choice script in depth-first order) at every stage, so the
    transitions come out in the scalar engine's order. A transition's kind (``_Combo``:
    label, status, violations) is the environment's picks, a mixed-radix key over the
    entries, with the tree's leaf."""

    TABLE = 1 << 22  # (environment key, tree leaf) pairs looked up in a dense table, else hashed

    def __init__(self, model, kept, s0):
        prog = model.program
        self.prog, self.run, self.op = prog, prog.step, None
        self.stages = []
        for i in range(len(prog.env)):
            self.stages.append(_Engine(model, self._entry(prog, i), kept, s0, None))
        tree = model.program.without_environment()
        self.tree = _Engine(model, tree.step, kept, s0, None)
        self.engines = self.stages + [self.tree]
        # an entry's readable picks: an event happened or not; a choice's option, or none
        # when a lone option was enabled (no choice point)
        self.radix = [len(o) + 1 if o is not None else 2 for _, _, _, o in prog.env]
        self.space = 1
        for r in self.radix:
            self.space *= r
        self.pick_of = [{} for _ in self.stages]  # per entry: readable label -> pick digit
        self.pick_label = [[] for _ in self.stages]  # ... and back
        self.leaves: list = []  # the _Combos, by id
        self.combos: dict = {}  # (environment key, tree leaf id) -> _Combo id
        self.table = None  # or a dense int32 table over environment key * tl + tree leaf id
        self.tl = 64
        self.digits = [np.zeros(0, np.int64) for _ in self.stages]  # per entry: leaf id -> pick digit
        self.max_paths = PATHS_MIN
        self.budget = None
        self.last = None  # the last batch's history (for scripts of errors and of the cut)

    @staticmethod
    def _entry(prog, i):
        def run(state, oracle):
            s = list(state)
            if prog.environment_phase(s, oracle, None, (i,)) is not None:
                return None  # a choice without enabled option: the tick cannot happen
            return _EnvStep(tuple(s))
        return run

    def __setattr__(self, name, value):
        object.__setattr__(self, name, value)
        if name in ("max_paths", "budget") and "engines" in self.__dict__:
            for e in self.engines:
                setattr(e, name, value)

    def state_of(self, code: int) -> tuple:
        return self.tree.state_of(code)

    def _digits(self, i, eng) -> np.ndarray:
        d = self.digits[i]
        if len(d) < len(eng.leaves):
            ids, labels = self.pick_of[i], self.pick_label[i]
            new = []
            for leaf in eng.leaves[len(d):]:
                p = ids.get(leaf.label)
                if p is None:
                    p = ids[leaf.label] = len(labels)
                    labels.append(leaf.label)
                new.append(p)
            d = self.digits[i] = np.concatenate([d, np.array(new, np.int64)])
        return d

    @staticmethod
    def _walk(eng, codes):
        """The ok leaves' rows of one trie, ordered by (row, leaf in script order):
        ``(rows, leaf ids, next codes, error leaves [(leaf, rows)])``."""
        if not len(codes):
            return codes, codes, codes, []
        out, ev = eng.expand(codes, 1 << 62)
        ords = eng.ordinals()
        ok = sorted(((leaf, r) for leaf, r in out if leaf.kind == "ok"), key=lambda x: ords[x[0].id])
        bad = [(leaf, r) for leaf, r in out if leaf.kind == "error"]
        if len(ok) <= 1:  # one leaf: its rows ascend
            return (*_transitions(ok, codes, ev), bad)
        # each leaf's rows go straight to their places (a row's successors in the leaves'
        # order): no sort
        n = len(codes)
        count = np.zeros(n, np.int64)
        for _, r in ok:
            count[r] += 1  # a leaf's rows are distinct
        start = np.cumsum(count)
        total = int(start[-1])
        start -= count
        rows = np.repeat(np.arange(n), count)
        lid, nxt = np.empty(total, np.int64), np.empty(total, np.int64)
        for leaf, r in ok:
            at = start[r]
            start[r] = at + 1
            lid[at] = leaf.id
            shift, terms = leaf.code
            v = codes[r] + shift
            for term in terms:
                t = ev(term)
                v += t[r] if isinstance(t, np.ndarray) else t
            nxt[at] = v
        return rows, lid, nxt, bad

    def expand(self, batch, cap, enough=None):
        """``(rows, target codes)`` of the batch's transitions in the scalar engine's order
        (their kinds: ``kinds``). Raises ``_Wide`` when a batch of more than one state
        reaches more than ``cap`` rows. One state whose rows pass ``cap`` is walked on in
        slices of ``cap`` rows, in order, and stops early once ``enough(targets so far)``
        says a budget is hit within them (the search cuts there, as on all of them)."""
        n_stages = len(self.stages)
        self._hist = [[] for _ in range(n_stages)]  # per entry: (input row, leaf id) of its output rows, in pieces
        self._made = [0] * (n_stages + 2)  # output rows so far: of entry i at i + 1, of the tree last
        self._tree, self._errs, self._sliced, self._slice = [], [], False, min(cap, SLICE)
        self._feed(0, batch, np.zeros(len(batch), np.int64), 0, cap, len(batch) > 1, enough)
        cat = (lambda xs: np.concatenate(xs) if len(xs) > 1 else xs[0])
        hist = [(cat([r for r, _ in h]), cat([li for _, li in h])) for h in self._hist]
        rows, lid, dst, key = (cat([t[k] for t in self._tree]) for k in range(4))
        self.last = (hist, rows, lid, self._errs, key)
        self._hist = self._tree = None
        src = rows
        for r, _ in reversed(hist):
            src = r[src]
        return src, dst

    def _feed(self, i, cur, key, base, cap, wide, enough) -> bool:
        """Stage ``i`` (the tree when ``i`` is the number of entries) on the rows ``cur``
        (numbered from ``base`` among the previous stage's output rows) and the stages
        after it. False: stop, ``enough`` said so."""
        if i == len(self.stages):
            rows, lid, dst, bad = self._walk(self.tree, cur)
            if bad:
                self._errs.append((i, [(leaf, r + base) for leaf, r in bad]))
            self._tree.append((rows + base, lid, dst, key[rows]))
            self._made[i + 1] += len(rows)
            if wide and self._made[i + 1] > cap:
                raise _Wide()
            return not (self._sliced and enough is not None and enough(np.concatenate([t[2] for t in self._tree])))
        rows, lid, nxt, bad = self._walk(self.stages[i], cur)
        if bad:
            self._errs.append((i, [(leaf, r + base) for leaf, r in bad]))
        key = key[rows] * self.radix[i] + self._digits(i, self.stages[i])[lid]
        first = self._made[i + 1]
        self._made[i + 1] += len(nxt)
        self._hist[i].append((rows + base, lid))
        if len(nxt) <= (cap if wide else self._slice):
            return self._feed(i + 1, nxt, key, first, cap, wide, enough)
        if wide:
            raise _Wide()
        self._sliced = True
        a = 0
        while a < len(nxt):  # slices of growing size: a budget hit early costs little
            if self.budget is not None and self.budget.out_of_time():
                raise _Stop("seconds")
            b = a + self._slice
            self._slice = min(cap, 2 * self._slice)
            if not self._feed(i + 1, nxt[a:b], key[a:b], first + a, cap, wide, enough):
                return False
            a = b
        return True

    def kinds(self, n: int) -> np.ndarray:
        """The ``_Combo`` ids of the last batch's first ``n`` transitions (those the search
        keeps, and the one it cuts at: labels are made for no other)."""
        _, _, lid, _, key = self.last  # key: the environment's picks of each transition
        return self._kinds(key[:n], lid[:n])

    def _kinds(self, key, lid) -> np.ndarray:
        """The ``_Combo`` id of each (environment key, tree leaf id) pair."""
        tl = self.tl
        while len(self.tree.leaves) > tl:
            tl *= 2
        if self.space * tl <= self.TABLE:
            if self.table is None or tl != self.tl:
                self.tl, self.table = tl, np.full(self.space * tl, -1, np.int32)
                for (k, li), c in self.combos.items():
                    self.table[k * tl + li] = c
            flat = key * tl + lid
            got = self.table[flat]
            miss = got < 0
            if miss.any():
                for f in np.unique(flat[miss]).tolist():
                    self.table[f] = self._combo(f // tl, f % tl)
                got = self.table[flat]
            return got.astype(np.int64)
        flat = key * (1 << 32) + lid if self.space < 1 << 30 else None
        if flat is not None:
            u, inv = np.unique(flat, return_inverse=True)
            ids = np.array([self._combo(f >> 32, f & 0xFFFFFFFF) for f in u.tolist()], np.int64)
        else:
            pairs = np.stack([key, lid], axis=1)
            u, inv = np.unique(pairs, axis=0, return_inverse=True)
            ids = np.array([self._combo(int(k), int(li)) for k, li in u.tolist()], np.int64)
        return ids[inv.reshape(-1)]

    def _combo(self, k: int, li: int) -> int:
        c = self.combos.get((k, li))
        if c is None:
            label, rest = (), k
            for i in reversed(range(len(self.stages))):
                rest, d = divmod(rest, self.radix[i])
                label = self.pick_label[i][d] + label
            leaf = self.tree.leaves[li]
            c = self.combos[(k, li)] = len(self.leaves)
            self.leaves.append(_Combo(c, label + leaf.label, leaf.status, leaf.violations))
        return c

    def ordinals(self):
        return None

    def script(self, stage: int, row: int, leaf) -> tuple:
        """The whole choice script of ``row`` of ``stage`` (an index into that stage's
        input rows) ending at ``leaf``."""
        hist = self.last[0]
        taken = list(leaf.taken)
        for j in reversed(range(stage)):
            rows, lid = hist[j]
            taken[:0] = self.stages[j].leaves[int(lid[row])].taken
            row = int(rows[row])
        return tuple(taken), row

    def errors(self, codes, head, cut):
        """DomainViolations of the last batch, in the scalar engine's order, before the
        transition at position ``cut`` of the batch (None: all)."""
        hist, rows, lid, errs, _ = self.last
        stop = None
        if cut is not None:
            script, r = self.script(len(self.stages), int(rows[cut]), self.tree.leaves[int(lid[cut])])
            stop = (r, _dfs_key(script))
        items = []
        for stage, bad in errs:
            for leaf, rs in bad:
                for r in rs.tolist():
                    script, src = self.script(stage, r, leaf)
                    k = (src, _dfs_key(script))
                    if stop is None or k < stop:
                        items.append((k, script))
        items.sort()
        return _rerun_errors(self, self.prog, [(k[0], s) for k, s in items], codes, head)


def _dfs_key(script) -> tuple:
    """The order of a choice script in the scalar engine's depth-first search."""
    return tuple(c and _LAST - c for c in script)


_declared: Search = search  # an engine of the shared interface (btfsm.verify.search.Search; mypy holds it to it)
