"""The ``nav2`` node library: Nav2's behaviour-tree nodes for ``btfsm check TREE.xml --node-library nav2``.

Ported from navigation2 (github.com/ros-navigation/navigation2, Apache-2.0) at commit
``a3a97043ee93d92fe8d70ec56d183933169beb1c``: ``nav2_behavior_tree/plugins/control/*.cpp``,
``plugins/decorator/*.cpp`` and the node models of ``nav2_behavior_tree/nav2_tree_nodes.xml``
(vendored as ``btfsm/interop/data/nav2_tree_nodes.xml`` with its license, ``NAV2_LICENSE``).
docs/semantics.md section 8.3 states every rule and docs/interop.md shows the library at work.

* **Controls** with tick rules of their own are btfsm node types, run by the one step
  function (``btfsm.semantics``): ``PipelineSequence``, ``RecoveryNode`` (``number_of_retries``
  -> ``retries``) and ``RoundRobin`` (``wrap_around``).
* **Decorators** whose rule depends on time, distance travelled or a topic are sound
  nondeterministic abstractions built from existing nodes: the question the C++ code asks
  of the clock or of tf ("has the period elapsed?") becomes an instant or async *gate*
  Action named ``NODE/QUESTION`` whose outcomes the oracle chooses, so the checker explores
  every answer and a counterexample shows which one it took:

  ======================= ====================================================================
  ``RateController``,     ``Sequence[NODE/elapsed (running|success), child]``: while the
  ``SpeedController``     child runs it is ticked; otherwise the gate decides: tick the
                          child (the period elapsed, or the first tick) or return RUNNING
  ``DistanceController``  the same with the gate ``NODE/travelled``
  ``GoalUpdatedController`` the same with the gate ``NODE/goal_updated``
  ``SingleTrigger``       ``Sequence[NODE/first_time (success|failure), child]``: tick the
                          child, or FAILURE without ticking it
  ``PathLongerOnApproach`` ``ReactiveFallback[Inverter(NODE/longer_path (success|failure)),
                          child]``: tick the child, or SUCCESS without ticking it
  ``GoalUpdater``         its child (it only rewrites the goal on the blackboard)
  ======================= ====================================================================

* **Leaves** get their kind and port types from ``nav2_tree_nodes.xml``; conditions may
  return SUCCESS or FAILURE, actions RUNNING, SUCCESS or FAILURE, except those whose C++
  tick never returns RUNNING (``SYNC_ACTIONS``: the selectors, which are ``BT::SyncActionNode``,
  and the path and goal utilities such as ``TruncatePathLocal``); and those whose tick()
  cannot fail succeed: ``ALWAYS_SUCCEED``, and a selector given a constant default (its
  only FAILURE is "no selection received and no default").
  A blackboard entry whose port type is not finite (a pose, a path, a string, a number)
  is not a world variable: the leaves that read it already answer every way, so leaving
  its value out over-approximates the tree (sound for every property btfsm checks).
  Entries of type ``bool`` are world variables, as without the library.

What is not modelled is refused with the reason: ``PersistentSequence`` (its index lives
on the blackboard, set by a Script), ``PauseResumeController`` (pause/resume services),
``NonblockingSequence``.

>>> sorted(CONTROLS), sorted(GATES)[:3]
(['PipelineSequence', 'RecoveryNode', 'RoundRobin'], ['DistanceController', 'GoalUpdatedController', 'PathLongerOnApproach'])
"""
from __future__ import annotations

import re

from ..bt import NODE_TYPES, Composite, arity_allows, arity_text, btcpp_tags
from .groot import NodeModel

__all__ = ["NodeLibrary", "CONTROLS", "GATES", "PASS_THROUGH", "SYNC_ACTIONS", "ACTION_SERVER_LEAVES", "ALWAYS_SUCCEED", "REFUSED", "COMMIT", "LIBRARY_NAME"]

LIBRARY_NAME = "nav2"
COMMIT = "a3a97043ee93d92fe8d70ec56d183933169beb1c"

