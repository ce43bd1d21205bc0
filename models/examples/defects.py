"""The seeded-defect catalogue: small models, each with one deliberate mistake.

Every model is a few states of a pick/place arm (or a belt) with one defect that one
``btfsm check`` property is there to catch; ``EXPECTED`` gives each model's full verdict
row (the table-driven test checks all of them) and docs/models.md explains each.

===========================  ==========================  ==========================================
model                        property                    the defect
===========================  ==========================  ==========================================
``trap()``                   workable-reachability       the tree gives up a job halfway; the arm stays there
``unreachable_goal()``       goal-reachability           ``place`` has no edge out of the pick chain
``nondeterminism()``         determinism                 two edges on one status with overlapping guards
``dead_state()``             no-dead-states (dead)       an environment choice with no enabled option
``nonprogress()``            no-dead-states (cycle)      a failing grasp has no FAILURE edge: retried forever
``latency()``                request-latency (+ cycle)   the authors' withdraw-first protocol
``invariant()``              invariants                  an alarm during a lift keeps the part in hand
``contract()``               contracts                   the pick replies SUCCESS before the grasp
``domain()``                 domain                      an off-by-one guard lets a counter overflow
``shadowed_marker()``        lints (a warning)           a direct marker behind a direct edge
``exclusive()``              exclusive-actions           a belt scan moves the arm beside the pick/place skills
===========================  ==========================  ==========================================
"""
from __future__ import annotations

from btfsm import (FSM, Action, Bool, Condition, Edge, Effects, EnvChoice, EnvEvent, Int, Marker, MemoryFallback,
                   MemorySequence, Model, Parallel, Primitive, ReactiveFallback, ReactiveSequence, SkillRequest, State,
                   failure, running, success)

__all__ = ["trap", "unreachable_goal", "nondeterminism", "dead_state", "nonprogress", "latency",
           "invariant", "contract", "domain", "shadowed_marker", "exclusive", "EXPECTED", "PROPERTIES"]

PROPERTIES = ("workable-reachability", "goal-reachability", "determinism", "no-dead-states",
              "request-latency", "invariants", "contracts", "domain", "exclusive-actions")

# model name -> the properties it violates (every other property holds)
EXPECTED = {
    "defect-trap": {"workable-reachability"},
    "defect-unreachable-goal": {"goal-reachability"},
    "defect-nondeterminism": {"determinism"},
    "defect-dead-state": {"no-dead-states"},
    "defect-nonprogress": {"no-dead-states"},
    # withdraw-first also lets a requester that changes the target on every tick starve
    # the skill: a non-progress cycle at FSM level (immediate retargeting has neither)
    "defect-latency": {"request-latency", "no-dead-states"},
    "defect-invariant": {"invariants"},
    "defect-contract": {"contracts"},
    "defect-domain": {"domain"},
    "defect-shadowed-marker": set(),
    "defect-exclusive": {"exclusive-actions"},
}

_MOVE = Primitive("move", (running("moving"), success("arrived")))
_GRASP = Primitive("grasp", (running("searching"), success("attached", holding=True)))
_RELEASE = Primitive("release", (success("released", holding=False),))


def _pick_place(extra_edges=(), extra_markers=(), *, pick_marker="lift", goals=("pick", "place"),
                extra_states=(), **fsm_kw) -> FSM:
    """home -> reach -> grasp -> lift -> home (pick); home -> put -> release -> home (place)."""
    states = [State("home", "move", {"pose": "home"}), State("reach", "move", {"pose": "part"}),
              State("grasp", "grasp"), State("lift", "move", {"pose": "above"}),
              State("put", "move", {"pose": "tray"}), State("release", "release")] + list(extra_states)
    edges = [Edge("home", "reach", ["pick"]), Edge("reach", "grasp", ["pick"]), Edge("grasp", "lift", ["pick"]),
             Edge("lift", "home", ["pick"]), Edge("home", "put", ["place"]), Edge("put", "release", ["place"]),
             Edge("release", "home", ["place"])]
    markers = [Marker(pick_marker, ["pick"]), Marker("release", ["place"])]
    return FSM("arm", states=states, initial="home", goals=goals,
               edges=edges + list(extra_edges), markers=markers + list(extra_markers), **fsm_kw)


def _undo_edges():
    """Every goal can take over: before the grasp go home, after it carry the part on."""
    return [Edge("reach", "home", ["place"], direct=True), Edge("grasp", "home", ["place"], direct=True),
            Edge("lift", "home", ["place"]), Edge("put", "home", ["pick"], direct=True),
            Edge("release", "home", ["pick"], direct=True)]


def _pick_place_tree(pick_post="holding"):
    return ReactiveFallback("root", [
        ReactiveSequence("deliver", [Condition("holding_part", "holding"),
                                     SkillRequest("place_part", fsm="arm", goal="place", post="not holding")]),
        SkillRequest("pick_part", fsm="arm", goal="pick", post=pick_post),
    ])


