"""The paper's skill-transition procedure, automated (``btfsm skills MODEL``).

The paper derives by hand, from the executive tree, which skill may follow which, and
which of these switches can happen before the running skill completes (preemptions);
the skill FSM must then support each of them. Here the steps are mechanical:

1. the skills are the ``(fsm, goal)`` pairs that SkillRequest nodes of the tree request
   (two nodes requesting the same goal of the same FSM are one skill);
2. the closed system (tree, FSMs, environment) is explored exhaustively, in product with
   the *last skill*: which skill ran last and how it ended (still running, SUCCESS,
   FAILURE, halted). The last skill is not part of the model's state, hence the product;
3. every tick in which an idle SkillRequest asks its FSM for ``b`` gives a pair ``(a, b)``
   with ``a`` the last skill: *after completion* when ``a`` replied SUCCESS, a
   *preemption* when ``a`` was halted (its goal withdrawn) while RUNNING, *after failure*
   when ``a`` replied FAILURE, *first* at the start of the run. If the FSM replies
   FAILURE at once (not applicable, a refusing marker) the request is *refused*: the
   pair is still derived (the tree asked for it) but ``b`` did not run. A request that
   never reaches its FSM (``pre`` false, busy) is not a transition;
4. the pairs are drawn as the transition diagram (text or dot) and counted out of the
   ``n * n`` possible ones (the paper: 9 of 16 for its ARIAC tree, 7 after completion and
   2 before);
5. each derived transition is checked against the FSM: from every state right after a
   tick in which the tree switched from ``a`` to ``b`` (``check_support(where="switch")``,
   the default), requesting ``b`` on every tick with the parameters of that switch must be
   able to reach ``b``'s SUCCESS reply while ``b`` is held. Environment events do not run
   during this check. ``where="held"`` checks the stricter reading: for a preemption from
   every reachable state in which ``a`` is held, after completion (failure) from every
   state right after ``a`` replied SUCCESS (FAILURE);
6. an unsupported transition gets a counterexample: the state it starts from and what the
   FSM does instead, with every primitive succeeding.

>>> from btfsm.models.examples.spectrum import reverse
>>> d = derive(reverse())
>>> sorted((d.name(a), d.name(b)) for (a, b, k) in d.pairs if k == "preemption")
[('work', 'serve')]
>>> all(s.supported for s in check_support(d))
True
"""
from __future__ import annotations

import json
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from btfsm.oracles import SucceedOracle, all_choices
from btfsm.bt import SkillRequest, walk
from btfsm.errors import DomainError, ModelError
from btfsm.expr import Type, compile_fn
from btfsm.status import Status

from .search import Budget, BudgetExceeded, describe_hit

__all__ = ["Skill", "Pair", "Derivation", "Support", "skills_of", "derive", "check_support",
           "counts", "format_text", "to_dot", "to_json", "args_skills", "cli_skills", "KINDS"]

KINDS = ("completion", "preemption", "failure", "concurrent", "first")
_MARK = {"completion": "C", "preemption": "P", "failure": "F", "concurrent": "||"}
RUNNING, SUCCESS, FAILURE = int(Status.RUNNING), int(Status.SUCCESS), int(Status.FAILURE)


@dataclass(frozen=True)
class Skill:
    """A skill: goal ``goal`` of FSM ``fsm``, requested by the SkillRequest ``nodes``."""

    fsm: str
    goal: str
    nodes: tuple

    def label(self, single_fsm: bool = True) -> str:
        return self.goal if single_fsm else f"{self.fsm}:{self.goal}"


@dataclass
class Pair:
    """A derived transition ``a -> b`` of one kind, with its shortest witness."""

    a: "int | None"
    b: int
    kind: str
    count: int = 0  # product transitions that show it
    witness: tuple = ()  # choice scripts of the ticks from the initial state
    refused: int = 0  # of those, how many the FSM refused at once (FAILURE on b's first tick)


