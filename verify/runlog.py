"""Conformance of recorded runs: is what a real engine did a behaviour of the model?

``btfsm conform --log RUN MODEL`` reads a recording of a real execution and checks it
against the model under the engine's profile (docs/semantics.md section 8):

* a BehaviorTree.CPP 4 FileLogger2 file (``.btlog``, ``btfsm.interop.btlog``), under
  ``btcpp``: every recorded status transition must be one that a tick of the checked
  system makes BehaviorTree.CPP record;
* a py_trees run recorded with ``btfsm.interop.pytrees.RunRecorder`` (JSON lines), under
  ``pytrees``: every tick's visited nodes and statuses, in order, and the nodes left
  RUNNING must be those of a tick of the checked system.

Nothing here interprets the tree. A recorded tick is explained by ``Program.step`` (the
one step function) under some answer of the oracle (environment events, primitive
outcomes): the search enumerates the answers the model allows, as the model checker does
(``btfsm.oracles.all_choices``), and prunes an answer as soon as the events of the tick so
far disagree with the recording. What BehaviorTree.CPP records for the events of one step
(``_items``) is its status bookkeeping, documented in docs/interop.md section 5 with what
is and is not checked. The first transition no explanation reaches is reported with its
time, node and the statuses the model allows there.
"""
from __future__ import annotations

import heapq
import json
import re
import sys
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Sequence, cast

from btfsm.bt import Condition, Leaf, SubTree, names_in
from btfsm.errors import ModelError
from btfsm.interop.btcpp_import import CONTROLS, DECORATORS
from btfsm.interop.btlog import MAGIC, STATUS_NAMES, read_btlog
from btfsm.oracles import ScriptOracle, all_choices

if TYPE_CHECKING:
    from btfsm.semantics import Site

__all__ = ["LogVerdict", "check_btlog", "check_pytrees_run", "read_pytrees_run", "cli_conform_log",
           "PYTREES_FORMAT", "DEFAULT_MAX_CONFIGS", "MAX_LOG_BYTES"]

PYTREES_FORMAT = "btfsm-pytrees-run/1"  # = btfsm.interop.pytrees.RUN_FORMAT (that module needs py_trees)
MAX_LOG_BYTES = 64 * 1024 * 1024  # a recording read at once: about 7 million .btlog transitions
DEFAULT_MAX_CONFIGS = 200_000  # configurations alive at once (btlog: queued; py_trees: after a tick)
IDLE, RUNNING, SUCCESS, FAILURE = 0, 1, 2, 3  # BehaviorTree.CPP's NodeStatus codes
START, END, HALT = 0, 1, 2
# how a BT.CPP node's tick begins (what it records before its children and its result)
CONTROL, SUBTREE, LEAF, CUSTOM, QUIET, ONCE = range(6)


@dataclass
class LogVerdict:
    """The answer of a log check. ``first`` (when it does not conform) describes the
    first recorded entry no run of the model explains."""
    conforms: bool
    engine: str
    semantics: str
    entries: int  # transitions (btlog) or ticks (py_trees) recorded
    ticks: int  # ticks of the explaining run (conforming), or ticks explained before ``first``
    searched: int
    first: "dict | None" = None
    incomplete: bool = False
    #: the explaining run as ``(state before, Step)`` pairs (the whole run when the log
    #: conforms, else the run up to the furthest point explained): what the HTML page shows
    steps: list = field(default_factory=list, repr=False, compare=False)

    def as_dict(self) -> dict:
        return {"conforms": self.conforms, "engine": self.engine, "semantics": self.semantics,
                "entries": self.entries, "ticks": self.ticks, "searched": self.searched,
                "incomplete": self.incomplete, "first": self.first}


class _Dead(Exception):
    """The events of the tick so far already disagree with the recording."""


