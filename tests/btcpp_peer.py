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
  ``(TYPE, name, child, params)`` for a decorator (params: the node's extra fields);
  ``("SubTree", name, child, {"tree_id": ID})`` is a ``<SubTree ID>`` of BT.CPP (SubTrees of
  one ID must have equal children: the XML defines the tree once).

``statuses`` is a string over ``S F R``, one letter per tick (the global tick number): a
leaf's answer is a pure function of (leaf, tick), so halting cannot change it. The tree
goes to BT.CPP through btfsm's own exporter (``to_btcpp_xml``); btfsm runs the model
that its importer makes of that same XML (``xml_to_data`` with a side file declaring the
leaves), so SubTrees go through both engines' XML readers. btfsm answers each leaf from
the same table through an oracle; start vs run comes from whether the leaf was running,
halts from the step's recorded events. A leaf inside a SubTree is named ``INSTANCE/LEAF``
by the importer; logs use the leaf's own name (its BT.CPP ID).
"""
from __future__ import annotations

import json
import os
import subprocess
import sys

try:
    import behaviortreepy as bt
except ImportError:  # the btfsm side (run_btfsm) still works; run_btcpp needs the engine
    bt = None

from btfsm import FSM, Action, Condition, EnvEvent, Int, Marker, Model, Outcome, Primitive, SkillRequest, State, walk
from btfsm.bt import NODE_TYPES
from btfsm.files import model_from_data, model_to_data
from btfsm.interop.btcpp_export import to_btcpp_xml
from btfsm.interop.btcpp_import import xml_to_data
from btfsm.oracles import Oracle
from btfsm.status import Status

__all__ = ["build", "imported", "run_btcpp", "run_btfsm", "compare", "LEAF_KINDS"]

LEAF_KINDS = ("async", "sync", "cond", "skill")
_BT = {} if bt is None else {"S": bt.NodeStatus.SUCCESS, "F": bt.NodeStatus.FAILURE, "R": bt.NodeStatus.RUNNING}
_NAME = {v: k for k, v in (("SUCCESS", _BT.get("S")), ("FAILURE", _BT.get("F")), ("RUNNING", _BT.get("R")))}
_STATUS = {"S": Status.SUCCESS, "F": Status.FAILURE, "R": Status.RUNNING}


def _node(spec, leaves, period, fsms, prims, prefix=""):
    kind, name = spec[0], spec[1]
    full = prefix + name  # inside a SubTree: INSTANCE/NAME, as btfsm's importer names it
    if kind in LEAF_KINDS:
        table = spec[2]
        if leaves.setdefault(name, (kind, table)) != (kind, table):
            raise ValueError(f"leaf {name} appears twice with different tables")
        if kind == "skill":
            if any(f.name == f"{name}_fsm" for f in fsms):
                raise ValueError(f"skill {name} appears twice (two requests on one FSM are btfsm's own rules)")
            outs = (Outcome(Status.SUCCESS), Outcome(Status.FAILURE), Outcome(Status.RUNNING))
            fsms.append(FSM(f"{name}_fsm", (State("work", outcomes=outs),), "work", ("do",), (),
                            (Marker("work", on=Status.SUCCESS, outcome=Status.SUCCESS),
                             Marker("work", on=Status.FAILURE, outcome=Status.FAILURE))))
            return SkillRequest(full, f"{name}_fsm", "do")
        if kind == "cond":
            ticks = [str(k) for k, c in enumerate(table[:max(period, 2)]) if c == "S"]
            expr = " or ".join(f"t == {k}" for k in ticks) if ticks else "false"
            return Condition(full, expr)
        outs = [Outcome(Status.SUCCESS), Outcome(Status.FAILURE)]
        if kind == "async":
            outs.append(Outcome(Status.RUNNING))
        prims.setdefault(name, Primitive(name, tuple(outs)))
        return Action(full, name)
    cls = NODE_TYPES[kind]
    params = dict(spec[3]) if len(spec) > 3 and spec[3] else {}
    body = spec[2]
    if isinstance(body, list):
        return cls(full, tuple(_node(c, leaves, period, fsms, prims, prefix) for c in body), **params)
    inner = prefix + name + "/" if kind == "SubTree" else prefix
    return cls(full, child=_node(body, leaves, period, fsms, prims, inner), **params)


def build(spec, ticks: int, semantics: str = "btcpp", tick: str = "exactly-once"):
    """(Model, {leaf name: (kind, statuses)}) for a spec; the model's clock ``t`` counts
    ticks (0 on the first) so that conditions can read the tick number."""
    leaves: dict = {}
    fsms: list = []
    prims: dict = {}
    tree = _node(spec, leaves, ticks, fsms, prims)
    n = max(ticks, 2)
    model = Model("peer", variables=(Int("t", 0, n - 1, init=n - 1),), fsms=tuple(fsms),
                  primitives=tuple(prims.values()),
                  environment=(EnvEvent("clock", effects={"t": f"(t + 1) % {n}"}),),
                  tree=tree, semantics=semantics, tick=tick)
    return model, leaves


def imported(model, leaves, xml: str):
    """The model btfsm's importer makes of ``xml``, with a side file that declares what
    the exported model knows: the clock, the FSMs of skill requests, the actions'
    outcomes (conditions and skill requests come from the TreeNodesModel descriptions)."""
    side = {k: v for k, v in model_to_data(model).items() if k not in ("tree", "name", "primitives")}
    side["primitives"] = {name: (["success", "failure", "running"] if kind == "async" else ["success", "failure"])
                          for name, (kind, _) in leaves.items() if kind in ("async", "sync")}
    result = xml_to_data(xml.encode(), "peer.xml", side, "peer.btfsm.yaml")
    return model_from_data(result.data, "peer.btfsm.yaml")


def _base(name: str) -> str:
    return name.rsplit("/", 1)[-1]


#: leaf callbacks in one tick past which BT.CPP's ``tick_once()`` is taken to loop for ever
LOOP_CALLBACKS = 5000
LOOP = ("LOOP", [])  # the log entry of a tick that does not return (and the last one)


def run_btcpp(model, leaves, ticks: int, xml: "str | None" = None, isolated: bool = False):
    """[(root status name, [(leaf, callback), ...]) per tick] from real BehaviorTree.CPP,
    ticked with ``tick_once()`` or ``tick_exactly_once()`` as ``model.tick`` says.

    A tick with more than ``LOOP_CALLBACKS`` leaf callbacks does not return in BT.CPP (its
    ``tick_once()`` loops for ever; nothing stops it from outside). ``isolated``: this runs
    in a process of its own (``run_btcpp_isolated``), which then prints the log so far
    with ``LOOP`` and exits. Otherwise the process ends with a message: a loop btfsm did
    not predict (``compare`` isolates the runs where btfsm predicts one)."""
    factory = bt.BehaviorTreeFactory()
    log: list = []
    out: list = []
    now = [0]
    for name, (kind, table) in leaves.items():
        def answer(name=name, table=table):
            if len(log) > LOOP_CALLBACKS:
                if isolated:
                    print(json.dumps(out + [LOOP]), flush=True)
                    os._exit(0)
                print(f"BehaviorTree.CPP's tick_once() loops at tick {now[0]} where btfsm predicts no loop:\n"
                      f"{xml}", file=sys.stderr, flush=True)
                os._exit(70)
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
    tick = tree.tick_once if model.tick == "once" else tree.tick_exactly_once
    for k in range(ticks):
        now[0] = k
        log.clear()
        status = tick()
        out.append((_NAME[status], list(log)))
    return out


def run_btcpp_isolated(model, leaves, ticks: int, xml: str, timeout: float = 300):
    """``run_btcpp`` in a child process (for a run whose ``tick_once()`` may never return)."""
    job = json.dumps({"tick": model.tick, "leaves": leaves, "ticks": ticks, "xml": xml})
    code = ("import json, sys, types; sys.path.insert(0, sys.argv[1]); import btcpp_peer as p; "
            "j = json.loads(sys.stdin.read()); "
            "print(json.dumps(p.run_btcpp(types.SimpleNamespace(tick=j['tick']), "
            "{k: tuple(v) for k, v in j['leaves'].items()}, j['ticks'], j['xml'], isolated=True)))")
    done = subprocess.run([sys.executable, "-c", code, os.path.dirname(os.path.abspath(__file__))], input=job,
                          capture_output=True, text=True, timeout=timeout, check=True)
    return [(s, [tuple(e) for e in log]) for s, log in json.loads(done.stdout.strip().splitlines()[-1])]


class _Oracle(Oracle):
    def __init__(self, leaves):
        self.leaves, self.tick = leaves, 0

    def env(self, i):
        return True

    def choose(self, i, enabled):
        return 0

    def outcome(self, site):
        leaf = site.primitive if site.kind == "action" else site.fsm[:-len("_fsm")]
        want = _STATUS[self.leaves[leaf][1][self.tick]]
        return next(k for k, o in enumerate(site.outcomes) if o[0] == want)

    def halt(self, site):
        pass


def run_btfsm(model, leaves, ticks: int):
    """The same log from ``Program.step`` under the model's profile."""
    prog = model.program if not callable(getattr(model, "program", None)) else model.program()
    oracle = _Oracle(leaves)
    nodes = [n for _, root in model.roots() for n in walk(root)]
    requester = {n.fsm[:-len("_fsm")]: n.name for n in nodes if isinstance(n, SkillRequest)}
    # node -> its BT.CPP ID (a declared condition is named after it, made unique as ID#k)
    ids = {n.name: (n.primitive if isinstance(n, Action) else _base(n.name).split("#")[0]) for n in nodes}
    state, running, out = prog.initial, set(), []
    for k in range(ticks):
        oracle.tick = k
        step = prog.step(state, oracle, record=True)
        log = []
        for ev in step.events:
            if ev[0] == "outcome":
                if ev[1].endswith("_fsm/work"):  # a skill request's FSM state: its requester
                    full = name = ev[1][:-len("_fsm/work")]
                    full = requester.get(name, name)
                else:
                    full, name = ev[1], ids[ev[1]]
                kind = leaves[name][0]
                if kind == "cond":
                    continue  # an undeclared condition (an Action of the import): logged by its status
                if kind == "sync":
                    log.append((name, "tick"))
                else:
                    log.append((name, "run" if full in running else "start"))
                    if leaves[name][1][k] == "R":
                        running.add(full)
                    else:
                        running.discard(full)
            elif ev[0] == "status" and ids.get(ev[1]) in leaves and leaves[ids[ev[1]]][0] == "cond":
                log.append((ids[ev[1]], "cond"))
            elif ev[0] == "halt" and ids.get(ev[1]) in leaves:
                log.append((ids[ev[1]], "halt"))
                running.discard(ev[1])
            elif ev[0] == "withdraw" and ev[2] in leaves:
                pass  # the halt event of the SkillRequest node was logged just before
        if any(v[0] == "tick-loop" for v in step.violations):
            out.append(LOOP)  # btfsm's rule 'tickOnce': this tick never returns
            break
        out.append((Status(step.status).name, log))
        state = step.state
    return out


def respell(xml: str, seed: int) -> str:
    """``xml`` written as users write it and BT.CPP accepts it (issue 18), chosen by
    ``seed``: ``then_skip`` in any of BT.CPP's bool spellings; some condition elements
    made to use another condition's ID (one ID in several places, named after it and
    made unique by the importer); some in the explicit form ``<Condition ID="L" name=".."/>`` (not under a
    Reactive node, where BT.CPP 4 refuses that form), and every condition written so
    anywhere loses its TreeNodesModel entry: an undeclared leaf in every place, compact
    ones included, of the kind its explicit form says."""
    import random
    import xml.etree.ElementTree as ET

    rnd = random.Random(seed)
    root = ET.fromstring(xml)
    models = root.find("TreeNodesModel")
    conds = sorted(e.get("ID") for e in models if e.tag == "Condition")
    explicit = set()
    for el in root.iter():
        if el.tag in conds and rnd.random() < 0.3:
            el.tag = rnd.choice(conds)
            el.set("name", el.tag)  # the importer makes it unique: ID#2
    for tree in root.iter("BehaviorTree"):
        for parent in tree.iter():
            if parent.get("then_skip") is not None:
                parent.set("then_skip", rnd.choice(("false", "False", "FALSE", "0")))
            if parent.tag in ("ReactiveSequence", "ReactiveFallback"):
                continue
            for el in parent:
                if el.tag in conds and rnd.random() < 0.5:
                    explicit.add(el.tag)
                    el.set("ID", el.tag)
                    el.tag = "Condition"
                    if rnd.random() < 0.5:
                        el.set("name", "ready")  # a name that is not the ID
    for e in list(models):
        if e.tag == "Condition" and e.get("ID") in explicit:
            models.remove(e)
    return ET.tostring(root, encoding="unicode")


def compare(spec, ticks: int, seed: "int | None" = None, tick: str = "exactly-once"):
    """(btcpp log, btfsm log, xml) for one spec: BT.CPP runs the exported XML (``respell``
    with ``seed`` when given), btfsm the model its importer makes of the same XML; both
    ticked as ``tick`` says (``once``: ``tick_once()``, btfsm's rule 'tickOnce')."""
    model, leaves = build(spec, ticks, tick=tick)
    xml = to_btcpp_xml(model)
    if seed is not None:
        xml = respell(xml, seed)
    ours = run_btfsm(imported(model, leaves, xml), leaves, ticks)
    if ours[-1] == LOOP:  # btfsm predicts that a tick_once() never returns: BT.CPP runs apart
        return run_btcpp_isolated(model, leaves, ticks, xml), ours, xml
    return run_btcpp(model, leaves, ticks, xml), ours, xml