@dataclass
class Derivation:
    """What ``derive`` found; ``pairs`` maps ``(a, b, kind)`` to a Pair."""

    model: Any  # btfsm.model.Model
    skills: list
    pairs: dict
    states: int  # product states (model state x last skill)
    model_states: int
    transitions: int
    complete: bool
    seconds: float
    switched: dict = field(default_factory=dict)  # (a, b, kind) -> {(state right after b started, b's params)}
    held: dict = field(default_factory=dict)  # skill -> model states in which its goal is held
    ended: dict = field(default_factory=dict)  # (skill, "success"|"failure") -> model states right after
    params: dict = field(default_factory=dict)  # skill -> parameter tuples it was started with
    errors: list = field(default_factory=list)  # (model state, script, message) of DomainErrors
    stopped: "str | None" = None  # the budget hit: "states", "transitions" or "seconds" (Budget.hit)

    @property
    def single_fsm(self) -> bool:
        return len({s.fsm for s in self.skills}) <= 1

    def name(self, i) -> str:
        return "(start)" if i is None else self.skills[i].label(self.single_fsm)


@dataclass
class Support:
    """Whether the FSM supports derived transition ``(a, b, kind)``."""

    a: "int | None"
    b: int
    kind: str
    supported: bool
    sources: int  # model states checked
    counterexample: "dict | None" = None


# --------------------------------------------------------------------------- skills
def skills_of(model) -> list:
    """The skills of ``model``: (fsm, goal) pairs of its tree's SkillRequests, in tree order.

    >>> from btfsm.models.ariac import preemptive
    >>> [s.goal for s in skills_of(preemptive(n_tray=1))]
    ['place_bins', 'pick_conveyor', 'place_agv', 'pick_bins']
    """
    out: dict = {}
    if model.tree is None:
        return []
    for node in walk(model.tree):
        if isinstance(node, SkillRequest):
            key = (node.fsm, node.goal)
            out[key] = out.get(key, ()) + (node.name,)
    return [Skill(f, g, nodes) for (f, g), nodes in out.items()]


# --------------------------------------------------------------------------- exploration
def _successors(step, state):
    """Every ``(script, Step | DomainError)`` of one tick from ``state`` (DFS over choices)."""
    for taken, result, _ in all_choices(step, state, errors=(DomainError,)):
        yield taken, result


class _Tracker:
    """Turns one tick's recorded events into skill events."""

    def __init__(self, prog, skills):
        self.node_skill = {n: i for i, s in enumerate(skills) for n in s.nodes}
        self.flags = {n: prog.nodes[n].flag for n in self.node_skill}
        self.fsm_of = {n: prog.nodes[n].node.fsm for n in self.node_skill}
        self.param_fns = {}
        for n in self.node_skill:
            info = prog.nodes[n]
            node = info.node
            f = prog.model.fsm(node.fsm)
            fns = []
            for p in f.params:
                ptype = Type(p.kind, p.values) if p.kind == "enum" else Type(p.kind)
                fns.append(compile_fn(dict(node.params)[p.name], prog.scope, f"tree.{n}.params.{p.name}", ptype))
            self.param_fns[n] = tuple(fns)

    def events(self, src, step):
        """``start`` (the FSM took the request), ``refused`` (the FSM was ticked for it and
        replied FAILURE at once), ``end`` (SUCCESS, FAILURE or halted). A request that never
        reached its FSM (``pre`` false, busy) gives nothing."""
        running = {n for n, fl in self.flags.items() if src[fl]}
        out = []
        stepped = set()  # FSMs stepped since the last node finished its tick
        dst = None
        for ev in step.events or ():
            kind, name = ev[0], ev[1]
            if kind in ("fire", "not-applicable"):
                stepped.add(name)
            elif kind == "outcome" and "/" in name:
                stepped.add(name.split("/", 1)[0])
            if kind == "halt" and name in running:
                running.discard(name)
                out.append(("end", name, "halted"))
            if kind != "status":
                continue
            touched, stepped = stepped, set()
            if name not in self.node_skill:
                continue
            st = ev[2]
            if name not in running:
                if dst is None:
                    dst = list(step.state)
                params = tuple(int(fn(dst)) for fn in self.param_fns[name])
                if st == FAILURE:
                    if self.fsm_of[name] in touched:
                        out.append(("refused", name, params))
                    continue
                out.append(("start", name, params))
            if st == RUNNING:
                running.add(name)
            else:
                running.discard(name)
                out.append(("end", name, "success" if st == SUCCESS else "failure"))
        return tuple(out)


