"""Problems of a model's checks that the loader repairs to look for the next one.

``Model`` checks itself and stops at its first problem. For most problems the loader
takes the element out (``reading._without``); the ones here need more than that, and are
repaired so that nothing reported later follows from them (docs/model-files.md, "Every
problem at once"):

* a duplicate name: the later duplicate is taken out (a state, a goal, an edge or marker
  id, an event or choice option, an outcome, a parameter, an invariant, a resource, a
  variable, a primitive, an FSM) and its uses resolve to the first; a tree node, which
  cannot be taken out of its parent, and an inline primitive declared twice are renamed
  instead, so that what they hold is still checked;
* a variable's (or an FSM parameter's) declaration: kept with a repaired declaration
  (bounds in order and within the int limits, an initial value outside the domain
  replaced by the default, an enum's repeated or unusable values dropped), so that its
  uses are not reported unknown; a declaration that cannot be repaired (a name that is
  not an identifier, no usable enum value) is taken out and the errors about its name
  are not reported;
* a variable and an FSM of one name: the variable is taken out, the errors about its
  name are not reported (its uses are expressions, which stop at their first unknown
  name anyway; the FSM holds more that can still be checked);
* a cycle of direct edges: reported once, at the edge that closes it, which is read as
  a non-direct edge from then on (its guard and effects are still checked);
* a resource that names an unknown node, a node that is not an Action or SkillRequest,
  or a node twice: that member is taken out (the resource too when it has no other).

``repair(reader, kw, exc)`` returns ``Repair`` or None when ``exc`` is none of these.
"""
from __future__ import annotations

import dataclasses
import functools
import re
from typing import Any, Callable, NamedTuple, Optional

from ..bt import Action, Composite, Decorator, Node, SkillRequest, walk
from ..errors import ModelError
from ..expr import INT_LIMIT
from ..model import EnvChoice
from ..primitives import PASS, Outcome
from ..status import Status
from ..world import Bool, Enum, Int, Var, check_label, check_name

from .text import err, where_of


class Repair(NamedTuple):
    """The Model's arguments repaired, the problem as reported and the names whose
    problems follow from it (a declaration taken out)."""

    kw: dict
    error: ModelError
    hidden: frozenset = frozenset()
    also: tuple = ()  # problems of the same kind that the repair takes away before they are found


_DUP = re.compile(r"duplicate (variable|primitive|state|goal|edge id|marker id|parameter|name|node name) '(.*)'"
                  r"(?: \(node names are trace ids\))?\Z")
_CYCLE = re.compile(r"direct edges form a cycle for goal '(.*)': (.*) \(a direct chain must end\)\Z")


