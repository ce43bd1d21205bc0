"""A faithful port of the authors' original FSM and executive (ScalABLE40/productive_multitasking).

``movement_manager()`` rebuilds the ``MovementManager`` FSM from its template exactly:
``generate_nodes``, ``generate_pick`` and ``generate_place`` for the three cyclic rotations
of (bins, conveyor, agv), the three conveyor overrides and the two ``preemptive?`` markers:
42 states, 8 goals, 105 edges (42 direct, 63 on SUCCESS) and 29 markers. Its defects are
kept on purpose so that ``btfsm check`` can show them (docs/models.md):

* the ``handle_tick`` protocol: ``retarget="withdraw"`` with parameter ``target``: every
  target change spends a tick (or more) on the ``withdraw`` goal (request latency);
* withdraw is refused (direct FAILURE markers) during release/detach/escape, so a new
  target requested there freezes the arm (non-progress, goal unreachable);
* primitives can fail and no edge handles FAILURE: the state is retried forever;
* the direct withdraw marker on ``put on X`` is shadowed by the direct edge (a lint).

``executive()`` ports the executive tree of ``behavior_tree.py`` with its parse structure:
``query_queue | ((X << done) << Y) << Z``, where ``<<`` becomes ``MemoryFallback`` (ours
has no extra RUNNING tick per failed branch) and the stateless ``*``/``+`` become reactive
sequences/fallbacks. ``original()`` is that model; ``original_preemptive()`` makes the
selector between X and the rest reactive (the paper's inferred preemptive variant), which
makes the freeze reachable from the tree. Every primitive may answer RUNNING, SUCCESS or
FAILURE, as the original's ``_update`` accepts; ``original_narrow()`` keeps the narrower,
more realistic declarations (``NARROW_PRIMITIVES``).

>>> f = movement_manager()
>>> len(f.states), len(f.goals), len(f.edges), sum(e.direct for e in f.edges), len(f.markers)
(42, 8, 105, 42, 29)
"""
from __future__ import annotations

from typing import cast

from btfsm import (FSM, Action, Bool, Condition, Edge, EnvEvent, Int, Inverter, Marker,
                   MemoryFallback, Model, Parallel, Primitive, ReactiveFallback, ReactiveSequence,
                   SkillRequest, State, failure, running, success)
from btfsm.bt import Node
from btfsm.status import Status

__all__ = ["ROTATIONS", "TRACKS", "TARGETS", "PRIMITIVES", "NARROW_PRIMITIVES", "generate_nodes", "generate_pick",
           "generate_place", "movement_manager", "executive", "original", "original_preemptive",
           "original_narrow", "transit_table"]

ROTATIONS = (("bins", "conveyor", "agv"), ("agv", "bins", "conveyor"), ("conveyor", "agv", "bins"))
TRACKS = ("bins/pick", "bins/place", "agv/pick", "agv/place", "conveyor/pick", "conveyor/place",
          "withdraw", "preemptive?")
# the blackboard ids a choose_* leaf puts in the request (0 is the initial empty target)
TARGETS = {"part": 1, "first_part_in_queue": 2, "location": 3, "intermediate_location": 4}

# The authors' primitives. They were printing stubs, and the FSM's ``_update`` accepts any
# status from any primitive, so the faithful port lets every one of them answer RUNNING,
# SUCCESS or FAILURE.
PRIMITIVES = tuple(Primitive(name, (running(), success(), failure()))
                   for name in ("move_to", "gripper_control", "grasp_in", "record_grasping_pose", "detach_approach"))

# What the real primitives would more likely do (``original_narrow``): motions and grasps
# run for a while and can fail, the gripper switch answers at once and can fail, recording
# the grasping pose and detaching always succeed at once.
NARROW_PRIMITIVES = (
    Primitive("move_to", (running(), success(), failure())),
    Primitive("gripper_control", (success(), failure())),
    Primitive("grasp_in", (running(), success(), failure())),
    Primitive("record_grasping_pose", (success(),)),
    Primitive("detach_approach", (success(),)),
)


def _ns(frame: str) -> str:
    return f"arm1/{frame}"