class _Pruning(ScriptOracle):
    """A ScriptOracle that sees the events of the tick as they happen (``events`` is the
    list ``Program.step`` records into) and gives up on an answer that cannot match."""

    __slots__ = ("events", "fits")

    def __init__(self, script, fits):
        super().__init__(script)
        self.events, self.fits = [], fits

    def outcome(self, site: Site) -> int:
        if len(site.outcomes) > 1 and not self.fits(self.events):
            raise _Dead
        return super().outcome(site)


def _explanations(program, state, fits):
    """Every Step from ``state`` whose events may still match (``fits``), by the same
    enumeration the checker uses."""
    run = lambda s, oracle: program.step(s, oracle, record=oracle.events)  # noqa: E731
    for _, result, _ in all_choices(run, state, lambda script: _Pruning(script, fits), errors=(_Dead,)):
        if not isinstance(result, _Dead) and result.state is not None:
            yield result


def _base(name: str) -> str:
    """A node's own name: without a SubTree prefix (``inst/``) and btfsm's ``#k`` suffix."""
    return re.sub(r"#\d+$", "", name.rsplit("/", 1)[-1])


# ============================================================================ mapping


@dataclass
class _Map:
    """The recorded tree's nodes (index k) against the model's: ``prim[x]`` is the recorded
    node of model node ``x``, ``wraps[x]`` the recorded nodes that only pass ``x``'s status
    on (SubTree, PassThrough...), inner first, ``anc[x]`` every recorded ancestor of
    ``prim[x]``, outermost first. ``rule[k]`` says how node k's tick begins."""
    labels: list = field(default_factory=list)  # k -> text for messages
    keys: list = field(default_factory=list)  # k -> uid (btlog) or index (py_trees)
    rule: list = field(default_factory=list)
    prim: dict = field(default_factory=dict)
    wraps: dict = field(default_factory=dict)
    anc: dict = field(default_factory=dict)
    parent: list = field(default_factory=list)

    def add(self, key, label, rule, parent) -> int:
        self.keys.append(key)
        self.labels.append(label)
        self.rule.append(rule)
        self.parent.append(parent)
        return len(self.keys) - 1

    def finish(self):
        for x, k in self.prim.items():
            chain, p = [], self.parent[k]
            while p is not None:
                chain.append(p)
                p = self.parent[p]
            self.anc[x] = tuple(reversed(chain))
            self.wraps[x] = tuple(self.wraps.get(x, ()))[::-1]  # collected outer first
        return self


def _map_tree(log_root, model, file, children, tag, name, label, key, wrapper, known):
    """Walk the recorded tree and the model's tree together (see ``_Map``)."""
    m = _Map()

    def fail(ln, mn, why):
        return ModelError("", f"the recorded tree is not the model's tree: at {label(ln)} "
                              f"vs model node '{mn.name}' ({type(mn).__name__}): {why}", file)

    def walk(ln, mn, parent):
        while isinstance(mn, SubTree):  # it returns its child's status: recorded SubTrees stand for the child
            mn = mn.children_of()[0]
        kids, lkids = mn.children_of(), children(ln)
        if wrapper(ln) or (known(ln) is None and len(lkids) == 1 and len(kids) != 1):
            k = m.add(key(ln), label(ln), SUBTREE if tag(ln) == "SubTree" else CUSTOM, parent)
            m.wraps.setdefault(mn.name, []).append(k)
            if len(lkids) != 1:
                raise fail(ln, mn, "it has no child to stand for")
            walk(lkids[0], mn, k)
            return
        if isinstance(mn, Leaf):
            if lkids:
                raise fail(ln, mn, f"{len(lkids)} child node(s) in the recording, a leaf in the model")
            if _base(name(ln)) != _base(mn.name):
                raise fail(ln, mn, f"the leaf is named '{name(ln)}' in the recording")
            # a sync action (BT.CPP's SimpleActionNode) records RUNNING before its result when it
            # was IDLE; a condition and an action that can return RUNNING (a StatefulActionNode) do not
            quiet = isinstance(mn, Condition) or model.program.nodes[mn.name].can_run
            m.prim[mn.name] = m.add(key(ln), label(ln), QUIET if quiet else LEAF, parent)
            return
        cls = known(ln)
        if cls is not None and type(mn).__name__ not in cls.split("|"):
            raise fail(ln, mn, f"a {tag(ln)} in the recording")
        if len(lkids) != len(kids):
            raise fail(ln, mn, f"{len(lkids)} child node(s) in the recording, {len(kids)} in the model")
        rule = CUSTOM if cls is None else ONCE if tag(ln) == "RunOnce" else CONTROL
        k = m.prim[mn.name] = m.add(key(ln), label(ln), rule, parent)
        for lc, mc in zip(lkids, kids):
            walk(lc, mc, k)

    if model.tree is None:
        raise ModelError("", "the model has no tree: a recorded run cannot be checked against it", file)
    walk(log_root, model.tree, None)
    return m.finish()