def repair(reader, kw: dict, exc: ModelError) -> "Repair | None":
    """``Repair`` for ``exc``, a problem of ``Model(**kw)``'s checks, or None."""
    el, problem = exc.element or "", str(exc.problem)
    dup = _DUP.match(problem)
    fsms = kw.get("fsms") or ()
    for f in fsms:
        head = f"fsms.{f.name}"
        twice = [st.id for st in f.states if el == f"{head}.states.{st.id}" or el.startswith(f"{head}.states.{st.id}.")]
        if twice and twice.count(twice[0]) > 1:  # a problem of a duplicate state (found before the duplicate)
            return _fsm_duplicate(reader, kw, ModelError(f"{head}.states", f"duplicate state '{twice[0]}'"), f, "states",
                                  twice[0])
        again = [g for i, g in enumerate(f.goals) if g in f.goals[:i]]
        if again and f" is not a goal of {f.name} (" in problem:  # a message that lists the goals (found before)
            return _fsm_duplicate(reader, kw, ModelError(f"{head}.goals", f"duplicate goal '{again[0]}'"), f, "goals", again[0])
        if not f.goals and f" is not a goal of {f.name} (" in problem:  # a request of an FSM without goals
            return _fsm_out(reader, kw, ModelError(f"{head}.goals", "an FSM needs at least one goal"), f)
        both = next((st for st in f.states if st.primitive and st.subtree is not None
                     and (el == f"{head}.states.{st.id}" or el.startswith(f"{head}.states.{st.id}."))), None)
        if both is not None:  # a state that runs both (its primitive's problems are found before): the subtree is kept
            new_st = dataclasses.replace(both, primitive="")
            return Repair(_replace_fsm(kw, f, dataclasses.replace(f, states=tuple(new_st if x is both else x for x in f.states))),
                          reader.translate(ModelError(f"{head}.states.{both.id}", "runs both a primitive and a subtree")))
        if el == head and problem == f"name '{f.name}' is used twice":
            return _fsm_name_twice(reader, kw, exc, f)
        if (el == head and (problem == "has no states" or problem.startswith(f"FSM name {f.name!r} is "))
                or (el == f"{head}.goals" and problem == "an FSM needs at least one goal")):
            return _fsm_out(reader, kw, exc, f)
        reentrant = re.match(r"requests FSM '(.*)' while '(.*)' is being ticked \(a re-entrant request\)\Z", problem)
        if reentrant:
            st = next((st for st in f.states if el == f"{head}.states.{st.id}.subtree" and st.subtree is not None), None)
            if st is not None:
                return _without_requests(reader, kw, exc, f, st, reentrant.group(1))
        if el in (f"{head}.retarget", f"{head}.withdraw_goal"):
            return Repair(_replace_fsm(kw, f, dataclasses.replace(f, retarget="immediate", withdraw_goal="")),
                          reader.translate(exc))
        if dup and el in (f"{head}.states", f"{head}.goals", f"{head}.edges", f"{head}.markers", f"{head}.params"):
            return _fsm_duplicate(reader, kw, exc, f, el[len(head) + 1:], dup.group(2))
        cycle = _CYCLE.match(problem)
        if cycle and el == f"{head}.edges":
            return _cycle(reader, kw, exc, f, cycle.group(1), cycle.group(2).split(" -> "))
        p = next((p for p in f.params if el == f"{head}.params.{p.name}"), None)
        if p is not None and problem == f"parameter '{p.name}' hides a variable":
            return _hiding_param(reader, kw, exc, p.name)
        if p is not None:
            return _declaration(reader, kw, exc, p, lambda v: _replace_param(kw, f, p, v), f.name)
    if el.startswith("variables."):
        var = next((v for v in kw.get("variables") or () if el == f"variables.{v.name}"), None)
        if var is not None:
            if dup and dup.group(1) == "variable":
                return Repair(dict(kw, variables=_without_later(kw["variables"], lambda v: v.name, var.name)),
                              reader.translate(exc))
            return _declaration(reader, kw, exc, var, lambda v: _replace_var(kw, var, v))
    if dup and dup.group(1) == "node name":
        return _node_twice(reader, kw, exc, dup.group(2))
    m = re.match(r"primitive '(.*)' is declared twice", problem)
    if m:
        return _primitive_twice(reader, kw, exc, m.group(1))
    if dup and dup.group(1) == "primitive" and el.startswith("primitives."):
        return Repair(dict(kw, primitives=_without_later(kw["primitives"], lambda p: p.name, dup.group(2))), reader.translate(exc))
    if dup and el.endswith(".outcomes"):
        return _outcome_twice(reader, kw, exc, el[:-len(".outcomes")], dup.group(2))
    if dup and el == "environment":
        return _event_twice(reader, kw, exc, dup.group(2))
    if el.startswith("environment.") and problem == "a choice needs options":
        env = kw.get("environment") or ()
        return Repair(dict(kw, environment=tuple(e for e in env if el != f"environment.{e.name}")), reader.translate(exc),
                      hidden=frozenset({el[len("environment."):]}))
    if dup and el == "invariants":
        return Repair(dict(kw, invariants=_without_later(kw["invariants"], lambda x: x[0], dup.group(2))), reader.translate(exc))
    if el.startswith("resources."):
        return _resource(reader, kw, exc)
    return None


# ------------------------------------------------------------------ helpers
def _without_later(items, key: Callable[[Any], str], name: str) -> tuple:
    """``items`` without the second one whose ``key`` is ``name``."""
    seen = 0
    out = []
    for x in items:
        if key(x) == name:
            seen += 1
            if seen == 2:
                continue
        out.append(x)
    return tuple(out)


