"""The paper's ARIAC kitting model, with the corrected skill FSM (docs/models.md).

One arm serves three areas: the AGV tray ``agv`` (A), the ``bins`` (B) and the
``conveyor`` (C). ``generate_fsm(X, Y, Z)`` is the paper's template for area X (the other
areas are Y and Z); the arm's FSM is the union of the template over the three cyclic
rotations of the areas: 42 states, one goal ``pick_<area>`` and ``place_<area>`` per area.

Corrections relative to the authors' original (``btfsm.models.original``):

* no ``withdraw`` goal: every goal takes over from every state through its own edges. A
  pick is undone (direct edges to ``put_back``/``disable_gripper``), a place before the
  release is aborted upward, a place after the release runs on to its escape pose;
* a failed grasp is retried ``grasp_attempts - 1`` times (a counter guards the retry
  edge), then the pick replies FAILURE through a marker: nothing is retried silently;
* no shadowed markers, no direct-edge cycles, disjoint guards (deterministic).

The executive tree is the paper's: a Parallel root that monitors the conveyor, the belt
branch X (rescue what the gripper holds into the bins, or pick the first belt part),
the goal condition ``done`` (``tray == n_tray``), Y (place on the tray) and Z (pick from
the bins). ``preemptive`` puts X in a reactive fallback before the rest, so X takes over
as soon as a belt part is detected; ``baseline`` puts all four in one memory fallback
(the paper's memory selector), so a detection waits until the running skill ends.

>>> m = preemptive(n_tray=2)
>>> len(m.fsm("arm").states), len(m.fsm("arm").goals)
(42, 6)
>>> [n for n in SKILLS]
['S1', 'S2', 'S3', 'S4']
"""
from __future__ import annotations

from typing import cast

from btfsm import (FSM, Action, Bool, Condition, Edge, Effects, Int, Marker, MemoryFallback,
                   MemorySequence, Model, Parallel, Primitive, ReactiveFallback, ReactiveSequence,
                   SkillRequest, State, EnvEvent, failure, running, success)
from btfsm.bt import Node
from btfsm.timing import Response

__all__ = ["AREAS", "ROTATIONS", "SKILLS", "PRIMITIVES", "ARM_REQUESTS", "generate_fsm", "unite", "arm_fsm",
           "tree", "preemptive", "baseline", "states_of", "HUBS", "ARM_DURATIONS", "ARRIVAL_MIN_INTERVAL",
           "PICK_WINDOW", "TIMING_FILE", "TIMING_FILE_NO_LOSS", "NO_LOSS", "derived_timing", "timed", "preemptive_timed",
           "baseline_timed", "preemptive_timed_no_loss", "baseline_timed_no_loss", "with_bins", "BIN_VARIABLES",
           "PLACE_BINS", "PICK_BINS", "BIN_COPIES", "BIN_TARGET", "AGE_STATES", "AGE_BOUNDS", "age_copies", "AGE_COPIES",
           "spaced", "TRAY_ROWS", "TRAY_COPIES", "THIRD"]

AREAS = ("agv", "bins", "conveyor")
# the authors' rotation order: (area, area before, area after)
ROTATIONS = (("bins", "conveyor", "agv"), ("agv", "bins", "conveyor"), ("conveyor", "agv", "bins"))
HUBS = tuple(f"approach_{a}" for a in AREAS)

# the paper's four skills: (name, goal of the FSM 'arm', SkillRequest node)
SKILLS = {
    "S1": ("pick_bins", "pick_part"),
    "S2": ("place_agv", "place_on_location"),
    "S3": ("pick_conveyor", "pick_part_from_queue"),
    "S4": ("place_bins", "place_on_intermediate_location"),
}

# Generic primitives bound by name; ``args`` say where and how (docs/models.md lists them).
PRIMITIVES = (
    Primitive("move", (running("moving"), success("arrived"))),
    Primitive("gripper", (success("switched"),)),
    Primitive("grasp", (running("searching"), success("attached", gripper_full=True), failure("missed"))),
    Primitive("record_pose", (success("recorded"),)),
    Primitive("detach", (success("detached"),)),
    Primitive("query_queue", (success("polled"),)),
)

_TOL_APPROACH = {"conveyor": "huge"}  # the belt moves: the authors use the loose tolerance there