def _btcpp_known(ln):
    spec = CONTROLS.get(ln.tag) or DECORATORS.get(ln.tag)
    return None if spec is None else spec[0]


def _map_btlog(log, model, file) -> _Map:
    return _map_tree(log.root, model, file, children=lambda ln: ln.children, tag=lambda ln: ln.tag,
                     name=lambda ln: ln.name,
                     label=lambda ln: f"'{ln.path}' (<{ln.tag}>, uid {ln.uid})", key=lambda ln: ln.uid,
                     wrapper=lambda ln: ln.tag == "SubTree", known=_btcpp_known)


# ============================================================================ BT.CPP logs


def _items(events, mp):
    """What BehaviorTree.CPP records for the events of one step, as items to match:
    (START, k, alone) when node k's tick begins (every ancestor's before its first
    descendant's; ``alone``: nothing below it is ticked),
    (END, k, status) when it returns, (HALT, k) when it is halted (children first)."""
    out, started = [], set()
    prim, anc, wraps = mp.prim, mp.anc, mp.wraps
    for ev in events:
        kind = ev[0]
        if kind == "status":
            k = prim.get(ev[1])
            if k is None:
                continue
            for a in anc[ev[1]]:
                if a not in started:
                    started.add(a)
                    out.append((START, a, False))
            if k not in started:
                out.append((START, k, True))  # nothing below it ticked (a leaf, a RunOnce that ran)
            started.discard(k)
            code = ev[2] + 1  # btfsm RUNNING 0, SUCCESS 1, FAILURE 2 -> BT.CPP 1, 2, 3
            out.append((END, k, code))
            for w in wraps[ev[1]]:
                out.append((END, w, code))
                started.discard(w)
        elif kind == "halt":
            k = prim.get(ev[1])
            if k is None:
                continue
            out.append((HALT, k))
            out.extend((HALT, w) for w in wraps[ev[1]])
    return out