#: Nav2 control tag -> (btfsm node type, {XML port: (btfsm field, default)}): the node
#: classes of ``btfsm.bt`` whose ``library`` is nav2
CONTROLS = btcpp_tags(LIBRARY_NAME, Composite)
#: Nav2 decorator tag -> (gate question, gate statuses, composition): see the module doc
GATES = {
    "RateController": ("elapsed", ("running", "success"), "sequence"),
    "SpeedController": ("elapsed", ("running", "success"), "sequence"),
    "DistanceController": ("travelled", ("running", "success"), "sequence"),
    "GoalUpdatedController": ("goal_updated", ("running", "success"), "sequence"),
    "SingleTrigger": ("first_time", ("success", "failure"), "sequence"),
    "PathLongerOnApproach": ("longer_path", ("success", "failure"), "bypass"),
}
#: decorators that tick their child on every tick and return its status
PASS_THROUGH = ("GoalUpdater",)
#: Nav2 actions that never return RUNNING: the selectors are BT::SyncActionNode (which
#: BehaviorTree.CPP forbids to return RUNNING); the others are BT::ActionNodeBase whose
#: tick() returns SUCCESS or FAILURE only (read in their .cpp at COMMIT)
SYNC_ACTIONS = ("PlannerSelector", "ControllerSelector", "SmootherSelector", "GoalCheckerSelector",
                "ProgressCheckerSelector", "PathHandlerSelector",
                "AppendGoalPoseToGoals", "ConcatenatePaths", "ExtractRouteNodesAsGoals", "GetCurrentPose",
                "GetNextFewGoals", "GetPoseFromPath", "RemovePassedGoals", "TruncatePath", "TruncatePathLocal",
                # BtCancelActionNode: waits for the cancel's answer within the tick
                "CancelControl", "CancelBackUp", "CancelSpin", "CancelWait", "CancelDriveOnHeading",
                "CancelAssistedTeleop", "CancelComputeAndTrackRoute", "CancelFollowObject")
#: leaves that are Nav2 BtActionNodes: they send a goal to a ROS 2 action server on the tick
#: they start and return RUNNING until its result arrives. The library assumes the result
#: comes on a later tick than the goal (the one assumption it makes, docs/semantics.md 8.3):
#: the node declares a duration of at least half a tick, so its first tick answers RUNNING
ACTION_SERVER_LEAVES = ("AssistedTeleop", "BackUp", "ComputeAndTrackRoute", "ComputePathThroughPoses",
                        "ComputePathToPose", "ComputeRoute", "DriveOnHeading", "FollowObject", "FollowPath",
                        "NavigateThroughPoses", "NavigateToPose", "SmoothPath", "Spin", "Wait", "DockRobot",
                        "UndockRobot")
#: actions whose tick() returns SUCCESS only; a selector (``*Selector``) fails only when it
#: has no default to fall back on, so with a constant ``default_...`` port it always succeeds
ALWAYS_SUCCEED = ("AppendGoalPoseToGoals", "TruncatePath")
REFUSED = {
    "PersistentSequence": "keeps its child index on the blackboard (set by a Script)",
    "PauseResumeController": "switches children on pause/resume service calls",
    "NonblockingSequence": "is not modelled by the nav2 library yet",
}
_FINITE = ("bool",)
_REF = re.compile(r"\{(@?)([^{}]*)\}\Z")