def _site_error(reader, model_path: str, k: int, problem: str, exc: ModelError) -> ModelError:
    """``problem`` at the ``k``-th place in the file that the model element ``model_path``
    comes from (``reader.sites``); where it is not known, ``exc`` translated as usual."""
    sites = reader.sites.get(model_path) or []
    if k < len(sites):
        path, parent, key = sites[k]
        return err(path, problem + where_of(parent, key), reader.file)
    return reader.translate(exc)


def _replace_fsm(kw: dict, f, new) -> dict:
    return dict(kw, fsms=tuple(new if g is f else g for g in kw["fsms"]))


# ------------------------------------------------------------------ FSMs
def _fsm_name_twice(reader, kw, exc, f) -> Repair:
    if any(v.name == f.name for v in kw.get("variables") or ()):
        # a variable and an FSM: the variable goes, its uses are not reported
        return Repair(dict(kw, variables=tuple(v for v in kw["variables"] if v.name != f.name)), reader.translate(exc),
                      hidden=frozenset({f.name}))
    later = [g for g in kw["fsms"] if g.name == f.name][1]
    return Repair(dict(kw, fsms=tuple(g for g in kw["fsms"] if g is not later)), reader.translate(exc))


def _fsm_out(reader, kw, exc, f) -> Repair:
    """An FSM of which nothing can be checked (no states, no goals, a name that is not an
    identifier) goes, and the problems of its requests and of its names with it."""
    return Repair(dict(kw, fsms=tuple(g for g in kw["fsms"] if g is not f)), reader.translate(exc),
                  hidden=frozenset({f"FSM {f.name}"}))


def pass_action(node: Node) -> Action:
    """An Action of ``node``'s name that runs the instant ``pass`` primitive (one SUCCESS)."""
    return Action(node.name, primitive=PASS.name, outcomes=(Outcome(Status.SUCCESS),))


def _without_requests(reader, kw, exc, f, st, fsm: str) -> Repair:
    """The requests of ``fsm`` in ``st``'s subtree (one leads back to the FSM being ticked)
    become Actions that succeed at once."""
    def change(n: Node) -> Node:
        return pass_action(n) if isinstance(n, SkillRequest) and n.fsm == fsm else n

    new_st = dataclasses.replace(st, subtree=_rebuild(st.subtree, change))
    return Repair(_replace_fsm(kw, f, dataclasses.replace(f, states=tuple(new_st if x is st else x for x in f.states))),
                  reader.translate(exc))


def _fsm_duplicate(reader, kw, exc, f, kind: str, name: str) -> Repair:
    head = f"fsms.{f.name}"
    if kind == "goals":
        new = dataclasses.replace(f, goals=_without_later(f.goals, str, name))
        return Repair(_replace_fsm(kw, f, new), reader.translate(exc))
    key: Callable[[Any], str] = {"states": lambda s: s.id, "edges": lambda e: e.id, "markers": lambda m: m.id,
                                 "params": lambda p: p.name}[kind]
    new = dataclasses.replace(f, **{kind: _without_later(getattr(f, kind), key, name)})
    at = f"{head}.{kind}.{name}"
    gone = reader.shifts[at] = reader.shifts.get(at, 0) + 1  # the later ones taken out before this one
    return Repair(_replace_fsm(kw, f, new), _site_error(reader, at, gone, exc.problem, exc))


def _cycle(reader, kw, exc, f, goal: str, path: list) -> "Repair | None":
    """The direct edges of ``goal`` that close the cycle ``path`` become non-direct."""
    last, first = path[-2], path[-1]
    closing = [e for e in f.edges if e.direct and goal in e.goals and e.source == last and e.target == first]
    if not closing:
        return None
    edges = tuple(dataclasses.replace(e, direct=False) if e in closing else e for e in f.edges)
    new = dataclasses.replace(f, edges=edges)
    return Repair(_replace_fsm(kw, f, new), _site_error(reader, f"fsms.{f.name}.edges.{closing[0].id}", 0, exc.problem, exc))


