"""Run one btfsm tree in real py_trees 2.6 and in btfsm (semantics="pytrees"), tick by tick.

Leaves are Actions whose status on tick ``t`` is ``table[leaf][t]`` (a pure function of
the tick and the leaf, so halting a leaf cannot change later answers); a Guard's
condition is ``table[guard][t]`` (set by an environment choice before the tree ticks in
btfsm, read by py_trees' EternalGuard). Both sides log the leaf lifecycle in order:
``("start", leaf)`` (py_trees ``initialise``; btfsm: an idle leaf is ticked),
``("tick", leaf, status)`` (``update``; btfsm: the oracle is asked the outcome) and
``("halt", leaf)`` (``stop(INVALID)`` of a RUNNING leaf; btfsm: the oracle is told
the primitive was abandoned), then ``("root", status)`` after every tick.
"""
from __future__ import annotations

import py_trees

from btfsm import Action, Bool, EnvChoice, EnvEvent, Guard, Model, Outcome, Status, walk
from btfsm.interop.pytrees import AnswerBehaviour, from_pytrees, node_names, to_pytrees
from btfsm.oracles import Oracle

STATUS = {"R": Status.RUNNING, "S": Status.SUCCESS, "F": Status.FAILURE}


def leaf(name, answers):
    """An Action answering ``answers[t]`` ('R', 'S' or 'F') on tick t; its declared
    outcomes are the statuses it uses (so RUNNING-free leaves have no running flag)."""
    used = sorted({STATUS[a] for a in answers})
    return Action(name, outcomes=tuple(Outcome(s) for s in used))


def build_model(tree, semantics="pytrees"):
    """The btfsm model: one bool variable and one environment choice per Guard."""
    guards = [n for n in walk(tree) if isinstance(n, Guard)]
    variables = tuple(Bool(f"{g.name}_open", True) for g in guards)
    env = tuple(EnvChoice(f"{g.name}_open", (EnvEvent(f"{g.name}_on", effects={f"{g.name}_open": True}),
                                             EnvEvent(f"{g.name}_off", effects={f"{g.name}_open": False})))
                for g in guards)
    return Model("peer", variables=variables, tree=tree, environment=env, semantics=semantics)


class LogOracle(Oracle):
    """Answers from the tables; logs start/tick/halt like the py_trees stub does.
    ``key`` maps a btfsm node name to its name in the tables (default: itself)."""

    def __init__(self, table, guards, log, key=None):
        self.table, self.guards, self.log = table, guards, log
        self.key = key or {}
        self.t = 0
        self.running: dict = {}

    def env(self, i):
        return False

    def choose(self, i, enabled):
        return 0 if self.table[self.guards[i]][self.t] != "F" else 1

    def outcome(self, site):
        name = self.key.get(site.node, site.node)
        if name not in self.table:  # a blackboard write (one outcome), not a logged leaf
            return 0
        a = STATUS[self.table[name][self.t]]
        if not self.running.get(name):
            self.log.append(("start", name))
        self.log.append(("tick", name, a.name))
        self.running[name] = a == Status.RUNNING
        return [o[0] for o in site.outcomes].index(int(a))

    def halt(self, site):
        name = self.key.get(site.node, site.node)
        self.log.append(("halt", name))
        self.running[name] = False


def run_btfsm(tree, table, ticks, semantics="pytrees"):
    model = build_model(tree, semantics)
    guards = [n.name for n in walk(tree) if isinstance(n, Guard)]
    return run_model(model, table, ticks, guards)


def run_model(model, table, ticks, guards, key=None):
    """Tick ``model`` with the tables; ``guards[i]`` is the table row of environment choice i."""
    log: list = []
    oracle = LogOracle(table, guards, log, key)
    p = model.program
    s = p.initial
    for t in range(ticks):
        oracle.t = t
        step = p.step(s, oracle)
        s = step.state
        log.append(("root", Status(step.status).name))
    return log


def run_pytrees(tree, table, ticks):
    model = build_model(tree)
    log: list = []
    clock = [0]

    def answer(name):
        a = table[name][clock[0]]
        return STATUS[a]
    root = to_pytrees(model, answer=answer, log=log)
    for t in range(ticks):
        clock[0] = t
        root.tick_once()
        log.append(("root", root.status.name))
    return log


class KeyedBehaviour(AnswerBehaviour):
    """An ``AnswerBehaviour`` that answers and logs under a fixed ``key``, whatever its
    ``name`` becomes (the imported-tree test renames behaviours after building them)."""

    def __init__(self, key, answer, log):
        super().__init__(key, answer, log)
        self.key = key

    def initialise(self) -> None:
        self.log.append(("start", self.key))

    def update(self):
        st = STATUS[self.answer(self.key)]
        self.log.append(("tick", self.key, st.name))
        return {Status.RUNNING: py_trees.common.Status.RUNNING, Status.SUCCESS: py_trees.common.Status.SUCCESS,
                Status.FAILURE: py_trees.common.Status.FAILURE}[st]

    def terminate(self, new_status) -> None:
        if new_status == py_trees.common.Status.INVALID and self.status == py_trees.common.Status.RUNNING:
            self.log.append(("halt", self.key))


def build_pytrees(tree, table, log, clock):
    """The py_trees tree of ``tree`` with keyed leaves answering from ``table[key][clock[0]]``."""
    def answer(key):
        return table[key][clock[0]]
    return to_pytrees(build_model(tree), behaviours=lambda n: KeyedBehaviour(n.name, answer, log),
                      answer=lambda name: STATUS[answer(name)])


def tick_pytrees(root, log, clock, ticks):
    for t in range(ticks):
        clock[0] = t
        root.tick_once()
        log.append(("root", root.status.name))
    return log


def run_imported(root, table, ticks, leaves):
    """Import the py_trees tree ``root`` (its behaviours renamed at will; each leaf a
    ``KeyedBehaviour``, each guard's condition reading its table row) with ``from_pytrees``
    and tick the model with the same tables: the log uses the tables' keys."""
    keys = {}
    for b, name in node_names(root):
        keys[name] = b.key if isinstance(b, KeyedBehaviour) else b.peer_key
    model = from_pytrees(root, leaves=leaves)
    guard_of_var = {g.condition.id: keys[g.name] for g in walk(model.tree) if isinstance(g, Guard)}
    guards = [guard_of_var[e.name] for e in model.environment]
    return run_model(model, table, ticks, guards, keys)