def derive(model, *, max_states: "int | None" = None, max_transitions: "int | None" = None,
           max_seconds: "float | None" = None, progress=None) -> Derivation:
    """Explore ``model`` in product with the last skill and derive the skill transitions.

    ``max_states`` bounds the product states, ``max_transitions`` the product transitions,
    ``max_seconds`` the time (a monotonic clock, ``btfsm.verify.search.Budget``): the
    exploration stops at the first one hit, within a state's successors too (they are
    enumerated lazily), with ``complete`` False and ``stopped`` naming it.
    ``progress(states, seconds)`` is called now and then."""
    t0 = time.perf_counter()
    budget = Budget(max_states, max_transitions, max_seconds)
    smax = budget.max_states
    tmax = budget.max_transitions
    prog = model.program
    skills = skills_of(model)
    tracker = _Tracker(prog, skills)
    goal_slots = [(fi, goal) for fi, (_, _, _, goal, _) in enumerate(prog.fsm_info)]
    skill_of_goal = {(s.fsm, s.goal): i for i, s in enumerate(skills)}
    held_code = [(prog.fsm_info[prog.fsm_index[s.fsm]][3], prog.model.fsm(s.fsm).goals.index(s.goal) + 1) for s in skills]
    d = Derivation(model, skills, {}, 0, 0, 0, True, 0.0)
    start: Any = (prog.initial, None)
    index = {start: 0}
    parent = [(-1, ())]
    order = [start]
    cache: dict = {}
    i = met = 0  # met: model states whose successors were enumerated (at least in part)
    while i < len(order) and d.complete:
        state, last = order[i]
        succ: Any = cache.get(state)
        fresh = succ is None
        if fresh:
            met += 1
            succ = _expand(prog, tracker, state, d, budget)
            for fi, slot in goal_slots:
                g = state[slot]
                if g:
                    f = prog.fsm_info[fi][0]
                    k = skill_of_goal.get((f.name, f.goals[g - 1]))
                    if k is not None:
                        d.held.setdefault(k, set()).add(state)
        kept: Any = [] if fresh else None
        for item in succ:
            if item is None:  # out of time while enumerating
                d.complete, d.stopped = False, "seconds"
                break
            if tmax is not None and d.transitions >= tmax:
                d.complete, d.stopped = False, "transitions"
                break
            if fresh:
                kept.append(item)
            script, dst, events = item
            d.transitions += 1
            cur = last
            started = []
            for ev in events:
                if ev[0] in ("start", "refused"):
                    b = tracker.node_skill[ev[1]]
                    d.params.setdefault(b, set()).add(ev[2])
                    kind = "first" if cur is None else {"success": "completion", "halted": "preemption",
                                                         "failure": "failure", "running": "concurrent"}[cur[1]]
                    a: Any = None if cur is None else cur[0]
                    pair = d.pairs.get((a, b, kind))
                    if pair is None:
                        pair = d.pairs[(a, b, kind)] = Pair(a, b, kind, 0, _path(parent, i) + (script,))
                    pair.count += 1
                    if ev[0] == "refused":  # the tree asked, the FSM said no: b did not run
                        pair.refused += 1
                        d.switched.setdefault((a, b, kind), set()).add((dst, ev[2]))
                        continue
                    started.append((a, b, kind, ev[2]))
                    cur = (b, "running")
                elif ev[0] == "end":
                    b = tracker.node_skill[ev[1]]
                    cur = (b, ev[2])
                    if ev[2] in ("success", "failure"):
                        d.ended.setdefault((b, ev[2]), set()).add(dst)
            for a, b, kind, params in started:
                slot, code = held_code[b]
                if dst[slot] == code:  # b is still under way after the tick that started it
                    d.switched.setdefault((a, b, kind), set()).add((dst, params))
            key = (dst, cur)
            if key not in index:
                if smax is not None and len(order) >= smax:
                    d.complete, d.stopped = False, "states"
                    break
                index[key] = len(order)
                order.append(key)
                parent.append((i, script))
        if not d.complete:
            break
        if fresh:
            cache[state] = kept
        i += 1
        if progress is not None and i % 5000 == 0:
            progress(len(order), time.perf_counter() - t0)
    d.states, d.model_states = len(order), met
    d.seconds = time.perf_counter() - t0
    return d