# ------------------------------------------------------------------ declarations
def _repaired_var(var: Var) -> "Var | None":
    """A declaration like ``var`` that passes its checks, or None when there is none. An
    enum value dropped here is never a valid value: a use of it is a problem of its own."""
    try:
        check_name(var.name, "", "variable name")
    except ModelError:
        return None
    new: Optional[Var]
    if var.kind == "enum":
        keep: list = []
        for v in var.values:
            try:
                if isinstance(v, str) and v not in keep:
                    keep.append(check_label(v, ""))
            except ModelError:
                continue  # not a valid label: left out (its problem is reported where it is declared)
        new = Enum(var.name, keep, var.init if var.init in keep else None) if keep else None
    elif var.kind == "int":
        if not all(isinstance(b, int) and not isinstance(b, bool) for b in (var.lo, var.hi)):
            return None
        lo, hi = sorted((max(-INT_LIMIT, min(INT_LIMIT, var.lo)), max(-INT_LIMIT, min(INT_LIMIT, var.hi))))
        init = var.init if isinstance(var.init, int) and not isinstance(var.init, bool) and lo <= var.init <= hi else None
        new = Int(var.name, lo, hi, init)
    elif var.kind == "bool":
        new = Bool(var.name, var.init if isinstance(var.init, bool) else False)
    else:
        return None
    try:
        return None if new is None else new.validated("")
    except ModelError:
        return None


def _declaration(reader, kw, exc, var: Var, replace: Callable[["Var | None"], dict], fsm: str = "") -> Repair:
    """A variable's or parameter's declaration repaired, or taken out with its name hidden."""
    new = _repaired_var(var)
    hidden: frozenset = frozenset()
    if new is None:
        hidden = frozenset({var.name} | ({f"{fsm}.{var.name}", f"params of {fsm}"} if fsm else set()))
    return Repair(replace(new), reader.translate(exc), hidden=hidden)


def _hiding_param(reader, kw, exc, name: str) -> Repair:
    """A parameter of the name of a variable: the variable is taken out (the FSM's
    expressions mean the parameter, as it hides the variable there), the problems about
    its name elsewhere are not reported, and every FSM with a parameter of that name is
    reported now (the variable gone, they would not be found)."""
    others = tuple(reader.translate(ModelError(f"fsms.{g.name}.params.{name}", str(exc.problem)))
                   for g in kw["fsms"] if any(q.name == name for q in g.params) and f"fsms.{g.name}.params.{name}" != exc.element)
    return Repair(dict(kw, variables=tuple(v for v in kw.get("variables") or () if v.name != name)), reader.translate(exc),
                  hidden=frozenset({name}), also=others)


def _replace_var(kw, var, new) -> dict:
    return dict(kw, variables=tuple(x for x in (new if v is var else v for v in kw["variables"]) if x is not None))


def _replace_param(kw, f, p, new) -> dict:
    params = tuple(x for x in (new if q is p else q for q in f.params) if x is not None)
    return _replace_fsm(kw, f, dataclasses.replace(f, params=params))


# ------------------------------------------------------------------ tree nodes and primitives
def _roots(kw) -> list:
    """``(element path, subtree)`` as ``Model.roots`` lists them."""
    out = [("tree", kw["tree"])] if kw.get("tree") is not None else []
    for f in kw.get("fsms") or ():
        out += [(f"fsms.{f.name}.states.{st.id}.subtree", st.subtree) for st in f.states if st.subtree is not None]
    return out


def _rebuild(node: Node, change: Callable[[Node], Node]) -> Node:
    """``node`` with ``change`` applied to each of its nodes (pre-order, as ``walk``)."""
    new = change(node)
    if isinstance(new, Composite):
        kids = tuple(_rebuild(c, change) for c in new.children)
        if any(a is not b for a, b in zip(kids, new.children)):
            new = dataclasses.replace(new, children=kids)
    elif isinstance(new, Decorator) and new.child is not None:
        kid = _rebuild(new.child, change)
        if kid is not new.child:
            new = dataclasses.replace(new, child=kid)
    return new