class _Matcher:
    """Matches a step's items against the log from some (position, recorded statuses)
    states; keeps the furthest position any match reached and what it needed there."""

    def __init__(self, log, rules):
        self.log, self.rules, self.n = log, rules, len(log)
        self.best = -1
        self.expect: set = set()

    def _want(self, pos, k, status):
        if pos > self.best:
            self.best, self.expect = pos, set()
        if pos == self.best:
            self.expect.add((k, status))

    def run(self, items, states) -> set:
        """Every (pos, statuses) after all ``items``, from any of ``states``."""
        log, n, rules = self.log, self.n, self.rules
        stack = [(0, pos, t) for pos, t in states]
        seen = set(stack)
        ends = set()
        last = len(items)

        def push(x):
            if x not in seen:
                seen.add(x)
                stack.append(x)

        while stack:
            i, pos, t = stack.pop()
            if pos > self.best:
                self.best, self.expect = pos, set()
            if i == last:
                ends.add((pos, t))
                continue
            entry = log[pos] if pos < n else None
            if entry is not None and entry[1] == IDLE and t[entry[0]] in (SUCCESS, FAILURE):
                k = entry[0]  # a reset of a finished node: BT.CPP bookkeeping, not checked
                push((i, pos + 1, t[:k] + (IDLE,) + t[k + 1:]))
            item = items[i]
            k = item[1]
            cur = t[k]
            if item[0] == START:
                if entry == (k, IDLE) and cur in (SUCCESS, FAILURE):
                    continue  # BT.CPP reset this node before its tick began: the reset (pushed above) comes first
                rule = rules[k]
                need = ((rule == CONTROL and cur != RUNNING) or (rule == SUBTREE and cur == IDLE)
                        or (rule == ONCE and cur != RUNNING and not item[2]))
                may = (rule == LEAF and cur == IDLE) or (rule == CUSTOM and cur != RUNNING)
                if need or may:
                    if entry == (k, RUNNING):
                        push((i + 1, pos + 1, t[:k] + (RUNNING,) + t[k + 1:]))
                    else:
                        self._want(pos, k, RUNNING)
                if not need:
                    push((i + 1, pos, t))
            else:
                want = item[2] if item[0] == END else (IDLE if cur == RUNNING else None)
                if want is None or cur == want:
                    push((i + 1, pos, t))
                elif entry == (k, want):
                    push((i + 1, pos + 1, t[:k] + (want,) + t[k + 1:]))
                else:
                    self._want(pos, k, want)
        return ends

    def tail(self, pos, t, children) -> bool:
        """The log ends at a tick's end: what is left from ``pos`` are resets of finished
        nodes and a halt of the whole tree (``Tree::haltTree``, which the Tree's destructor
        calls): RUNNING nodes going IDLE, each after the RUNNING nodes below it, all of them."""
        t, halted = list(t), False
        for k, status in self.log[pos:]:
            if status != IDLE or t[k] == IDLE or (t[k] == RUNNING and any(t[c] == RUNNING for c in children[k])):
                return False
            halted = halted or t[k] == RUNNING
            t[k] = IDLE
        return not halted or RUNNING not in t  # a halt of the tree halts every running node


class _Ends:
    """``matcher.run(items, {(pos, t)})`` for the items of one step from one configuration,
    remembered: the answers of one tick share their first events, so a run that extends
    the last one goes on from where that one ended."""

    def __init__(self, matcher, pos, t):
        self.matcher, self.cache = matcher, {(): {(pos, t)}}
        self.last = ()

    def __call__(self, items) -> set:
        key = tuple(items)
        got = self.cache.get(key)
        if got is None:
            last = self.last
            j = len(last) if len(last) < len(key) and key[:len(last)] == last else 0
            start = self.cache[key[:j]]
            got = self.matcher.run(key[j:], start) if start else set()
            self.cache[key] = got
        self.last = key
        return got


