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

from .cell import BELT, GRIPPER, Place

__all__ = ["CellBinding"]

_INSTANT = {"record_pose": "recorded", "detach": "detached", "query_queue": "polled"}


def _area_of(goal: "str | None") -> "str | None":
    return goal.split("_", 1)[1] if goal else None


def _kind_of(goal: "str | None") -> "str | None":
    return goal.split("_", 1)[0] if goal else None


class CellBinding:
    """Primitive implementations and sensor events for ``models.ariac`` in a ``Cell``."""

    def __init__(self, cell, model, bins=(2, 3), speed_scale: float = 0.5):
        self.cell, self.model, self.bins = cell, model, tuple(bins)
        self.speed = speed_scale  # the authors' move_to default velocity scaling is 0.5
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
        self.n_tray = model.var("tray").hi

    NEEDS_PRIMITIVES = ("move", "gripper", "grasp")
    NEEDS_VARIABLES = ("queue", "gripper_full", "tray")

    @classmethod
    def unsupported(cls, model) -> str:
        """Why the cell cannot run ``model`` ("" when it can)."""
        prims = model.all_primitives()
        names = {v.name for v in model.variables}
        missing = [f"primitive '{p}'" for p in cls.NEEDS_PRIMITIVES if p not in prims]
        missing += [f"variable '{v}'" for v in cls.NEEDS_VARIABLES if v not in names]
        if not any(f.name == "arm" for f in model.fsms):
            missing.append("FSM 'arm'")
        if "arrive" not in {ev.name for ev in model.environment}:
            missing.append("environment event 'arrive'")
        return ("it lacks " + ", ".join(missing)) if missing else ""

    # ------------------------------------------------------------------ runtime glue
    def implementations(self) -> dict:
        impls = {"move": _Impl(self.move, self.stop), "gripper": self.gripper, "grasp": _Impl(self.grasp, self.stop)}
        impls.update({name: (lambda call, a=answer: a) for name, answer in _INSTANT.items()})
        return impls

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
        Returns a pose, or ("track", part) for a belt part."""
        kind = _kind_of(goal)
        if _area_of(goal) == area:
            tgt = self._target(area, kind)
            if tgt is not None:
                if kind == "place" and not isinstance(tgt, int):
                    return self._above(self._place_pose(tgt))
                if area == "conveyor":
                    return ("track", tgt)
                return self.cell.pose_above(tgt)
        return self._hub(area)

    # ------------------------------------------------------------------ primitives
    def move(self, call):
        area, state = call.args["area"], call.site.state
        arm = self.cell.arm
        if call.first:
            self._moving_to = self._move_target(area, state, call.goal)
            if self._moving_to is None:
                return "arrived"  # nothing to reach: the skill learns it at the grasp
            kind, where = self._moving_to
            if kind == "track":
                arm.track(where, self.cell.pose_above(where)[2])
            else:
                arm.move_to(*where, speed_scale=self.speed)
            return "moving"
        if self._moving_to is None:
            return "arrived"
        kind, where = self._moving_to
        if kind == "track" and self.cell.place_of(where) != BELT and self.cell.gripper.attached_part != where:
            arm.stop()
            return "arrived"  # the part left the belt: stop chasing it
        return "arrived" if arm.arrived else "moving"

    def _move_target(self, area: str, state: str, goal):
        cell = self.cell
        x, y, z = cell.arm.pose
        if state.startswith(("raise_", "escape_")):
            return ("move", (x, y, max(z, self._hub(area)[2])))
        if state.startswith("put_back_"):
            pose = self.origin.get(area)
            return ("move", pose) if pose is not None else None
        if state.startswith("put_"):
            tgt = self._target(area, "place")
            return ("move", self._place_pose(tgt)) if tgt is not None else None
        pose = self._work_pose(area, goal)  # approach_X and the transits arriving at X
        if isinstance(pose, tuple) and pose and pose[0] == "track":
            return pose
        return ("move", pose)

    def stop(self, call):
        self.cell.arm.stop()
        self._moving_to = None

    def gripper(self, call):
        if call.args["on"]:
            self.cell.gripper.enable()
        else:
            self.cell.gripper.disable()
        return "switched"

    def grasp(self, call):
        cell, area = self.cell, call.args["area"]
        held = cell.gripper.attached_part
        if held is not None:
            return "attached"
        if call.first:
            tgt = self._target(area, "pick") if _area_of(call.goal) == area else self.targets.get(area)
            if not isinstance(tgt, int) or cell.place_of(tgt).kind not in ("BIN", "BELT"):
                return "missed"
            self._grasping = tgt
            x, y, z = cell.pose_at(tgt)
            self.origin[area] = (x, y, z)
            if area == "conveyor":
                cell.arm.track(tgt, z)
            else:
                cell.arm.move_to(x, y, z, speed_scale=self.speed)
            return "searching"
        tgt = self._grasping
        if tgt is None or cell.place_of(tgt).kind not in ("BIN", "BELT"):
            cell.arm.stop()
            return "missed"
        if cell.arm.arrived and not cell.arm.moving:
            return "missed"  # reached the part's top and the vacuum did not take it
        return "searching"

    # ------------------------------------------------------------------ conformance
    def abstraction_errors(self, vars: dict, arm_state: str) -> list:
        """Model variables that disagree with the cell (empty when they agree)."""
        cell, out = self.cell, []
        full = cell.gripper.attached_part is not None
        if vars["gripper_full"] != full:
            out.append(f"gripper_full is {vars['gripper_full']} but the gripper {'holds' if full else 'holds nothing'}")
        extra = cell.tray_count - vars["tray"]
        at_tray_end = arm_state in ("detach_place_agv", "escape_agv", "release_agv")
        if not (extra == 0 or (extra == 1 and at_tray_end)):
            out.append(f"tray is {vars['tray']} but {cell.tray_count} parts are on the tray")
        if vars["queue"] != len(self.delivered):
            out.append(f"queue is {vars['queue']} but {len(self.delivered)} detected parts wait")
        return out


class _Impl:
    """An implementation object with a halt hook (the runtime calls ``halt`` on preemption)."""

    __slots__ = ("tick", "halt")

    def __init__(self, tick, halt):
        self.tick, self.halt = tick, halt