def _change_roots(kw, change: Callable[[str, Node], Node]) -> dict:
    """``kw`` with ``change(root path, node)`` applied to every node of every root, in order."""
    out = dict(kw)
    if kw.get("tree") is not None:
        out["tree"] = _rebuild(kw["tree"], functools.partial(change, "tree"))
    if kw.get("fsms"):
        fsms = []
        for f in kw["fsms"]:
            states = tuple(st if st.subtree is None else dataclasses.replace(
                st, subtree=_rebuild(st.subtree, functools.partial(change, f"fsms.{f.name}.states.{st.id}.subtree")))
                for st in f.states)
            fsms.append(f if all(a is b for a, b in zip(states, f.states)) else dataclasses.replace(f, states=states))
        out["fsms"] = tuple(fsms)
    return out


def _fresh(name: str, used: set) -> str:
    k = 1
    while f"{name}~{k}" in used:
        k += 1
    return f"{name}~{k}"


def _node_twice(reader, kw, exc, name: str) -> "Repair | None":
    """The second node named ``name`` (in ``Model.roots`` order) gets a name of its own."""
    used = {n.name for _, r in _roots(kw) for n in walk(r)}
    fresh = _fresh(name, used)
    originals = reader.renamed
    seen, where = [0], []
    per_root: dict = {}

    def change(root: str, n: Node) -> Node:
        if originals.get(n.name, n.name) != name:
            return n
        k = per_root.get(root, 0)
        per_root[root] = k + 1
        if n.name != name:
            return n
        seen[0] += 1
        if seen[0] != 2:
            return n
        where.append((root, k))
        return dataclasses.replace(n, name=fresh)

    new = _change_roots(kw, change)
    if not where:
        return None
    root, k = where[0]
    sites = [s for s in reader.sites.get(f"{root}.{name}") or ()
             if root != "tree" or s[0] == "tree" or s[0].startswith(("tree.", "tree["))]
    reader.renamed[fresh] = name
    if k < len(sites):
        for prefix in ("tree", root):
            reader.where[f"{prefix}.{fresh}"] = sites[k]
        path, parent, key = sites[k]
        error = err(path, str(exc.problem) + where_of(parent, key), reader.file)
    else:
        error = reader.translate(exc)
    return Repair(new, error)


def _change_inline(kw, head: str, change: Callable[[Any], Any]) -> "dict | None":
    """``kw`` with ``change`` applied to the state or Action ``head`` (a Model element path)
    that declares its primitive inline; None when there is none."""
    for f in kw.get("fsms") or ():
        for st in f.states:
            if head == f"fsms.{f.name}.states.{st.id}" and st.outcomes is not None:
                return _replace_fsm(kw, f, dataclasses.replace(f, states=tuple(change(x) if x is st else x for x in f.states)))
    done = [False]

    def at(root: str, n: Node) -> Node:
        if done[0] or head != f"{root}.{n.name}" or not isinstance(n, Action) or n.outcomes is None:
            return n
        done[0] = True
        return change(n)

    new = _change_roots(kw, at)
    return new if done[0] else None


def _primitive_twice(reader, kw, exc, prim: str) -> "Repair | None":
    """An inline declaration of a primitive declared before gets a primitive name of its own."""
    names = {p.name for p in kw.get("primitives") or ()}
    names |= {n.primitive for _, r in _roots(kw) for n in walk(r) if isinstance(n, Action)}
    names |= {st.primitive or st.id for f in kw.get("fsms") or () for st in f.states}
    fresh = _fresh(prim, names)
    new = _change_inline(kw, exc.element or "", lambda x: dataclasses.replace(x, primitive=fresh))
    return None if new is None else Repair(new, reader.translate(exc))


def _outcome_twice(reader, kw, exc, head: str, name: str) -> "Repair | None":
    """The second outcome named ``name`` of the primitive, state or node ``head`` goes."""
    def fewer(outcomes):
        return _without_later(outcomes, lambda o: o.name, name)

    for p in kw.get("primitives") or ():
        if head == f"primitives.{p.name}":
            new_p = dataclasses.replace(p, outcomes=fewer(p.outcomes))
            return Repair(dict(kw, primitives=tuple(new_p if q is p else q for q in kw["primitives"])), reader.translate(exc))
    new = _change_inline(kw, head, lambda x: dataclasses.replace(x, outcomes=fewer(x.outcomes)))
    return None if new is None else Repair(new, reader.translate(exc))