def states_of(x: str, y: str, z: str) -> list:
    """The 14 states of area ``x``: its hub, the two transits arriving at it, the pick
    chain with its undo states, and the place chain."""
    approach_tol = _TOL_APPROACH.get(x, "fine")
    return [
        State(f"{y}_to_{x}", "move", {"area": x, "pose": f"from_{y}", "tolerance": "via_point"}),
        State(f"{z}_to_{x}", "move", {"area": x, "pose": f"from_{z}", "tolerance": "via_point"}),
        State(f"approach_{x}", "move", {"area": x, "pose": "approach", "tolerance": approach_tol}),
        State(f"enable_gripper_{x}", "gripper", {"on": True}),
        State(f"grasp_{x}", "grasp", {"area": x, "shaking": x != "conveyor"}),
        State(f"record_pose_{x}", "record_pose", {"area": x}),
        State(f"detach_pick_{x}", "detach", {"area": x}),
        State(f"raise_{x}", "move", {"area": x, "pose": "approach", "tolerance": _TOL_APPROACH.get(x, "coarse")}),
        State(f"put_back_{x}", "move", {"area": x, "pose": "grasp", "tolerance": "coarse"}),
        State(f"disable_gripper_{x}", "gripper", {"on": False}),
        State(f"put_{x}", "move", {"area": x, "pose": "grasp", "tolerance": "coarse"}),
        State(f"release_{x}", "gripper", {"on": False}),
        State(f"detach_place_{x}", "detach", {"area": x}),
        State(f"escape_{x}", "move", {"area": x, "pose": "approach", "tolerance": "fine"}),
    ]


def generate_fsm(x: str, y: str, z: str, grasp_attempts: int = 2) -> tuple:
    """The template for area ``x`` (other areas ``y``, ``z``): ``(states, edges, markers)``.

    Edges of the goals ``pick_x``/``place_x`` everywhere (the transit part), and the
    edges of *every* goal inside x's own chains (progress for x's goals, preemption for
    the others).

    >>> st, ed, mk = generate_fsm("bins", "conveyor", "agv")
    >>> len(st), sorted({m.state for m in mk})
    (14, ['disable_gripper_bins', 'escape_bins', 'grasp_bins', 'raise_bins'])
    """
    if grasp_attempts < 1:
        raise ValueError("grasp_attempts must be at least 1")
    pick, place = f"pick_{x}", f"place_{x}"
    mine = (pick, place)
    every = tuple(f"{k}_{a}" for a in (x, y, z) for k in ("pick", "place"))
    place_elsewhere = (f"place_{y}", f"place_{z}")
    pick_elsewhere = (f"pick_{y}", f"pick_{z}")
    A = f"approach_{x}"
    edges = [
        # transit part: reach x's hub from anywhere, then enter the chain
        Edge(A, f"enable_gripper_{x}", [pick], effects={"retries": 0}),
        Edge(A, f"put_{x}", [place]),
        Edge(f"approach_{y}", f"{y}_to_{x}", mine),
        Edge(f"approach_{z}", f"{z}_to_{x}", mine),
        Edge(f"{y}_to_{x}", A, mine),
        Edge(f"{z}_to_{x}", A, mine),
    ]
    for p, q in ((x, y), (x, z), (y, z), (z, y)):  # transits that do not arrive at x
        edges.append(Edge(f"{p}_to_{q}", f"approach_{p}", mine, direct=True))
    others = tuple(g for g in every if g != pick)
    E, G, R, D, U = (f"{s}_{x}" for s in ("enable_gripper", "grasp", "record_pose", "detach_pick", "raise"))
    B, OFF = f"put_back_{x}", f"disable_gripper_{x}"
    edges += [
        # pick chain; before the part is held every other goal switches the gripper off
        Edge(E, G, [pick]),
        Edge(E, OFF, others, direct=True),
        Edge(G, R, [pick], effects={"retries": 0}),
        Edge(G, OFF, others, direct=True),
    ]
    markers = []
    if grasp_attempts > 1:
        last = grasp_attempts - 1
        edges.append(Edge(G, E, [pick], on="failure", guard=f"retries < {last}", effects={"retries": "retries + 1"}))
        edges.append(Edge(G, OFF, [pick], on="failure", guard=f"retries >= {last}", effects={"retries": 0}))
        markers.append(Marker(G, [pick], on="failure", outcome="failure", guard=f"retries >= {last}"))
    else:
        edges.append(Edge(G, OFF, [pick], on="failure"))
        markers.append(Marker(G, [pick], on="failure", outcome="failure"))
    carry_on = (pick,) + place_elsewhere  # the part is held: finish lifting it
    put_down = pick_elsewhere + (place,)  # another pick, or a place right here: put it back
    edges += [
        Edge(R, D, carry_on), Edge(R, OFF, put_down, direct=True),
        Edge(D, U, carry_on), Edge(D, OFF, put_down, direct=True),
        Edge(U, A, carry_on), Edge(U, B, put_down, direct=True),
        Edge(B, OFF, every),
        Edge(OFF, A, every, effects={"gripper_full": False}),
    ]
    markers += [
        Marker(U, [pick], outcome="success"),
        # putting a held part back down is a place on x
        Marker(OFF, [place], outcome="success", guard="gripper_full"),
    ]
    P, L, DP, S = f"put_{x}", f"release_{x}", f"detach_place_{x}", f"escape_{x}"
    not_place = tuple(g for g in every if g != place)
    edges += [
        # place chain: before the release abort upward, after it run on to the escape pose
        Edge(P, L, [place]), Edge(P, A, not_place, direct=True),
        Edge(L, DP, [place], effects={"gripper_full": False}), Edge(L, A, not_place, direct=True),
        Edge(DP, S, every),
        Edge(S, A, every),
    ]
    markers.append(Marker(S, [place], outcome="success"))
    return states_of(x, y, z), edges, markers


