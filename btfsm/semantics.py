"""The BT-FSM tick semantics, written once: ``Program.step(state, oracle) -> Step``.

A model compiles into a ``Program``: a flat state layout (world variables, then each FSM's
token, held goal and parameters, then one running flag or memory slot per tree node that
needs one) and one closure per node. ``step`` is a pure function of the state tuple and
the oracle's answers:

* ``oracle.env(i)``: does enabled environment event ``i`` happen this tick?
* ``oracle.outcome(site)``: which declared outcome did the primitive at ``site`` have?
* ``oracle.halt(site)``: notification that a running primitive was abandoned.
* ``oracle.request(fsm_index, goal_index)`` (optional): notification of the goal an FSM is
  driven toward, before its state runs (implementations may choose targets by goal).

The runtime answers from implementations and sensors, the model checker answers every
way the model allows, replay answers from a trace. docs/semantics.md states the rules;
each rule's implementation below carries the same name as its row there.

Node types compile through ``RULES``: one function per row of docs/semantics.md sections
2, 3 and 8.3, registered with ``@rule(NodeType)`` at the end of this module (a new node
type: docs/nodes.md). Why one module of more than 1,000 lines: it is the one step
function, written once. The layout of the state (slots, flags, memories), the rules'
tick closures, the FSM tick and ``Program.step`` share compile-time facts (``_N``) and the
helpers of the hot path (``_halt_running``, ``finish``); split across modules, each of
those would become a public interface that only this function uses.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Optional

from .bt import (Action, Condition, Effects, FailureIsRunning, ForceFailure, ForceSuccess, Guard, IfThenElse,
                 Inverter, KeepRunningUntilFailure, MemoryFallback, MemorySequence, Node, Parallel, ParallelAll,
                 PipelineSequence, RecoveryNode, RoundRobin, RunningIsFailure, RunningIsSuccess,
                 ReactiveFallback, ReactiveSequence, Repeat, Retry, RunOnce, SequenceWithMemory,
                 SkillRequest, SubTree, WhileDoElse, check_arity, check_bounds)
from .errors import ModelError
from .expr import (BOOL, INT, BinOp, Compare, Const, Expr, Name, Scope, Slot, Type, compile_effects, compile_fn,
                   flat, names_in)
from .profiles import profile
from .timing import duration_ticks, interval_ticks
from .status import Status

__all__ = ["Program", "Site", "Step", "SlotInfo", "RULES", "SLOTS", "CAN_RUN", "rule", "NodeRule", "Tick"]

RUNNING, SUCCESS, FAILURE = int(Status.RUNNING), int(Status.SUCCESS), int(Status.FAILURE)
_INVERT = (RUNNING, FAILURE, SUCCESS)


class Site:
    """A place where a primitive runs: an Action node or an FSM state."""

    __slots__ = ("kind", "node", "fsm", "state", "primitive", "args", "outcomes", "index", "ticks", "timer")

    def __init__(self, kind: str, node: Optional[str], fsm: Optional[str], state: Optional[str], primitive: str,
                 args: Any, outcomes: tuple[Any, ...], index: int, ticks: Any = None,
                 timer: Optional[int] = None) -> None:
        self.kind, self.node, self.fsm, self.state = kind, node, fsm, state
        self.primitive, self.args, self.outcomes, self.index = primitive, args, outcomes, index
        self.ticks = ticks  # (lo, hi or None): the ticks of running on which a run may end (section 6.1)
        self.timer = timer  # the slot counting this run's RUNNING answers, or None

    @property
    def label(self) -> str:
        return str(self.node) if self.kind == "action" else f"{self.fsm}/{self.state}"

    def __repr__(self) -> str:
        return f"Site({self.label} runs {self.primitive})"


@dataclass(frozen=True)
class SlotInfo:
    """What a state slot holds: ``kind`` is var, token, goal, param, flag or memory."""

    name: str
    kind: str
    size: int  # number of values: 0..size-1 (ints: lo..hi stored as is, size = hi-lo+1)
    lo: int = 0


class Step:
    """The result of one tick: next state, root status, trace events, contract violations.

    ``state`` is None when the tick cannot happen (an environment choice had no enabled
    option); ``violations`` then holds ``("blocked", choice)``."""

    __slots__ = ("state", "status", "events", "violations")

    def __init__(self, state: Optional[tuple[int, ...]], status: int, events: Any, violations: list[Any]) -> None:
        self.state, self.status, self.events, self.violations = state, status, events, violations

    def __repr__(self) -> str:
        return f"Step(status={Status(self.status).name}, state={self.state})"


class _Late(Exception):
    """An answer the declared timing does not allow (a duration, section 6.1): the tick
    cannot go this way (``Step.state`` None, violation ``("timing", site label, text)``)."""

    def __init__(self, site: Site, text: str) -> None:
        super().__init__(text)
        self.site, self.text = site, text


class _Ctx:
    """The context of one tick (made by ``_context``)."""

    __slots__ = ("s", "oracle", "rec", "fsm_done", "violations", "on_request", "on_merge", "reticks")
    s: list[int]  # the state, changed in place
    oracle: Any
    rec: Any  # the events of the tick, when recorded (list), else None
    fsm_done: dict[int, tuple[int, int, str, Any]]  # FSM -> (goal, reply, requester, params)
    violations: list[Any]
    reticks: tuple[tuple[int, ...], ...]  # the states the tickOnce re-ticks of this tick started from (rule 'tickOnce')
    on_request: Any  # the oracle's optional hook: told which goal an FSM drives
    on_merge: Any  # the oracle's optional hook: told where the tick's context is its state

    def merge_point(self, key: Any) -> None:
        """Tell the oracle (``oracle.merge``, when it has one) that the rest of the tick
        depends only on the state list, the violations, FSM records and re-ticks so far."""
        if self.on_merge is not None:
            self.on_merge(key, self.s, self.violations, self.fsm_done, self.reticks)


_new = object.__new__


def _context(s: list[int], oracle: Any, rec: Optional[list[Any]], hooks: bool = True) -> _Ctx:
    """A new tick context (once per tick: filled in here rather than by an ``__init__``,
    which costs more to call). The oracle's optional hooks are looked up only when the
    program can call them (``hooks``: it has an FSM or a merge point)."""
    ctx: _Ctx = _new(_Ctx)
    ctx.s = s
    ctx.oracle = oracle
    ctx.rec = rec
    ctx.fsm_done = {}
    ctx.violations = []
    ctx.reticks = ()
    ctx.on_request = getattr(oracle, "request", None) if hooks else None
    ctx.on_merge = getattr(oracle, "merge", None) if hooks else None
    return ctx


def _step(state: Optional[tuple[int, ...]], status: int, events: Any, violations: list[Any]) -> Step:
    """``Step(state, status, events, violations)``, filled in without calling ``__init__``
    (once per tick)."""
    out: Step = _new(Step)
    out.state = state
    out.status = status
    out.events = events
    out.violations = violations
    return out


class _N:
    """Compile-time facts about one node."""

    __slots__ = ("node", "can_run", "flag", "mem", "mems", "keep", "stale", "kids", "parent", "tick", "halt",
                 "on_halt", "root", "node_site")

    def __init__(self, node: Node, parent: Optional[_N], root: str) -> None:
        self.node, self.parent, self.root = node, parent, root
        self.kids: list[_N] = []
        self.can_run = False
        # slots, None until the layout gives them (Any: the compiled closures index with them)
        self.flag: Any = None
        self.mem: Any = None
        self.keep: Any = None  # memory that a halt keeps
        self.stale: Any = None
        self.mems: tuple[int, ...] = ()  # per-child memory (Parallel under parallel_memory, ParallelAll)
        self.tick: Any = None  # Tick, once compiled
        self.halt: Any = None  # Halt, once compiled
        self.on_halt: Optional[Halt] = None
        self.node_site: Optional[Site] = None  # an Action's site

    def state_slots(self) -> tuple[int, ...]:
        """Every state slot this node owns: running flag, memories and an Action's run counter."""
        site = self.node_site
        timer = site.timer if site is not None else None
        return tuple(x for x in (self.flag, self.mem, self.keep, self.stale, *self.mems, timer) if x is not None)



#: a compiled node: ``tick(ctx) -> status`` (RUNNING, SUCCESS or FAILURE as ints)
Tick = Callable[["_Ctx"], int]
#: halting a node's subtree
Halt = Callable[["_Ctx"], None]
#: (running-flag slot, halt) pairs: the running ones are halted
Halts = tuple[tuple[int, Halt], ...]
#: ``finish(status, ctx) -> status``: a node's status recorded and its running flag kept
Finish = Callable[[int, "_Ctx"], int]
#: node type -> the function that compiles its tick rule: ``rule(program, NodeRule) -> Tick``
RULES: "dict[type[Node], Callable[[Program, NodeRule], Tick]]" = {}
#: node type -> ``slots(program, info)``: lays out the memory its rule keeps between ticks
SLOTS: "dict[type[Node], Callable[[Program, _N], None]]" = {}
#: node type -> ``can_run(program, info)``: whether it can return RUNNING (default: a child can)
CAN_RUN: "dict[type[Node], Callable[[Program, _N], bool]]" = {}
#: node type -> its part in merging in-tick answers (rule 'in-tick retries', ``Program._merge_points``):
#: "tells" (it tells the oracle where the rest of the tick depends on the state alone) or "keeps"
#: (once a child returns, it reads only the state, that child's status and its position); absent: neither
MERGE: "dict[type[Node], str]" = {}
#: node type -> ``wakes(node)``: whether the node can emit BehaviorTree.CPP's wake-up signal
#: (rule 'tickOnce', ``Program._wake_slot``); absent: it never does
WAKES: "dict[type[Node], Callable[[Any], bool]]" = {}
#: node type -> ``on_halt(program, info)``: what halting the node does instead of resetting its
#: memory (a function of the tick context, or None: nothing); absent: the memory reset
ON_HALT: "dict[type[Node], Callable[[Program, _N], Optional[Halt]]]" = {}