def check_btlog(model, log, file: str = "log", allow=None, max_configs: int = DEFAULT_MAX_CONFIGS) -> LogVerdict:
    """Check a FileLogger2 recording (a ``BtLog``) against ``model`` (its own profile:
    pass a model under ``btcpp``). ``allow(step)`` may restrict the explaining steps
    (tests pin leaves' answers with it). The search goes through the log in order: a
    configuration (model state, log position, recorded statuses) is expanded once, and
    those behind the furthest position being expanded are forgotten, so memory holds the
    frontier; ``max_configs`` bounds it (``incomplete`` when hit)."""
    mp = _map_btlog(log, model, file)
    index = {uid: k for k, uid in enumerate(mp.keys)}  # every node of the log's tree is mapped
    entries = [(index[uid], status) for _, uid, status in log.transitions]
    program = model.program
    matcher = _Matcher(entries, mp.rule)
    n = len(entries)
    children: list = [[] for _ in mp.keys]
    for k, p in enumerate(mp.parent):
        if p is not None:
            children[p].append(k)
    start = (program.initial, 0, (IDLE,) * len(mp.keys))
    parents: dict = {start: None}  # configuration -> (configuration before, Step): the explaining run
    furthest = start
    seen = {0: {start}}  # log position -> configurations found there
    heap = [(0, 0, 0, start)]  # (position, ticks, order, configuration)
    counter = searched = 1
    done_ticks = 0  # complete ticks before the tick that reached the furthest transition
    while heap:
        pos, ticks, _, config = heapq.heappop(heap)
        for old in [p for p in seen if p < pos]:
            del seen[old]  # every configuration there was expanded
        state, _, t = config
        if pos > furthest[1]:
            furthest = config
        if matcher.tail(pos, t, children):
            return LogVerdict(True, "btcpp", model.semantics, n, ticks, searched, steps=_path(parents, config, lambda c: c[0]))
        reached = matcher.best
        ends = _Ends(matcher, pos, t)

        def fits(events, ends=ends):
            return bool(ends(_items(events, mp)))

        for step in _explanations(program, state, fits):
            if allow is not None and not allow(step):
                continue
            for pos2, t2 in ends(_items(step.events, mp)):
                nxt = (step.state, pos2, t2)
                there = seen.setdefault(pos2, set())
                if nxt not in there:
                    there.add(nxt)
                    parents.setdefault(nxt, (config, step))
                    heapq.heappush(heap, (pos2, ticks + 1, counter, nxt))
                    counter += 1
                    searched += 1
                    if len(heap) > max_configs:
                        return LogVerdict(False, "btcpp", model.semantics, n, ticks, searched, incomplete=True)
        if matcher.best > reached:
            done_ticks = ticks
    return LogVerdict(False, "btcpp", model.semantics, n, done_ticks, searched,
                      first=_first_btlog(log, mp, entries, matcher, done_ticks), steps=_path(parents, furthest, lambda c: c[0]))


def _path(parents, last, state_of) -> list:
    """The ``(state before, Step)`` pairs that lead to key ``last`` (``parents``: key ->
    (key before, Step), None at the start; ``state_of(key)``: its model state)."""
    out = []
    while parents.get(last) is not None:
        before, step = parents[last]
        out.append((state_of(before), step))
        last = before
    return out[::-1]


def _first_btlog(log, mp, entries, matcher, ticks) -> dict:
    pos = max(matcher.best, 0)
    allowed = sorted(matcher.expect)
    out = {"index": pos, "allowed": [{"node": mp.labels[k], "status": STATUS_NAMES[s]} for k, s in allowed]}
    if pos >= len(entries):
        out.update(time=log.transitions[-1][0] / 1e6 if log.transitions else 0.0, node=None, status=None,
                   text="the log ends inside a tick: the model's tick goes on with "
                        + (", ".join(f"{mp.labels[k]} -> {STATUS_NAMES[s]}" for k, s in allowed) or "nothing it can record"))
        return out
    usec, uid, status = log.transitions[pos]
    k = entries[pos][0]
    mine = [STATUS_NAMES[s] for kk, s in allowed if kk == k]
    if mine:
        here = f"the model allows {' or '.join(mine)} here"
    else:
        others = ", ".join(f"{mp.labels[kk]} -> {STATUS_NAMES[s]}" for kk, s in allowed[:6])
        here = f"the model allows no transition of this node here, only {others or 'resets of finished nodes'}"
    prev = [STATUS_NAMES[s] for kk, s in entries[:pos] if kk == k]
    out.update(time=usec / 1e6, node=mp.labels[k], uid=uid, status=STATUS_NAMES[status],
               previous=prev[-1] if prev else "IDLE", model_allows=mine,
               text=f"transition {pos + 1} ({usec / 1e6:.6f} s), tick {ticks + 1}: {mp.labels[k]} "
                    f"{prev[-1] if prev else 'IDLE'} -> {STATUS_NAMES[status]} is not a step of the model; {here}")
    return out


# ============================================================================ py_trees runs