class NodeLibrary:
    """A family of custom nodes for the BehaviorTree.CPP importer: node models (ports,
    kinds) and how each control, decorator and leaf ID is modelled. ``btcpp_import``
    calls ``inner`` for a node with children, ``leaf`` for a leaf, ``opaque`` for a
    blackboard entry's port type."""

    def __init__(self, name: str, models: "dict[str, NodeModel]"):
        self.name, self.models = name, dict(models)

    def knows(self, ident: str) -> bool:
        return ident in CONTROLS or ident in GATES or ident in PASS_THROUGH or ident in REFUSED

    def inner_ids(self) -> list:
        """The control and decorator IDs the library models."""
        return [*CONTROLS, *GATES, *PASS_THROUGH]

    def opaque(self, ptype: str) -> bool:
        """A blackboard entry of this port type is left out of the model (not finite)."""
        return ptype not in _FINITE

    # ---------------------------------------------------------------- controls and decorators
    def inner(self, imp, el, ident, path, scope, stack, prefix) -> dict:
        if ident in REFUSED:
            raise imp.fail(el, f"{ident} {REFUSED[ident]}: not modelled by the {self.name} node library "
                               "(declare the node under nodes: with abstract: child, or rewrite it)")
        model = self.models.get(ident)
        fields = CONTROLS[ident][1] if ident in CONTROLS else {}
        values: dict = {}
        for a, v in el.attrs.items():
            if a in ("name", "ID", "_description", "_uid", "_fullpath"):
                continue
            if model is not None and a not in model.ports:
                raise imp.fail(el, f"port '{a}' is not declared for {ident} in the {self.name} node models "
                                   f"(ports: {', '.join(model.ports) or 'none'})")
            if a in fields:
                fname, _default = fields[a]
                kind = "bool" if isinstance(_default, bool) else "int"
                text = v.strip()
                if _REF.match(text):
                    raise imp.fail(el, f"{a}=\"{v}\" reads the blackboard: not modelled by btfsm (give a constant)")
                if kind == "bool":
                    if text not in ("true", "false", "1", "0"):
                        raise imp.fail(el, f"{a}=\"{v}\": expected true or false")
                    values[fname] = text in ("true", "1")
                else:
                    try:
                        values[fname] = int(text)
                    except ValueError:
                        raise imp.fail(el, f"{a}=\"{v}\": expected an integer") from None
                    if values[fname] < 0:
                        raise imp.fail(el, f"{a}=\"{v}\": expected a count of at least 0")
        shown = el.attrs.get("name") or ident
        if ident in PASS_THROUGH:
            one = self._one_child(imp, el, ident)
            return imp.node(one, path, scope, stack, prefix)
        name = imp.unique(prefix + shown, el)
        imp.lines[path] = el.where()
        if ident in CONTROLS:
            if not el.children:
                raise imp.fail(el, f"a {ident} needs children")
            if not arity_allows(NODE_TYPES[CONTROLS[ident][0]], len(el.children)):
                raise imp.fail(el, f"a {ident} has {arity_text(NODE_TYPES[CONTROLS[ident][0]])}, has {len(el.children)}")
            out = {CONTROLS[ident][0]: name, **{k: v for k, v in values.items()
                                               if v != _default_of(ident, k)}}
            out["children"] = [imp.node(c, f"{path}.children[{i}]", scope, stack, prefix)
                               for i, c in enumerate(el.children)]
            return out
        question, statuses, shape = GATES[ident]
        one = self._one_child(imp, el, ident)
        gate_name = imp.unique(f"{name}/{question}", el)
        prim = f"{ident}.{question}"
        imp.primitives.setdefault(prim, list(statuses))
        gate = {"Action": gate_name, "primitive": prim}
        if shape == "sequence":
            imp.lines[f"{path}.children[0]"] = el.where()
            child = imp.node(one, f"{path}.children[1]", scope, stack, prefix)
            return {"MemorySequence": name, "children": [gate, child]}
        inv = imp.unique(f"{name}/not_{question}", el)
        imp.lines[f"{path}.children[0]"] = el.where()
        imp.lines[f"{path}.children[0].child"] = el.where()
        child = imp.node(one, f"{path}.children[1]", scope, stack, prefix)
        return {"ReactiveFallback": name, "children": [{"Inverter": inv, "child": gate}, child]}

    @staticmethod
    def _one_child(imp, el, ident):
        if len(el.children) != 1:
            raise imp.fail(el, f"a {ident} has exactly one child, has {len(el.children)}")
        return el.children[0]

    # ---------------------------------------------------------------- leaves
    def leaf(self, imp, el, name, ident, kind, written, args) -> "dict | None":
        """The leaf's model from the library (None: not one of its leaves)."""
        model = self.models.get(ident)
        if model is None or model.kind not in ("Action", "Condition"):
            return None
        if ident in ALWAYS_SUCCEED or (ident.endswith("Selector") and ident in SYNC_ACTIONS and any(
                k.startswith("default_") and v.strip() and not _REF.match(v.strip()) for k, v in el.attrs.items())):
            statuses = ["success"]
        elif model.kind == "Condition" or ident in SYNC_ACTIONS:
            statuses = ["success", "failure"]
        else:
            statuses = ["running", "success", "failure"]
        outcomes = imp.havoc(el, statuses, written)
        out = {"Action": name, "primitive": ident}
        if written:
            out["primitive"] = name
            out["outcomes"] = outcomes
        elif imp.primitives.setdefault(ident, outcomes) != outcomes or ident in imp.side_prims:
            out["primitive"] = name
            out["outcomes"] = outcomes
        if ident in ACTION_SERVER_LEAVES:
            rate = imp.side.get("tick_rate", 10.0)
            rate = rate if isinstance(rate, (int, float)) and not isinstance(rate, bool) and rate > 0 else 10.0
            out["duration"] = [0.5 / rate, None]
        if args:
            out["args"] = args
        return out


def _default_of(ident, fname):
    return next(d for f, d in CONTROLS[ident][1].values() if f == fname)