def generate_nodes(x: str, before: str, after: str) -> list:
    """The 14 states of area ``x`` with the authors' state names and primitive arguments."""
    out = [State(f"{p} to {x}", "move_to", {"frame": _ns(f"{x}/{p}"), "tolerance": "via point", "speed": "0.5"})
           for p in (before, after)]
    out += [
        State(f"approach {x}", "move_to", {"frame": _ns(f"{x}/approach"), "tolerance": "fine", "speed": "0.5"}),
        State(f"enable gripper on {x}", "gripper_control", {"on": True}),
        State(f"grasp on {x}", "grasp_in", {"frame": _ns(f"{x}/grasp"), "speed": "0.5", "shaking": True}),
        State(f"record grasping pose on {x}", "record_grasping_pose"),
        State(f"detach approach on {x} (pick)", "detach_approach"),
        State(f"raise on {x}", "move_to", {"frame": _ns(f"{x}/approach"), "tolerance": "coarse", "speed": "0.5"}),
        State(f"disable gripper on {x}", "gripper_control", {"on": False}),
        State(f"put back on {x}", "move_to", {"frame": _ns(f"{x}/grasp"), "tolerance": "coarse", "speed": "0.5"}),
        State(f"put on {x}", "move_to", {"frame": _ns(f"{x}/grasp"), "tolerance": "coarse", "speed": "0.5"}),
        State(f"release on {x}", "gripper_control", {"on": False}),
        State(f"detach approach on {x} (place)", "detach_approach"),
        State(f"escape {x}", "move_to", {"frame": _ns(f"{x}/approach"), "tolerance": "fine", "speed": "0.5"}),
    ]
    return out


def _edge(src, dst, track, direct=False):
    kind = "direct" if direct else "success"
    return Edge(src, dst, [track], direct=direct, id=f"{src} -> {dst} [{track}, {kind}]")


def _marker(state, track, outcome, direct=False):
    kind = "direct" if direct else "success"
    return Marker(state, [track], outcome=outcome, direct=direct, id=f"{state} [{track}, {kind}] => {outcome}")


def _transit(x: str, before: str, after: str, track: str, first: str) -> list:
    """The transit part of track ``x/...`` (original-design.md section 3.3)."""
    areas = (x, before, after)
    out = [_edge(f"approach {x}", first, track)]
    out += [_edge(f"approach {p}", f"{p} to {x}", track) for p in (before, after)]
    out += [_edge(f"{p} to {x}", f"approach {x}", track) for p in (before, after)]
    for p in areas:  # transits that do not arrive at x: abandon them, back to where they began
        for q in areas:
            if p != q and q != x:
                out.append(_edge(f"{p} to {q}", f"approach {p}", track, direct=True))
    return out


def generate_pick(x: str, before: str, after: str) -> tuple:
    """Edges and markers of track ``x/pick`` and the pick side of ``withdraw``."""
    track = f"{x}/pick"
    chain = [f"approach {x}", f"enable gripper on {x}", f"grasp on {x}", f"record grasping pose on {x}",
             f"detach approach on {x} (pick)", f"raise on {x}", f"approach {x}"]
    edges = _transit(x, before, after, track, chain[1])
    edges += [_edge(a, b, track) for a, b in zip(chain[1:-1], chain[2:])]
    markers = [_marker(f"raise on {x}", track, "success")]
    w = "withdraw"
    for s in chain[1:5]:
        edges.append(_edge(s, f"disable gripper on {x}", w, direct=True))
    edges += [_edge(f"raise on {x}", f"put back on {x}", w, direct=True),
              _edge(f"put back on {x}", f"disable gripper on {x}", w),
              _edge(f"disable gripper on {x}", f"approach {x}", w)]
    markers += [_marker(f"approach {x}", w, "success")]
    markers += [_marker(f"{p} to {x}", w, "success", direct=True) for p in (before, after)]
    return edges, markers


def generate_place(x: str, before: str, after: str) -> tuple:
    """Edges and markers of track ``x/place`` and the place side of ``withdraw``."""
    track = f"{x}/place"
    chain = [f"approach {x}", f"put on {x}", f"release on {x}", f"detach approach on {x} (place)",
             f"escape {x}", f"approach {x}"]
    edges = _transit(x, before, after, track, chain[1])
    edges += [_edge(a, b, track) for a, b in zip(chain[1:-1], chain[2:])]
    markers = [_marker(f"escape {x}", track, "success")]
    w = "withdraw"
    edges.append(_edge(f"put on {x}", f"approach {x}", w, direct=True))
    # refused during the place; the one on 'put on x' is shadowed by the direct edge above
    markers += [_marker(s, w, "failure", direct=True) for s in chain[1:5]]
    return edges, markers