@dataclass
class PytreesRun:
    """A run recorded by ``RunRecorder``: ``nodes`` (name, type, parent index) in
    pre-order and per tick ``(visited [(index, status)], running {index})``."""
    nodes: list
    ticks: list


def read_pytrees_run(text: str, file: str) -> PytreesRun:
    """The ``PytreesRun`` in a recording's text (JSON lines; errors name the line)."""
    ticks: list
    nodes, ticks = None, []
    for no, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue

        def fail(problem):
            return ModelError(f"line {no}", problem, file)
        try:
            rec = json.loads(line)
        except ValueError as exc:
            raise fail(f"not JSON ({getattr(exc, 'msg', exc)})") from None
        if not isinstance(rec, dict):
            raise fail("expected a JSON object")
        if nodes is None:
            if rec.get("format") != PYTREES_FORMAT:
                raise fail(f"expected the header {{\"format\": \"{PYTREES_FORMAT}\", \"nodes\": [...]}}")
            raw = rec.get("nodes")
            if not isinstance(raw, list) or not raw:
                raise fail("nodes: expected a list of {name, type, parent}")
            nodes = []
            for i, nd in enumerate(raw):
                if (not isinstance(nd, dict) or not isinstance(nd.get("name"), str) or not isinstance(nd.get("type"), str)
                        or not (nd.get("parent") is None if i == 0 else
                                isinstance(nd.get("parent"), int) and 0 <= nd["parent"] < i)):
                    raise fail(f"nodes[{i}]: expected {{name, type, parent: an earlier index (null for the root)}}")
                nodes.append({"name": nd["name"], "type": nd["type"], "parent": nd.get("parent"), "index": i,
                              "children": []})
                if i:
                    nodes[nd["parent"]]["children"].append(nodes[i])
            continue
        if rec.get("tick") != len(ticks):
            raise fail(f"tick: expected {len(ticks)} (ticks are numbered from 0, in order)")
        visited, running = rec.get("visited"), rec.get("running")
        if (not isinstance(visited, list) or not all(
                isinstance(v, list) and len(v) == 2 and isinstance(v[0], int) and 0 <= v[0] < len(nodes)
                and v[1] in ("RUNNING", "SUCCESS", "FAILURE", "INVALID") for v in visited)):
            raise fail("visited: expected [[node index, RUNNING|SUCCESS|FAILURE|INVALID], ...]")
        if not isinstance(running, list) or not all(isinstance(v, int) and 0 <= v < len(nodes) for v in running):
            raise fail("running: expected a list of node indices")
        ticks.append(([(i, s) for i, s in visited], frozenset(running)))
    if nodes is None:
        raise ModelError("", "empty recording (no header line)", file)
    return PytreesRun(nodes, ticks)


def _pytrees_known() -> dict:
    """py_trees class name -> the btfsm node type it records (the node classes' ``pytrees``
    names); None for a class that stands for several (Sequence, Selector: memory decides)."""
    types: dict = {}
    for key, name in names_in("pytrees").items():
        types.setdefault(name.split("(")[0], []).append(key)
    out = {name: keys[0] if len(keys) == 1 else None for name, keys in types.items()}
    out["Repeat"] = "Repeat|KeepRunningUntilFailure"  # a count py_trees never reaches is imported as the latter
    return out


_PYTREES_KNOWN = _pytrees_known()
_PY_STATUS = {"RUNNING": 0, "SUCCESS": 1, "FAILURE": 2}


def _map_pytrees(run, model, file) -> _Map:
    from btfsm.interop.pytrees import btfsm_names

    # the names from_pytrees gives the recorded behaviours (a second 'a' is 'a_2'...)
    named = [nd for nd in run.nodes if nd["type"] not in ("PassThrough", "Count")]
    names = {nd["index"]: nm for nd, nm in zip(named, btfsm_names([nd["name"] for nd in named]))}
    return _map_tree(run.nodes[0], model, file, children=lambda nd: nd["children"], tag=lambda nd: nd["type"],
                     name=lambda nd: names.get(nd["index"], nd["name"]),
                     label=lambda nd: f"'{nd['name']}' ({nd['type']}, node {nd['index']})", key=lambda nd: nd["index"],
                     wrapper=lambda nd: nd["type"] in ("PassThrough", "Count"),
                     known=lambda nd: _PYTREES_KNOWN.get(nd["type"]))