def unite(parts) -> tuple:
    """Union of template instances: states in order, edges and markers that differ only
    in their goals merged into one element serving all of them."""
    states, seen = [], set()
    edges: dict = {}
    markers: dict = {}
    for st, ed, mk in parts:
        for s in st:
            if s.id not in seen:
                seen.add(s.id)
                states.append(s)
        for e in ed:
            key: tuple = (e.source, e.target, e.direct, e.on, e.guard, e.effects)
            edges[key] = edges[key] + tuple(g for g in e.goals if g not in edges[key]) if key in edges else e.goals
        for m in mk:
            key = (m.state, m.direct, m.on, m.guard, m.outcome)
            markers[key] = markers[key] + tuple(g for g in m.goals if g not in markers[key]) if key in markers else m.goals
    out_edges = [Edge(s, t, goals, on=on, guard=gd, direct=d, effects=eff) for (s, t, d, on, gd, eff), goals in edges.items()]
    out_markers = [Marker(s, goals, on=on, outcome=o, guard=gd, direct=d) for (s, d, on, gd, o), goals in markers.items()]
    return states, out_edges, out_markers


def arm_fsm(grasp_attempts: int = 2) -> FSM:
    """The arm's skill FSM: the template united over the three rotations."""
    states, edges, markers = unite(generate_fsm(x, y, z, grasp_attempts) for x, y, z in ROTATIONS)
    # the hub states first (in AREAS order) for readability; the token starts at the bins
    order = {sid: k for k, sid in enumerate(HUBS)}
    states.sort(key=lambda s: order.get(s.id, len(order)))
    goals = tuple(f"{k}_{a}" for a in AREAS for k in ("pick", "place"))
    return FSM("arm", states=states, initial="approach_bins", goals=goals, edges=edges, markers=markers)


def _at_tray() -> str:
    near = ", ".join(repr(s) for s in ("approach_agv", "put_agv", "release_agv", "detach_place_agv", "escape_agv"))
    return f"arm.state in ({near})"


ARM_REQUESTS = ("pick_part", "place_on_location", "pick_part_from_queue", "place_on_intermediate_location")


def tree(n_tray: int = 18, variant: str = "preemptive"):
    """The executive tree (the paper's BT with explicit pre/post-conditions)."""
    s1 = SkillRequest("pick_part", fsm="arm", goal="pick_bins", post="gripper_full")
    s2 = SkillRequest("place_on_location", fsm="arm", goal="place_agv", post="not gripper_full")
    s3 = SkillRequest("pick_part_from_queue", fsm="arm", goal="pick_conveyor", post="gripper_full")
    s4 = SkillRequest("place_on_intermediate_location", fsm="arm", goal="place_bins", post="not gripper_full")
    belt = ReactiveSequence("belt_branch", [
        Condition("queue_not_empty", "queue > 0"),
        MemoryFallback("serve_queue", [
            MemorySequence("free_gripper", [
                Condition("gripper_not_empty_for_belt", "gripper_full"),
                # hold the part in the bins unless the arm is already at the tray
                Condition("check_intermediate_location", f"not ({_at_tray()})"),
                s4]),
            MemorySequence("take_first_in_queue", [
                Condition("gripper_empty_for_belt", "not gripper_full"),
                # the part leaves the queue whether it was picked or missed (it rode past)
                Effects("update_queue", child=s3, on_success={"queue": "queue - 1"},
                        on_failure={"queue": "queue - 1"})]),
        ]),
    ])
    done = Condition("done", f"tray == {n_tray}")
    place = MemorySequence("place_branch", [
        Condition("gripper_not_empty", "gripper_full"),
        # count the part when the place succeeds, or when it is halted after the release
        Effects("register_placing", child=s2, on_success={"tray": "tray + 1"},
                on_halt={"tray": "tray + 1 if not gripper_full else tray"})])
    pick = MemorySequence("pick_branch", [Condition("gripper_empty", "not gripper_full"), s1])
    if variant == "preemptive":
        executive: Node = ReactiveFallback("executive", [belt, MemoryFallback("kitting", [done, place, pick])])
    elif variant == "baseline":
        executive = MemoryFallback("executive", [belt, done, place, pick])
    else:
        raise ValueError(f"unknown variant {variant!r} (preemptive or baseline)")
    monitor = Action("monitor_conveyor", primitive="query_queue")
    return Parallel("root", [monitor, executive])