# ------------------------------------------------------------------ environment and resources
def _event_twice(reader, kw, exc, name: str) -> "Repair | None":
    """The second event, choice or option named ``name`` goes (a choice left without
    options goes too, and the errors about its name and its options' are not reported)."""
    seen = 0
    env = list(kw.get("environment") or ())
    index = reader.shifts.setdefault("environment", list(range(len(env))))  # where each is in the file
    for i, ev in enumerate(env):
        seen += ev.name == name
        if seen == 2:
            gone = {ev.name} | {o.name for o in getattr(ev, "options", ())}
            error = _site_error(reader, f"environment[{index.pop(i)}]", 0, exc.problem, exc)
            return Repair(dict(kw, environment=tuple(e for e in env if e is not ev)), error, hidden=frozenset(gone - {name}))
        if isinstance(ev, EnvChoice):
            for k, opt in enumerate(ev.options):
                seen += opt.name == name
                if seen == 2:
                    at = f"environment.{ev.name}.options"
                    where = reader.shifts.setdefault(at, list(range(len(ev.options))))
                    error = _site_error(reader, f"{at}[{where.pop(k)}]", 0, exc.problem, exc)
                    options = tuple(o for j, o in enumerate(ev.options) if j != k)
                    if not options:
                        index.pop(i)
                        return Repair(dict(kw, environment=tuple(e for e in env if e is not ev)), error,
                                      hidden=frozenset({ev.name}))
                    env[i] = dataclasses.replace(ev, options=options)
                    return Repair(dict(kw, environment=tuple(env)), error)
    return None


def _resource(reader, kw, exc) -> "Repair | None":
    """A resource declared twice (the second goes), or a member of one that is unknown,
    not an Action or SkillRequest, or listed twice (that member goes; the problem keeps
    the member's index in the file)."""
    el, problem = exc.element or "", str(exc.problem)
    items = list(kw.get("resources") or ())
    if problem.startswith("resource '") and problem.endswith("' is declared twice"):
        return Repair(dict(kw, resources=_without_later(items, lambda r: r[0], el[len("resources."):])), reader.translate(exc))
    for i, (name, members) in enumerate(items):
        for k in range(len(members)):
            if el == f"resources.{name}[{k}]" and (problem.startswith("unknown node") or " is listed twice" in problem
                                                  or "a resource lists Action and SkillRequest" in problem):
                index = reader.shifts.setdefault(f"resources.{name}", list(range(len(members))))
                error = reader.translate(ModelError(f"resources.{name}[{index.pop(k)}]", problem))
                rest = tuple(m for j, m in enumerate(members) if j != k)
                if rest:
                    items[i] = (name, rest)
                else:
                    del items[i]
                return Repair(dict(kw, resources=tuple(items)), error)
    return None


def hides(exc: ModelError, hidden: set) -> bool:
    """Whether ``exc`` is about a name in ``hidden`` (a declaration taken out): an unknown
    variable, name or event, the parameters of an FSM whose parameter was taken out, or
    an FSM taken out (``FSM NAME``: a request of it, one of its goals, a name ``NAME.x``)."""
    problem = str(exc.problem)
    m = re.search(r"unknown (?:name|variable) '([^']*)'|no environment event or option '([^']*)'", problem)
    if m and (m.group(1) or m.group(2)) in hidden:
        return True
    if m and m.group(1) and f"FSM {m.group(1).partition('.')[0]}" in hidden:
        return True
    m = re.match(r"unknown FSM '(.*)'\Z|'.*' is not a goal of (.*) \(|(\S+) takes parameters ", problem)
    return bool(m and (f"FSM {m.group(1) or m.group(2) or m.group(3)}" in hidden or f"params of {m.group(3)}" in hidden))