def check_pytrees_run(model, run, file: str = "run", allow=None, max_configs: int = DEFAULT_MAX_CONFIGS) -> LogVerdict:
    """Check a py_trees recording (a ``PytreesRun``) against ``model`` (pass it under
    ``pytrees``): each recorded tick must be a step of the model from a state the earlier
    ticks reach: the visited nodes with their statuses in order, and the RUNNING ones after.
    ``allow(tick, step)`` may restrict the explaining steps (tests pin leaves' answers)."""
    mp = _map_pytrees(run, model, file)
    index = {key: k for k, key in enumerate(mp.keys)}
    program = model.program
    flags = [(info.flag, name) for name, info in program.nodes.items() if info.flag is not None and name in mp.prim]
    states = {program.initial}
    parents: dict = {(0, program.initial): None}  # (tick, state) -> ((tick, state) before, Step)
    searched = 1
    for tick, (visited, running) in enumerate(run.ticks):
        want = [(index[i], _PY_STATUS.get(s)) for i, s in visited]
        want_running = {index[i] for i in running}
        best: list = [-1, set()]

        def expected(events):
            out = []
            for ev in events:
                if ev[0] == "status" and ev[1] in mp.prim:
                    out.append((mp.prim[ev[1]], ev[2]))
                    out.extend((w, ev[2]) for w in mp.wraps[ev[1]])
            return out

        def agree(got):
            j = 0
            while j < len(got) and j < len(want) and got[j] == want[j]:
                j += 1
            if j < len(got):
                if j > best[0]:
                    best[0], best[1] = j, set()
                if j == best[0]:
                    best[1].add(got[j])
            return j == len(got)

        def fits(events):
            return agree(expected(events))

        nxt = set()
        why_running = None
        for state in states:
            for step in _explanations(program, state, fits):
                got = expected(step.events)
                if not agree(got) or len(got) != len(want):
                    if len(got) < len(want) and agree(got):
                        if len(got) > best[0]:
                            best[0], best[1] = len(got), {None}
                        elif len(got) == best[0]:
                            best[1].add(None)
                    continue
                now = set()
                for flag, name in flags:
                    if step.state[flag]:
                        now.add(mp.prim[name])
                        now.update(mp.wraps[name])
                if now != want_running:
                    why_running = why_running or (now, want_running)
                    continue
                if allow is None or allow(tick, step):
                    nxt.add(step.state)
                    parents.setdefault((tick + 1, step.state), ((tick, state), step))
        searched += len(nxt)
        if not nxt:
            return LogVerdict(False, "pytrees", model.semantics, len(run.ticks), tick, searched,
                              first=_first_pytrees(tick, want, best, why_running, mp),
                              steps=_path(parents, (tick, min(states)), lambda k: k[1]))
        if len(nxt) > max_configs:  # the states a tick may have left the model in
            return LogVerdict(False, "pytrees", model.semantics, len(run.ticks), tick, searched, incomplete=True)
        states = nxt
    return LogVerdict(True, "pytrees", model.semantics, len(run.ticks), len(run.ticks), searched,
                      steps=_path(parents, (len(run.ticks), min(states)), lambda k: k[1]))