def _model(variant: str, n_tray: int, queue_max: int, grasp_attempts: int) -> Model:
    if n_tray < 1 or queue_max < 1:
        raise ValueError("n_tray and queue_max must be at least 1")
    hubs = ", ".join(repr(h) for h in HUBS)
    releases = ", ".join(repr(f"release_{a}") for a in AREAS)
    enables = ", ".join(repr(f"enable_gripper_{a}") for a in AREAS)
    return Model(
        f"ariac-{variant}",
        variables=[Int("queue", 0, queue_max), Bool("gripper_full"), Int("tray", 0, n_tray),
                   Int("retries", 0, max(grasp_attempts - 1, 0))],
        primitives=PRIMITIVES,
        fsms=[arm_fsm(grasp_attempts)],
        tree=tree(n_tray, variant),
        environment=[EnvEvent("arrive", f"queue < {queue_max}", {"queue": "queue + 1"})],
        invariants={
            # a grasp only starts with an empty gripper: never two parts in the gripper
            "one_part_at_a_time": f"not (gripper_full and arm.state in ({enables}))",
            # the gripper is only switched off to release a part it holds
            "release_holds_a_part": f"gripper_full or not (arm.state in ({releases}))",
        },
        workable=f"arm.state in ({hubs}) and arm.goal == 'none'",
        # the four skill requests drive the one arm: never two at once (exclusive-actions)
        resources={"arm": ARM_REQUESTS},
        tick_rate=10.0,
        description=(f"ARIAC kitting, {variant}: {n_tray} parts on the tray, at most {queue_max} belt parts "
                     f"waiting, {grasp_attempts} grasp attempts per pick"),
    )


def preemptive(n_tray: int = 18, queue_max: int = 2, grasp_attempts: int = 2) -> Model:
    """The preemptive executive: the belt branch is checked on every tick."""
    return _model("preemptive", n_tray, queue_max, grasp_attempts)


def baseline(n_tray: int = 18, queue_max: int = 2, grasp_attempts: int = 2) -> Model:
    """The paper's non-preemptive baseline: one memory fallback over the four branches."""
    return _model("baseline", n_tray, queue_max, grasp_attempts)


# ---------------------------------------------------------------------- time (issue 12)

#: Seconds the arm may spend in each state whose primitive runs (docs/semantics.md 6.1):
#: the longest visit measured in the 80 trials of the experiment plus 10 %, rounded up to a
#: tick (``python -m btfsm.sim.durations`` prints the measurement beside this table). States
#: never visited there have no bound. Measured, not derived from the motion profiles.
ARM_DURATIONS = {
    "approach_agv": 6.6, "approach_bins": 6.6, "approach_conveyor": 4.3,
    "agv_to_bins": 6.9, "conveyor_to_bins": 4.7, "bins_to_agv": 5.9, "conveyor_to_agv": 6.6,
    "agv_to_conveyor": 3.8, "bins_to_conveyor": 4.3,
    "grasp_bins": 1.3, "raise_bins": 1.7, "put_back_bins": 1.6, "put_bins": 1.5, "escape_bins": 1.7,
    "put_agv": 1.5, "escape_agv": 2.0, "grasp_conveyor": 0.7, "raise_conveyor": 1.7,
}
#: The experiment's belt parts are detected dTa(k) = 30 + 0.2 k >= 30.2 s apart.
ARRIVAL_MIN_INTERVAL = 30.0
#: ``timed(m, arrivals="job")``: belt parts arrive only while the kit is incomplete, in words
ARRIVALS_JOB = ("arrivals while the kit is incomplete (tray < n): the experiment's trial ends when the kit is "
                "complete, so it sends no belt part after")
#: The pick window dt* (s): a belt part is lost this long after its detection.
PICK_WINDOW = 16.0


TIMING_FILE = "ariac_timing.json"  # written by ``python -m btfsm.sim.durations --write``
#: the same derived under "no part lost yet" (``derive(model, no_loss=True)``; ``--write-no-loss``)
TIMING_FILE_NO_LOSS = "ariac_timing_no_loss.json"
#: what ``timed(m, assume="no_loss")`` assumes, in words (``btfsm bound`` prints it)
NO_LOSS = ("no part lost yet: sound up to the first detected part that leaves the belt ungrasped, so for the first "
           "late response within dt* (arrivals spaced more than dt*), not for figures past dt*")


#: The bins' occupancy that ``with_bins`` adds (the timed models' variables; the untimed models have none)
BIN_VARIABLES = ("bin2_free", "bin_target")
#: Where a place in the bins goes, by the cell's rule (``KittingBinding._choose_spot``: the first
#: free spot of bin2 in grid order, else of bin3): the copies of a place's approach at the bins
#: (``btfsm.positions.split_by_guard``) and the bins their target can be in; ``free``: the guard
#: says the bin has a free spot (no run of the copy ends at the hub for want of one)
PLACE_BINS = {
    "bin2": {"guard": "bin2_free > 0", "bins": ["bin2"], "free": True},
    "bin3": {"guard": "bin2_free == 0", "bins": ["bin3"], "free": False},
    "bins": {"guard": "bin2_free < 0", "bins": ["bin2", "bin3"], "free": False},
}
_T2, _T3 = "(bin_target == 0 or bin_target == 2 or bin_target == 3 or bin_target == 6 or bin_target == 7)", \
    "(bin_target == 1 or bin_target == 4 or bin_target == 5)"