def rule(*types: "type[Node]", slots: "Optional[Callable[[Program, _N], None]]" = None,
         can_run: "Optional[Callable[[Program, _N], bool]]" = None, merge: str = "",
         wakes: "Optional[Callable[[Any], bool]]" = None,
         on_halt: "Optional[Callable[[Program, _N], Optional[Halt]]]" = None,
         ) -> "Callable[[Callable[[Program, NodeRule], Tick]], Callable[[Program, NodeRule], Tick]]":
    """Register the decorated function as the tick rule of the node ``types``: called once
    per node when a model compiles, it returns the node's tick function. ``slots`` lays
    out the node's memory (``program._slot(...)`` into ``info.mem``, ``info.keep``,
    ``info.mems``, ``info.stale``: a halt resets all but ``keep``); ``can_run`` says
    whether the node can return RUNNING when that is not just "a child can"; ``merge``
    its part in merging in-tick answers ("tells" or "keeps", ``MERGE``); ``wakes(node)``
    whether the node can emit BT.CPP's wake-up signal (``WAKES``); ``on_halt`` what a
    halt does instead of the memory reset (``ON_HALT``).
    docs/nodes.md shows a whole new node type."""
    def register(fn: "Callable[[Program, NodeRule], Tick]") -> "Callable[[Program, NodeRule], Tick]":
        for t in types:
            RULES[t] = fn
            if slots is not None:
                SLOTS[t] = slots
            if can_run is not None:
                CAN_RUN[t] = can_run
            if merge:
                MERGE[t] = merge
            if wakes is not None:
                WAKES[t] = wakes
            if on_halt is not None:
                ON_HALT[t] = on_halt
        return fn
    return register


class NodeRule:
    """What a node's rule is compiled from: ``node``; ``kids``, the tick functions of its
    children; ``finish(status, ctx)``, which every tick function returns through (it keeps
    the running flag and records the status; the hottest rules inline it, with ``evs``, the
    status events it records); ``where`` (``tree.NAME``); ``flag``, its running-flag slot
    or None; ``info``, the compile-time facts of the layout (memory slots, children's flags
    and halts)."""

    __slots__ = ("info", "node", "name", "where", "kids", "flag", "finish", "evs")

    def __init__(self, info: "_N") -> None:
        self.info = info
        self.node: Any = info.node  # of the type the rule is registered for
        self.name, self.where = info.node.name, f"tree.{info.node.name}"
        self.kids: "tuple[Tick, ...]" = tuple(k.tick for k in info.kids)
        self.flag: Any = info.flag  # int, or None for a node that never runs
        # the status events ``finish`` records, by status: preallocated, no tuple per tick (the
        # hottest rules inline ``finish`` with them)
        self.evs = evs = tuple(("status", self.name, st) for st in (RUNNING, SUCCESS, FAILURE))
        flag = info.flag

        def finish(st: int, ctx: "_Ctx") -> int:
            if flag is not None:
                ctx.s[flag] = 1 if st == RUNNING else 0
            if ctx.rec is not None:
                ctx.rec.append(evs[st])
            return st
        self.finish = finish

    def halts(self) -> Halts:
        """(flag, halt) of every child that can run."""
        return self.later_halts(-1)

    def later_halts(self, i: int) -> Halts:
        """(flag, halt) of the children after child ``i`` that can run."""
        return tuple((k.flag, k.halt) for k in self.info.kids[i + 1:] if k.can_run)


def _since_read(model: Any) -> set[str]:
    """The events whose ``since(E)`` an expression of ``model`` reads (a walk of its
    dataclasses: the FSMs, the trees, the requirements...)."""
    out: set[str] = set()
    stack: list[Any] = [model]
    seen: set[int] = set()
    while stack:
        x = stack.pop()
        if isinstance(x, Name):
            if x.id.startswith("since("):
                out.add(x.id[len("since("):-1])
        elif isinstance(x, (tuple, list)):
            stack.extend(x)
        elif isinstance(x, dict):
            stack.extend(x.values())
        elif hasattr(x, "__dataclass_fields__") and not isinstance(x, type) and id(x) not in seen:
            seen.add(id(x))
            stack.extend(getattr(x, f) for f in x.__dataclass_fields__)
    return out