def _model(name, fsm, tree, description, variables=None, **kw) -> Model:
    return Model(name, variables=variables or [Bool("holding")], primitives=[_MOVE, _GRASP, _RELEASE],
                 fsms=[fsm], tree=tree, description=description, **kw)


def trap() -> Model:
    """The tree stops asking for anything once ``stop`` is set, halfway through a job: the
    halted request leaves the arm where it was, and nothing ever brings it home."""
    f = FSM("arm", states=[State("home", "move", {"pose": "home"}), State("w1", "move", {"pose": "a"}),
                           State("w2", "move", {"pose": "b"})],
            initial="home", goals=["work"],
            edges=[Edge("home", "w1"), Edge("w1", "w2"), Edge("w2", "home")], markers=[Marker("w2")])
    tree = ReactiveSequence("root", [Condition("running_shift", "not stop"),
                                     SkillRequest("do_work", fsm="arm", goal="work")])
    return Model("defect-trap", variables=[Bool("stop")], primitives=[_MOVE], fsms=[f], tree=tree,
                 environment=[EnvEvent("stop", "not stop", {"stop": True})],
                 description="seeded defect: a halted job strands the arm (workable-reachability)")


def unreachable_goal() -> Model:
    """``place`` has no edge in the pick chain: requested there, it is not applicable
    (FAILURE) for ever. This tree (a memory fallback: each skill runs to its end) never
    asks for that, but the FSM alone allows it, and a reactive tree would hit it."""
    tree = MemoryFallback("root", [
        MemorySequence("deliver", [Condition("holding_part", "holding"),
                                   SkillRequest("place_part", fsm="arm", goal="place", post="not holding")]),
        SkillRequest("pick_part", fsm="arm", goal="pick", post="holding")])
    return _model("defect-unreachable-goal", _pick_place(), tree,
                  "seeded defect: goal 'place' cannot succeed from the pick chain (goal-reachability)")


def nondeterminism() -> Model:
    """The sorting state has two edges on SUCCESS whose guards overlap at ``weight == 2``."""
    f = FSM("arm", states=[State("home", "move", {"pose": "home"}), State("weigh", "move", {"pose": "scale"}),
                           State("light_bin", "move", {"pose": "a"}), State("heavy_bin", "move", {"pose": "b"})],
            initial="home", goals=["sort"],
            edges=[Edge("home", "weigh"), Edge("weigh", "light_bin", guard="weight <= 2"),
                   Edge("weigh", "heavy_bin", guard="weight >= 2"), Edge("light_bin", "home"), Edge("heavy_bin", "home")],
            markers=[Marker("light_bin"), Marker("heavy_bin")])
    return Model("defect-nondeterminism", variables=[Int("weight", 0, 3)], primitives=[_MOVE], fsms=[f],
                 tree=SkillRequest("sort_part", fsm="arm", goal="sort"),
                 environment=[EnvChoice("scale", [EnvEvent(f"reads_{w}", None, {"weight": w}) for w in range(4)])],
                 description="seeded defect: overlapping guards (determinism)")


def dead_state() -> Model:
    """The belt's choice covers 'feed' while the buffer has room and 'wait' only with one
    part in it: with two parts neither is enabled and time cannot go on."""
    f = FSM("arm", states=[State("home", "take", {"from": "buffer"})], initial="home", goals=["take"],
            markers=[Marker("home", ["take"])])
    belt = EnvChoice("belt", [EnvEvent("feed", "parts < 2", {"parts": "parts + 1"}),
                              EnvEvent("wait", "parts == 1")])
    tree = ReactiveSequence("root", [Condition("part_there", "parts > 0"),
                                     SkillRequest("take_part", fsm="arm", goal="take")])
    return Model("defect-dead-state", variables=[Int("parts", 0, 2)],
                 primitives=[Primitive("take", (running("taking"), success("taken", parts="parts - 1")))],
                 fsms=[f], tree=tree, environment=[belt],
                 description="seeded defect: an environment choice with no enabled option (no-dead-states)")


def nonprogress() -> Model:
    """The grasp can miss, and no edge handles the miss: the arm grasps again and again
    (the authors' silent retry)."""
    grasp = Primitive("grasp", (running("searching"), success("attached", holding=True), failure("missed")))
    f = _pick_place(_undo_edges())
    return Model("defect-nonprogress", variables=[Bool("holding")], primitives=[_MOVE, grasp, _RELEASE],
                 fsms=[f], tree=_pick_place_tree(),
                 description="seeded defect: a failing primitive retried forever (no-dead-states, non-progress)")