#: Which bin a pick at the bins goes to (its target: chosen from the turn's bin, or kept, or
#: held): the copies of a pick's approach at the bins, as ``PLACE_BINS``
PICK_BINS = {
    "bin2": {"guard": f"bin2_free >= 0 and {_T2}", "bins": ["bin2"], "free": True},
    "bin3": {"guard": f"bin2_free >= 0 and {_T3}", "bins": ["bin3"], "free": True},
    "bins": {"guard": f"bin2_free < 0 or bin_target == 8", "bins": ["bin2", "bin3"], "free": False},
}
#: ``derive``'s guard splits: {goal: copies}
BIN_COPIES = {"place_bins": PLACE_BINS, "pick_bins": PICK_BINS}
#: ``bin_target``'s values: the bins' pick target, the bin it was chosen from, where it is
BIN_TARGET = ("none chosen, the next from bin2", "none chosen, the next from bin3", "chosen from bin2, in bin2",
              "chosen from bin2, held", "chosen from bin3, in bin3", "chosen from bin3, held (taken from bin3)",
              "chosen from bin3, in bin2 (a rescue put it there)", "chosen from bin3, held (taken from bin2)",
              "none chosen, the next from bin2; a part taken from bin3 held")
#: The goal copies that pursue a belt part, split by its age (``derive``'s ``ages``): a pursuit
#: that starts late finds the part far down the pick stretch, and is shorter
AGE_STATES = ("bins_to_conveyor#pick_conveyor", "agv_to_conveyor#pick_conveyor")
#: the ages (s) that start a copy: [0, 6) and [6, ...) seconds since the last arrival (from the bins' hub a
#: pursuit takes at most 2.49 s for a part of any age, 1.92 s for one at least 6 s old: ``Derivation.track``'s
#: samples plus its margin; one bound at 9 s, or three at 4, 8 and 12 s, give the same figures)
AGE_BOUNDS = (6.0,)


def age_copies(states=AGE_STATES, bounds=AGE_BOUNDS, rate: float = 10.0) -> dict:
    """``{goal copy: {tag: {"guard": .., "age": seconds}}}``: each of ``states`` split by
    the ticks since the last arrival (``since(arrive)``, docs/semantics.md 7) at ``bounds``
    seconds; a copy's ``age`` is the least age of the part its run pursues (the part was
    detected no later than the last arrival).

    >>> age_copies(("s",), (9.0,))["s"]["age9"]
    {'guard': 'since(arrive) >= 90', 'age': 9.0}
    """
    import math

    ticks = [math.ceil(b * rate) for b in bounds]
    out: dict = {}
    for s in states:
        out[s] = {}
        for k, lo in enumerate([0] + ticks):
            hi = ticks[k] if k < len(ticks) else None
            guard = " and ".join(([f"since(arrive) >= {lo}"] if lo else []) + ([f"since(arrive) < {hi}"] if hi else []))
            out[s][f"age{lo / rate:g}"] = {"guard": guard or "true", "age": lo / rate}
    return out


#: ``derive``'s age splits
AGE_COPIES = age_copies()


def spaced(model: Model) -> Model:
    """``model`` with its belt parts arriving at least ``ARRIVAL_MIN_INTERVAL`` apart (what
    ``since(arrive)``, which the copies by age read, needs)."""
    import dataclasses

    return dataclasses.replace(model, environment=tuple(
        dataclasses.replace(cast(EnvEvent, e), min_interval=ARRIVAL_MIN_INTERVAL) for e in model.environment))


#: the states whose runs choose the place's target at the bins (their ``#place_bins`` copies)
_PLACE_MOVES = ("approach_bins", "agv_to_bins", "conveyor_to_bins")

#: Which tray slot a place on the tray goes to, by the cell's rule (``KittingBinding._choose_spot``:
#: the first free slot, kept until used): the tray is never picked from and a part is released
#: there only at its target slot, so the slots fill in order and the target is slot ``tray``
#: (the count, which the model keeps as the cell does). The copies of a place's approach at
#: the tray (``split_by_guard`` on ``tray``, which no edge changes while such a copy runs: a
#: place's count comes after its release) by the tray's row of 3 slots (``slots``: the
#: indices in the scene's ``slots``), and ``full`` for a count past the 18 slots (no slot:
#: all of them, and it may stay at the hub). A model with n tray parts keeps the copies whose
#: ``least`` count is at most n (``timed``); the 2-part models, row 0 alone.
TRAY_ROWS = {**{f"row{r}": {"guard": f"tray >= {3 * r} and tray < {3 * r + 3}" if r else "tray < 3",
                            "slots": [3 * r, 3 * r + 1, 3 * r + 2], "free": True, "least": 3 * r} for r in range(6)},
             "full": {"guard": "tray >= 18", "slots": list(range(18)), "free": False, "least": 18}}