class Program:
    """A model compiled for execution and exploration. Build it with ``model.program``."""

    def __init__(self, model: Any) -> None:
        self.model = model
        self.profile = profile(model.semantics)  # the rule switches (btfsm.profiles)
        self._initial: list[int] = []
        self.slots: list[SlotInfo] = []
        self.sites: list[Site] = []
        self.scope = Scope()
        for var in model.variables:
            self._slot(var.name, "var", var.hi - var.lo + 1, var.lo)
            self.scope[var.name] = Scope.of([var], len(self.slots) - 1)[var.name]
        self.since_slots: dict[str, int] = {}  # event -> its 'Event spacing' slot, laid out before the expressions that read it
        spaced = [(ev.name, interval_ticks(ev.min_interval, model.tick_rate)) for ev in model.environment
                  if getattr(ev, "min_interval", None)]
        read = _since_read(model) if any(wait > 1 for _, wait in spaced) else ()
        for name, wait in spaced:
            if wait > 1 and name in read:
                self.since_slots[name] = self._since_slot(name, wait)
        self.prims = model.all_primitives()
        self._fsm_timers: dict[str, int] = {}  # FSM name -> the slot counting its state's run (rule 'Durations')
        self._layout_fsms()
        self._layout_nodes()
        self.wake: Any = self._wake_slot()
        self.merge_points = self._merge_points()
        self.exclusive = self._exclusive_groups()
        self._crowded_fn = self._crowded()
        self._compile_fsms()
        timers: list[tuple[int, int, int]] = []  # (event index, slot, ticks) of events with a minimum interval
        self.env_timers: Any = timers
        self.env = [self._compile_env(i, ev) for i, ev in enumerate(model.environment)]
        self.env_timers = {i: (slot, wait) for i, slot, wait in self.env_timers}
        # what environment_phase reads of each entry, in one flat row: (index, name, guard,
        # effects, options, (timer slot, wait) or None)
        self._env_rows = tuple((i, *entry, self.env_timers.get(i)) for i, entry in enumerate(self.env))
        self.root: Any = self.nodes[model.tree.name].tick if model.tree is not None else None
        self.invariants = [(name, compile_fn(e, self.scope, f"invariants.{name}", BOOL)) for name, e in model.invariants]
        self._check_responses()
        self.workable = self._predicate(model.workable, "workable")
        self.terminal = self._predicate(model.terminal, "terminal") if model.terminal is not None else None
        self.initial = tuple(self._initial)
        self.width = len(self.slots)
        self._hooks = bool(self.fsm_info or self.merge_points)  # _Ctx: whether the oracle's hooks can be called

    # ------------------------------------------------------------------ layout
    def _slot(self, name: str, kind: str, size: int, lo: int = 0, init: int = 0) -> int:
        self.slots.append(SlotInfo(name, kind, size, lo))
        if kind == "var":
            init = self.model.var(name).init_code
        self._initial.append(init)
        return len(self.slots) - 1

    def _since_slot(self, event: str, wait: int) -> int:
        """The slot of rule 'Event spacing' (ticks since ``event`` happened, saturated at
        ``wait``, its initial value), readable as ``since(event)`` (docs/semantics.md 7)."""
        slot = self._slot(f"{event}:since", "timer", wait + 1, 0, wait)
        self.scope[f"since({event})"] = Slot(slot, INT, 0, wait, writable=False)
        return slot

    def _layout_fsms(self) -> None:
        self.fsm_index = {}
        self.fsm_info = []
        for fi, f in enumerate(self.model.fsms):
            ids = tuple(st.id for st in f.states)
            tok = self._slot(f"{f.name}.state", "token", len(ids), 0, ids.index(f.initial))
            goal = self._slot(f"{f.name}.goal", "goal", len(f.goals) + 1)
            self.scope[f"{f.name}.state"] = Slot(tok, Type("enum", ids), 0, len(ids) - 1, writable=False)
            self.scope[f"{f.name}.goal"] = Slot(goal, Type("enum", ("none",) + f.goals), 0, len(f.goals), writable=False)
            pslots = []
            for p in f.params:
                ps = self._slot(f"{f.name}.{p.name}", "param", p.hi - p.lo + 1, p.lo, p.init_code)
                self.scope[f"{f.name}.{p.name}"] = Slot(ps, Type(p.kind, p.values) if p.kind == "enum" else Type(p.kind), p.lo, p.hi, writable=False)
                pslots.append(ps)
            self.fsm_index[f.name] = fi
            self.fsm_info.append((f, ids, tok, goal, tuple(pslots)))

    def fsm_scope(self, f: Any) -> Scope:
        """World scope plus the FSM's parameters by their bare names."""
        scope = Scope(self.scope)
        for p in f.params:
            if p.name in self.scope:
                raise ModelError(f"fsms.{f.name}.params.{p.name}", f"parameter '{p.name}' hides a variable")
            scope[p.name] = self.scope[f"{f.name}.{p.name}"]
        return scope

    def _layout_nodes(self) -> None:
        self.nodes: dict[str, _N] = {}
        for path, root in self.model.roots():
            self._collect(root, None, root.name)
        for info in reversed(list(self.nodes.values())):  # children before parents
            check_bounds(info.node)  # fields below their declared bound (Retry's attempts...)
            info.can_run = self._can_run(info)
        for info in self.nodes.values():
            n = info.node
            if info.can_run:
                info.flag = self._slot(f"{n.name}:running", "flag", 2)
            slots = SLOTS.get(type(n))
            if slots is not None:  # the memory the type's rule keeps between ticks
                slots(self, info)

    def _wake_slot(self) -> Optional[int]:
        """Rule 'tickOnce' (docs/semantics.md 8.1): under ``loop_wake_up`` with
        ``Model.tick == "once"``, a slot holding BT.CPP's pending wake-up signal, when a
        node of the tree can emit one (its type's ``wakes``, ``rule``: Retry/Repeat with a
        bound above 1, a SequenceWithMemory of several children); else None."""
        if not self.profile.loop_wake_up or self.model.tick != "once" or self.model.tree is None:
            return None
        for info in self.nodes.values():
            if info.root != self.model.tree.name:
                continue
            wakes = WAKES.get(type(info.node))
            if wakes is not None and wakes(info.node):
                return self._slot("tick:wake-up", "memory", 2)
        return None

    def _collect(self, node: Node, parent: Optional[_N], root: str) -> None:
        info = _N(node, parent, root)
        self.nodes[node.name] = info
        if parent is not None:
            parent.kids.append(info)
        for child in node.children_of():
            self._collect(child, info, root)

    def _can_run(self, info: _N) -> bool:
        """Whether the node can return RUNNING (it then has a running flag): its type's
        ``can_run`` (``rule``), else whether a child can (a Parallel of instant children
        decides every tick: like every other composite it runs only through a child)."""
        can_run = CAN_RUN.get(type(info.node))
        return can_run(self, info) if can_run is not None else any(k.can_run for k in info.kids)

    # ------------------------------------------------------------------ helpers
    def _predicate(self, expr: Any, where: str) -> Callable[[Any], bool]:
        if expr is None:  # default workable: every FSM token on its initial state
            pairs = [(tok, ids.index(f.initial)) for f, ids, tok, _, _ in self.fsm_info]
            return lambda s: all(s[t] == v for t, v in pairs)
        fn: Callable[[Any], bool] = compile_fn(expr, self.scope, where, BOOL)
        return fn

    def _compile_env(self, i: int, ev: Any, where: Optional[str] = None, option: bool = False) -> tuple[Any, ...]:
        """(name, guard, effects, options): options is None for an event, else a tuple
        of compiled options for a choice."""
        where = where or f"environment.{ev.name}"
        options = getattr(ev, "options", None)
        if options is not None:
            opts = tuple(self._compile_env(i, o, f"{where}.options.{o.name}", True) for o in options)
            return (ev.name, None, None, opts)
        guard = compile_fn(ev.guard, self.scope, f"{where}.guard", BOOL) if ev.guard is not None else None
        wait = interval_ticks(ev.min_interval, self.model.tick_rate) if getattr(ev, "min_interval", None) else 0
        if wait > 1 and option:
            raise ModelError(f"{where}.min_interval", "an option of an environment choice cannot have a minimum interval")
        for x in (ev.guard, *(value for _, value in ev.effects)):
            if any(n.startswith("since(") for n in names_in(x)):  # its value would depend on the entries' order
                raise ModelError(where, "since() cannot be read by an environment entry (docs/semantics.md 7)")
        if wait > 1:  # rule 'Event spacing' (section 6.1): ticks since it happened, saturated at wait
            slot = self.since_slots.get(ev.name)
            self.env_timers.append((i, self._since_slot(ev.name, wait) if slot is None else slot, wait))
        return (ev.name, guard, compile_effects(ev.effects, self.scope, f"{where}.effects"), None)

    def _check_responses(self) -> None:
        """The requirements' expressions compile and their trigger events exist (property
        'response' evaluates them over the explored states)."""
        events = {e.name for e in self.model.environment} | {
            o.name for e in self.model.environment for o in (getattr(e, "options", None) or ())}
        for r in self.model.responses:
            where = f"responses.{r.name}"
            if r.trigger_event is None:
                compile_fn(r.trigger, self.scope, f"{where}.trigger", BOOL)
            elif r.trigger_event not in events:
                raise ModelError(f"{where}.trigger", f"no environment event or option '{r.trigger_event}'")
            compile_fn(r.response, self.scope, f"{where}.response", BOOL)

    def _site(self, kind: str, node: Optional[str], fsm: Optional[str], state: Optional[str], primitive: str,
              args: Any, where: str, duration: Any = None) -> Site:
        prim = self.prims.get(primitive)
        if prim is None:
            raise ModelError(where, f"unknown primitive '{primitive}'")
        outs = tuple((int(o.status), compile_effects(o.effects, self.scope, f"{where}.outcomes.{o.name}"), o.name)
                     for o in prim.outcomes)
        site = Site(kind, node, fsm, state, primitive, dict(args), outs, len(self.sites))
        duration = duration or prim.duration
        if duration is not None:
            self._time_site(site, duration, where)
        self.sites.append(site)
        return site

    def _time_site(self, site: Site, duration: Any, where: str) -> None:
        """Rule 'Durations' (docs/semantics.md section 6.1): a run may end (answer a
        non-RUNNING outcome) on its k-th tick of running only when lo <= k <= hi. A counter
        slot holds the RUNNING answers so far, saturated where no bound needs more."""
        lo, hi = duration_ticks(duration, self.model.tick_rate)
        statuses = {o[0] for o in site.outcomes}
        if lo > 1 and RUNNING not in statuses:
            raise ModelError(f"{where}.duration", f"primitive '{site.primitive}' takes at least {duration[0]:g} s "
                                                  "but has no RUNNING outcome")
        if hi is not None and statuses == {RUNNING}:
            raise ModelError(f"{where}.duration", f"primitive '{site.primitive}' must end within {duration[1]:g} s "
                                                  "but has only RUNNING outcomes")
        if lo == 1 and hi is None:
            return  # [0, unbounded): no restriction
        site.ticks = (lo, hi)
        cap = (hi if hi is not None else lo) - 1
        if cap <= 0:
            return
        if site.kind != "state":
            site.timer = self._slot(f"{site.label}:ran", "timer", cap + 1)
            return
        # one counter per FSM: only the token's state runs, and leaving a state resets it
        fsm = str(site.fsm)
        slot = self._fsm_timers.get(fsm)
        if slot is None:
            slot = self._fsm_timers[fsm] = self._slot(f"{fsm}:ran", "timer", cap + 1)
        elif self.slots[slot].size < cap + 1:
            self.slots[slot] = SlotInfo(f"{site.fsm}:ran", "timer", cap + 1)
        site.timer = slot

    def _halt_fn(self, info: _N) -> Halt:
        """halt(ctx): halt every running node of ``info``'s subtree, children first."""
        found: list[tuple[int, Optional[Halt], str]] = []

        def post(i: _N) -> None:
            for k in i.kids:
                post(k)
            if i.can_run:
                found.append((i.flag, i.on_halt, i.node.name))
        post(info)
        items = tuple(found)

        def halt(ctx: _Ctx) -> None:
            s = ctx.s
            for flag, on_halt, name in items:
                if s[flag]:
                    s[flag] = 0
                    if on_halt is not None:
                        on_halt(ctx)
                    if ctx.rec is not None:
                        ctx.rec.append(("halt", name))
        return halt

    # ------------------------------------------------------------------ FSMs
    def _compile_fsms(self) -> None:
        self.fsm_rows = []  # per FSM: rows[state][goal]
        # node on_halt/tick closures need FSM ticks, and FSM states may run subtrees,
        # so compile subtrees first (their closures only look FSM ticks up at run time)
        for info in self.nodes.values():
            info.halt = None
        for info in self.nodes.values():
            self._prepare_on_halt(info)
        for info in self.nodes.values():
            info.halt = self._halt_fn(info)
        for info in reversed(list(self.nodes.values())):
            info.tick = self._compile_node(info)
        self._lint_reactive_sequences()
        for fi, (f, ids, tok, goal, pslots) in enumerate(self.fsm_info):
            self.fsm_rows.append(self._compile_fsm(fi, f, ids))
        self.fsm_ticks = [self._fsm_tick_fn(fi) for fi in range(len(self.fsm_info))]

    def _compile_fsm(self, fi: int, f: Any, ids: tuple[str, ...]) -> list[Any]:
        scope = self.fsm_scope(f)
        where = f"fsms.{f.name}"
        index = {sid: k for k, sid in enumerate(ids)}
        rows = []
        for st in f.states:
            runner, leave = self._state_runner(f, st, f"{where}.states.{st.id}")
            row_for_goal = []
            for g in f.goals:
                dedges: list[Any] = []
                dmarkers: list[Any] = []
                edges: tuple[list[Any], list[Any], list[Any]] = ([], [], [])
                markers: tuple[list[Any], list[Any], list[Any]] = ([], [], [])
                applicable = False
                for e in f.edges_from(st.id, g):  # in declaration order, indexed by source once
                    applicable = True
                    ew = f"{where}.edges.{e.id}"
                    guard = compile_fn(e.guard, scope, f"{ew}.guard", BOOL) if e.guard is not None else None
                    item = (guard, index[e.target], compile_effects(e.effects, self.scope, f"{ew}.effects"), e.id)
                    (dedges if e.direct else edges[int(e.on)]).append(item)
                for m in f.markers_at(st.id, g):
                    applicable = True
                    guard = compile_fn(m.guard, scope, f"{where}.markers.{m.id}.guard", BOOL) if m.guard is not None else None
                    mitem = (guard, int(m.outcome), m.id)
                    (dmarkers if m.direct else markers[int(m.on)]).append(mitem)
                row_for_goal.append((tuple(dedges), tuple(dmarkers), applicable,
                                     tuple(map(tuple, edges)), tuple(map(tuple, markers)), runner, leave))
            rows.append(row_for_goal)
        return rows

    def _state_runner(self, f: Any, st: Any, where: str) -> Any:
        """(run(ctx) -> status, leave(ctx)) for one FSM state."""
        if st.subtree is not None:
            info = self.nodes[st.subtree.name]
            tick, halt, flag = info.tick, info.halt, info.flag

            def leave(ctx: _Ctx) -> None:
                if flag is not None and ctx.s[flag]:
                    halt(ctx)
            return tick, leave
        prim = st.primitive or (st.id if st.outcomes is not None else "pass")
        site = self._site("state", None, f.name, st.id, prim, st.args, where, st.duration)
        return self._primitive_runner(site), _site_halt(site)

    def _primitive_runner(self, site: Site) -> Tick:
        outs = site.outcomes
        evs = tuple(("outcome", site.label, o[2]) for o in outs)
        if site.ticks is not None:
            return self._timed_runner(site, evs)

        def run(ctx: _Ctx) -> int:
            k = ctx.oracle.outcome(site)
            status: int
            status, eff, _ = outs[k]
            if eff is not None:
                eff(ctx.s)
            if ctx.rec is not None:
                ctx.rec.append(evs[k])
                if eff is not None:
                    _record_writes(ctx, eff)
            return status
        return run

    def _timed_runner(self, site: Site, evs: Any) -> Tick:
        """A primitive run under rule 'Durations': the answer must fit the run's tick count."""
        outs, (lo, hi), timer = site.outcomes, site.ticks, site.timer
        cap = (hi if hi is not None else lo) - 1
        rate = self.model.tick_rate

        def run(ctx: _Ctx) -> int:
            s = ctx.s
            done = s[timer] if timer is not None else 0  # RUNNING answers so far (saturated at cap)
            k = ctx.oracle.outcome(site)
            status: int
            status, eff, name = outs[k]
            if status == RUNNING:
                if hi is not None and done >= hi - 1:
                    raise _Late(site, f"{site.label}: outcome '{name}' (RUNNING) on tick {hi} of the run; "
                                      f"it must end by then ({(hi - 1) / rate:g} s)")
                if timer is not None and done < cap:
                    s[timer] = done + 1
            else:
                if done < lo - 1:
                    raise _Late(site, f"{site.label}: outcome '{name}' on tick {done + 1} of the run; it may end "
                                      f"from tick {lo} ({(lo - 1) / rate:g} s) on")
                if timer is not None:
                    s[timer] = 0
            if eff is not None:
                eff(s)
            if ctx.rec is not None:
                ctx.rec.append(evs[k])
                if eff is not None:
                    _record_writes(ctx, eff)
            return status
        return run

    def _fsm_tick_fn(self, fi: int) -> Any:
        f, ids, tok, goal_slot, pslots = self.fsm_info[fi]
        rows = self.fsm_rows[fi]
        name = f.name
        withdraw = f.goals.index(f.withdraw_goal) if f.retarget == "withdraw" else None
        bound = len(ids)
        restart = self.profile.restart_in_tick

        def move(ctx: _Ctx, row: Any, target: int, eff: Any, eid: str) -> None:
            row[6](ctx)  # leave the source state
            s = ctx.s
            s[tok] = target
            if eff is not None:
                eff(s)
            if ctx.rec is not None:
                ctx.rec.append(("fire", name, eid))
                if eff is not None:
                    _record_writes(ctx, eff)

        def drive(ctx: _Ctx, g: int) -> int:
            """FSM tick rule (docs/semantics.md, 'FSM tick'), steps 1-6."""
            s = ctx.s
            if ctx.on_request is not None:
                ctx.on_request(fi, g)
            row = rows[s[tok]][g]
            for _ in range(bound + 1):  # 1. direct edges first (a chain is bounded)
                for guard, target, eff, eid in row[0]:
                    if guard is None or guard(s):
                        move(ctx, row, target, eff, eid)
                        row = rows[target][g]
                        break
                else:
                    break
            else:
                raise RuntimeError(f"{name}: direct-edge chain longer than {bound}")
            outcome: int
            for guard, outcome, mid in row[1]:  # 2. direct markers
                if guard is None or guard(s):
                    if ctx.rec is not None:
                        ctx.rec.append(("fire", name, mid))
                    return outcome
            if not row[2]:  # 3. goal not applicable here
                if ctx.rec is not None:
                    ctx.rec.append(("not-applicable", name, ids[s[tok]]))
                return FAILURE
            st = row[5](ctx)  # 4. run the state once
            reply = RUNNING
            for guard, outcome, mid in row[4][st]:  # 5. marker on that status
                if guard is None or guard(s):
                    reply = outcome
                    if ctx.rec is not None:
                        ctx.rec.append(("fire", name, mid))
                    break
            for guard, target, eff, eid in row[3][st]:  # 6. edge on that status
                if guard is None or guard(s):
                    move(ctx, row, target, eff, eid)
                    break
            return reply

        def tick(ctx: _Ctx, g: int, pvals: tuple[int, ...], requester: str, starting: bool = True) -> int:
            """Rules 'Requests, goals and parameters' (docs/semantics.md section 5):
            once per request, share, hand-over, conflict."""
            done = ctx.fsm_done.get(fi)
            if done is not None:  # the FSM already stepped in this BT tick
                if restart and done[2] == requester and starting and done[1] != RUNNING:
                    pass  # the request finished and starts again in this tick (profile switch restart_in_tick)
                elif done[2] == requester or (done[0] == g and done[3] == pvals):
                    return done[1]  # the same request again, or an identical one: share the reply
                if not starting or done[1] == RUNNING:
                    # two requests use the FSM in one tick: a conflict (reported by 'contracts')
                    ctx.violations.append(("busy", requester, name))
                    if ctx.rec is not None:
                        ctx.rec.append(("busy", name, requester))
                    return FAILURE
                # hand-over: the previous requester let go (SUCCESS/FAILURE) in this tick
                # and this request starts: the FSM steps again, for it
                if ctx.rec is not None:
                    ctx.rec.append(("handover", name, requester))
            s = ctx.s
            if pslots and tuple(s[p] for p in pslots) != pvals:
                if withdraw is None:
                    for p, val in zip(pslots, pvals):
                        s[p] = val
                    result = drive(ctx, g)
                else:  # the original protocol: withdraw first, adopt on success
                    if drive(ctx, withdraw) == SUCCESS:
                        for p, val in zip(pslots, pvals):
                            s[p] = val
                    result = RUNNING
            else:
                result = drive(ctx, g)
            s[goal_slot] = g + 1 if result == RUNNING else 0
            ctx.fsm_done[fi] = (g, result, requester, pvals)
            return result

        def withdraw_goal(ctx: _Ctx, requester: str) -> None:
            done = ctx.fsm_done.get(fi)
            if done is not None and done[2] != requester:
                return  # another request drove the FSM this tick
            s = ctx.s
            if s[goal_slot]:
                s[goal_slot] = 0
                rows[s[tok]][0][6](ctx)  # abandon the current state's run
                if ctx.rec is not None:
                    ctx.rec.append(("withdraw", name, requester))

        tick.withdraw = withdraw_goal  # type: ignore[attr-defined]
        return tick

    # ------------------------------------------------------------------ nodes
    def _prepare_on_halt(self, info: _N) -> None:
        """What halting the node does: its type's ``on_halt`` (``rule``), else resetting
        the memory its rule keeps (all but ``keep``)."""
        own = ON_HALT.get(type(info.node))
        if own is not None:
            info.on_halt = own(self, info)
        elif info.mem is not None or info.mems or info.stale is not None:
            resets = tuple(x for x in (info.mem, *info.mems, info.stale) if x is not None)

            def on_halt(ctx: _Ctx) -> None:
                s = ctx.s
                for x in resets:
                    s[x] = 0
            info.on_halt = on_halt

    def _compile_node(self, info: _N) -> Tick:
        """The tick function of one node: its type's rule (``RULES``, one function per row
        of docs/semantics.md sections 2 and 3) compiled with what the layout gave it."""
        n = info.node
        check_arity(n)
        try:
            compile_rule = RULES[type(n)]
        except KeyError:
            raise ModelError(f"tree.{n.name}", f"unknown node type {type(n).__name__}") from None
        return compile_rule(self, NodeRule(info))

    def _merge_points(self) -> frozenset[str]:
        """The nodes that tell the oracle (``oracle.merge``, rule 'in-tick retries',
        docs/semantics.md 8.3) where the rest of the tick depends on nothing but the tick's
        state list, its violations, FSM records and tickOnce re-ticks so far: a
        RecoveryNode where a retry starts within the tick, and the sequences and fallbacks
        before each child after the first. Only when the main tree has a RecoveryNode that
        can retry, and only nodes of the main tree whose ancestors, once a child returns,
        read nothing but the state, the child's status and its position (no count of
        earlier children's results, as a Parallel keeps). Empty for every other model."""
        if self.model.tree is None:
            return frozenset()
        main = self.model.tree.name
        clean: dict[str, bool] = {}
        for info in self.nodes.values():  # parents before children
            p = info.parent
            clean[info.node.name] = info.root == main and (p is None or (
                clean[p.node.name] and type(p.node) in MERGE))
        if not any(isinstance(i.node, RecoveryNode) and i.node.retries > 0 and clean[i.node.name]
                   for i in self.nodes.values()):
            return frozenset()
        return frozenset(name for name, ok in clean.items() if ok and MERGE.get(type(self.nodes[name].node)) == "tells")

    def _signal(self, info: _N) -> Optional[int]:
        """The wake-up slot a loop node of the main tree sets (rule 'tickOnce'), or None
        (``tick: exactly-once``, or a subtree an FSM state runs: its FSM steps once a tick)."""
        return self.wake if info.root == (self.model.tree.name if self.model.tree is not None else None) else None

    def _parallel_memory(self, info: _N, kids: tuple[Tick, ...], need: int, fail_at: int, halts: Halts,
                         finish: Finish) -> Tick:
        """BehaviorTree.CPP's Parallel (profile switch ``parallel_memory``): finished children
        are not ticked again; after each child, success then failure is checked."""
        count, mems = len(kids), info.mems
        pairs = tuple(zip(kids, mems))

        def done(ctx: _Ctx, st: int) -> int:
            s = ctx.s
            for m in mems:
                s[m] = 0
            _halt_running(ctx, halts)
            return finish(st, ctx)

        def tick(ctx: _Ctx) -> int:
            s = ctx.s
            ok = bad = 0
            for m in mems:
                if s[m] == SUCCESS:
                    ok += 1
                elif s[m] == FAILURE:
                    bad += 1
            for child, m in pairs:
                if not s[m]:
                    st = child(ctx)
                    if st == SUCCESS:
                        s[m] = st
                        ok += 1
                    elif st == FAILURE:
                        s[m] = st
                        bad += 1
                if ok >= need:
                    return done(ctx, SUCCESS)
                if count - bad < need or bad == fail_at:  # BT.CPP's ==: a threshold of 0 holds until a failure
                    return done(ctx, FAILURE)
            return finish(RUNNING, ctx)
        return tick

    def _compile_parallel(self, info: _N, kids: tuple[Tick, ...], finish: Finish, where: str) -> Tick:
        """Rules 'Parallel' (docs/semantics.md section 2) and, per profile, 'parallel
        failure first', 'parallel synchronise', 'parallel selected' (section 8)."""
        n: Any = info.node
        count = len(kids)
        names = [k.node.name for k in info.kids]
        if n.selected:
            bad_names = [x for x in n.selected if x not in names]
            if bad_names or len(set(n.selected)) != len(n.selected):
                raise ModelError(f"{where}.selected", f"must name distinct children of the parallel, got {', '.join(map(repr, n.selected))}")
            if n.success_threshold is not None:
                raise ModelError(f"{where}.selected", "a parallel has either a success_threshold or selected children, not both")
            eligible = tuple(x in n.selected for x in names)
            need = len(n.selected)
        else:
            eligible = (True,) * count
            need = count if n.success_threshold is None else _threshold(n.success_threshold, count)
        fail_at, pool = _threshold(n.failure_threshold, count), sum(eligible)
        if not 1 <= need <= count or fail_at < 1:
            raise ModelError(where, f"thresholds must satisfy 1 <= success <= {count} and failure >= 1")
        halts = tuple((k.flag, k.halt) for k in info.kids if k.can_run)
        failure_first = self.profile.parallel_failure_first
        done = info.mems or (None,) * count
        items = tuple(zip(kids, eligible, done))

        def tick(ctx: _Ctx) -> int:
            s = ctx.s
            ok = bad = lost = 0  # successes that count, failures, failures that count
            for child, counts, d in items:
                if d is not None and s[d]:  # synchronised: succeeded earlier, not ticked
                    ok += counts
                    continue
                st = child(ctx)
                if st == SUCCESS:
                    ok += counts
                    if d is not None:
                        s[d] = 1
                elif st == FAILURE:
                    bad += 1
                    lost += counts
            won = ok >= need
            failed = bad >= fail_at or lost > pool - need
            if won and not (failure_first and failed):
                st = SUCCESS
            elif failed:
                st = FAILURE
            else:
                return finish(RUNNING, ctx)
            _halt_running(ctx, halts)
            for d in info.mems:
                s[d] = 0
            return finish(st, ctx)
        return tick

    def _conflicts(self, info: _N) -> Halts:
        """Halt-before-start: branches to halt before this leaf starts (rule 'halt order')."""
        if not info.can_run or not self.profile.halt_before_start:
            return ()
        out, seen = [], set()
        for other in self.nodes.values():
            if other is info or other.root != info.root or not other.can_run or other.kids:
                continue
            lca, branch = _lca(info, other)
            if isinstance(lca.node, (Parallel, ParallelAll, PipelineSequence)) or branch.name in seen:
                continue
            seen.add(branch.name)
            b = self.nodes[branch.name]
            out.append((b.flag, b.halt))
        return tuple(out)

    def _rivals(self, info: _N) -> tuple[Any, ...]:
        """Rule 'Exclusive resources': for each running leaf that shares a resource with
        ``info``'s leaf, the (flag, violation, event) to report when this leaf starts
        while that one runs."""
        me, out = info.node.name, []
        for res, members in self.model.resources:
            if me in members:
                for m in members:
                    other = self.nodes[m]
                    if m != me and other.flag is not None:
                        out.append((other.flag, ("exclusive", res, me, m, "start"),
                                    ("violation", me, f"exclusive {res}: starts while {m} runs")))
        return tuple(out)

    def _exclusive_groups(self) -> tuple[Any, ...]:
        """Per resource with two leaves that can run: ((flag, name), ...) checked at the end
        of every tick (rule 'Exclusive resources')."""
        out = []
        for res, members in self.model.resources:
            flags = tuple((self.nodes[m].flag, m) for m in members if self.nodes[m].flag is not None)
            if len(flags) > 1:
                out.append((res, flags))
        return tuple(out)

    def _crowded(self) -> Optional[Callable[[Any], bool]]:
        """The end-of-tick test of rule 'Exclusive resources' as one compiled expression:
        does some resource have running flags that sum above 1 (two of its leaves run)?
        None without such a resource. Only when it holds does ``_exclusive_end`` look which
        leaves: one call a tick instead of a loop over flags."""
        if not self.exclusive:
            return None
        return self._flags_above([tuple(flag for flag, _ in flags) for _, flags in self.exclusive], 1)

    def _flags_above(self, groups: "list[tuple[int, ...]]", bound: int) -> Callable[[Any], bool]:
        """``f(state)``: whether the running flags of some group (slots) sum above ``bound``,
        compiled into one expression (a flag holds 0 or 1)."""
        scope, tests = Scope(), []
        for flags in groups:
            terms: list[Expr] = []
            for flag in flags:
                scope[self.slots[flag].name] = Slot(flag, INT, 0, 1)
                terms.append(Name(self.slots[flag].name))
            while len(terms) > 1:  # a balanced sum: nested no deeper than log2 of the flags
                terms = [BinOp("+", *terms[i:i + 2]) if i + 1 < len(terms) else terms[i]
                         for i in range(0, len(terms), 2)]
            tests.append(Compare(">", terms[0], Const(bound)))
        fn: Callable[[Any], bool] = compile_fn(flat("or", *tests), scope, "resources", BOOL)
        return fn

    def _lint_reactive_sequences(self) -> None:
        self.lints = []
        for info in self.nodes.values():
            if isinstance(info.node, ReactiveSequence):
                running = [k.node.name for k in info.kids if k.can_run]
                if len(running) > 1:
                    # in the profile's own node names (BehaviorTree.CPP's, py_trees')
                    what = "reactive sequence" if self.profile.name == "btfsm" else \
                        self.profile.node_name("ReactiveSequence")
                    self.lints.append((f"tree.{info.node.name}", f"{what} with several children that can run ({', '.join(running)}): an earlier one restarts each tick and halts the later ones; use {self.profile.node_name('MemorySequence')}"))

    # ------------------------------------------------------------------ running
    def step(self, state: Any, oracle: Any, record: "bool | list[Any]" = False) -> Step:
        """One BT tick: environment events, then the tree. Pure in ``state``. ``record``:
        collect the trace events (``Step.events``); a list given here receives them as they
        happen, so an oracle holding it can see the tick so far."""
        ctx = _context(list(state), oracle,
                   None if record is False else record if isinstance(record, list) else ([] if record else None),
                   self._hooks)
        s = ctx.s
        blocked = self.environment_phase(s, oracle, ctx.rec)
        if blocked is not None:
            return _step(None, FAILURE, ctx.rec, [("blocked", blocked)])
        root, wake, crowded = self.root, self.wake, self._crowded_fn
        try:
            status = root(ctx) if root is not None else SUCCESS
            if wake is not None and status == RUNNING and s[wake]:
                status = self._reticks(ctx, status)
        except _Late as late:
            return _step(None, FAILURE, ctx.rec, [("timing", late.site.label, late.text)])
        if crowded is not None and crowded(s):  # two leaves of a resource run: which ones
            _exclusive_end(ctx, self.exclusive)
        return _step(tuple(s), status, ctx.rec, ctx.violations)

    def _reticks(self, ctx: _Ctx, status: int) -> int:
        """Rule 'tickOnce' (docs/semantics.md 8.1): BT.CPP's ``tickOnce()`` ticks the root
        again while it returns RUNNING and a wake-up signal is pending (each tick takes the
        signal). Each re-tick is a BT tick of its own (an FSM may step again). When the
        state before a re-tick repeats, the oracle can answer as it did before, so the
        loop can go on for ever: the violation ``("tick-loop", root)`` ends the tick (the
        state is the repeated one; property ``contracts`` reports it)."""
        s, wake = ctx.s, self.wake
        seen: list[list[int]] = []
        while status == RUNNING and s[wake]:
            s[wake] = 0
            if s in seen:
                name = self.model.tree.name
                ctx.violations.append(("tick-loop", name))
                if ctx.rec is not None:
                    ctx.rec.append(("violation", name, f"tickOnce never returns: re-tick {len(seen) + 1} "
                                                       "starts from the state of an earlier one"))
                return RUNNING
            seen.append(list(s))
            ctx.reticks += (tuple(s),)
            ctx.fsm_done = {}
            if ctx.rec is not None:
                ctx.rec.append(("wake-up", self.model.tree.name))
            status = self.root(ctx)
        return status

    def without_environment(self) -> "Program":
        """The program of this model's tick without its environment phase (tick step 1),
        with the same slots (the 'Event spacing' counters that ``since(E)`` reads too): what
        the exploration engines step after they applied the environment themselves (the
        same model compiled again: its layout is this one's, whatever reads ``since(E)``)."""
        prog = Program(self.model)
        prog.env, prog.env_timers, prog._env_rows = [], {}, ()
        return prog

    def environment_phase(self, s: list[int], oracle: Any, rec: Optional[list[Any]] = None,
                          indices: Any = None) -> "str | None":
        """Tick step 1 (docs/semantics.md section 1): the environment entries (those at
        ``indices`` when given) change the state list ``s`` in place, asking ``oracle``;
        ``rec`` collects env and write events. Returns the name of a choice with no enabled
        option (the tick cannot happen), else None."""
        rows = self._env_rows
        name: str
        for i, name, guard, eff, options, timer in (rows if indices is None else [rows[i] for i in indices]):
            if options is not None:  # a choice: exactly one enabled option
                enabled = [k for k, o in enumerate(options) if o[1] is None or o[1](s)]
                if not enabled:
                    return name
                name, _, eff, _ = options[enabled[oracle.choose(i, enabled)]]
            elif timer is not None:  # rule 'Event spacing': enabled once `wait` ticks have passed
                slot, wait = timer
                since = s[slot]
                if since < wait:
                    since = s[slot] = since + 1
                if not (since >= wait and (guard is None or guard(s)) and oracle.env(i)):
                    continue
                s[slot] = 0
            elif not ((guard is None or guard(s)) and oracle.env(i)):
                continue
            if eff is not None:
                eff(s)
            if rec is not None:
                rec.append(("env", name))
                if eff is not None:
                    rec.extend(("write", k, s[k]) for k in eff.targets)
        return None

    def fsm_step(self, state: Any, fsm: "str | int", goal: "str | int", params: Any, oracle: Any,
                 record: bool = False) -> Step:
        """One tick of one FSM requested from outside a tree (the FSM-level open system)."""
        fi = self.fsm_index[fsm] if isinstance(fsm, str) else fsm
        f = self.fsm_info[fi][0]
        g = f.goals.index(goal) if isinstance(goal, str) else goal
        ctx = _context(list(state), oracle, [] if record else None)
        try:
            status = self.fsm_ticks[fi](ctx, g, tuple(params), "<request>")
        except _Late as late:
            return _step(None, FAILURE, ctx.rec, [("timing", late.site.label, late.text)])
        return _step(tuple(ctx.s), status, ctx.rec, ctx.violations)

    def decode(self, state: Any) -> dict[str, Any]:
        """Readable values of a state: variables, FSM states/goals/params, node memory."""
        return {info.name: self.decode_slot(i, val) for i, (info, val) in enumerate(zip(self.slots, state))}

    def decode_slot(self, index: int, value: int) -> Any:
        """The readable value of one slot."""
        info = self.slots[index]
        if info.kind == "var":
            return self.model.var(info.name).decode(value)
        slot = self.scope.get(info.name)
        if slot is not None and slot.type.kind == "enum":
            return slot.type.values[value]
        return bool(value) if slot is not None and slot.type == BOOL else value

    def encode(self, values: dict[str, Any]) -> tuple[int, ...]:
        """The state tuple of readable values (as ``decode`` gives them); slots missing
        from ``values`` keep their initial value."""
        out = list(self.initial)
        for i, info in enumerate(self.slots):
            if info.name not in values:
                continue
            val = values[info.name]
            if info.kind == "var":
                out[i] = self.model.var(info.name).encode(val)
                continue
            slot = self.scope.get(info.name)
            if slot is not None and slot.type.kind == "enum":
                out[i] = slot.type.values.index(val)
            else:
                out[i] = int(val)
        return tuple(out)

    def fsm_state(self, state: Any, fsm: str) -> tuple[Any, ...]:
        """(state id, held goal or None) of an FSM."""
        f, ids, tok, goal, _ = self.fsm_info[self.fsm_index[fsm]]
        return ids[state[tok]], (f.goals[state[goal] - 1] if state[goal] else None)