def latency() -> Model:
    """The authors' request protocol: a request for another part first drives the FSM to
    ``withdraw`` (one tick or more) before the requested goal starts."""
    w = ["withdraw"]
    f = _pick_place(_undo_edges() + [Edge("reach", "home", w, direct=True), Edge("grasp", "home", w, direct=True),
                                     Edge("lift", "home", w), Edge("put", "home", w, direct=True),
                                     Edge("release", "home", w)],
                    [Marker("home", w, direct=True)], goals=("pick", "place", "withdraw"),
                    params=[Int("part", 0, 1)], retarget="withdraw", withdraw_goal="withdraw")
    tree = ReactiveFallback("root", [
        ReactiveSequence("deliver", [Condition("holding_part", "holding"),
                                     SkillRequest("place_part", fsm="arm", goal="place", params={"part": "next"},
                                                  post="not holding")]),
        Effects("count", child=SkillRequest("pick_part", fsm="arm", goal="pick", params={"part": "next"}, post="holding"),
                on_success={"next": "1 - next"}),
    ])
    return _model("defect-latency", f, tree, "seeded defect: a withdraw tick per new target (request-latency)",
                  variables=[Bool("holding"), Int("next", 0, 1)])


def invariant() -> Model:
    """An alarm preempts the job; from ``lift`` the alarm's edge goes straight home and on to
    the safe pose with the part still in the gripper, which the invariant forbids."""
    stop = ["stop"]
    f = _pick_place(_undo_edges() + [Edge("home", "alarm", stop), Edge("alarm", "home"),
                                     Edge("reach", "home", stop, direct=True), Edge("grasp", "home", stop, direct=True),
                                     Edge("lift", "home", stop, direct=True),  # the defect: keeps the part
                                     Edge("put", "home", stop, direct=True), Edge("release", "home", stop)],
                    [Marker("alarm", stop)], goals=("pick", "place", "stop"),
                    extra_states=[State("alarm", "move", {"pose": "safe"})])
    tree = ReactiveFallback("root", [
        ReactiveSequence("emergency", [Condition("alarm_on", "alarm"),
                                       Effects("clear", child=SkillRequest("go_safe", fsm="arm", goal="stop"),
                                               on_success={"alarm": False})]),
        ReactiveSequence("deliver", [Condition("holding_part", "holding"),
                                     SkillRequest("place_part", fsm="arm", goal="place", post="not holding")]),
        SkillRequest("pick_part", fsm="arm", goal="pick", post="holding"),
    ])
    return _model("defect-invariant", f, tree, "seeded defect: the arm goes home holding a part (invariants)",
                  variables=[Bool("holding"), Bool("alarm")],
                  environment=[EnvEvent("alarm", "not alarm", {"alarm": True})],
                  invariants={"empty_handed_at_the_safe_pose": "arm.state != 'alarm' or not holding"})


def contract() -> Model:
    """The pick's SUCCESS marker sits on ``reach`` instead of ``lift``: the skill says
    'picked' before anything is in the gripper, breaking the request's post-condition."""
    return _model("defect-contract", _pick_place(_undo_edges(), pick_marker="reach"), _pick_place_tree(),
                  "seeded defect: success reported before the grasp (contracts)")


def domain() -> Model:
    """The arrival guard is off by one (``waiting <= 2`` for a counter of range 0..2): a
    third waiting part would be counted into a value the variable cannot hold."""
    tree = ReactiveFallback("root", [
        ReactiveSequence("deliver", [Condition("holding_part", "holding"),
                                     SkillRequest("place_part", fsm="arm", goal="place", post="not holding")]),
        ReactiveSequence("fetch", [Condition("part_waiting", "waiting > 0"),
                                   Effects("take", child=SkillRequest("pick_part", fsm="arm", goal="pick", post="holding"),
                                           on_success={"waiting": "waiting - 1"})])])
    return _model("defect-domain", _pick_place(_undo_edges()), tree, "seeded defect: a counter overflows (domain)",
                  variables=[Bool("holding"), Int("waiting", 0, 2)],
                  environment=[EnvEvent("arrive", "waiting <= 2", {"waiting": "waiting + 1"})])


def shadowed_marker() -> Model:
    """A refusal marker that can never fire: the direct edge on the same state and goal is
    taken first (the authors' 'put on X' marker). Only a lint; every property holds."""
    f = _pick_place(_undo_edges(), [Marker("put", ["pick"], direct=True, outcome="failure")])
    return _model("defect-shadowed-marker", f, _pick_place_tree(), "seeded defect: a shadowed marker (lint)")


def exclusive() -> Model:
    """A belt scan (the arm sweeps its camera over the belt) runs beside the pick/place
    skills under a ``Parallel``: it was meant for an idle arm, but nothing keeps it from
    moving the arm while a pick or a place drives it. The model declares the three leaves
    one resource, ``arm``; ``exclusive-actions`` reports the scan starting while the pick
    runs (any profile: leaves under a Parallel never halt each other)."""
    tree = Parallel("cell", [_pick_place_tree(), Action("scan_belt", "move", args={"pose": "belt"})])
    return _model("defect-exclusive", _pick_place(_undo_edges()), tree,
                  "seeded defect: a belt scan moves the arm beside the skills (exclusive-actions)",
                  resources={"arm": ["pick_part", "place_part", "scan_belt"]})
