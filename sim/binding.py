"""Binds the ARIAC model's primitives to the pymunk cell, and the cell's sensors to events.

The runtime that drives the cell is the ordinary ``btfsm.runtime.Runtime`` over the same
``Model`` that ``btfsm check`` verified; this module only supplies, by primitive name:

* ``move(area, pose, tolerance)``: transits and approaches go above the target of the
  goal being driven (a bin part, a free bin spot, a tray slot, a belt part that is
  tracked), ``put``/``put_back`` descend to it, ``raise``/``escape`` lift straight up;
* ``gripper(on)``: suction on/off (a held part is released where it is);
* ``grasp(area)``: descend onto the target part until the vacuum attaches ("attached"),
  or report "missed" when there is nothing to grasp;
* ``record_pose``, ``detach``, ``query_queue``: bookkeeping, instant.

Sensor events: each belt detection becomes one ``arrive`` event (at most one per tick, and
only while the model's ``queue`` is below its bound; later ones wait their turn).

``abstraction_errors`` compares the model's variables with the cell after each tick (the
conformance check of what the primitives physically did).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from .cell import BELT, Place

__all__ = ["CellBinding", "Dialect", "ARIAC", "ORIGINAL", "DIALECTS"]

@dataclass(frozen=True)
class Dialect:
    """How a model names things: its arm FSM, primitives, variables, goals and states.
    The cell runs any model written in one of the dialects below."""

    fsm: str
    move: str
    gripper: str
    grasp: str
    instant: tuple  # primitives that just succeed
    gripper_var: str
    gripper_var_means_full: bool
    tray_var: str
    goal_sep: str  # "pick_bins" (sep "_", kind first) or "bins/pick" (sep "/", area first)
    roles: tuple  # (state-name prefix, role)
    tray_end_states: tuple  # states after the release at the tray, before the place reports
    gripper_var_after_skill: bool = False  # the tree, not the FSM, updates it when a skill ends

    def goal(self, name):
        """(kind, area) of a goal name, or (None, None) for withdraw-like goals."""
        if not name or self.goal_sep not in name:
            return None, None
        a, b = name.split(self.goal_sep, 1)
        kind, area = (a, b) if self.goal_sep == "_" else (b, a)
        return (kind, area) if kind in ("pick", "place") else (None, None)

    def role(self, state: str) -> str:
        for prefix, role in self.roles:
            if state.startswith(prefix):
                return role
        return "approach"  # hubs and transits go to the goal's work pose

    def area(self, args) -> str:
        if "area" in args:
            return args["area"]
        return args["frame"].split("/")[1]  # "arm1/<area>/<pose>"


ARIAC = Dialect("arm", "move", "gripper", "grasp", ("record_pose", "detach", "query_queue"),
                "gripper_full", True, "tray", "_",
                (("raise_", "lift"), ("escape_", "lift"), ("put_back_", "put_back"), ("put_", "put")),
                ("release_agv", "detach_place_agv", "escape_agv"))
ORIGINAL = Dialect("movement_manager", "move_to", "gripper_control", "grasp_in",
                   ("record_grasping_pose", "detach_approach", "query_queue"),
                   "gripper_empty", False, "placed", "/",
                   (("raise on ", "lift"), ("escape ", "lift"), ("put back on ", "put_back"), ("put on ", "put")),
                   ("release on agv", "detach approach on agv (place)", "escape agv"), True)
DIALECTS = (ARIAC, ORIGINAL)


_STATUS = {"RUNNING": 0, "SUCCESS": 1, "FAILURE": 2}


class CellBinding:
    """Primitive implementations and sensor events for ``btfsm.models.ariac`` in a ``Cell``."""

    def __init__(self, cell, model, bins=(2, 3), speed_scale: float = 0.5):
        self.cell, self.model, self.bins = cell, model, tuple(bins)
        self.speed = speed_scale  # the authors' move_to default velocity scaling is 0.5
        self.d = self.dialect_of(model)
        if self.d is None:
            raise ValueError(f"{model.name}: the kitting cell cannot run this model ({self.unsupported(model)})")
        self.targets: dict = {}  # area -> part id (pick) or Place (place)
        self.origin: dict = {}  # area -> (x, y, z) where the held part was grasped
        self.delivered: list = []  # belt part ids told to the model, in queue order
        self.backlog: list = []  # detected belt parts not told yet
        self._seen = 0  # detections consumed
        self._bin_turn = 0
        self._moving_to = None
        self._grasping = None
        qvar = model.var("queue")
        self.queue_max = qvar.hi
        self.n_tray = model.var(self.d.tray_var).hi

    @staticmethod
    def _missing(model, d: Dialect) -> list:
        prims = model.all_primitives()
        names = {v.name for v in model.variables}
        missing = [f"primitive '{p}'" for p in (d.move, d.gripper, d.grasp) if p not in prims]
        missing += [f"variable '{v}'" for v in ("queue", d.gripper_var, d.tray_var) if v not in names]
        if not any(f.name == d.fsm for f in model.fsms):
            missing.append(f"FSM '{d.fsm}'")
        if "arrive" not in {ev.name for ev in model.environment}:
            missing.append("environment event 'arrive'")
        return missing

    @classmethod
    def dialect_of(cls, model) -> "Dialect | None":
        for d in DIALECTS:
            if not cls._missing(model, d):
                return d
        return None

    @classmethod
    def unsupported(cls, model) -> str:
        """Why the cell cannot run ``model`` ("" when it can)."""
        if cls.dialect_of(model) is not None:
            return ""
        return "it lacks " + ", ".join(cls._missing(model, ARIAC)) + " (the ARIAC dialect)"

    # ------------------------------------------------------------------ runtime glue
    def implementations(self) -> dict:
        d = self.d
        impls = {d.move: _Impl(self.move, self.stop), d.gripper: self.gripper, d.grasp: _Impl(self.grasp, self.stop)}
        prims = self.model.all_primitives()
        for name in d.instant:
            prim = prims.get(name)
            if prim is not None:
                answer = next(o.name for o in prim.outcomes if o.status.name == "SUCCESS")
                impls[name] = (lambda call, a=answer: a)
        return impls

    def _answer(self, call, status: str) -> str:
        """The name of the site's declared outcome with ``status``."""
        for _, _, name in (o for o in call.site.outcomes if o[0] == _STATUS[status]):
            return name
        raise KeyError(f"{call.site.primitive} declares no {status} outcome")

    def events(self, queue_now: int) -> list:
        """Environment events for the next tick, from the belt sensor."""
        det = self.cell.detections
        while self._seen < len(det):
            self.backlog.append(det[self._seen][0])
            self._seen += 1
        if self.backlog and queue_now < self.queue_max:
            self.delivered.append(self.backlog.pop(0))
            return ["arrive"]
        return []

    def after_tick(self, queue_now: int) -> None:
        """The model consumed queue entries (a belt pick ended): forget those parts."""
        while len(self.delivered) > queue_now:
            pid = self.delivered.pop(0)
            if self.targets.get("conveyor") == pid:
                del self.targets["conveyor"]

    # ------------------------------------------------------------------ targets
    def _target(self, area: str, kind: str):
        """The target of a ``kind`` (pick/place) skill at ``area``; chosen anew when the
        old one is used up."""
        cell, tgt = self.cell, self.targets.get(area)
        if kind == "pick":
            if isinstance(tgt, int) and cell.place_of(tgt).kind in ("BELT" if area == "conveyor" else "BIN", "GRIPPER"):
                return tgt
            tgt = self._choose_part(area)
        else:
            if isinstance(tgt, Place) and self._free(tgt):
                return tgt
            tgt = self._choose_spot(area)
        if tgt is None:
            self.targets.pop(area, None)
        else:
            self.targets[area] = tgt
        return tgt

    def _choose_part(self, area: str):
        cell = self.cell
        if area == "conveyor":
            for pid in self.delivered:
                if cell.place_of(pid) == BELT:
                    return pid
            return None
        if area == "bins":
            for i in range(len(self.bins)):  # alternate bins 2 and 3 while both have parts
                k = self.bins[(self._bin_turn + i) % len(self.bins)]
                pid = cell.next_bin_part(k)
                if pid is not None:
                    self._bin_turn = (self._bin_turn + i + 1) % len(self.bins)
                    return pid
            return None
        return None  # the tray is never picked from in this experiment

    def _choose_spot(self, area: str):
        cell = self.cell
        if area == "agv":
            free = cell.free_slots()
            return Place.tray(free[0]) if free else None
        if area == "bins":
            for k in self.bins:
                spot = self._free_bin_spot(k)
                if spot is not None:
                    return ("bin", k, spot)
        return None

    def _free_bin_spot(self, k: int):
        cell = self.cell
        spec = next(s for s in cell.config.bins if s.index == k)
        taken = [cell.position(pid)[:2] for pid in cell.parts_in(Place.bin(k))]
        for x, y in cell.config.bin_grid(spec):
            if all(math.hypot(x - a, y - b) > 0.75 * cell.config.bin_pitch for a, b in taken):
                return (x, y)
        return None

    def _free(self, tgt) -> bool:
        if isinstance(tgt, Place):
            return tgt.index in self.cell.free_slots()
        return False

    # ------------------------------------------------------------------ poses
    def _place_pose(self, spot) -> tuple:
        cell = self.cell
        if isinstance(spot, Place):
            return cell.pose_at(spot)
        _, k, (x, y) = spot
        return (x, y, cell.pose_at(Place.bin(k))[2])

    def _above(self, pose) -> tuple:
        x, y, z = pose
        return (x, y, z + self.cell.config.clearance)

    def _hub(self, area: str) -> tuple:
        cell = self.cell
        if area == "agv":
            return cell.tray_approach()
        if area == "bins":
            return cell.bin_approach(self.bins[0])
        return cell.conveyor_approach()

    def _work_pose(self, area: str, goal: "str | None"):
        """Above the goal's target when the goal works at ``area``; else the area's hub.
        Returns ("move", pose), or ("track", part) for a belt part."""
        kind, goal_area = self.d.goal(goal)
        if goal_area == area:
            tgt = self._target(area, kind)
            if tgt is not None:
                if kind == "place" and not isinstance(tgt, int):
                    return ("move", self._above(self._place_pose(tgt)))
                if area == "conveyor":
                    return ("track", tgt)
                return ("move", self.cell.pose_above(tgt))
        return ("move", self._hub(area))

    # ------------------------------------------------------------------ primitives
    def move(self, call):
        arm = self.cell.arm
        running, success = self._answer(call, "RUNNING"), self._answer(call, "SUCCESS")
        if call.first:
            self._moving_to = self._move_target(self.d.area(call.args), self.d.role(call.site.state), call.goal)
            if self._moving_to is None:
                return success  # nothing to reach: the skill learns it at the grasp
            kind, where = self._moving_to
            if kind == "track":
                arm.track(where, self.cell.pose_above(where)[2])
            else:
                arm.move_to(*where, speed_scale=self.speed)
            return running
        if self._moving_to is None:
            return success
        kind, where = self._moving_to
        if kind == "track" and self.cell.place_of(where) != BELT and self.cell.gripper.attached_part != where:
            arm.stop()
            return success  # the part left the belt: stop chasing it
        return success if arm.arrived else running

    def _move_target(self, area: str, role: str, goal):
        x, y, z = self.cell.arm.pose
        if role == "lift":
            return ("move", (x, y, max(z, self._hub(area)[2])))
        if role == "put_back":
            pose = self.origin.get(area)
            return ("move", pose) if pose is not None else None
        if role == "put":
            tgt = self._target(area, "place")
            return ("move", self._place_pose(tgt)) if tgt is not None else None
        return self._work_pose(area, goal)  # hubs and the transits arriving at ``area``

    def stop(self, call):
        self.cell.arm.stop()
        self._moving_to = None

    def gripper(self, call):
        if call.args["on"]:
            self.cell.gripper.enable()
        else:
            self.cell.gripper.disable()
        return self._answer(call, "SUCCESS")

    def grasp(self, call):
        cell, area = self.cell, self.d.area(call.args)
        running, success, failure = (self._answer(call, s) for s in ("RUNNING", "SUCCESS", "FAILURE"))
        if cell.gripper.attached_part is not None:
            return success
        if call.first:
            tgt = self._target(area, "pick") if self.d.goal(call.goal)[1] == area else self.targets.get(area)
            if not isinstance(tgt, int) or cell.place_of(tgt).kind not in ("BIN", "BELT"):
                return failure
            self._grasping = tgt
            x, y, z = cell.pose_at(tgt)
            self.origin[area] = (x, y, z)
            if area == "conveyor":
                cell.arm.track(tgt, z)
            else:
                cell.arm.move_to(x, y, z, speed_scale=self.speed)
            return running
        tgt = self._grasping
        if tgt is None or cell.place_of(tgt).kind not in ("BIN", "BELT"):
            cell.arm.stop()
            return failure
        if cell.arm.arrived and not cell.arm.moving:
            return failure  # reached the part's top and the vacuum did not take it
        return running

    # ------------------------------------------------------------------ conformance
    def abstraction_errors(self, vars: dict, arm_state: str, goal=None) -> list:
        """Model variables that disagree with the cell (empty when they agree)."""
        cell, d, out = self.cell, self.d, []
        full = cell.gripper.attached_part is not None
        model_full = vars[d.gripper_var] if d.gripper_var_means_full else not vars[d.gripper_var]
        if model_full != full and not (d.gripper_var_after_skill and goal is not None):
            out.append(f"{d.gripper_var} is {vars[d.gripper_var]} but the gripper {'holds a part' if full else 'holds nothing'}")
        extra = cell.tray_count - vars[d.tray_var]
        if not (extra == 0 or (extra == 1 and arm_state in d.tray_end_states)):
            out.append(f"{d.tray_var} is {vars[d.tray_var]} but {cell.tray_count} parts are on the tray")
        if vars["queue"] != len(self.delivered):
            out.append(f"queue is {vars['queue']} but {len(self.delivered)} detected parts wait")
        return out


class _Impl:
    """An implementation object with a halt hook (the runtime calls ``halt`` on preemption)."""

    __slots__ = ("tick", "halt")

    def __init__(self, tick, halt):
        self.tick, self.halt = tick, halt