def _stateful(info: _N) -> bool:
    """A leaf that keeps a status between ticks in BehaviorTree.CPP (a StatefulActionNode).
    Only a leaf: every decorator, SubTree included, resets its child's status when the
    child finishes (BT.CPP's ``DecoratorNode::executeTick`` and ``SubTreeNode::tick``)."""
    return isinstance(info.node, SkillRequest) or (isinstance(info.node, Action) and info.can_run)


def _condition(ctx: _Ctx, tick: Tick, stale: Optional[int]) -> int:
    """The status of an IfThenElse/WhileDoElse condition: the one its leaf kept (profile
    switch ``stale_condition``; ``stale`` is then its memory slot), else a fresh tick."""
    if stale is not None and ctx.s[stale]:
        return ctx.s[stale]
    return tick(ctx)


def _threshold(value: int, count: int) -> int:
    """BehaviorTree.CPP's reading of a Parallel threshold: negative counts from the end."""
    return value if value >= 0 else max(count + value + 1, 0)


def _halt_running(ctx: _Ctx, pairs: Halts) -> None:
    """Halt each ``(flag, halt)`` whose running flag is set (section 4): the children a node
    leaves running, or halt before start's competing branches."""
    s = ctx.s
    for flag, halt in pairs:
        if s[flag]:
            halt(ctx)


