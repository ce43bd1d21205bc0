"""The paper's kitting binding: the ARIAC models' primitives in a scene world, and the
belt sensor's detections as ``arrive`` events.

The ARIAC cell is a scene file (``models/scenes/ariac.yaml``) whose ``binding`` names
:class:`KittingBinding` with its arguments (the robot, the bins, the tray, the belt and
its sensor, the arm's speed scale and the approach clearance). It is a Python binding,
not a ``bind`` table of library primitives, because the paper's primitives choose their
targets from the goal the arm is driven to: ``move(area, pose)`` goes above the target of
the goal being driven (a bin part, a free bin spot, a tray slot, a belt part that is
tracked), ``put``/``put_back`` descend to it, ``raise``/``escape`` lift straight up;
``gripper(on)`` switches the vacuum (a held part is released where it is);
``grasp(area)`` descends onto the target part until the vacuum attaches to it ("attached";
the cup is aimed at that part, ``World.aim``, and takes none it passes over), or
reports "missed" when there is nothing to grasp; ``record_pose``, ``detach``,
``query_queue`` are bookkeeping and instant.

Sensor events: each part the belt sensor sees becomes one ``arrive`` event (at most one
per tick, and only while the model's ``queue`` is below its bound; later ones wait their
turn). ``after_tick`` compares the model's variables with the world after each tick
(gripper contents, tray count, belt queue): the conformance check of what the
primitives physically did.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import cast

from btfsm.errors import ModelError
from btfsm.runtime import Constant

from .protocol import Binding
from .scene import Place, incident_text

__all__ = ["KittingBinding", "Dialect", "ARIAC", "ORIGINAL", "DIALECTS", "dialect_of", "unsupported",
           "check_outcomes"]

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


PHYSICS_WINDOW = 30.0  # s of world time a mismatch's report looks back for incidents


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


def dialect_of(model) -> "Dialect | None":
    """The dialect ``model`` is written in, or None."""
    for d in DIALECTS:
        if not _missing(model, d):
            return d
    return None


def unsupported(model) -> str:
    """Why the kitting binding cannot run ``model`` ("" when it can)."""
    if dialect_of(model) is not None:
        return ""
    return "it lacks " + ", ".join(_missing(model, ARIAC)) + " (the ARIAC dialect)"


def _reported(d: Dialect) -> dict:
    """{primitive: ((status, when the binding reports it), ...)}: what the cell answers."""
    out = {d.move: (("RUNNING", "while the arm moves"), ("SUCCESS", "when it arrives")),
           d.gripper: (("SUCCESS", "when the vacuum is switched"),),
           d.grasp: (("RUNNING", "while it descends"), ("SUCCESS", "when the part attaches"),
                     ("FAILURE", "when there is nothing to grasp"))}
    for name in d.instant:
        out[name] = (("SUCCESS", "at once (bookkeeping)"),)
    return out


def check_outcomes(model) -> None:
    """ModelError naming the primitive and the outcome when ``model`` (in a kitting
    dialect) declares a primitive without a status the kitting binding reports for it."""
    d = dialect_of(model)
    if d is None:
        return
    prims = model.all_primitives()
    for name, needs in _reported(d).items():
        prim = prims.get(name)
        if prim is None:
            continue
        has = {o.status.name for o in prim.outcomes}
        for status, when in needs:
            if status not in has:
                raise ModelError(f"primitives.{name}", f"declares no {status.lower()} outcome, but the kitting "
                                 f"binding reports {status.lower()} {when}: declare one, or run the model in "
                                 "a scene with a bind section (docs/cell.md)")


class KittingBinding(Binding):
    """The ARIAC models' primitives and belt events in a scene world (see the module text).

    Constructed by ``btfsm.sim.library.bind_model`` from the scene's ``binding`` section:
    ``KittingBinding(scene, model, world, robot=..., bins=[...], tray=..., belt=...,
    sensor=..., speed_scale=0.5, clearance=0.2)``."""

    def __init__(self, scene, model, world, *, robot: str = "arm", bins=("bin2", "bin3"), tray: str = "tray",
                 belt: str = "conveyor", sensor: str = "beam", speed_scale: float = 0.5, clearance: float = 0.2):
        self.scene, self.world, self.model = scene, world, model
        self.d = cast(Dialect, dialect_of(model))  # None is refused just below
        if self.d is None:
            raise ModelError("binding", f"the kitting binding cannot run model '{model.name}' ({unsupported(model)})",
                             scene.file)
        check_outcomes(model)
        for what, name, table in (("robot", robot, scene.robots), ("belt", belt, scene.belts),
                                  ("sensor", sensor, scene.sensors), ("area", tray, scene.areas),
                                  *(("area", b, scene.areas) for b in bins)):
            if name not in table:
                raise ModelError("binding.args", f"no {what} named '{name}' (known: {', '.join(sorted(table)) or 'none'})",
                                 scene.file)
        if scene.robots[robot]["z"] is None:
            raise ModelError(f"robots.{robot}", "the kitting binding needs a robot with a z axis", scene.file)
        if not scene.areas[tray]["slots"]:
            raise ModelError(f"areas.{tray}", "the kitting binding needs a tray with slots", scene.file)
        self.robot, self.bins, self.tray, self.belt, self.sensor = robot, tuple(bins), tray, belt, sensor
        self._tray_place = Place("AREA", tray)
        self.belt_area = "conveyor"  # the model's name for the belt's area
        self.speed = float(speed_scale)  # the authors' move_to default velocity scaling is 0.5
        self.clearance = float(clearance)
        self.r = world.robots[robot]
        self.targets: dict = {}  # area -> part id (pick) or spot (place)
        self.origin: dict = {}  # area -> (x, y, z) where the held part was grasped
        self.delivered: list = []  # belt part ids told to the model, in queue order
        self.backlog: list = []  # detected belt parts not told yet
        self.detections: list = []  # (part id, time) of every part the belt sensor saw, once each
        self._seen_ids: set = set()
        self._seen = 0  # world events consumed
        self._bin_turn = 0
        self._moving_to = None
        self._grasping = None
        qvar = model.var("queue")
        self.queue_max = qvar.hi
        self.n_tray = model.var(self.d.tray_var).hi
        prog = model.program
        self._q_slot = prog.scope["queue"].index
        # the three variables the abstraction check reads after every tick: (slot, variable)
        self._checked = tuple((prog.scope[v].index, model.var(v)) for v in (self.d.gripper_var, self.d.tray_var, "queue"))
        self._raw = all(v.kind in ("bool", "int") for _, v in self._checked)
        self._answers: dict = {}  # site index -> {status: the site's (first) outcome name with it}
        self._check_reach()

    def _check_reach(self) -> None:
        """ModelError unless the arm reaches every tray slot, bin spot, and the belt from
        its sensor to its end (where a part is lost)."""
        sc = self.scene
        points = list(sc.areas[self.tray]["slots"])
        for k in self.bins:
            points += [spot for spot in self._bin_grid(k)]
        points += list(self._window())
        for x, y in points:
            if not sc.reachable(self.robot, (x, y)):
                raise ModelError("binding", f"({x:.3f}, {y:.3f}) is out of the arm's reach: move the rail, "
                                            "the pick window or the layout", sc.file)

    # ------------------------------------------------------------------ runtime glue
    def implementations(self) -> dict:
        d = self.d
        impls = {d.move: _Impl(self.move, self.stop), d.gripper: self.gripper, d.grasp: _Impl(self.grasp, self.stop)}
        prims = self.model.all_primitives()
        for name in d.instant:
            prim = prims.get(name)
            if prim is not None:
                impls[name] = Constant(next(o.name for o in prim.outcomes if o.status.name == "SUCCESS"))
        return impls

    def _answer(self, call, status: str) -> str:
        """The name of the site's declared outcome with ``status`` (looked up once per site)."""
        names = self._answers.get(call.site.index)
        if names is None:
            names = self._answers[call.site.index] = {}
            for st, _, name in reversed(call.site.outcomes):  # the first outcome of each status
                names[st] = name
        name = names.get(_STATUS[status])
        if name is None:
            raise KeyError(f"{call.site.primitive} declares no {status} outcome")
        return name

    def _collect(self) -> None:
        ev = self.world.events
        while self._seen < len(ev):
            _t, sensor, _name, pid = ev[self._seen][:4]
            self._seen += 1
            if sensor == self.sensor and pid not in self._seen_ids:
                self._seen_ids.add(pid)
                self.detections.append((pid, _t))
                self.backlog.append(pid)

    def events(self, state) -> list:
        """Environment events for the next tick, from the belt sensor."""
        self._collect()
        if self.backlog and state[self._q_slot] < self.queue_max:
            self.delivered.append(self.backlog.pop(0))
            return ["arrive"]
        return []

    def after_tick(self, rt) -> list:
        """Forget the belt parts the model consumed (a belt pick ended); then the model's
        variables that disagree with the world (empty when they agree)."""
        queue_now = rt.state[self._q_slot]
        while len(self.delivered) > queue_now:
            pid = self.delivered.pop(0)
            if self.targets.get(self.belt) == pid:
                del self.targets[self.belt]
        # the usual case first: the three variables agree with the world outright (the full
        # check below, which reads every variable and the arm's state, says so too)
        state, d = rt.state, self.d
        (gs, gv), (ts, tv), (qs, qv) = self._checked
        if self._raw:  # bools and ints are stored as their values (0/1, n)
            g, tray, queue = state[gs], state[ts], state[qs]
        else:
            g, tray, queue = gv.decode(state[gs]), tv.decode(state[ts]), qv.decode(state[qs])
        if ((not g) is (self.r.holding is None if d.gripper_var_means_full else self.r.holding is not None)
                and tray == self.tray_count() and queue == len(self.delivered)):
            return []
        out = self.abstraction_errors(rt.vars, *rt.fsm_state(d.fsm))
        if out:
            out += self.physics_since(self.world.time - PHYSICS_WINDOW)
        return out

    def physics_since(self, t0: float) -> list:
        """What physics did uncommanded since world time ``t0`` (the world's incidents), as
        one line, or nothing."""
        seen = [incident_text(inc) for inc in self.world.incidents if inc[0] >= t0]
        if not seen:
            return []
        return [f"physics in the last {PHYSICS_WINDOW:g} s: " + "; ".join(seen)]

    # ------------------------------------------------------------------ world queries
    def place_of(self, pid: int) -> Place:
        return self.world.parts[pid].place

    def _area_of(self, model_area: str) -> str:
        """The scene name for one of the model's areas (bins, agv, conveyor)."""
        return {"agv": self.tray, "conveyor": self.belt}.get(model_area, model_area)

    def _pickable(self, pid: int) -> bool:
        """True while part ``pid`` lies in a bin or on the belt (where the arm picks)."""
        kind, name = self.place_of(pid)
        return kind == "BELT" or (kind == "AREA" and name in self.bins)

    def tray_count(self) -> int:
        return len(self.world.members.get(self._tray_place, ()))

    def free_slots(self) -> list:
        w = self.world
        taken = [(w.parts[i].x, w.parts[i].y) for i in w.parts_in(Place("AREA", self.tray))]
        return [k for k, (sx, sy) in enumerate(self.scene.areas[self.tray]["slots"])
                if all(math.hypot(sx - x, sy - y) > 1e-6 for x, y in taken)]

    def _held_height(self) -> float:
        pid = self.r.holding
        return 0.0 if pid is None else self.world.parts[pid].height

    def _centre(self, area: str) -> tuple:
        x0, y0, x1, y1 = self.scene.areas[area]["region"]
        return ((x0 + x1) / 2, (y0 + y1) / 2)

    def pose_at(self, target) -> tuple:
        """Contact pose: on top of a part (id), or a held part touching a tray slot
        (``("slot", k)``) or a bin (``("bin", area, (x, y))``)."""
        if isinstance(target, int):
            p = self.world.parts[target]
            return (p.x, p.y, self.world.top(target))
        if target[0] == "slot":
            x, y = self.scene.areas[self.tray]["slots"][target[1]]
            return (x, y, self.scene.areas[self.tray]["height"] + self._held_height())
        _, area, (x, y) = target
        return (x, y, self.scene.areas[area]["height"] + self._held_height())

    def _approach(self, area: str) -> tuple:
        x, y = self._centre(area)
        return (x, y, self.scene.areas[area]["height"] + 0.05 + self.clearance)

    def _window(self) -> tuple:
        """The belt's stretch where the arm picks: from the sensor (projected on the belt's
        centre line) to the belt's end, as two points."""
        b = self.scene.belts[self.belt]
        (ax, ay), (bx, by), L = b["from"], b["to"], b["length"]
        ux, uy = (bx - ax) / L, (by - ay) / L
        x0, y0, x1, y1 = self.scene.sensors[self.sensor]["region"]
        s_in = ((x0 + x1) / 2 - ax) * ux + ((y0 + y1) / 2 - ay) * uy
        return (ax + ux * s_in, ay + uy * s_in), (bx, by)

    def _conveyor_approach(self) -> tuple:
        """Above the belt, half-way along the pick stretch (clamped to the arm's reach)."""
        (px, py), (ex, ey) = self._window()
        x, y = self.scene.clamp_to_reach(self.robot, ((px + ex) / 2, (py + ey) / 2))
        return (x, y, self.scene.belts[self.belt]["height"] + 0.05 + self.clearance)

    def geometry(self) -> dict:
        """Where the primitives move the arm, for deriving their durations
        (``btfsm.sim.durations``): ``hub`` {model area: (x, y, z)}; ``spots`` {model area:
        [(x, y)]} the targets a pick or place can choose there (bin spots, tray slots; the
        belt's pick stretch as its two ends); ``contact`` {model area: [z]} the heights of
        the contact poses (a part's top, or a held part touching the surface, for every
        part type); ``clearance``, ``speed`` (the velocity scale; accelerations scale by
        its square), ``home`` (x, y, z); ``bin`` {bin: (spots, contact heights)}, each bin's
        share of the bins' spots and heights."""
        sc = self.scene
        heights = sorted({float(h) for h in sc.part_heights.values()})
        surface = {"agv": sc.areas[self.tray]["height"], "conveyor": sc.belts[self.belt]["height"]}
        bins = [spot for k in self.bins for spot in self._bin_grid(k)]
        surface["bins"] = None
        contact = {a: sorted({h + p for p in heights}) for a, h in surface.items() if h is not None}
        contact["bins"] = sorted({sc.areas[k]["height"] + p for k in self.bins for p in heights})
        spots = {"agv": list(sc.areas[self.tray]["slots"]), "bins": bins,
                 "conveyor": [sc.clamp_to_reach(self.robot, p) for p in self._window()]}
        r = sc.robots[self.robot]
        return {"hub": {a: self._hub(a) for a in ("agv", "bins", "conveyor")}, "spots": spots, "contact": contact,
                "clearance": self.clearance, "speed": self.speed,
                "home": (r["home"][0], r["home"][1], r["z"]["home"]),
                "bin": {k: (self._bin_grid(k), sorted({sc.areas[k]["height"] + p for p in heights})) for k in self.bins}}

    # ------------------------------------------------------------------ targets
    def _target(self, area: str, kind: str):
        """The target of a ``kind`` (pick/place) skill at model area ``area``; chosen
        anew when the old one is used up."""
        tgt = self.targets.get(area)
        if kind == "pick":
            if isinstance(tgt, int) and (self._pickable(tgt) or self.place_of(tgt).kind == "GRIPPER"):
                return tgt
            tgt = self._choose_part(area)
        else:
            if isinstance(tgt, tuple) and tgt[0] == "slot" and tgt[1] in self.free_slots():
                return tgt
            tgt = self._choose_spot(area)
        if tgt is None:
            self.targets.pop(area, None)
        else:
            self.targets[area] = tgt
        return tgt

    def _choose_part(self, area: str):
        w = self.world
        if area == "conveyor":
            for pid in self.delivered:
                if self.place_of(pid).kind == "BELT":
                    return pid
            return None
        if area == "bins":
            for i in range(len(self.bins)):  # alternate the bins while both have parts
                k = self.bins[(self._bin_turn + i) % len(self.bins)]
                ids = w.parts_in(Place("AREA", k))
                if ids:
                    self._bin_turn = (self._bin_turn + i + 1) % len(self.bins)
                    return ids[0]
            return None
        return None  # the tray is never picked from in this experiment

    def _choose_spot(self, area: str):
        if area == "agv":
            free = self.free_slots()
            return ("slot", free[0]) if free else None
        if area == "bins":
            for k in self.bins:
                spot = self._free_bin_spot(k)
                if spot is not None:
                    return ("bin", k, spot)
        return None

    def _bin_grid(self, k: str) -> list:
        """The 3 x 3 spots of bin ``k``, row by row from its +y side (where its parts start)."""
        x0, y0, x1, y1 = self.scene.areas[k]["region"]
        return [(x0 + (x1 - x0) / 3 * (c + 0.5), y1 - (y1 - y0) / 3 * (r + 0.5)) for r in range(3) for c in range(3)]

    def _free_bin_spot(self, k: str):
        w = self.world
        x0, _, x1, _ = self.scene.areas[k]["region"]
        pitch = (x1 - x0) / 3
        taken = [(w.parts[i].x, w.parts[i].y) for i in w.parts_in(Place("AREA", k))]
        for x, y in self._bin_grid(k):
            if all(math.hypot(x - a_, y - b_) > 0.75 * pitch for a_, b_ in taken):
                return (x, y)
        return None

    # ------------------------------------------------------------------ poses
    def _above(self, pose) -> tuple:
        x, y, z = pose
        return (x, y, z + self.clearance)

    def _hub(self, area: str) -> tuple:
        if area == "agv":
            return self._approach(self.tray)
        if area == "bins":
            return self._approach(self.bins[0])
        return self._conveyor_approach()

    def _work_pose(self, area: str, goal: "str | None"):
        """Above the goal's target when the goal works at ``area``; else the area's hub.
        Returns ("move", pose), or ("track", part) for a belt part."""
        kind, goal_area = self.d.goal(goal)
        if goal_area == area:
            tgt = self._target(area, kind)
            if tgt is not None:
                if kind == "place":
                    return ("move", self._above(self.pose_at(tgt)))
                if area == "conveyor":
                    return ("track", tgt)
                return ("move", self._above(self.pose_at(tgt)))
        return ("move", self._hub(area))

    def _move_to(self, pose) -> None:
        x, y, z = pose
        self.world.move_to(self.robot, (x, y), self.speed, z=z, acceleration=self.speed * self.speed)

    # ------------------------------------------------------------------ primitives
    def move(self, call):
        running, success = self._answer(call, "RUNNING"), self._answer(call, "SUCCESS")
        if call.first:
            self._moving_to = self._move_target(self.d.area(call.args), self.d.role(call.site.state), call.goal)
            if self._moving_to is None:
                return success  # nothing to reach: the skill learns it at the grasp
            kind, where = self._moving_to
            if kind == "track":
                self.world.track(self.robot, where, self._above(self.pose_at(where))[2])
            else:
                self._move_to(where)
            return running
        if self._moving_to is None:
            return success
        kind, where = self._moving_to
        if kind == "track" and self.place_of(where).kind != "BELT" and self.r.holding != where:
            self.world.stop(self.robot)
            return success  # the part left the belt: stop chasing it
        return success if self.r.arrived else running

    def _move_target(self, area: str, role: str, goal):
        r = self.r
        if role == "lift":
            return ("move", (r.x, r.y, max(r.z, self._hub(area)[2])))
        if role == "put_back":
            pose = self.origin.get(area)
            return ("move", pose) if pose is not None else None
        if role == "put":
            tgt = self._target(area, "place")
            return ("move", self.pose_at(tgt)) if tgt is not None else None
        return self._work_pose(area, goal)  # hubs and the transits arriving at ``area``

    def stop(self, call):
        self.world.stop(self.robot)
        self._moving_to = None

    def gripper(self, call):
        if call.args["on"]:
            self.world.grip(self.robot)
        else:
            self.world.release(self.robot)
        return self._answer(call, "SUCCESS")

    def grasp(self, call):
        area = self.d.area(call.args)
        running, success, failure = (self._answer(call, s) for s in ("RUNNING", "SUCCESS", "FAILURE"))
        if self.r.holding is not None:
            return success
        if call.first:
            tgt = self._target(area, "pick") if self.d.goal(call.goal)[1] == area else self.targets.get(area)
            if not isinstance(tgt, int) or not self._pickable(tgt):
                return failure
            self._grasping = tgt
            self.world.aim(self.robot, tgt)  # the cup takes this part only, not one it passes over
            x, y, z = self.pose_at(tgt)
            self.origin[area] = (x, y, z)
            if area == "conveyor":
                self.world.track(self.robot, tgt, z)
            else:
                self._move_to((x, y, z))
            return running
        tgt = self._grasping
        if tgt is None or not self._pickable(tgt):
            self.world.stop(self.robot)
            return failure
        if self.r.arrived and not self.r.moving:
            return failure  # reached the part's top and the vacuum did not take it
        return running

    # ------------------------------------------------------------------ conformance
    def abstraction_errors(self, vars: dict, arm_state: str, goal=None) -> list:
        """Model variables that disagree with the world (empty when they agree)."""
        d, out = self.d, []
        full = self.r.holding is not None
        model_full = vars[d.gripper_var] if d.gripper_var_means_full else not vars[d.gripper_var]
        if model_full != full and not (d.gripper_var_after_skill and goal is not None):
            out.append(f"{d.gripper_var} is {vars[d.gripper_var]} but the gripper {'holds a part' if full else 'holds nothing'}")
        tray = self.tray_count()
        extra = tray - vars[d.tray_var]
        if not (extra == 0 or (extra == 1 and arm_state in d.tray_end_states)):
            out.append(f"{d.tray_var} is {vars[d.tray_var]} but {tray} parts are on the tray")
        if vars["queue"] != len(self.delivered):
            out.append(f"queue is {vars['queue']} but {len(self.delivered)} detected parts wait")
        return out


class _Impl:
    """An implementation object with a halt hook (the runtime calls ``halt`` on preemption)."""

    __slots__ = ("tick", "halt")

    def __init__(self, tick, halt):
        self.tick, self.halt = tick, halt