def _expand(prog, tracker, state, d, budget):
    """The successors ``(script, state, skill events)`` of ``state``, one at a time; None
    (then nothing more) when the time budget runs out."""
    timed = budget.max_seconds is not None
    for k, (script, result) in enumerate(_successors(lambda s, o: prog.step(s, o, record=True), state)):
        if timed and k % 256 == 255 and budget.out_of_time():
            yield None
            return
        if isinstance(result, DomainError):
            d.errors.append((state, script, str(result)))
            continue
        if result.state is None:
            continue
        yield script, result.state, tracker.events(state, result)


def _path(parent, i) -> tuple:
    scripts = []
    while i > 0:
        i, script = parent[i]
        scripts.append(script)
    return tuple(reversed(scripts))


def counts(d: Derivation) -> dict:
    """Distinct skill pairs by kind, out of ``n * n``."""
    by = {k: {(p.a, p.b) for p in d.pairs.values() if p.kind == k and p.a is not None} for k in KINDS}
    distinct = set().union(*(by[k] for k in ("completion", "preemption", "failure", "concurrent")))
    n = len(d.skills)
    requested = by["completion"] | by["preemption"]
    return {"skills": n, "possible": n * n, "distinct": len(distinct), "completion_or_preemption": len(requested),
            "completion": len(by["completion"]), "preemption": len(by["preemption"]),
            "failure": len(by["failure"]), "concurrent": len(by["concurrent"]),
            "completion_and_preemption": len(by["completion"] & by["preemption"]),
            "only_by_preemption": len(by["preemption"] - by["completion"]),
            "only_after_failure": len(by["failure"] - by["completion"] - by["preemption"])}


# --------------------------------------------------------------------------- FSM support

def _tree_slots(prog) -> set:
    if prog.model.tree is None:
        return set()
    root = prog.model.tree.name
    out = set()
    for info in prog.nodes.values():
        if info.root == root:
            out.update(info.state_slots())
    return out


def _project(state, drop) -> tuple:
    return tuple(0 if k in drop else v for k, v in enumerate(state))


def _good_region(prog, skill, params, sources, drop, budget, clock=None):
    """FSM-level states (projected) from which ``skill``'s SUCCESS reply is reachable while
    it is requested on every tick; also the explored graph for explanations."""
    fsm, goal = skill.fsm, skill.goal
    succ: dict = {}
    todo = deque(sources)
    seen = set(sources)
    good = set()
    while todo:
        if clock is not None and clock.out_of_time():
            raise BudgetExceeded("seconds", f"time budget hit while checking FSM support of {skill.goal} "
                                            f"({len(seen):,} FSM states explored)")
        key = todo.popleft()
        out = []
        for script, result in _successors(lambda s, o: prog.fsm_step(s, fsm, goal, params, o), key):
            if isinstance(result, DomainError):
                out.append((FAILURE, None))
                continue
            reply, dst = result.status, _project(result.state, drop)
            out.append((reply, dst))
            if reply == SUCCESS:
                good.add(key)
            elif reply == RUNNING and dst not in seen:
                if len(seen) >= budget:
                    return None, succ
                seen.add(dst)
                todo.append(dst)
        succ[key] = out
    pred: dict = {}
    for key, out in succ.items():
        for reply, dst in out:
            if reply == RUNNING:
                pred.setdefault(dst, []).append(key)
    todo = deque(good)
    while todo:
        key = todo.popleft()
        for p in pred.get(key, ()):
            if p not in good:
                good.add(p)
                todo.append(p)
    return good, succ