def movement_manager(n_targets: int = len(TARGETS)) -> FSM:
    """The authors' MovementManager FSM (``retarget="withdraw"``, parameter ``target``)."""
    nodes, edges, markers = {}, [], []
    for x, before, after in ROTATIONS:
        for st in generate_nodes(x, before, after):
            nodes[st.id] = st
        for gen in (generate_pick, generate_place):
            e, m = gen(x, before, after)
            edges += e
            markers += m
    # the three conveyor overrides
    c = "conveyor"
    nodes[f"approach {c}"] = State(f"approach {c}", "move_to", {"frame": _ns(f"{c}/approach"), "tolerance": "huge", "speed": "0.5"})
    nodes[f"raise on {c}"] = State(f"raise on {c}", "move_to", {"frame": _ns(f"{c}/approach"), "tolerance": "huge", "speed": "0.5"})
    nodes[f"grasp on {c}"] = State(f"grasp on {c}", "grasp_in", {"frame": _ns(f"{c}/grasp"), "speed": "0.5", "shaking": False})
    markers += [_marker("approach bins", "preemptive?", "success", direct=True),
                _marker("bins to agv", "preemptive?", "success", direct=True)]
    return FSM("movement_manager", states=list(nodes.values()), initial="approach bins", goals=TRACKS,
               edges=edges, markers=markers, params=[Int("target", 0, n_targets)],
               retarget="withdraw", withdraw_goal="withdraw")


def transit_table(fsm: FSM) -> dict:
    """``{(state, track): "S:target" | "D:target" | "marker ..."}`` for the table of
    original-design.md section 3.3 (first element per state and track)."""
    out: dict = {}
    for e in fsm.edges:
        for g in e.goals:
            out.setdefault((e.source, g), f"{'D' if e.direct else 'S'}:{e.target}")
    for m in fsm.markers:
        for g in m.goals:
            on, outcome = cast(Status, m.on), cast(Status, m.outcome)  # Statuses once built
            out.setdefault((m.state, g), f"marker {'direct' if m.direct else on.name.lower()}->{outcome.name.lower()}")
    return out


def _act(name, primitive=None):
    return Action(name, primitive=primitive or name)


def executive(n_parts: int = 18, variant: str = "memory"):
    """The executive tree of ``behavior_tree.py`` (original-design.md section 4.1)."""
    mm = "movement_manager"

    def request(name, goal):
        return SkillRequest(name, fsm=mm, goal=goal, params={"target": "chosen"})

    def gripper_empty(k):
        return Condition(f"gripper_empty_{k}", "gripper_empty")

    def not_gripper_empty(k):
        return Inverter(f"not_gripper_empty_{k}", child=gripper_empty(k))

    x = ReactiveSequence("X", [
        Inverter("not_queue_empty", child=Condition("queue_empty", "queue == 0")),
        ReactiveFallback("x_sel", [
            ReactiveSequence("x_full", [
                not_gripper_empty("x"),
                ReactiveFallback("x_place_sel", [
                    ReactiveSequence("x_intermediate", [
                        _act("check_intermediate_location"),
                        _act("choose_intermediate_location"),
                        request("place_on_intermediate_location", "bins/place"),
                        _act("register_gripper_empty_x1", "register_gripper_empty"),
                        _act("register_intermediate_placing"),
                        _act("forget_intermediate_location"),
                    ]),
                    ReactiveSequence("x_location", [
                        _act("choose_location_x", "choose_location"),
                        request("place_on_location_x", "agv/place"),
                        _act("register_gripper_empty_x2", "register_gripper_empty"),
                        _act("register_placing_x", "register_placing"),
                        _act("forget_location_x", "forget_location"),
                    ]),
                ]),
            ]),
            ReactiveSequence("x_empty", [
                gripper_empty("x2"),
                _act("choose_first_part_in_queue"),
                request("pick_part_x", "conveyor/pick"),
                _act("update_queue"),
                _act("register_gripper_not_empty_x", "register_gripper_not_empty"),
                _act("forget_part_x", "forget_part"),
            ]),
        ]),
    ])
    done = Condition("done", f"placed >= {n_parts}")  # the goal condition
    y = ReactiveSequence("Y", [
        not_gripper_empty("y"),
        _act("choose_location"),
        request("place_on_location", "agv/place"),
        _act("register_gripper_empty_y", "register_gripper_empty"),
        _act("register_placing"),
        _act("forget_location"),
    ])
    z = ReactiveSequence("Z", [
        gripper_empty("z"),
        _act("forget_part_z1", "forget_part"),
        _act("choose_part"),
        request("pick_part", "bins/pick"),
        _act("register_picking"),
        _act("register_gripper_not_empty"),
        _act("forget_part_z2", "forget_part"),
    ])
    if variant == "memory":  # ((X << done) << Y) << Z
        chain: Node = MemoryFallback("memsel_z", [MemoryFallback("memsel_y", [MemoryFallback("memsel_done", [x, done]), y]), z])
    elif variant == "preemptive":  # X + ((done << Y) << Z)
        chain = ReactiveFallback("sel_x", [x, MemoryFallback("memsel_z", [MemoryFallback("memsel_y", [done, y]), z])])
    else:
        raise ValueError(f"unknown variant {variant!r} (memory or preemptive)")
    return Parallel("executive", [_act("query_queue"), chain])