def _first_pytrees(tick, want, best, why_running, mp) -> dict:
    names = ("RUNNING", "SUCCESS", "FAILURE")
    j, options = best
    if j < 0 or (j >= len(want) and why_running is not None and None not in options):
        now, rec = why_running or (set(), set())
        extra = ", ".join(mp.labels[k] for k in sorted(rec - now)) or "none"
        missing = ", ".join(mp.labels[k] for k in sorted(now - rec)) or "none"
        return {"tick": tick, "node": None, "status": None, "allowed": [],
                "text": f"tick {tick}: the recorded statuses are a step of the model, but the nodes left RUNNING "
                        f"differ: recorded running and not in the model: {extra}; running in the model and not "
                        f"recorded: {missing}"}
    allowed = [(mp.labels[k], names[s]) for k, s in sorted(x for x in options if x is not None)]
    if j >= len(want):
        text = (f"tick {tick}: the recording ends the tick after {len(want)} visited node(s); the model's tick goes "
                f"on with " + (", ".join(f"{n} {s}" for n, s in allowed) or "nothing"))
        return {"tick": tick, "index": j, "node": None, "status": None, "allowed": allowed, "text": text}
    k, st = want[j]
    status = names[st] if st is not None else "INVALID"
    mine = [s for n, s in allowed if n == mp.labels[k]]
    here = (f"the model allows {' or '.join(mine)} here" if mine else
            "the model allows " + (", ".join(f"{n} {s}" for n, s in allowed) or "the tick to end") + " here")
    if None in options and not allowed:
        here = "the model's tick ends before it"
    return {"tick": tick, "index": j, "node": mp.labels[k], "status": status, "model_allows": mine,
            "allowed": allowed, "text": f"tick {tick}, visited node {j + 1}: {mp.labels[k]} returned {status}, "
                                        f"which is not a step of the model; {here}"}


# ============================================================================ CLI


def cli_conform_log(args) -> int:
    """``btfsm conform --log RUN MODEL``: exit 0 conforms, 1 not, 2 bad input, 3 budget."""
    from btfsm.files import load_model, read_model_bytes

    path = args.log
    data = read_model_bytes(path, path, MAX_LOG_BYTES, "recorded run")
    if data.startswith(MAGIC):
        engine, semantics = "btcpp", args.semantics or "btcpp"
    elif data.lstrip().startswith(b"{"):
        engine, semantics = "pytrees", args.semantics or "pytrees"
    else:
        raise ModelError("", "not a BehaviorTree.CPP FileLogger2 log (.btlog) nor a py_trees run recorded by "
                             "btfsm.interop.pytrees.RunRecorder", path)
    model = load_model(args.model, semantics=semantics)
    page = args.html
    if page:
        from btfsm.html import require_dot

        require_dot()
    budget = args.max_states if args.max_states is not None else DEFAULT_MAX_CONFIGS
    if engine == "btcpp":
        verdict = check_btlog(model, read_btlog(data, path), path, max_configs=budget)
        what = f"{verdict.entries} transition(s)"
    else:
        try:
            text = data.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ModelError(f"byte {exc.start}", "not UTF-8", path) from None
        verdict = check_pytrees_run(model, read_pytrees_run(text, path), path, max_configs=budget)
        what = f"{verdict.entries} tick(s)"
    if verdict.incomplete:
        text = f"incomplete: more than --max-states {budget:,} configurations alive at once after {verdict.ticks} tick(s)"
    elif verdict.conforms:
        text = (f"{path}: conforms to {model.name} under {semantics}: {what} explained by a run of "
                f"{verdict.ticks} tick(s) ({verdict.searched:,} configurations searched)")
    else:
        text = f"{path}: does not conform to {model.name} under {semantics}: {cast(dict, verdict.first)['text']}"
    if page:
        from btfsm.html import log_page, write_page

        written = write_page(page, model, **log_page(model, path, verdict, text))
        print(f"html: {written}", file=sys.stderr if args.json else sys.stdout)
    if args.json:
        print(json.dumps(dict(verdict.as_dict(), log=path, model=model.name)))
    elif verdict.incomplete:
        print(f"btfsm conform: {text}; raise it", file=sys.stderr)
    else:
        print(text)
    if verdict.incomplete:
        return 3
    return 0 if verdict.conforms else 1