def _explain(prog, skill, params, source, limit=60) -> dict:
    """What the FSM does from ``source`` when ``skill`` is requested on every tick and
    every primitive succeeds: up to the first repeated state or non-RUNNING reply."""
    f = prog.model.fsm(skill.fsm)
    steps, seen, state = [], set(), source
    for _ in range(limit):
        seen.add(state)
        res = prog.fsm_step(state, skill.fsm, skill.goal, params, SucceedOracle(), record=True)
        fired = [ev[2] for ev in res.events or () if ev[0] == "fire"]
        na = any(ev[0] == "not-applicable" for ev in res.events or ())
        token, _ = prog.fsm_state(res.state, skill.fsm)
        steps.append({"reply": Status(res.status).name, "fired": fired, "state": token,
                      **({"not_applicable": True} if na else {})})
        if res.status != RUNNING:
            break
        state = res.state
        if state in seen:
            steps[-1]["repeats"] = True
            break
    token, held = prog.fsm_state(source, skill.fsm)
    world = {v.name: prog.decode_slot(k, source[k]) for k, v in enumerate(prog.model.variables)}
    pvals = dict(zip((p.name for p in f.params), params))
    return {"fsm": skill.fsm, "from_state": token, "held_goal": held, "variables": world,
            "request": skill.goal, "params": pvals, "steps": steps}


def check_support(d: Derivation, *, where: str = "switch", budget: int = 1_000_000,
                  max_seconds: "float | None" = None) -> list:
    """Check every derived transition against the FSMs (step 5); a list of Support.

    ``where="switch"`` (default): from every state right after a tick in which the tree
    switched from ``a`` to ``b`` (``b`` held, its first FSM tick done). ``where="held"``:
    for a preemption, from every reachable state in which ``a`` is held, and after
    completion (failure), from every state right after ``a`` replied SUCCESS (FAILURE),
    whatever the tree would request there. The second is stricter than the tree needs
    when ``b``'s FSM refuses on purpose in states where the tree never asks for ``b``
    (a guarded FAILURE marker that reads a world variable).

    ``budget`` bounds the FSM-level states of each region searched, ``max_seconds`` the
    time; hitting either raises ``btfsm.verify.search.BudgetExceeded``."""
    if where not in ("switch", "held"):
        raise ValueError(f"where must be 'switch' or 'held', not {where!r}")
    prog = d.model.program
    drop = _tree_slots(prog)
    clock = Budget(max_seconds=max_seconds) if max_seconds is not None else None
    out = []
    regions: dict = {}
    for (a, b, kind), pair in sorted(d.pairs.items(), key=lambda kv: (str(kv[0][0]), kv[0][1], kv[0][2])):
        if where == "switch":
            sources = d.switched.get((a, b, kind), set())  # (state, params) pairs
        else:
            if kind == "first":
                states = {prog.initial}
            elif kind == "preemption" or kind == "concurrent":
                states = d.held.get(a, set())
            else:
                states = d.ended.get((a, "success" if kind == "completion" else "failure"), set())
            sources = {(s, p) for s in states for p in d.params.get(b, {()})}
        skill = d.skills[b]
        by_params: dict = {}
        for s, params in sources:
            by_params.setdefault(params, {}).setdefault(_project(s, drop), s)
        bad = None
        for params in sorted(by_params):
            keys = by_params[params]
            cache_key = (b, params)
            region: Any = regions.get(cache_key)
            missing = [k for k in keys if region is None or k not in region[1]]
            if missing:
                start = set(missing) | (region[1] if region else set())
                good, _ = _good_region(prog, skill, params, start, drop, budget, clock)
                if good is None:
                    raise BudgetExceeded("states", f"state budget of {budget:,} FSM states hit while checking "
                                                   f"FSM support of {skill.goal}")
                region = (good, start)
                regions[cache_key] = region
            for k in sorted(keys, key=lambda k: repr(prog.decode(k))):
                if k not in region[0]:
                    bad = _explain(prog, skill, params, keys[k])
                    break
            if bad is not None:
                break
        n_keys = sum(len(v) for v in by_params.values())
        out.append(Support(a, b, kind, bad is None, n_keys, bad))
    return out


# --------------------------------------------------------------------------- output
def _matrix(d: Derivation) -> list:
    names = [d.name(i) for i in range(len(d.skills))]
    cells: dict = {}
    for (a, b, kind) in d.pairs:
        if a is not None:
            cells.setdefault((a, b), []).append(_MARK[kind])
    width = max([len(n) for n in names] + [6])
    rows = ["last \\ next".ljust(width) + " | " + " | ".join(n.ljust(width) for n in names)]
    rows.append("-" * len(rows[0]))
    for a, na in enumerate(names):
        marks = ["/".join(sorted(cells.get((a, b), []), key="CPF|".index)) or "." for b in range(len(names))]
        rows.append(na.ljust(width) + " | " + " | ".join(m.ljust(width) for m in marks))
    return rows


