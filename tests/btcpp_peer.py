"""Run one tree in real BehaviorTree.CPP (``behaviortreepy``) and in btfsm under the
``btcpp`` profile, tick by tick, and log the leaf callbacks of both the same way.

A tree is given as a *spec* (nested tuples):

* ``("async", name, statuses)``: an action that may return RUNNING (BT.CPP: a stateful
  action; logs ``start`` / ``run`` / ``halt``);
* ``("sync", name, statuses)``: an instant action (BT.CPP: a simple action; logs ``tick``);
* ``("cond", name, statuses)``: a condition (BT.CPP: a simple condition; logs ``cond``);
* ``("skill", name, statuses)``: a ``SkillRequest`` on its own one-state FSM whose state's
  primitive answers the table (markers reply SUCCESS/FAILURE, else RUNNING); BT.CPP: a
  stateful action like ``async`` (a halt withdraws the goal, which halts the primitive);
* ``(TYPE, name, [children], params)`` for a btfsm control node type, or
  ``(TYPE, name, child, params)`` for a decorator (params: the node's extra fields).

``statuses`` is a string over ``S F R``, one letter per tick (the global tick number): a
leaf's answer is a pure function of (leaf, tick), so halting cannot change it. The tree
goes to BT.CPP through btfsm's own exporter (``to_btcpp_xml``). btfsm answers each leaf
from the same table through an oracle; start vs run comes from whether the leaf was
running, halts from the step's recorded events.
"""
from __future__ import annotations

try:
    import behaviortreepy as bt
except ImportError:  # the btfsm side (run_btfsm) still works; run_btcpp needs the engine
    bt = None

from btfsm import FSM, Action, Condition, EnvEvent, Int, Marker, Model, Outcome, SkillRequest, State
from btfsm.bt import NODE_TYPES
from btfsm.interop.btcpp_export import to_btcpp_xml
from btfsm.status import Status

__all__ = ["build", "run_btcpp", "run_btfsm", "compare", "LEAF_KINDS"]

LEAF_KINDS = ("async", "sync", "cond", "skill")
_BT = {} if bt is None else {"S": bt.NodeStatus.SUCCESS, "F": bt.NodeStatus.FAILURE, "R": bt.NodeStatus.RUNNING}
_NAME = {v: k for k, v in (("SUCCESS", _BT.get("S")), ("FAILURE", _BT.get("F")), ("RUNNING", _BT.get("R")))}
_STATUS = {"S": Status.SUCCESS, "F": Status.FAILURE, "R": Status.RUNNING}


def _node(spec, leaves, period, fsms):
    kind, name = spec[0], spec[1]
    if kind in LEAF_KINDS:
        table = spec[2]
        leaves[name] = (kind, table)
        if kind == "skill":
            outs = (Outcome(Status.SUCCESS), Outcome(Status.FAILURE), Outcome(Status.RUNNING))
            fsms.append(FSM(f"{name}_fsm", (State("work", outcomes=outs),), "work", ("do",), (),
                            (Marker("work", on=Status.SUCCESS, outcome=Status.SUCCESS),
                             Marker("work", on=Status.FAILURE, outcome=Status.FAILURE))))
            return SkillRequest(name, f"{name}_fsm", "do")
        if kind == "cond":
            ticks = [str(k) for k, c in enumerate(table[:max(period, 2)]) if c == "S"]
            expr = " or ".join(f"t == {k}" for k in ticks) if ticks else "false"
            return Condition(name, expr)
        outs = [Outcome(Status.SUCCESS), Outcome(Status.FAILURE)]
        if kind == "async":
            outs.append(Outcome(Status.RUNNING))
        return Action(name, outcomes=tuple(outs))
    cls = NODE_TYPES[kind]
    params = dict(spec[3]) if len(spec) > 3 and spec[3] else {}
    body = spec[2]
    if isinstance(body, list):
        return cls(name, tuple(_node(c, leaves, period, fsms) for c in body), **params)
    return cls(name, child=_node(body, leaves, period, fsms), **params)