def _exclusive_check(ctx: _Ctx, rivals: tuple[Any, ...]) -> None:
    s = ctx.s
    for flag, violation, event in rivals:
        if s[flag]:
            ctx.violations.append(violation)
            if ctx.rec is not None:
                ctx.rec.append(event)


def _exclusive_end(ctx: _Ctx, groups: tuple[Any, ...]) -> None:
    """Rule 'Exclusive resources' at the end of a tick: two leaves of one resource running."""
    s = ctx.s
    for res, flags in groups:
        a = None
        for flag, name in flags:
            if s[flag]:
                if a is None:
                    a = name
                    continue
                ctx.violations.append(("exclusive", res, a, name, "end"))
                if ctx.rec is not None:
                    ctx.rec.append(("violation", a, f"exclusive {res}: runs with {name} at the end of the tick"))
                break


def _site_halt(site: Site) -> Halt:
    """leave(ctx) of an FSM state that runs a primitive: the run is abandoned (a timed run's
    counter starts afresh, rule 'Durations') and the oracle is told."""
    timer = site.timer
    if timer is None:
        return lambda ctx: ctx.oracle.halt(site)

    def leave(ctx: _Ctx) -> None:
        ctx.s[timer] = 0
        ctx.oracle.halt(site)
    return leave


def _apply(ctx: _Ctx, eff: Any) -> None:
    eff(ctx.s)
    if ctx.rec is not None:
        _record_writes(ctx, eff)