#: ``derive``'s guard splits on the tray (every timed model keeps them): {goal: copies}
TRAY_COPIES = {"place_agv": TRAY_ROWS}
#: ``derive``'s third state of history: for the rescue (a place's approach at the bins,
#: entered from a move halted at the bins: where that move began)
THIRD = ("approach_bins#place_bins",)


def with_bins(model: Model) -> Model:
    """``model`` (an ARIAC variant, at most 18 tray parts, its arm FSM split by goal class:
    ``btfsm.positions.split_by_goal``) with what a timed model needs to know which bin a
    place in the bins goes to, as the cell's rules make it (``btfsm.sim.binding``): a place
    goes to the first free spot of bin2, else of bin3; a pick's new target comes from bin2
    and bin3 in turn; a target still in a bin is kept, until a place at the bins chooses its
    spot (the cell keeps one target per area: the place's spot replaces the pick's part, so
    the next pick chooses anew). Two variables (``BIN_VARIABLES``), changed only by arm FSM
    edges:

    * ``bin2_free``: bin2's free spots (3 x 3, full at the start); -1: not known any more
      (a place's target may be in either bin: the wide durations). It becomes so when a pick
      takes bin2's last part (the cell's choice would skip an empty bin2), or a part not
      taken from bin3 is put in the bins while bin2 is full (bin3 may be full too, and the
      part then drops at the bins' hub);
    * ``bin_target`` (``BIN_TARGET``): the pick target, the bin it was chosen from (which
      says the next new one's bin) and where it is: in bin2, in bin3 or held (and taken
      from which bin). A target chosen from bin2 stays in bin2 (held from bin2, bin2 has a
      free spot for its rescue); one from bin3 may move to bin2.

    Edges: a grasp at the bins succeeds (``grasp_bins -> record_pose_bins``): the target
    (chosen now if none: the cell chooses it when the pick's approach starts, from the same
    turn; no other choice can come between) leaves its bin; the token enters a place's
    approach at the bins (``approach_bins#place_bins``, the transits' place copies; not
    from ``disable_gripper_bins``, a put-back that counts as a place): the place chooses its
    spot, the pick target is forgotten (the turn, and whether the held part came from bin3,
    stay); a release in the bins (``release_bins -> detach_place_bins``): the held part goes
    to bin2 if it has a free spot, else to bin3; the gripper switched off at the bins
    holding the target (``disable_gripper_bins -> approach_bins``): it is back where it was
    taken; a release on the tray: the target is used up; on the belt (never requested): not
    known. bin3 is never empty when its turn comes while the bins are known: parts leave
    bin3 only as targets chosen from it, and a job of at most 18 parts chooses at most 9
    there, each after the one before left its bin for good. The variables only observe: no
    guard of the model reads them, so the model has the original's runs
    (``tests/test_positions.py``); ``tests/test_ariac_timing.py`` compares them with the
    cell in trials."""
    import dataclasses

    from btfsm import Int as _Int
    from btfsm.positions import base_state

    n_tray = next(v for v in model.variables if v.name == "tray").hi
    if n_tray > 18:
        raise ValueError(f"{model.name}: the bins hold 18 parts, the kit {n_tray}")
    if any(v.name in BIN_VARIABLES for v in model.variables):
        raise ValueError(f"{model.name} tracks the bins already")
    t = "bin_target"
    from2 = f"({t} == 0 or {t} == 2 or {t} == 6)"  # the target to grasp lies in bin2
    gone = f"(bin2_free < 0 or ({t} != 0 and {t} != 1 and {t} != 2 and {t} != 4 and {t} != 6) or " \
           f"({from2} and bin2_free == 8))"
    grasp = {"bin2_free": f"-1 if {gone} else (bin2_free + 1 if {from2} else bin2_free)",
             t: f"0 if {gone} else ({t} + 1 if {t} >= 2 else (3 if {t} == 0 else 5))"}
    forget = f"({t} if {t} <= 1 or {t} == 8 else 1 if {t} <= 3 else 8 if {t} == 5 else 0)"
    bin3 = f"({t} == 5 or {t} == 8)"  # the held part was taken from bin3: its spot there is free
    lost = f"(bin2_free < 0 or (bin2_free == 0 and not {bin3}))"  # bin2 full: bin3 may be full too
    place = {"bin2_free": f"-1 if {lost} else (bin2_free - 1 if bin2_free > 0 else bin2_free)",
             t: f"0 if {lost} or {bin3} else {forget}"}
    held = f"({t} == 3 or {t} == 5 or {t} == 7)"
    back = {"bin2_free": f"bin2_free - 1 if gripper_full and ({t} == 3 or {t} == 7) else bin2_free",
            t: f"{t} - 1 if gripper_full and {held} else {t}"}
    tray = {t: f"1 if {t} == 3 else 0 if {held} or {t} == 8 else {t}"}
    belt = {"bin2_free": f"-1 if {held} or {t} == 8 else bin2_free", t: f"0 if {held} or {t} == 8 else {t}"}
    added = {("grasp_bins", "record_pose_bins"): grasp, ("release_bins", "detach_place_bins"): place,
             ("disable_gripper_bins", "approach_bins"): back, ("release_agv", "detach_place_agv"): tray,
             ("release_conveyor", "detach_place_conveyor"): belt}
    f = model.fsms[0]
    seen: set = set()
    edges = []
    for e in f.edges:
        src, dst = base_state(e.source), base_state(e.target)
        more = dict(added.get((src, dst), {})) if not e.direct else {}
        if more:
            seen.add((src, dst))
        if dst in _PLACE_MOVES and "#place_bins" in e.target and src != "disable_gripper_bins":
            seen.add("choose")
            if t in more:
                raise ValueError(f"{model.name}: edge {e.source} -> {e.target} both chooses a place and tracks a pick")
            more[t] = forget
        if more:
            e = dataclasses.replace(e, effects=tuple(e.effects) + tuple(Edge("x", "y", effects=more).effects))
        edges.append(e)
    if seen != set(added) | {"choose"}:
        raise ValueError(f"{model.name}: no edge {sorted(map(str, (set(added) | {'choose'}) - seen))} to track the bins on "
                         "(the arm FSM must be split by goal class)")
    # 9 free spots (bin2 empty) is "not known": -1
    variables = tuple(model.variables) + (_Int("bin2_free", -1, 8, 0), _Int(t, 0, 8, 0))
    return dataclasses.replace(model, variables=variables, fsms=(dataclasses.replace(f, edges=tuple(edges)),))