def build(spec, ticks: int, semantics: str = "btcpp"):
    """(Model, {leaf name: (kind, statuses)}) for a spec; the model's clock ``t`` counts
    ticks (0 on the first) so that conditions can read the tick number."""
    leaves: dict = {}
    fsms: list = []
    tree = _node(spec, leaves, ticks, fsms)
    n = max(ticks, 2)
    model = Model("peer", variables=(Int("t", 0, n - 1, init=n - 1),), fsms=tuple(fsms),
                  environment=(EnvEvent("clock", effects={"t": f"(t + 1) % {n}"}),),
                  tree=tree, semantics=semantics)
    return model, leaves


def run_btcpp(model, leaves, ticks: int, xml: "str | None" = None):
    """[(root status name, [(leaf, callback), ...]) per tick] from real BehaviorTree.CPP."""
    factory = bt.BehaviorTreeFactory()
    log: list = []
    now = [0]
    for name, (kind, table) in leaves.items():
        def answer(name=name, table=table):
            return _BT[table[now[0]]]
        if kind in ("async", "skill"):
            factory.register_simple_stateful_action(
                name,
                lambda node, name=name, answer=answer: (log.append((name, "start")), answer())[1],
                lambda node, name=name, answer=answer: (log.append((name, "run")), answer())[1],
                lambda node, name=name: log.append((name, "halt")))
        elif kind == "sync":
            factory.register_simple_action(name, lambda node, name=name, answer=answer: (log.append((name, "tick")), answer())[1])
        else:
            factory.register_simple_condition(name, lambda node, name=name, answer=answer: (log.append((name, "cond")), answer())[1])
    tree = factory.create_tree_from_text(xml if xml is not None else to_btcpp_xml(model))
    out = []
    for k in range(ticks):
        now[0] = k
        log.clear()
        status = tree.tick_exactly_once()
        out.append((_NAME[status], list(log)))
    return out


class _Oracle:
    def __init__(self, leaves):
        self.leaves, self.tick = leaves, 0

    def env(self, i):
        return True

    def choose(self, i, enabled):
        return 0

    def outcome(self, site):
        leaf = site.node if site.kind == "action" else site.fsm[:-len("_fsm")]
        want = _STATUS[self.leaves[leaf][1][self.tick]]
        return next(k for k, o in enumerate(site.outcomes) if o[0] == want)

    def halt(self, site):
        pass


def run_btfsm(model, leaves, ticks: int):
    """The same log from ``Program.step`` under the model's profile."""
    prog = model.program if not callable(getattr(model, "program", None)) else model.program()
    oracle = _Oracle(leaves)
    state, running, out = prog.initial, set(), []
    for k in range(ticks):
        oracle.tick = k
        step = prog.step(state, oracle, record=True)
        log = []
        for ev in step.events:
            if ev[0] == "outcome":
                name = ev[1].split("/")[0][:-len("_fsm")] if "/" in ev[1] else ev[1]
                kind = leaves[name][0]
                if kind == "sync":
                    log.append((name, "tick"))
                else:
                    log.append((name, "run" if name in running else "start"))
                    if leaves[name][1][k] == "R":
                        running.add(name)
                    else:
                        running.discard(name)
            elif ev[0] == "status" and ev[1] in leaves and leaves[ev[1]][0] == "cond":
                log.append((ev[1], "cond"))
            elif ev[0] == "halt" and ev[1] in leaves:
                log.append((ev[1], "halt"))
                running.discard(ev[1])
            elif ev[0] == "withdraw" and ev[2] in leaves:
                pass  # the halt event of the SkillRequest node was logged just before
        out.append((Status(step.status).name, log))
        state = step.state
    return out


def compare(spec, ticks: int):
    """(btcpp log, btfsm log, xml) for one spec."""
    model, leaves = build(spec, ticks)
    xml = to_btcpp_xml(model)
    return run_btcpp(model, leaves, ticks, xml), run_btfsm(model, leaves, ticks), xml
