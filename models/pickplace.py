"""The SPIN pick/place benchmark (shared/bench/spin/pickplace.pml) as a btfsm model.

The Promela model is one process that, every step, lets the environment choose a goal
(HOLD, PICK, PL1, PL2; only goals whose ``EN(g)`` holds) and whether a part arrives, and
then moves the robot one phase. Here:

* world variables ``area, goal, grip, queue, d1, d2, bat`` are the Promela globals of the
  same names (``goal`` is an enum ``hold/pick/place1/place2``);
* the environment is an ``EnvChoice`` ``request`` whose options set ``goal`` and are
  guarded by ``EN(g)``, followed by an ``EnvEvent`` ``arrive`` (``queue < Q``);
* the robot is FSM ``skill`` whose token is the Promela ``phase`` (``idle, approach,
  grasp, lift, withdraw, transit``); it has one goal, ``serve``, and reads the requested
  Promela goal from the world variable. One ``SkillRequest`` is the whole tree. Every FSM
  tick takes at most one edge (status edges only, no direct edges) and replies SUCCESS
  (a marker on every state), so the held goal and the request's running flag stay 0 and
  the reachable states are in one-to-one correspondence with SPIN's (run with ``-o2``):
  10,288 / 104,860 / 1,305,694 / 6,053,248 / 18,291,250 states at Q=D=B = 3/6/12/18/24.
* ``bug=True``: idle and approach ignore a full gripper; SPIN's GRASP assertion becomes
  the invariant ``grasp_needs_part`` here.
* ``dead=True``: no reserve transit home at ``bat == 0``; the states where no goal is
  enabled are dead states (8,624 states, 1,024 dead, at size 3).

>>> m = pickplace(3)
>>> [s.name for s in m.program.slots][:8]
['area', 'goal', 'grip', 'queue', 'd1', 'd2', 'bat', 'skill.state']
"""
from __future__ import annotations

from btfsm import (FSM, Bool, Edge, EnvChoice, EnvEvent, Enum, Int, Marker, Model, SkillRequest,
                   State)

__all__ = ["pickplace", "pickplace_dead", "pickplace_bug", "GOALS", "PHASES", "SPIN_STATES"]

GOALS = ("hold", "pick", "place1", "place2")
PHASES = ("idle", "approach", "grasp", "lift", "withdraw", "transit")
# SPIN 6.5.2 `spin -o2` stored states of pickplace.pml at Q=D=B=n (bench/README.md)
SPIN_STATES = {3: 10_288, 6: 104_860, 12: 1_305_694, 18: 6_053_248, 24: 18_291_250}

_TARGET = {"pick": "0", "place1": "1", "place2": "2"}  # TGT(g); hold keeps the area


def _target() -> str:
    """TGT(goal) as an expression of the world variable ``goal``."""
    return "(0 if goal == 'pick' else 1 if goal == 'place1' else 2 if goal == 'place2' else area)"


def _doable(bug: bool) -> str:
    """DOABLE(goal): the requested task can be done at the current area."""
    empty = "" if bug else " and not grip"
    return (f"((goal == 'pick' and area == 0 and queue > 0{empty})"
            " or ((goal == 'place1' and area == 1 or goal == 'place2' and area == 2) and grip))")


def _enabled(g: str, dead: bool) -> str:
    """EN(g) of pickplace.pml for a fixed goal ``g`` (evaluated before the arrival)."""
    batok = "(bat > 0 or area == 0)" if dead else "true"
    if g == "hold":
        return f"skill.state != 'idle' or {batok}"
    t = _TARGET[g]
    reserve = "false" if dead or t != "0" else "true"
    return (f"skill.state != 'idle' or (area != {t} and (bat > 0 or {reserve}))"
            f" or (area == {t} and {batok})")


def pickplace(n: int = 3, *, qmax: "int | None" = None, dmax: "int | None" = None,
              bmax: "int | None" = None, bug: bool = False, dead: bool = False) -> Model:
    """The benchmark at sizes Q = D = B = ``n`` (or each given separately)."""
    q, d, b = (n if x is None else x for x in (qmax, dmax, bmax))
    if min(q, d, b) < 1:
        raise ValueError("sizes must be at least 1")
    tgt, doable = _target(), _doable(bug)
    edges = [
        Edge("idle", "transit", guard=f"goal != 'hold' and {tgt} != area and bat > 0",
             effects={"area": tgt, "bat": "bat - 1"}, id="travel"),
    ]
    if not dead:  # the reserve transit home (EN(g) guarantees TGT(g) == 0 here)
        edges.append(Edge("idle", "transit", guard=f"goal != 'hold' and {tgt} != area and bat == 0",
                          effects={"area": "0"}, id="reserve_home"))
    edges += [
        Edge("idle", "approach", guard=f"goal != 'hold' and {tgt} == area and {doable}", id="start"),
        Edge("transit", "idle", guard="area == 0", effects={"bat": str(b)}, id="dock"),
        Edge("transit", "idle", id="arrive_at_place"),
        Edge("approach", "grasp", guard=doable, id="commit"),
        Edge("approach", "withdraw", id="give_up"),
        Edge("grasp", "lift", guard="area == 0", effects={"grip": "true", "queue": "queue - 1"}, id="take"),
        Edge("grasp", "lift", guard="area == 1", effects={"grip": "false", "d1": f"(d1 + 1) % {d + 1}"}, id="drop1"),
        Edge("grasp", "lift", guard="area == 2", effects={"grip": "false", "d2": f"(d2 + 1) % {d + 1}"}, id="drop2"),
        Edge("lift", "withdraw", id="lift_done"),
        Edge("withdraw", "idle", id="withdrawn"),
    ]
    skill = FSM("skill", states=[State(p) for p in PHASES], initial="idle", goals=["serve"],
                edges=edges, markers=[Marker(p, ["serve"], id=f"{p}_done") for p in PHASES])
    request = EnvChoice("request", [EnvEvent(g, _enabled(g, dead), {"goal": repr(g)}) for g in GOALS])
    arrive = EnvEvent("arrive", f"queue < {q}", {"queue": "queue + 1"})
    flags = "".join(f for f, on in (("-bug", bug), ("-dead", dead)) if on)
    return Model(
        f"pickplace{q}" + (f"x{d}x{b}" if (d, b) != (q, q) else "") + flags,
        variables=[Int("area", 0, 2), Enum("goal", GOALS), Bool("grip"), Int("queue", 0, q),
                   Int("d1", 0, d), Int("d2", 0, d), Int("bat", 0, b, init=b)],
        fsms=[skill],
        tree=SkillRequest("robot_step", fsm="skill", goal="serve"),
        environment=[request, arrive],
        invariants={
            "grasp_needs_part": "skill.state != 'grasp' or area != 0 or (not grip and queue > 0)",
            "release_needs_part": "skill.state != 'grasp' or area == 0 or grip",
        },
        workable="skill.state == 'idle' and area == 0",
        description="SPIN pick/place benchmark (pickplace.pml): one goal-driven skill, "
                    "an adversarial goal stream and part arrivals",
    )


def pickplace_dead() -> Model:
    """The ``dead`` variant at size 3 (for a registry entry without arguments)."""
    return pickplace(3, dead=True)


def pickplace_bug() -> Model:
    """The ``bug`` variant at size 3 (for a registry entry without arguments)."""
    return pickplace(3, bug=True)