def _record_writes(ctx: _Ctx, eff: Any) -> None:
    s = ctx.s
    ctx.rec.extend([("write", idx, s[idx]) for idx in eff.targets])


def _param(value: Any, lo: int, hi: int, is_bool: bool, pname: str, node: str) -> int:
    out = int(value)
    if not lo <= out <= hi:
        from .errors import DomainError

        raise DomainError(pname, out, f"tree.{node}.params")
    return out


def _lca(a: _N, b: _N) -> tuple[_N, Node]:
    """Lowest common ancestor of two node infos and the child of it on b's side."""
    ancestors = []
    x: Optional[_N] = a
    while x is not None:
        ancestors.append(x)
        x = x.parent
    seen = {id(x) for x in ancestors}
    prev: Optional[_N] = None
    y: Any = b
    while id(y) not in seen:
        prev, y = y, y.parent
    return y, (prev.node if prev is not None else b.node)


# ============================================================================ node rules
# One function per row of docs/semantics.md sections 2, 3 and 8.3, registered for its node
# types. Each runs once per node when a model compiles and returns the node's tick
# function; the closures are the hot path of every tick.


def _never(prog: Program, info: _N) -> bool:
    return False


def _always(prog: Program, info: _N) -> bool:
    return True


def _child_slot(prog: Program, info: _N) -> None:
    info.mem = prog._slot(f"{info.node.name}:child", "memory", len(info.node.children_of()))


def _done_slots(prog: Program, info: _N) -> None:
    # which children finished: 0 not yet, else their status (SUCCESS 1, FAILURE 2)
    info.mems = tuple(prog._slot(f"{info.node.name}:done{i}", "memory", 3) for i in range(len(info.kids)))


def _parallel_slots(prog: Program, info: _N) -> None:
    n: Any = info.node
    if prog.profile.parallel_memory:
        _done_slots(prog, info)
    elif n.synchronise and info.can_run:
        # rule 'parallel synchronise': which children succeeded since the parallel started
        info.mems = tuple(prog._slot(f"{n.name}:succeeded:{k.node.name}", "memory", 2) for k in info.kids)


def _stale_slot(prog: Program, info: _N) -> None:
    if prog.profile.stale_condition and info.kids and _stateful(info.kids[0]):
        # the condition leaf's last status while the node keeps it (0: none)
        info.stale = prog._slot(f"{info.node.name}:condition", "memory", 3)


def _if_then_else_slots(prog: Program, info: _N) -> None:
    info.mem = prog._slot(f"{info.node.name}:branch", "memory", 3)
    _stale_slot(prog, info)


def _sequence_with_memory_slots(prog: Program, info: _N) -> None:
    info.keep = prog._slot(f"{info.node.name}:child", "memory", max(len(info.kids), 1))


def _sequence_with_memory_can_run(prog: Program, info: _N) -> bool:
    # RUNNING after a child that succeeded at once (the wake-up)
    return (prog.profile.loop_wake_up and len(info.kids) > 1) or any(k.can_run for k in info.kids)


def _loop_slots(prog: Program, info: _N) -> None:
    n: Any = info.node
    if isinstance(n, Retry):
        info.mem = prog._slot(f"{n.name}:failures", "memory", max(n.attempts, 1))
    else:
        info.mem = prog._slot(f"{n.name}:done", "memory", max(n.times, 1))


def _loop_can_run(prog: Program, info: _N) -> bool:
    n: Any = info.node
    return (n.attempts if isinstance(n, Retry) else n.times) > 1 or bool(info.kids[0].can_run)


def _run_once_slots(prog: Program, info: _N) -> None:
    info.keep = prog._slot(f"{info.node.name}:result", "memory", 3)


def _action_can_run(prog: Program, info: _N) -> bool:
    n: Any = info.node
    return Status.RUNNING in prog.prims[n.primitive].statuses()


def _pipeline_slots(prog: Program, info: _N) -> None:
    info.mem = prog._slot(f"{info.node.name}:last", "memory", max(len(info.kids), 1))


def _recovery_slots(prog: Program, info: _N) -> None:
    n: Any = info.node
    info.mem = prog._slot(f"{n.name}:retries", "memory", n.retries + 1)


def _round_robin_slots(prog: Program, info: _N) -> None:
    # the child to tick next (kept when the node finishes, reset by a halt) and the
    # failures in a row of this run
    count = max(len(info.kids), 1)
    info.mem = prog._slot(f"{info.node.name}:child", "memory", count)
    info.mems = (prog._slot(f"{info.node.name}:failed", "memory", count),)


@rule(ReactiveSequence, ReactiveFallback, merge="tells")
def _reactive(prog: Program, c: NodeRule) -> Tick:
    """Rules 'ReactiveSequence' and 'ReactiveFallback' (docs/semantics.md section 2)."""
    n, kids, finish, flag, evs = c.node, c.kids, c.finish, c.flag, c.evs
    go_on = SUCCESS if isinstance(n, ReactiveSequence) else FAILURE
    halts = tuple(c.later_halts(i) for i in range(len(kids)))
    pairs = tuple(zip(kids, halts))
    if c.name in prog.merge_points:
        return _merging_reactive(c.name, pairs, go_on, finish)

    def tick(ctx: _Ctx) -> int:
        st = go_on
        for child, hs in pairs:
            st = child(ctx)
            if st != go_on:
                s = ctx.s
                for fl, h in hs:  # _halt_running, inlined: the hottest loop of a tick
                    if s[fl]:
                        h(ctx)
                break
        if flag is not None:  # finish(st, ctx), inlined (the hot path)
            ctx.s[flag] = 1 if st == RUNNING else 0
        if ctx.rec is not None:
            ctx.rec.append(evs[st])
        return st
    return tick


def _merging_reactive(name: str, pairs: "tuple[tuple[Tick, Halts], ...]", go_on: int, finish: Finish) -> Tick:
    """A ReactiveSequence/ReactiveFallback that is a merge point (``Program._merge_points``):
    the same tick, telling the oracle before each child after the first."""
    def tick(ctx: _Ctx) -> int:
        for i, (child, hs) in enumerate(pairs):
            if i:
                ctx.merge_point((name, i))
            st = child(ctx)
            if st != go_on:
                _halt_running(ctx, hs)
                return finish(st, ctx)
        return finish(go_on, ctx)
    return tick


@rule(MemorySequence, MemoryFallback, slots=_child_slot, merge="tells")
def _memory(prog: Program, c: NodeRule) -> Tick:
    """Rules 'MemorySequence' and 'MemoryFallback' (section 2)."""
    n, info, kids, flag, evs = c.node, c.info, c.kids, c.flag, c.evs
    go_on = SUCCESS if isinstance(n, MemorySequence) else FAILURE
    mem, count = info.mem, len(kids)
    name, merge = c.name, c.name in prog.merge_points

    def tick(ctx: _Ctx) -> int:
        s = ctx.s
        i = s[mem]
        st = go_on
        while i < count:
            if merge and i:
                ctx.merge_point((name, i))
            st = kids[i](ctx)
            if st != go_on:
                s[mem] = i if st == RUNNING else 0
                break
            i += 1
        else:
            s[mem] = 0
        if flag is not None:  # finish(st, ctx), inlined (the hot path)
            s[flag] = 1 if st == RUNNING else 0
        if ctx.rec is not None:
            ctx.rec.append(evs[st])
        return st
    return tick


@rule(Parallel, slots=_parallel_slots)
def _parallel(prog: Program, c: NodeRule) -> Tick:
    """Rule 'Parallel' (section 2; BehaviorTree.CPP's and py_trees' variants: section 8)."""
    n, info, kids, finish, where = c.node, c.info, c.kids, c.finish, c.where
    if prog.profile.parallel_memory and n.selected:
        raise ModelError(f"{where}.selected", "selected children are py_trees' SuccessOnSelected policy; "
                                              "BehaviorTree.CPP's Parallel has thresholds only")
    if not prog.profile.parallel_memory and (
            n.synchronise or n.selected or prog.profile.parallel_failure_first):
        # py_trees' options and order (under parallel_memory finished children are never
        # ticked again anyway, so synchronise changes nothing there)
        return prog._compile_parallel(info, kids, finish, where)

    count = len(kids)
    need = count if n.success_threshold is None else _threshold(n.success_threshold, count)
    fail_at = _threshold(n.failure_threshold, count)
    top = count if prog.profile.parallel_memory else fail_at  # BT.CPP refuses failure > children
    low = 0 if prog.profile.parallel_memory else 1  # BT.CPP's 0: decide after the first child
    if not low <= need <= count or not low <= fail_at <= top:
        bound = f" <= {count}" if prog.profile.parallel_memory else ""
        zero = "" if low else " (0 is BehaviorTree.CPP's, under semantics: btcpp)"
        raise ModelError(where, f"thresholds must satisfy {low} <= success <= {count} and {low} <= failure{bound} "
                                f"(negative ones count from the end: -1 is all {count} children){zero}")
    halts = tuple((k.flag, k.halt) for k in info.kids if k.can_run)
    if info.mems:
        return prog._parallel_memory(info, kids, need, fail_at, halts, finish)

    def tick(ctx: _Ctx) -> int:
        ok = bad = 0
        for child in kids:
            st = child(ctx)
            if st == SUCCESS:
                ok += 1
            elif st == FAILURE:
                bad += 1
        if ok >= need:
            st = SUCCESS
        elif bad >= fail_at or bad > count - need:
            st = FAILURE
        else:
            return finish(RUNNING, ctx)
        _halt_running(ctx, halts)
        return finish(st, ctx)
    return tick