def _bookkeeping() -> tuple:
    """The executive's leaves as instant primitives: the five with logic in the original,
    the queue update, choose/forget of the request target, and the SUCCESS stubs."""
    t = TARGETS
    return (
        Primitive("query_queue", (success(),)),  # arrivals are the environment event 'arrive'
        Primitive("update_queue", (success(queue="queue - 1"),)),
        Primitive("register_gripper_empty", (success(gripper_empty=True),)),
        Primitive("register_gripper_not_empty", (success(gripper_empty=False),)),
        Primitive("register_placing", (success(placed="placed + 1"),)),
        Primitive("check_intermediate_location", (success(),)),
        Primitive("register_intermediate_placing", (success(),)),
        Primitive("register_picking", (success(),)),
        Primitive("choose_part", (success(chosen=str(t["part"])),)),
        Primitive("choose_first_part_in_queue", (success(chosen=str(t["first_part_in_queue"])),)),
        Primitive("choose_location", (success(chosen=str(t["location"])),)),
        Primitive("choose_intermediate_location", (success(chosen=str(t["intermediate_location"])),)),
        Primitive("forget_part", (success(chosen="0"),)),
        Primitive("forget_location", (success(chosen="0"),)),
        Primitive("forget_intermediate_location", (success(chosen="0"),)),
    )


def _model(name: str, variant: str, n_parts: int, queue_max: int, primitives=PRIMITIVES) -> Model:
    if n_parts < 1 or queue_max < 1:
        raise ValueError("n_parts and queue_max must be at least 1")
    hubs = [f"approach {a}" for a, _, _ in ROTATIONS] + [f"{p} to {q}" for q, a, b in ROTATIONS for p in (a, b)]
    return Model(
        name,
        variables=[Int("queue", 0, queue_max), Bool("gripper_empty", True), Int("placed", 0, n_parts),
                   Int("chosen", 0, len(TARGETS))],
        primitives=tuple(primitives) + _bookkeeping(),
        fsms=[movement_manager()],
        tree=executive(n_parts, variant),
        environment=[EnvEvent("arrive", f"queue < {queue_max}", {"queue": "queue + 1"})],
        # where withdraw leads: an approach pose or a transit, with no goal held
        workable="movement_manager.state in (" + ", ".join(repr(h) for h in hubs) + ") and movement_manager.goal == 'none'",
        tick_rate=10.0,
        description=f"the authors' MovementManager and executive ({variant} selector chain), goal {n_parts} parts",
    )


def original(n_parts: int = 18, queue_max: int = 2) -> Model:
    """The authors' FSM and executive, memory selectors as in ``behavior_tree.py``."""
    return _model("original", "memory", n_parts, queue_max)


def original_preemptive(n_parts: int = 18, queue_max: int = 2) -> Model:
    """The same FSM under the inferred preemptive executive ``X + ((done << Y) << Z)``."""
    return _model("original-preemptive", "preemptive", n_parts, queue_max)


def original_narrow(n_parts: int = 18, queue_max: int = 2) -> Model:
    """``original()`` with the narrower primitive declarations (``NARROW_PRIMITIVES``):
    ``gripper_control`` never RUNNING, ``record_grasping_pose`` and ``detach_approach``
    always SUCCESS at once. Not what the original accepts, but what its hardware would do."""
    return _model("original-narrow", "memory", n_parts, queue_max, NARROW_PRIMITIVES)