def format_text(d: Derivation, support: "list | None" = None) -> str:
    """The report for people: skills, diagram, counts, FSM support."""
    c = counts(d)
    lines = [f"skills of {d.model.name}: {c['skills']} ((fsm, goal) pairs requested by the tree)"]
    for i, s in enumerate(d.skills):
        lines.append(f"  {d.name(i)}: FSM {s.fsm}, goal {s.goal}, nodes {', '.join(s.nodes)}")
    lines.append("")
    lines.append("transition diagram (row: last skill, column: next skill; C after completion, P preemption, F after failure)")
    lines += ["  " + r for r in _matrix(d)]
    firsts = sorted(d.name(b) for (a, b, k) in d.pairs if k == "first")
    if firsts:
        lines.append(f"  first skill of a run: {', '.join(firsts)}")
    lines.append("")
    lines.append(f"requested transitions: {c['completion_or_preemption']} of {c['possible']} = {c['completion']} after "
                 f"completion + {c['only_by_preemption']} only by preemption ({c['preemption']} pairs can happen by "
                 f"preemption, {c['completion_and_preemption']} of them also after completion)")
    lines.append(f"all transitions, also those after a failure ({c['failure']} pairs)"
                 + (f" and concurrent starts ({c['concurrent']} pairs)" if c["concurrent"] else "")
                 + f": {c['distinct']} of {c['possible']}")
    for kind in ("preemption", "completion", "failure", "concurrent"):
        ps = sorted((p for p in d.pairs.values() if p.kind == kind and p.a is not None), key=lambda p: (p.a, p.b))
        if ps:
            lines.append(f"  {kind}: " + ", ".join(
                f"{d.name(p.a)} -> {d.name(p.b)} ({len(p.witness)} ticks"
                + (f"; refused by the FSM {p.refused} of {p.count} times" if p.refused else "") + ")" for p in ps))
    lines.append(f"explored {d.states} product states ({d.model_states} model states), {d.transitions} transitions "
                 f"in {d.seconds:.2f} s{'' if d.complete else f' -- INCOMPLETE: {describe_hit(d.stopped)} hit'}")
    if d.errors:
        lines.append(f"note: {len(d.errors)} transitions raised a domain error and were left out ({d.errors[0][2]})")
    if support is not None:
        bad = [s for s in support if not s.supported]
        lines.append("")
        lines.append(f"FSM support: {len(support) - len(bad)} of {len(support)} derived transitions supported")
        for s in bad:
            lines.append(f"  UNSUPPORTED {s.kind} {d.name(s.a)} -> {d.name(s.b)}:")
            lines += ["    " + x for x in _explain_text(s.counterexample)]
    return "\n".join(lines)


def _explain_text(cx: dict) -> list:
    params = "".join(f", {k}={v}" for k, v in cx["params"].items())
    out = [f"from state '{cx['from_state']}' (held goal {cx['held_goal']}; "
           + ", ".join(f"{k}={v}" for k, v in cx["variables"].items()) + ")",
           f"requesting {cx['request']}{params} on every tick, with every primitive succeeding:"]
    for k, st in enumerate(cx["steps"]):
        extra = " (goal not applicable here)" if st.get("not_applicable") else ""
        fired = f" fires {', '.join(st['fired'])}" if st["fired"] else " fires nothing"
        out.append(f"  tick {k + 1}:{fired}; reply {st['reply']}; token at '{st['state']}'{extra}"
                   + (" -- the same state again: it never gets further" if st.get("repeats") else ""))
    out.append(f"  no choice of outcomes reaches the SUCCESS reply of {cx['request']} from there")
    return out