@rule(ParallelAll, slots=_done_slots)
def _parallel_all(prog: Program, c: NodeRule) -> Tick:
    """Rule 'ParallelAll' (section 2)."""
    n, info, kids, finish, where = c.node, c.info, c.kids, c.finish, c.where
    count, mems = len(kids), info.mems
    most = _threshold(n.max_failures, count)
    if not 1 <= most <= count:
        raise ModelError(f"{where}.max_failures", f"must satisfy 1 <= max_failures <= {count} (negative ones count from the end)")
    halts = tuple((k.flag, k.halt) for k in info.kids if k.can_run)
    pairs = tuple(zip(kids, mems))

    def tick(ctx: _Ctx) -> int:
        s = ctx.s
        for child, m in pairs:
            if not s[m]:
                st = child(ctx)
                if st != RUNNING:
                    s[m] = st
        bad = 0
        for m in mems:
            if not s[m]:
                return finish(RUNNING, ctx)
            if s[m] == FAILURE:
                bad += 1
        for m in mems:
            s[m] = 0
        _halt_running(ctx, halts)
        return finish(FAILURE if bad >= most else SUCCESS, ctx)
    return tick


@rule(SequenceWithMemory, slots=_sequence_with_memory_slots, can_run=_sequence_with_memory_can_run,
      wakes=lambda n: len(n.children) > 1)
def _sequence_with_memory(prog: Program, c: NodeRule) -> Tick:
    """Rule 'SequenceWithMemory' (section 2; the wake-up under ``loop_wake_up``: section 8.1)."""
    info, kids, finish = c.info, c.kids, c.finish
    keep, count = info.keep, len(kids)
    wake, signal = prog.profile.loop_wake_up, prog._signal(info)
    steps = tuple((child, k.flag) for child, k in zip(kids, info.kids))

    def tick(ctx: _Ctx) -> int:
        s = ctx.s
        i = s[keep]
        while i < count:
            child, fl = steps[i]
            was_running = fl is not None and s[fl]
            st = child(ctx)
            if st != SUCCESS:
                s[keep] = i  # RUNNING: resume here; FAILURE: tick this child again next time
                return finish(st, ctx)
            i += 1
            if wake and not was_running and i < count:
                s[keep] = i  # the wake-up: RUNNING now, the next child on the next tick
                if signal is not None:
                    s[signal] = 1
                return finish(RUNNING, ctx)
        s[keep] = 0
        return finish(SUCCESS, ctx)
    return tick


@rule(IfThenElse, slots=_if_then_else_slots)
def _if_then_else(prog: Program, c: NodeRule) -> Tick:
    """Rule 'IfThenElse' (section 2; a stale condition under ``stale_condition``: section 8.1)."""
    info, kids, finish = c.info, c.kids, c.finish
    mem, stale, count = info.mem, info.stale, len(kids)
    halts = tuple((k.flag, k.halt) for k in info.kids if k.can_run)

    def tick(ctx: _Ctx) -> int:
        s = ctx.s
        i = s[mem]
        if i == 0:
            c = _condition(ctx, kids[0], stale)
            if c == RUNNING:
                return finish(RUNNING, ctx)
            if c == SUCCESS:
                i = 1
            elif count == 3:
                i = 2
            else:
                if stale is not None:
                    s[stale] = c
                return finish(c, ctx)
        st = kids[i](ctx)
        if st == RUNNING:
            s[mem] = i
            return finish(RUNNING, ctx)
        s[mem] = 0
        if stale is not None:
            s[stale] = 0
        _halt_running(ctx, halts)
        return finish(st, ctx)
    return tick

@rule(WhileDoElse, slots=_stale_slot)
def _while_do_else(prog: Program, c: NodeRule) -> Tick:
    """Rule 'WhileDoElse' (section 2; a stale condition under ``stale_condition``: section 8.1)."""
    info, kids, finish = c.info, c.kids, c.finish
    stale, count = info.stale, len(kids)
    halts = tuple((k.flag, k.halt) for k in info.kids if k.can_run)
    other: tuple[Any, ...] = tuple((k.flag, k.halt) if k.can_run else None for k in info.kids)

    def halt_kid(ctx: _Ctx, i: int) -> None:
        if i < count and other[i] is not None and ctx.s[other[i][0]]:
            other[i][1](ctx)

    def tick(ctx: _Ctx) -> int:
        s = ctx.s
        c = _condition(ctx, kids[0], stale)
        if c == RUNNING:
            return finish(RUNNING, ctx)
        if c == SUCCESS:
            halt_kid(ctx, 2)
            st = kids[1](ctx)
        elif count == 3:
            halt_kid(ctx, 1)
            st = kids[2](ctx)
        else:
            st = FAILURE
        if st == RUNNING:
            if stale is not None:
                s[stale] = c
            return finish(RUNNING, ctx)
        if stale is not None:
            s[stale] = 0
        _halt_running(ctx, halts)
        return finish(st, ctx)
    return tick


#: the child's status through a table (indexed by RUNNING, SUCCESS, FAILURE)
_STATUS_TABLES = {
    Inverter: _INVERT, ForceSuccess: (RUNNING, SUCCESS, SUCCESS), ForceFailure: (RUNNING, FAILURE, FAILURE),
    KeepRunningUntilFailure: (RUNNING, RUNNING, FAILURE), FailureIsRunning: (RUNNING, SUCCESS, RUNNING),
}


@rule(*_STATUS_TABLES, merge="keeps")
def _status_map(prog: Program, c: NodeRule) -> Tick:
    """Rules 'Inverter', 'ForceSuccess', 'ForceFailure', 'KeepRunningUntilFailure' and
    'FailureIsRunning' (section 3): the child's status through the type's table."""
    child, finish, table = c.kids[0], c.finish, _STATUS_TABLES[type(c.node)]
    return lambda ctx: finish(table[child(ctx)], ctx)


rule(KeepRunningUntilFailure, FailureIsRunning, can_run=_always)(_status_map)  # they make RUNNING themselves


@rule(Retry, Repeat, slots=_loop_slots, can_run=_loop_can_run,
      wakes=lambda n: (n.attempts if isinstance(n, Retry) else n.times) > 1)
def _retry_repeat(prog: Program, c: NodeRule) -> Tick:
    """Rules 'Retry' and 'Repeat' (section 3; under ``loop_wake_up``: section 8.1)."""
    n, info, kids, finish = c.node, c.info, c.kids, c.finish
    child, mem, kid_flag = kids[0], info.mem, info.kids[0].flag
    again, stop = (FAILURE, SUCCESS) if isinstance(n, Retry) else (SUCCESS, FAILURE)
    limit = n.attempts if isinstance(n, Retry) else n.times

    if prog.profile.loop_wake_up:
        signal = prog._signal(info)

        def tick_wake(ctx: _Ctx) -> int:
            s = ctx.s
            k = s[mem]
            for _ in range(2):  # a child that had been running may finish and start again
                was_running = kid_flag is not None and s[kid_flag]
                st = child(ctx)
                if st == RUNNING:
                    s[mem] = k
                    return finish(RUNNING, ctx)
                if st == stop:
                    s[mem] = 0
                    return finish(st, ctx)
                k += 1
                if k >= limit:
                    s[mem] = 0
                    return finish(st, ctx)
                if not was_running:  # the wake-up: RUNNING now, the next attempt next tick
                    s[mem] = k
                    if signal is not None:
                        s[signal] = 1
                    return finish(RUNNING, ctx)
            raise AssertionError("unreachable: the second attempt started from idle")
        return tick_wake

    def tick(ctx: _Ctx) -> int:
        st = child(ctx)
        s = ctx.s
        if st == again:
            k = s[mem] + 1
            if k < limit:
                s[mem] = k
                return finish(RUNNING, ctx)
            s[mem] = 0
        elif st == stop:
            s[mem] = 0
        return finish(st, ctx)
    return tick


@rule(SubTree, merge="keeps")
def _subtree(prog: Program, c: NodeRule) -> Tick:
    """Rule 'SubTree' (section 3)."""
    kids, finish = c.kids, c.finish
    # rule 'SubTree': the child's status. BT.CPP's SubTreeNode also resets its child
    # when it finishes, which only matters to a stale condition (section 8.1): a
    # SubTree is not a stateful leaf, so IfThenElse/WhileDoElse tick it afresh
    child = kids[0]
    return lambda ctx: finish(child(ctx), ctx)


@rule(RunningIsFailure, RunningIsSuccess, merge="keeps")
def _running_is(prog: Program, c: NodeRule) -> Tick:
    """Rules 'RunningIsFailure' and 'RunningIsSuccess' (section 3)."""
    n, info, kids, finish = c.node, c.info, c.kids, c.finish
    child, kid = kids[0], info.kids[0]
    instead = FAILURE if isinstance(n, RunningIsFailure) else SUCCESS

    def tick(ctx: _Ctx) -> int:
        st = child(ctx)
        if st != RUNNING:
            return finish(st, ctx)
        kid.halt(ctx)  # it finished in its parent's eyes: stopped, as py_trees stops it
        return finish(instead, ctx)
    return tick


@rule(RunOnce, slots=_run_once_slots, merge="keeps")
def _run_once(prog: Program, c: NodeRule) -> Tick:
    """Rule 'RunOnce' (section 3)."""
    n, info, kids, finish, where = c.node, c.info, c.kids, c.finish, c.where
    if n.then_skip:
        raise ModelError(f"{where}.then_skip", "RunOnce with then_skip: true returns SKIPPED after its first "
                                               "run, which btfsm does not model; use then_skip: false")
    child, keep = kids[0], info.keep

    def tick(ctx: _Ctx) -> int:
        s = ctx.s
        done = s[keep]
        if done:
            return finish(done, ctx)
        st = child(ctx)
        if st != RUNNING:
            s[keep] = st
        return finish(st, ctx)
    return tick


@rule(Guard, merge="keeps")
def _guard(prog: Program, c: NodeRule) -> Tick:
    """Rule 'Guard' (section 3)."""
    n, info, kids, finish, where = c.node, c.info, c.kids, c.finish, c.where
    child, kid = kids[0], info.kids[0]
    cond = compile_fn(n.condition, prog.scope, f"{where}.condition", BOOL)

    def tick(ctx: _Ctx) -> int:
        s = ctx.s
        if cond(s):
            return finish(child(ctx), ctx)
        if kid.flag is not None and s[kid.flag]:
            kid.halt(ctx)
        return finish(FAILURE, ctx)
    return tick