def derived_timing(assume: "str | None" = None) -> dict:
    """The position abstraction with the durations derived from the ARIAC scene
    (``btfsm.sim.durations.derive``): ``{"classes": .., "table": .., "where": ..}``;
    ``assume="no_loss"``: derived under "no part lost yet" (``models/ariac_timing_no_loss.json``)."""
    import json
    from pathlib import Path

    name = {None: TIMING_FILE, "no_loss": TIMING_FILE_NO_LOSS}[assume]
    return json.loads((Path(__file__).resolve().parent / name).read_text(encoding="utf-8"))


def timed(model: Model, durations: str = "derived", *, timing: "dict | None" = None,
          window: float = PICK_WINDOW, assume: "str | None" = None, arrivals: str = "job",
          bins: str = "wide") -> Model:
    """``model`` (an ARIAC variant) with the arm's durations, the arrivals' minimum
    interval and the requirement ``reach``: every detected belt part is reached (the arm
    starts grasping at the conveyor) within dt* = 16 s. Picking it cannot be bounded in this
    model: its grasp may miss (a declared outcome), after which the part is given up.

    ``durations="derived"``: the arm FSM split by goal class and entry (``btfsm.positions``)
    with every copy's slowest run derived from the scene (``derived_timing``);
    ``"measured"``: one context-free maximum per state, measured in trials
    (``ARM_DURATIONS``). ``timing``: another derivation (``Timing.to_data()``, e.g. at
    another belt speed) instead of ``models/ariac_timing.json``; ``window``: the bound of
    ``reach`` in seconds (dt*). ``assume="no_loss"``: the durations derived under "no
    part lost yet" (``NO_LOSS``; named ``...-timed-no-loss``): every run of this model is
    a run of the unconditioned one, and every run of the cell up to its first lost part
    is a run of this one, so its first late response decides ``reach``
    (docs/verification.md 2.1); its figures past dt* are not bounds of the cell's.

    ``arrivals="job"`` (the default): belt parts arrive only while the kit is incomplete
    (``tray < n`` in the arrival's guard, ``ARRIVALS_JOB``), as in the experiment, whose trial
    ends when the kit is complete (``btfsm.sim.trial.KittingHooks.done``); ``"any"``: also
    after, the model's own environment (the figures before issue 21's scoping).

    ``bins="wide"`` (the default): no bins' variables, every pick and place in the bins may
    go to either bin (only the copies ``%bins`` are kept: the states and figures of the
    models before the bins were tracked); ``"tracked"``: the model tracks the bins'
    occupancy (``with_bins``) and a pick or place in the bins has one copy per bin it can
    go to (``BIN_COPIES``), with the durations of moves to that bin (named
    ``...-tracked-bins``; about 2 to 5 times the states, docs/verification.md 2.1)."""
    import dataclasses

    from btfsm.expr import as_expr, to_text
    from btfsm.positions import (base_state, check_requests, split_by_entry, split_by_goal, split_by_guard, split_deeper,
                                 split_history)

    f = model.fsms[0]
    if arrivals not in ("job", "any"):
        raise ValueError(f"arrivals: 'job' or 'any', not {arrivals!r}")
    n_tray = next(v for v in model.variables if v.name == "tray").hi
    job = f" and tray < {n_tray}" if arrivals == "job" else ""
    events = [cast(EnvEvent, e) for e in model.environment]
    env = tuple(dataclasses.replace(e, min_interval=ARRIVAL_MIN_INTERVAL,
                                    guard=f"({to_text(as_expr(e.guard))}){job}" if job and e.guard is not None
                                    else f"tray < {n_tray}" if job else e.guard)
                for e in events)
    model = dataclasses.replace(model, environment=env)  # the splits by age read the arrivals' spacing
    if assume not in (None, "no_loss") or (assume and timing is not None):
        raise ValueError(f"assume: None or 'no_loss' (with the stored derivation), not {assume!r}")
    if durations == "derived":
        t = derived_timing() if timing is None else timing
        check_requests(model, f.name, t.get("requested"))
        table = {s: {u: tuple(iv) for u, iv in rows.items()} for s, rows in t["table"].items()}
        split = split_by_goal(model, f.name, t["classes"])
        if bins not in ("tracked", "wide"):
            raise ValueError(f"bins: 'tracked' or 'wide', not {bins!r}")
        guards = {}
        for s, g in (t.get("guards") or {}).items():
            if set(g) <= set(TRAY_ROWS):  # the tray's rows: those the count can reach (the others never entered)
                kept = [c for c in g if cast(int, TRAY_ROWS[c]["least"]) <= n_tray]
                guards[s] = {c: ("true" if len(kept) == 1 else g[c]) if c in kept else "false" for c in g}
            elif bins == "tracked":  # the copies read the bins' occupancy
                guards[s] = g
            else:  # only the copy that may go to either bin is kept (the others never entered)
                guards[s] = {c: "true" if c == "bins" else "false" for c in g}
        if guards:
            split = split_by_guard(with_bins(split) if bins == "tracked" else split, f.name, guards)
        if t.get("ages"):  # the pursuits of a belt part by its age (``since(arrive)``, read once arrivals are spaced)
            split = split_by_guard(split, f.name, t["ages"])
        split = split_history(split, f.name, t["history"])
        ids = {st.id for st in split.fsms[0].states}  # the rows of the copies that can be entered
        table = {s: rows for s, rows in table.items() if s in ids}
        if assume is None:
            split, table = split_deeper(split, f.name, table, t.get("deep") or {})
            model = split_by_entry(split, f.name, table)
        else:  # the same copies (state names) as without the assumption, each with its conditioned maximum
            cond = derived_timing(assume)
            if (cond["classes"], cond["history"], cond.get("guards"), cond.get("ages"), set(cond.get("deep") or {})) != \
                    (t["classes"], t["history"], t.get("guards"), t.get("ages"), set(t.get("deep") or {})):
                raise ValueError(f"{TIMING_FILE_NO_LOSS} splits the FSM unlike {TIMING_FILE}: derive both again")
            split, table, ctable = split_deeper(split, f.name, table, t.get("deep") or {},
                                                (cond["table"], cond.get("deep") or {}))
            model = split_by_entry(split, f.name, table, ctable)
        how = "derived from the scene per goal class and entry (models/" + \
            (TIMING_FILE if assume is None else f"{TIMING_FILE}, maxima from {TIMING_FILE_NO_LOSS}") + ")"
        if assume or t.get("assume"):
            how += "; conditioned on " + NO_LOSS
    elif durations == "measured" and assume is None:
        states = tuple(dataclasses.replace(s, duration=(0.0, ARM_DURATIONS[s.id])) if s.id in ARM_DURATIONS else s
                       for s in f.states)
        model = dataclasses.replace(model, fsms=(dataclasses.replace(f, states=states),))
        how = "measured in the cell (ARM_DURATIONS)"
    else:
        raise ValueError(f"durations: 'derived' or 'measured', not {durations!r}")
    grasp = [s.id for s in model.fsms[0].states if base_state(s.id) == "grasp_conveyor"]
    reach = Response("reach", "event:arrive", " or ".join(f"arm.state == '{g}'" for g in grasp), window)
    suffix = ("-timed" if assume is None else "-timed-no-loss") + ("-tracked-bins" if bins == "tracked" else "")
    return dataclasses.replace(model, name=model.name + suffix, environment=env, responses=(reach,),
                               description=model.description + "; durations " + how
                               + ("; " + ARRIVALS_JOB if job else "; arrivals also after the kit is complete"))


def preemptive_timed(n_tray: int = 2) -> Model:
    """The preemptive variant with time (``timed``); 2 tray parts keep the check small."""
    return timed(preemptive(n_tray=n_tray))


def baseline_timed(n_tray: int = 2) -> Model:
    """The baseline variant with time (``timed``); 2 tray parts keep the check small."""
    return timed(baseline(n_tray=n_tray))


def preemptive_timed_no_loss(n_tray: int = 2) -> Model:
    """``preemptive_timed`` with the durations conditioned on no part lost yet (``NO_LOSS``)."""
    return timed(preemptive(n_tray=n_tray), assume="no_loss")


def baseline_timed_no_loss(n_tray: int = 2) -> Model:
    """``baseline_timed`` with the durations conditioned on no part lost yet (``NO_LOSS``)."""
    return timed(baseline(n_tray=n_tray), assume="no_loss")