def to_dot(d: Derivation, support: "list | None" = None) -> str:
    """The transition diagram in Graphviz dot: solid after completion, dashed preemption,
    dotted after failure; unsupported transitions in red."""
    bad = {(s.a, s.b, s.kind) for s in support or () if not s.supported}
    style = {"completion": "solid", "preemption": "dashed", "failure": "dotted", "concurrent": "bold"}
    lines = [f'digraph "{d.model.name} skills" {{', "  rankdir=LR;", '  node [shape=box, style=rounded];']
    for i in range(len(d.skills)):
        lines.append(f'  s{i} [label="{d.name(i)}"];')
    for (a, b, kind), p in sorted(d.pairs.items(), key=lambda kv: (str(kv[0][0]), kv[0][1], kv[0][2])):
        if a is None:
            continue
        colour = ', color=red, fontcolor=red, label="unsupported"' if (a, b, kind) in bad else ""
        lines.append(f"  s{a} -> s{b} [style={style[kind]}{colour}];")
    lines.append("}")
    return "\n".join(lines) + "\n"


def to_json(d: Derivation, support: "list | None" = None) -> dict:
    """Plain data for tools."""
    sup = {(s.a, s.b, s.kind): s for s in support or ()}
    trans = []
    for (a, b, kind), p in sorted(d.pairs.items(), key=lambda kv: (str(kv[0][0]), kv[0][1], kv[0][2])):
        item = {"from": None if a is None else d.name(a), "to": d.name(b), "kind": kind, "count": p.count,
                "refused": p.refused,
                "witness": [list(s) for s in p.witness]}
        s = sup.get((a, b, kind))
        if s is not None:
            item["supported"] = s.supported
            item["sources"] = s.sources
            item["counterexample"] = s.counterexample
        trans.append(item)
    return {"model": d.model.name, "skills": [{"name": d.name(i), "fsm": s.fsm, "goal": s.goal, "nodes": list(s.nodes)}
                                              for i, s in enumerate(d.skills)],
            "counts": counts(d), "transitions": trans, "states": d.states, "model_states": d.model_states,
            "explored_transitions": d.transitions, "complete": d.complete, "budget": d.stopped,
            "seconds": round(d.seconds, 4),
            "domain_errors": len(d.errors)}


# --------------------------------------------------------------------------- CLI
def _load(args):
    from btfsm.files import load_cli_model

    return load_cli_model(args)


def args_skills(sp) -> None:
    """The flags of ``btfsm skills`` (``btfsm.cli.COMMANDS``)."""
    from btfsm import cliargs

    cliargs.model(sp)
    sp.add_argument("--format", choices=("text", "dot", "json"), default="text")
    sp.add_argument("--json", dest="format", action="store_const", const="json", help="same as --format json")
    cliargs.max_states(sp)
    cliargs.budgets(sp)


def cli_skills(args) -> int:
    """``btfsm skills MODEL [--format text|dot|json] [--max-states N] [--max-transitions N]
    [--max-seconds S]``: exit 0 when every derived transition is supported, 1 when one is
    not, 3 when a budget was hit."""
    import sys

    max_transitions, max_seconds = args.max_transitions, args.max_seconds  # ranges checked by the parser
    model = _load(args)
    if model.tree is None:
        raise ModelError("tree", f"{model.name} has no tree: there are no skill requests to derive from")
    from btfsm.progress import ExplorationProgress

    max_states = args.max_states if args.max_states is not None else 2_000_000
    with ExplorationProgress() as bar:  # on a terminal only, after a second
        d = derive(model, max_states=max_states, max_transitions=max_transitions, max_seconds=max_seconds,
                   progress=lambda states, seconds: bar("skills", states))
    support: Any = None
    if d.complete:
        try:
            support = check_support(d, budget=min(max_states, 1_000_000),
                                    max_seconds=None if max_seconds is None else max(max_seconds - d.seconds, 1e-9))
        except BudgetExceeded as exc:
            print(f"btfsm skills: incomplete: {exc}; explored {d.states:,} product states, {d.transitions:,} "
                  f"transitions (raise the budget)", file=sys.stderr)
            return 3
    if args.format == "json":
        print(json.dumps(to_json(d, support), indent=1))
    elif args.format == "dot":
        print(to_dot(d, support), end="")
    else:
        print(format_text(d, support))
    if not d.complete:
        hit = describe_hit(d.stopped, max_states, max_transitions, max_seconds)
        print(f"btfsm skills: incomplete: the {hit} was hit after {d.states:,} product states, {d.transitions:,} "
              f"transitions, {d.seconds:.2f} s (raise it)", file=sys.stderr)
        return 3
    return 0 if all(s.supported for s in support) else 1