def _effects_on_halt(prog: Program, info: _N) -> Optional[Halt]:
    """An Effects node's ``on_halt`` effects, applied when it is halted (rule 'Effects')."""
    n: Any = info.node
    if not n.on_halt:
        return None
    eff = compile_effects(n.on_halt, prog.scope, f"tree.{n.name}.on_halt")
    return lambda ctx: _apply(ctx, eff)


@rule(Effects, merge="keeps", on_halt=_effects_on_halt)
def _effects(prog: Program, c: NodeRule) -> Tick:
    """Rule 'Effects' (section 3)."""
    n, kids, finish, where, flag = c.node, c.kids, c.finish, c.where, c.flag
    child = kids[0]
    start = compile_effects(n.on_start, prog.scope, f"{where}.on_start")
    done = (None,
            compile_effects(n.on_success, prog.scope, f"{where}.on_success"),
            compile_effects(n.on_failure, prog.scope, f"{where}.on_failure"))

    def tick(ctx: _Ctx) -> int:
        if start is not None and (flag is None or not ctx.s[flag]):
            _apply(ctx, start)
        st = child(ctx)
        if done[st] is not None:
            _apply(ctx, done[st])
        return finish(st, ctx)
    return tick


@rule(Condition, can_run=_never)
def _condition_leaf(prog: Program, c: NodeRule) -> Tick:
    """Rule 'Condition' (section 3)."""
    n, evs, where = c.node, c.evs, c.where
    cond = compile_fn(n.expr, prog.scope, f"{where}.expr", BOOL)

    def tick(ctx: _Ctx) -> int:
        st = SUCCESS if cond(ctx.s) else FAILURE
        if ctx.rec is not None:  # finish(st, ctx), inlined: a condition has no running flag
            ctx.rec.append(evs[st])
        return st
    return tick


def _action_on_halt(prog: Program, info: _N) -> Halt:
    """A halted Action: its run counter starts afresh (rule 'Durations') and the oracle is
    told (section 4). The site is made when the rule compiles: looked up at halt time."""
    def on_halt(ctx: _Ctx) -> None:
        site: Any = info.node_site
        if site.timer is not None:
            ctx.s[site.timer] = 0  # a halted run starts afresh (rule 'Durations')
        ctx.oracle.halt(site)
    return on_halt


@rule(Action, can_run=_action_can_run, on_halt=_action_on_halt)
def _action(prog: Program, c: NodeRule) -> Tick:
    """Rule 'Action' (section 3; halt before start: section 4)."""
    n, info, evs, where, flag = c.node, c.info, c.evs, c.where, c.flag
    conflicts = prog._conflicts(info)  # () for a leaf that cannot run
    site = prog._site("action", n.name, None, None, n.primitive, n.args, where, n.duration)
    info.node_site = site
    run, rivals = prog._primitive_runner(site), prog._rivals(info)
    # whether a rival runs, as one compiled expression: most starts find none
    rival_runs = prog._flags_above([tuple(flag for flag, _, _ in rivals)], 0) if rivals else None

    def tick(ctx: _Ctx) -> int:
        s = ctx.s
        if flag is None or not s[flag]:  # it starts (a leaf that cannot run starts every tick)
            for fl, h in conflicts:  # _halt_running, inlined: halt before start
                if s[fl]:
                    h(ctx)
            # rule 'Exclusive resources', once the competing branches are halted
            if rival_runs is not None and rival_runs(s):
                _exclusive_check(ctx, rivals)
        st = run(ctx)
        if flag is not None:  # finish(st, ctx), inlined (the hot path)
            s[flag] = 1 if st == RUNNING else 0
        if ctx.rec is not None:
            ctx.rec.append(evs[st])
        return st
    return tick


def _skill_request_on_halt(prog: Program, info: _N) -> Halt:
    """A halted SkillRequest withdraws its goal from its FSM (rule 'SkillRequest', section 5)."""
    n: Any = info.node
    fi, name = prog.fsm_index[n.fsm], n.name
    return lambda ctx: prog.fsm_ticks[fi].withdraw(ctx, name)


@rule(SkillRequest, can_run=_always, on_halt=_skill_request_on_halt)
def _skill_request(prog: Program, c: NodeRule) -> Tick:
    """Rule 'SkillRequest' (section 3; the FSM tick: section 5)."""
    n, info, finish, where, flag, name = c.node, c.info, c.finish, c.where, c.flag, c.name
    conflicts = prog._conflicts(info)
    fi = prog.fsm_index[n.fsm]
    f = prog.model.fsms[fi]
    g = f.goals.index(n.goal)
    pre = compile_fn(n.pre, prog.scope, f"{where}.pre", BOOL) if n.pre is not None else None
    post = compile_fn(n.post, prog.scope, f"{where}.post", BOOL) if n.post is not None else None
    found = []
    for p in f.params:
        expr = dict(n.params)[p.name]
        ptype = Type(p.kind, p.values) if p.kind == "enum" else Type(p.kind)
        fn = compile_fn(expr, prog.scope, f"{where}.params.{p.name}", ptype)
        found.append((fn, p.lo, p.hi, p.kind == "bool", p.name))
    pfns = tuple(found)
    rivals = prog._rivals(info)

    def tick(ctx: _Ctx) -> int:
        s = ctx.s
        starting = not s[flag]
        if starting:
            _halt_running(ctx, conflicts)
        if pre is not None and not pre(s):
            if s[flag]:  # a running request ends: withdraw its goal
                prog.fsm_ticks[fi].withdraw(ctx, name)
            return finish(FAILURE, ctx)
        if starting and rivals:
            _exclusive_check(ctx, rivals)
        pvals = tuple(_param(fn(s), lo, hi, is_bool, pname, name) for fn, lo, hi, is_bool, pname in pfns)
        st = prog.fsm_ticks[fi](ctx, g, pvals, name, starting)
        if st == SUCCESS and post is not None and not post(s):
            ctx.violations.append(("post", name))
            if ctx.rec is not None:
                ctx.rec.append(("violation", name, "post"))
        return finish(st, ctx)
    return tick


@rule(PipelineSequence, slots=_pipeline_slots, merge="tells")
def _pipeline_sequence(prog: Program, c: NodeRule) -> Tick:
    """Rule 'PipelineSequence' (docs/semantics.md 8.3), ported from navigation2's
    nav2_behavior_tree/plugins/control/pipeline_sequence.cpp."""
    info, kids, finish = c.info, c.kids, c.finish
    s_mem, count, every = info.mem, len(kids), c.halts()  # every: BT.CPP's haltChildren()
    name, merge = c.name, c.name in prog.merge_points

    def tick(ctx: _Ctx) -> int:
        s = ctx.s
        last = s[s_mem]
        for i in range(count):
            if merge and i:
                ctx.merge_point((name, i))
            st = kids[i](ctx)
            if st == FAILURE:
                _halt_running(ctx, every)
                s[s_mem] = 0
                return finish(FAILURE, ctx)
            if st == RUNNING and i >= last:
                s[s_mem] = i
                return finish(RUNNING, ctx)
            # SUCCESS, or RUNNING of an earlier stage: it keeps running, go on
        _halt_running(ctx, every)
        s[s_mem] = 0
        return finish(SUCCESS, ctx)
    return tick


@rule(RecoveryNode, slots=_recovery_slots, merge="tells")
def _recovery_node(prog: Program, c: NodeRule) -> Tick:
    """Rule 'RecoveryNode' (docs/semantics.md 8.3), ported from navigation2's recovery_node.cpp."""
    n, info, kids, finish = c.node, c.info, c.kids, c.finish
    s_mem, every = info.mem, c.halts()  # every: BT.CPP's haltChildren()
    first, second = kids
    k0, k1 = info.kids
    limit = n.retries
    halt0 = ((k0.flag, k0.halt),) if k0.can_run else ()
    halt1 = ((k1.flag, k1.halt),) if k1.can_run else ()
    name, merge = c.name, c.name in prog.merge_points

    def end(ctx: _Ctx, st: int) -> int:
        _halt_running(ctx, every)  # halt(): the children, the index and the count
        ctx.s[s_mem] = 0
        return finish(st, ctx)

    def tick(ctx: _Ctx) -> int:
        s = ctx.s
        retry = s[s_mem]
        recovering = k1.flag is not None and s[k1.flag]  # current_child_idx_ == 1
        while retry <= limit:
            if not recovering:
                st = first(ctx)
                if st == SUCCESS:
                    _halt_running(ctx, halt1)
                    return end(ctx, SUCCESS)
                if st == RUNNING:
                    s[s_mem] = retry
                    return finish(RUNNING, ctx)
                if retry >= limit:
                    return end(ctx, FAILURE)
                _halt_running(ctx, halt0)
                recovering = True
            else:
                st = second(ctx)
                if st == RUNNING:
                    s[s_mem] = retry
                    return finish(RUNNING, ctx)
                if st == FAILURE:
                    return end(ctx, FAILURE)
                _halt_running(ctx, halt1)
                retry += 1
                recovering = False
                s[s_mem] = retry  # the count in the state, where an oracle can see it
                if merge:
                    ctx.merge_point(name)
        return end(ctx, FAILURE)  # pragma: no cover - the count never passes the limit
    return tick


@rule(RoundRobin, slots=_round_robin_slots, merge="keeps")
def _round_robin(prog: Program, c: NodeRule) -> Tick:
    """Rule 'RoundRobin' (docs/semantics.md 8.3), ported from navigation2's round_robin_node.cpp."""
    n, info, kids, finish = c.node, c.info, c.kids, c.finish
    s_mem, count, every = info.mem, len(kids), c.halts()  # every: BT.CPP's haltChildren()
    fail_mem, wrap = info.mems[0], n.wrap_around

    def tick(ctx: _Ctx) -> int:
        s = ctx.s
        i, failed = s[s_mem], s[fail_mem]
        while failed < count:
            st = kids[i](ctx)
            if st == RUNNING:
                s[s_mem], s[fail_mem] = i, failed
                return finish(RUNNING, ctx)
            i += 1
            if i == count:
                if not wrap:
                    break  # the end of the children: FAILURE, whatever the last one returned
                i = 0
            if st == SUCCESS:
                _halt_running(ctx, every)
                s[s_mem], s[fail_mem] = i, 0
                return finish(SUCCESS, ctx)
            failed += 1
        _halt_running(ctx, every)  # halt(): the children, the index and the count
        s[s_mem] = s[fail_mem] = 0
        return finish(FAILURE, ctx)
    return tick
