"""The smallest complete example: one arm moves parts from an input area to an output area.

The arm FSM has two hubs (``at_in``, ``at_out``), one transit each way, a pick chain at
the input and a place chain at the output; goals ``pick`` and ``place``. Every goal can
take over from every state: a transit toward the other area is abandoned (direct edge
back), a grasp that has not attached is abandoned, a lifted part is carried on, a put
before the release is aborted upward, after the release the arm retreats first.

The FSM writes only what it physically changes (``holding``); the tree counts parts.
The tree is a memory fallback ``[done, place if holding, pick if a part waits]``, so
each skill runs to its end before the next decision (no preemption here; see
``models.examples.spectrum`` for that).

>>> m = two_area()
>>> [s.id for s in m.fsm("arm").states][:3]
['at_in', 'in_to_out', 'out_to_in']
"""
from __future__ import annotations

from btfsm import (FSM, Bool, Condition, Edge, Effects, EnvEvent, Int, Marker, MemoryFallback,
                   MemorySequence, Model, Primitive, SkillRequest, State, Status, failure, running, success)

__all__ = ["two_area", "two_area_drops", "arm"]


def arm(drops: bool = False) -> FSM:
    """The two-area arm FSM; with ``drops`` the transit to the output area carries the
    part with ``carry``, which can fail (``dropped``): the skill fails and the arm goes on
    to the output hub empty-handed."""
    states = [
        State("at_in", "move", {"area": "in", "pose": "approach"}),
        State("in_to_out", "carry" if drops else "move", {"area": "out", "pose": "via"}),
        State("out_to_in", "move", {"area": "in", "pose": "via"}),
        State("at_out", "move", {"area": "out", "pose": "approach"}),
        State("grasp_in", "grasp", {"area": "in"}),
        State("lift_in", "move", {"area": "in", "pose": "approach"}),
        State("put_out", "move", {"area": "out", "pose": "place"}),
        State("release_out", "gripper", {"on": False}),
        State("retreat_out", "move", {"area": "out", "pose": "approach"}),
    ]
    edges = [
        # pick: go to the input area, grasp, lift
        Edge("at_in", "grasp_in", ["pick"]),
        Edge("grasp_in", "lift_in", ["pick"]),
        Edge("lift_in", "at_in", ["pick", "place"]),  # a lifted part is carried on
        Edge("grasp_in", "at_in", ["place"], direct=True),  # not attached yet: abandon
        Edge("at_out", "out_to_in", ["pick"]),
        Edge("out_to_in", "at_in", ["pick"]),
        Edge("in_to_out", "at_in", ["pick"], direct=True),
        # place: go to the output area, put, release, retreat
        Edge("at_in", "in_to_out", ["place"]),
        Edge("in_to_out", "at_out", ["place"]),
        Edge("out_to_in", "at_out", ["place"], direct=True),
        Edge("at_out", "put_out", ["place"]),
        Edge("put_out", "release_out", ["place"]),
        Edge("put_out", "at_out", ["pick"], direct=True),  # before the release: abort upward
        Edge("release_out", "retreat_out", ["place"], effects={"holding": False}),
        Edge("release_out", "at_out", ["pick"], direct=True),
        Edge("retreat_out", "at_out", ["pick", "place"]),  # after the release: retreat first
    ]
    markers = [Marker("lift_in", ["pick"]), Marker("retreat_out", ["place"])]
    if drops:  # the part slipped on the way: the place skill fails, the arm goes on to the output hub
        edges.append(Edge("in_to_out", "at_out", ["place"], on=Status.FAILURE))
        markers.append(Marker("in_to_out", ["place"], on=Status.FAILURE, outcome=Status.FAILURE))
    return FSM("arm", states=states, initial="at_in", goals=["pick", "place"], edges=edges, markers=markers)


def two_area(n_parts: int = 3, waiting_max: int = 2, drops: bool = False) -> Model:
    """Move ``n_parts`` parts; at most ``waiting_max`` wait at the input at a time. With
    ``drops`` (``two_area_drops``) a carried part may slip on the way to the output."""
    tree = MemoryFallback("work", [
        Condition("done", f"placed == {n_parts}"),
        MemorySequence("deliver", [Condition("holding_part", "holding"),
                                   Effects("count", child=SkillRequest("place_part", fsm="arm", goal="place", post="not holding"),
                                           on_success={"placed": "placed + 1"})]),
        MemorySequence("fetch", [Condition("part_waiting", "waiting > 0 and not holding"),
                                 Effects("take", child=SkillRequest("pick_part", fsm="arm", goal="pick", post="holding"),
                                         on_success={"waiting": "waiting - 1"})]),
    ])
    return Model(
        "two-area-drops" if drops else "two-area",
        variables=[Bool("holding"), Int("waiting", 0, waiting_max), Int("placed", 0, n_parts)],
        primitives=[Primitive("move", (running("moving"), success("arrived"))),
                    Primitive("grasp", (running("searching"), success("attached", holding=True))),
                    Primitive("gripper", (success("switched"),))]
        + ([Primitive("carry", (running("moving"), success("arrived"), failure("dropped", holding=False)))]
           if drops else []),
        fsms=[arm(drops)],
        tree=tree,
        # parts keep coming until all that are needed have come
        environment=[EnvEvent("arrive", f"waiting < {waiting_max} and placed + waiting + (1 if holding else 0) < {n_parts}",
                              {"waiting": "waiting + 1"})],
        invariants={"release_holds_a_part": "arm.state != 'release_out' or holding"},
        workable="arm.state in ('at_in', 'at_out') and arm.goal == 'none'",
        terminal=f"placed == {n_parts}",
        description=f"one arm, two areas: pick at 'in', place at 'out', {n_parts} parts"
        + (" (a carried part may slip)" if drops else ""),
    )


def two_area_drops(n_parts: int = 3, waiting_max: int = 2) -> Model:
    """``two_area`` whose transit to the output declares that the carried part may be
    dropped (``carry``: failure ``dropped``, ``holding`` becomes false): the model of the
    slip scene (``models/scenes/two_area_slip.yaml``, docs/cell.md)."""
    return two_area(n_parts, waiting_max, drops=True)
