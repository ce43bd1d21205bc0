"""Scene files: a 2D cell described as data, and the physical world that runs it.

A scene file (YAML or JSON, schema ``btfsm/schema/scene.schema.json``, described in
docs/cell.md) names, in SI units (metres, seconds), seen from above:

* ``frames``: named points ``[x, y]``; anywhere a point is expected a frame name works;
* ``areas``: rectangles where parts rest (bins, tables, trays, machine fixtures), with
  initial ``parts`` (a count or ``{type: count}``), optional ``capacity`` and ``slots``;
* ``belts``: from a point to a point, ``speed`` (m/s), ``width``, an ``end`` (``lost``: a
  part reaching the end is lost; ``stop``: parts queue at the end) and ``arrivals`` (a
  ``schedule`` of times, a ``period`` with ``first``/``count``, or a seeded ``random``
  process with ``mean_interval``/``min_interval``);
* ``sinks``: regions where a part that is not held is **lost**;
* ``doors``: regions the tool may enter only while the door is open;
* ``sensors``: regions that raise an environment event when a part enters (``on_enter``)
  or leaves (``on_exit``; a part a gripper takes does not leave, it is taken) and count
  the parts inside (``sensor(NAME)`` in checks);
* ``faults``: regions where a held part drops (with a ``probability``, seeded);
* ``robots``: a kinematic tool point on a ``rail`` or around a fixed ``base`` within
  ``reach``, with ``speed``/``acceleration`` limits (rest-to-rest trapezoidal profiles
  along straight lines) and a ``gripper`` (``vacuum``: attaches at once; ``fingers``:
  ``close_time`` seconds, then attaches what is within ``radius``);
* ``bind`` and ``checks``: how a model's primitives map onto the primitive library
  (``btfsm.sim.library``) and which model variables must agree with the world.

The world is physical in the plane (pymunk, seen from above, no gravity): parts are
discs with a mass and a friction, held to their support (ground or a belt's moving body)
by friction joints, colliding with one another and with ``walls``; the tool is a
kinematic body on rest-to-rest profiles and the gripper holds a part with at most its
``max_force`` (a part dragged harder slips). Heights (z) stay kinematic: a part let go
lands on the surface under it. What physics does uncommanded is an incident
(``World.incidents``: slip, collision, fell_off, pushed_off, pushed_out_of_slot,
off_target, drop). Every part is always in exactly one place: ``AREA(name)``,
``BELT(name)``, ``GRIPPER(robot)``, ``FLOOR`` or ``LOST``; ``World.check_invariant``
verifies it. Time is ``steps * dt`` (no wall clock); randomness comes from one
``random.Random`` per world seeded from the seed, so the same seed and the same commands
give the same ``World.digest()``.

Why one module of more than 1,000 lines: ``World`` (most of it) is one physical world
whose stepping, arrivals, gripper, incidents and bookkeeping of places share its bodies,
joints and part records in the simulator's hot loop; the scene's validation (``Scene``,
about 250 lines) uses the same geometry helpers as the world (``_inside``, ``_seg_dist``,
``_nearest_on_segment``). Split apart, those helpers and the world's records would become
public interfaces that only this module's two halves use.

>>> w = World(scene_from_data({"robots": {"r": {"base": [0, 0], "reach": 1, "home": [0.5, 0]}},
...                            "areas": {"bin": {"region": [0.3, -0.2, 0.7, 0.2], "parts": 2}}}))
>>> w.count("bin"), [str(p.place) for p in w.parts]
(2, ['AREA(bin)', 'AREA(bin)'])
"""
from __future__ import annotations

import hashlib
import math
import random
from typing import NamedTuple

from btfsm.errors import ModelError

__all__ = ["Place", "FLOOR", "LOST", "INCIDENTS", "Scene", "World", "load_scene", "scene_from_data", "Profile",
           "DEFAULT_PART", "builtin_scene"]

DEFAULT_PART = "part"
DEFAULT_MASS = 0.5  # kg
DEFAULT_FRICTION = 0.5  # coefficient of friction of a part on its support
DEFAULT_GRIP_FORCE = 50.0  # N: the most a gripper exerts on a held part
G = 9.81
MAX_ARRIVALS = 100_000  # per belt and run
_EPS = 1e-9


class Place(NamedTuple):
    """Where a part is: kind AREA, BELT, GRIPPER (name: the area, belt or robot), FLOOR, LOST."""

    kind: str
    name: str = ""

    def __str__(self) -> str:
        return f"{self.kind}({self.name})" if self.name else self.kind


FLOOR = Place("FLOOR")
LOST = Place("LOST")


# --------------------------------------------------------------------------- loading
class Scene:
    """A validated scene: plain geometry, every point resolved to ``(x, y)``."""

    def __init__(self, data: dict, file: "str | None" = None):
        self.data, self.file = data, file
        self.name = data.get("name", "scene")
        self.model = data.get("model")
        self.dt = float(data.get("dt", 0.01))
        self.seed = int(data.get("seed", 0))
        self.time_limit = float(data.get("time_limit", 600.0))
        self.frames = {k: (float(v[0]), float(v[1])) for k, v in data.get("frames", {}).items()}
        self.part_types = {DEFAULT_PART: 0.03}
        self.part_types.update({k: float(v["radius"]) for k, v in data.get("part_types", {}).items()})
        self.part_heights = {DEFAULT_PART: 0.0}
        self.part_heights.update({k: float(v.get("height", 0.0)) for k, v in data.get("part_types", {}).items()})
        ptypes = data.get("part_types", {})
        self.part_mass = {DEFAULT_PART: DEFAULT_MASS}
        self.part_mass.update({k: float(v.get("mass", DEFAULT_MASS)) for k, v in ptypes.items()})
        self.part_friction = {DEFAULT_PART: DEFAULT_FRICTION}
        self.part_friction.update({k: float(v.get("friction", DEFAULT_FRICTION)) for k, v in ptypes.items()})
        self.part_colours = {DEFAULT_PART: None}
        self.part_colours.update({k: v.get("colour") for k, v in ptypes.items()})
        self.doors: dict
        self.faults: dict
        self.areas, self.belts, self.sinks, self.doors = {}, {}, {}, {}
        self.sensors, self.faults, self.robots = {}, {}, {}
        for name, a in data.get("areas", {}).items():
            where = f"areas.{name}"
            parts = a.get("parts", 0)
            parts = {DEFAULT_PART: parts} if isinstance(parts, int) else dict(parts)
            for t in parts:
                self._type(t, f"{where}.parts.{t}")
            slots = [self.point(p, f"{where}.slots[{i}]") for i, p in enumerate(a.get("slots", []))]
            region = self.region(a["region"], f"{where}.region")
            for i, s in enumerate(slots):
                if not _inside(region, s):
                    raise self.error(f"{where}.slots[{i}]", "the slot lies outside the area's region")
            capacity = a.get("capacity", len(slots) if slots else None)
            n = sum(parts.values())
            if capacity is not None and n > capacity:
                raise self.error(f"{where}.parts", f"{n} parts exceed the capacity {capacity}")
            self.areas[name] = {"region": region, "parts": parts, "capacity": capacity, "slots": slots,
                                "slot_tolerance": float(a.get("slot_tolerance", 0.03)),
                                "height": float(a.get("height", 0.0)), "friction": a.get("friction")}
        for name, b in data.get("belts", {}).items():
            where = f"belts.{name}"
            p0, p1 = self.point(b["from"], f"{where}.from"), self.point(b["to"], f"{where}.to")
            length = math.hypot(p1[0] - p0[0], p1[1] - p0[1])
            if length <= _EPS:
                raise self.error(where, "'from' and 'to' are the same point")
            ptypes = b.get("part_type", DEFAULT_PART)
            ptypes = [ptypes] if isinstance(ptypes, str) else list(ptypes)
            for i, pt in enumerate(ptypes):
                self._type(pt, f"{where}.part_type" + (f"[{i}]" if len(ptypes) > 1 else ""))
            ptype = ptypes[0]
            arr = b.get("arrivals", {})
            kinds = [k for k in ("schedule", "period", "random") if k in arr]
            if len(kinds) > 1:
                raise self.error(f"{where}.arrivals", f"give one of schedule, period or random, not {' and '.join(kinds)}")
            self.belts[name] = {"name": name, "from": p0, "to": p1, "length": length, "speed": float(b["speed"]),
                                "width": float(b.get("width", 0.3)), "end": b.get("end", "lost"),
                                "part_type": ptype, "part_types": ptypes, "arrivals": dict(arr), "height": float(b.get("height", 0.0)),
                                "friction": b.get("friction")}
            step = self.belts[name]["speed"] * self.dt
            smallest = min(self.part_types[pt] for pt in ptypes)
            if step > smallest / 2:
                raise self.error(f"{where}.speed", f"a part on the belt moves {step:g} m per step of dt = {self.dt:g} s, "
                                 f"more than half the smallest part radius ({smallest:g} m): parts would pass "
                                 "through one another (lower the speed or dt)")
        for name, r in data.get("sinks", {}).items():
            self.sinks[name] = self.region(r, f"sinks.{name}")
        for name, d in data.get("doors", {}).items():
            self.doors[name] = {"region": self.region(d["region"], f"doors.{name}.region"),
                                "open": bool(d.get("open", False)), "open_time": float(d.get("open_time", 1.0))}
        for name, s in data.get("sensors", {}).items():
            where = f"sensors.{name}"
            r = s["region"]
            if isinstance(r, str):
                if r not in self.areas:
                    raise self.error(f"{where}.region", f"no area named '{r}' (areas: {_names(self.areas)})")
                r = self.areas[r]["region"]
            else:
                r = self.region(r, f"{where}.region")
            ptype = s.get("part_type")
            if ptype is not None:
                self._type(ptype, f"{where}.part_type")
            self.sensors[name] = {"region": r, "on_enter": s.get("on_enter"), "on_exit": s.get("on_exit"),
                                  "part_type": ptype}
        for name, f in data.get("faults", {}).items():
            self.faults[name] = {"region": self.region(f["region"], f"faults.{name}.region"),
                                 "probability": float(f.get("probability", 1.0))}
        for name, r in data.get("robots", {}).items():
            where = f"robots.{name}"
            if ("base" in r) == ("rail" in r):
                raise self.error(where, "give exactly one of 'base' (a fixed arm) or 'rail' (a tool on a rail)")
            rail = ((self.point(r["base"], f"{where}.base"),) * 2 if "base" in r else
                    tuple(self.point(p, f"{where}.rail[{i}]") for i, p in enumerate(r["rail"])))
            g = r.get("gripper", {})
            robot = {"rail": rail, "reach": float(r["reach"]), "speed": float(r.get("speed", 1.0)),
                     "acceleration": float(r.get("acceleration", 2.0)),
                     "gripper": g.get("type", "vacuum"), "radius": float(g.get("radius", 0.04)),
                     "close_time": float(g.get("close_time", 0.5 if g.get("type") == "fingers" else 0.0)),
                     "grasp_tolerance": float(g.get("grasp_tolerance", 0.01)),
                     "max_force": float(g.get("max_force", DEFAULT_GRIP_FORCE)),
                     "track_tolerance": float(r.get("track_tolerance", 0.005)), "z": None}
            if "z" in r:
                z = r["z"]
                lo, hi = float(z.get("min", 0.0)), float(z.get("max", 10.0))
                if not lo <= float(z["home"]) <= hi:
                    raise self.error(f"{where}.z.home", f"{z['home']:g} is outside [{lo:g}, {hi:g}]")
                robot["z"] = {"home": float(z["home"]), "min": lo, "max": hi,
                              "speed": float(z.get("speed", robot["speed"])),
                              "acceleration": float(z.get("acceleration", robot["acceleration"]))}
            self.robots[name] = robot
            home = self.point(r["home"], f"{where}.home")
            if not self.reachable(name, home):
                raise self.error(f"{where}.home", f"({home[0]:g}, {home[1]:g}) is out of the robot's reach")
            robot["home"] = home
        self.walls = {}
        supports = {"FLOOR", *self.areas, *self.belts}
        for name, w in data.get("walls", {}).items():
            where = f"walls.{name}"
            pts = [self.point(q, f"{where}.points[{i}]") for i, q in enumerate(w["points"])]
            on = w.get("on")
            if on is not None and on not in supports:
                raise self.error(f"{where}.on", f"no area or belt named '{on}' (known: {_names(supports)})")
            self.walls[name] = {"points": pts, "closed": bool(w.get("closed", False)),
                                "thickness": float(w.get("thickness", 0.01)), "on": on}
        self.bind = data.get("bind", {})
        self.binding = data.get("binding")  # {python: "module:Class", args: {...}} or None
        if self.binding is not None and self.bind:
            raise self.error("binding", "give either 'bind' (the primitive library) or 'binding' (a Python class), not both")
        self.checks = list(data.get("checks", []))
        for i, c in enumerate(self.checks):
            self.world_query(c["world"], f"checks[{i}].world")

    # ---- helpers used while loading and by the primitive library
    def error(self, element: str, problem: str) -> ModelError:
        return ModelError(element, problem, self.file)

    def _type(self, name: str, where: str) -> str:
        if name not in self.part_types:
            raise self.error(where, f"unknown part type '{name}' (part types: {_names(self.part_types)})")
        return name

    def point(self, p, where: str) -> tuple:
        if isinstance(p, str):
            if p not in self.frames:
                raise self.error(where, f"unknown frame '{p}' (frames: {_names(self.frames)})")
            return self.frames[p]
        return (float(p[0]), float(p[1]))

    def region(self, r, where: str) -> tuple:
        if isinstance(r, dict):
            (x, y), (w, h) = self.point(r["at"], f"{where}.at"), r["size"]
            r = (x - w / 2, y - h / 2, x + w / 2, y + h / 2)
        x0, y0, x1, y1 = (float(v) for v in r)
        if not (x0 < x1 and y0 < y1):
            raise self.error(where, "a region needs x_min < x_max and y_min < y_max")
        return (x0, y0, x1, y1)

    def reachable(self, robot: str, p) -> bool:
        r = self.robots[robot]
        return _seg_dist(p, *r["rail"]) <= r["reach"] + _EPS

    def carriage(self, robot: str, p) -> tuple:
        """Where on its rail (or at its base) the robot stands to reach ``p``: the nearest point."""
        return _nearest_on_segment(p, *self.robots[robot]["rail"])

    def clamp_to_reach(self, robot: str, p) -> tuple:
        """The reachable point nearest to ``p`` (``p`` itself when it is reachable)."""
        r = self.robots[robot]
        cx, cy = self.carriage(robot, p)
        ex, ey = p[0] - cx, p[1] - cy
        d = math.hypot(ex, ey)
        if d <= r["reach"]:
            return (float(p[0]), float(p[1]))
        return (cx + ex * r["reach"] / d, cy + ey * r["reach"] / d)

    def world_query(self, text: str, where: str) -> tuple:
        """``holding(ROBOT)``, ``count(AREA)``, ``sensor(NAME)`` or ``door(NAME)`` as (kind,
        name); ``count(AREA, TYPE)`` and ``sensor(NAME, TYPE)`` count only parts of a type:
        (kind, (name, type))."""
        kind, _, rest = str(text).partition("(")
        name = rest[:-1] if rest.endswith(")") else None
        kind = kind.strip()
        tables = {"holding": ("robot", self.robots), "count": ("area", self.areas),
                  "sensor": ("sensor", self.sensors), "door": ("door", self.doors)}
        what, table = tables.get(kind, (None, None))
        if table is None or name is None:
            raise self.error(where, "expected holding(ROBOT), count(AREA[, TYPE]), sensor(NAME[, TYPE]) or door(NAME), "
                                    f"got '{text}'")
        name, _, ptype = (s.strip() for s in name.partition(","))
        if name not in table:
            raise self.error(where, f"no {what} named '{name}' (known: {_names(table)})")
        if not ptype:
            return kind, name
        if kind not in ("count", "sensor"):
            raise self.error(where, f"only count(AREA, TYPE) and sensor(NAME, TYPE) take a part type, got '{text}'")
        return kind, (name, self._type(ptype, where))


def _names(d) -> str:
    return ", ".join(sorted(d)) or "none"


def scene_from_data(data, file: "str | None" = None, *, check: "tuple | None" = None) -> Scene:
    """A Scene from plain data; ModelError ``file: element: problem`` when it is wrong.
    ``check``: the top-level sections to check against the schema (and ``robots``, which
    it requires) when the caller wrote only those into data checked before; None: all."""
    from btfsm.formats import FormatError, describe, validate

    if not isinstance(data, dict):
        kind = f"a list of {len(data)} item(s)" if isinstance(data, list) else describe(data)
        raise ModelError("", f"expected a mapping with the scene, got {kind}", file)
    try:
        validate(data if check is None else {k: data[k] for k in ("robots", *check) if k in data}, "scene",
                 file or "<scene>")
    except FormatError as exc:
        where = exc.where
        raise ModelError(where, exc.problem, file) from None
    return Scene(data, file)


def load_scene(path) -> Scene:
    """Read and validate a scene file (.yaml, .yml or .json)."""
    from btfsm.files import load_data

    name = str(path)
    try:
        data = load_data(path, file_name=name)
    except ModelError as exc:
        if exc.problem.startswith("the file is empty"):
            raise ModelError("", "the file is empty (expected a mapping with the scene)", name) from None
        raise ModelError(exc.element, exc.problem.replace("model file", "scene file"), exc.file) from None
    return scene_from_data(data, name)


def builtin_scene(name: str) -> "str | None":
    """The path of a scene shipped with btfsm (``models/scenes/NAME.yaml``), or None."""
    from importlib import resources

    try:
        p = resources.files("btfsm.models").joinpath("scenes", f"{name}.yaml")
    except ModuleNotFoundError:  # pragma: no cover
        return None
    return str(p) if p.is_file() else None


# --------------------------------------------------------------------------- geometry
def _inside(r, p) -> bool:
    return r[0] <= p[0] <= r[2] and r[1] <= p[1] <= r[3]


def _nearest_on_segment(p, a, b) -> tuple:
    """The point of the segment a-b nearest to p."""
    ax, ay = a
    dx, dy = b[0] - ax, b[1] - ay
    L2 = dx * dx + dy * dy
    t = 0.0 if L2 == 0.0 else max(0.0, min(1.0, ((p[0] - ax) * dx + (p[1] - ay) * dy) / L2))
    return (ax + t * dx, ay + t * dy)


def _seg_dist(p, a, b) -> float:
    cx, cy = _nearest_on_segment(p, a, b)
    return math.hypot(p[0] - cx, p[1] - cy)


class Profile:
    """Rest-to-rest trapezoidal (or triangular) profile over ``dist`` with limits v, a.

    >>> p = Profile(1.0, 0.5, 1.0); round(p.total, 3), p.at(0.0), p.at(p.total)
    (2.5, 0.0, 1.0)
    """

    __slots__ = ("dist", "a", "t_acc", "total", "v")

    def __init__(self, dist: float, v: float, a: float):
        self.dist, self.a = dist, a
        if dist <= 0.0:
            self.t_acc = self.total = self.v = 0.0
        elif v * v / a >= dist:
            self.t_acc = math.sqrt(dist / a)
            self.total, self.v = 2.0 * self.t_acc, a * self.t_acc
        else:
            self.t_acc = v / a
            self.total, self.v = dist / v + self.t_acc, v

    def at(self, t: float) -> float:
        if t >= self.total:
            return self.dist
        if t <= self.t_acc:
            return 0.5 * self.a * t * t
        if t <= self.total - self.t_acc:
            return 0.5 * self.a * self.t_acc * self.t_acc + self.v * (t - self.t_acc)
        r = self.total - t
        return self.dist - 0.5 * self.a * r * r


def _horizon(m: int, margins, e: float) -> int:
    """The largest ``j <= m`` (0 if below 2) such that no margin ``a + i * b`` (satisfied
    when >= 0) changes sign for i <= j when each may be off by ``i * e``."""
    for a, b in margins:
        if a >= 0.0:
            if b - e < 0.0:  # satisfied now; it holds while a + i (b - e) >= 0
                m = min(m, int(a / (e - b)) - 1)
        elif b + e > 0.0:  # violated now; it stays so while a + i (b + e) < 0
            m = min(m, int(-a / (b + e)) - 1)
        if m < 2:
            return 0
    return m


# --------------------------------------------------------------------------- world
_PART, _WALL = 1, 2  # collision types of parts and walls
INCIDENTS = ("slip", "drop", "collision", "fell_off", "pushed_off", "pushed_out_of_slot", "off_target")


def incident_text(incident: tuple) -> str:
    """One of ``World.incidents``, ``(time, kind, part id, cause)``, as the reports print it.

    >>> incident_text((8.54, "slip", 0, "slipped from arm's gripper"))
    "t=8.54 s slip of part 0: slipped from arm's gripper"
    """
    t, kind, pid, cause = incident
    return f"t={t:.2f} s {kind} of part {pid}: {cause}"
class _Part:
    __slots__ = ("id", "type", "radius", "height", "x", "y", "place", "s", "body", "shape", "joints", "mass",
                 "friction", "slot", "pushed_by", "cb")

    def __init__(self, pid, ptype, radius, x, y, height=0.0):
        self.id, self.type, self.radius, self.height, self.x, self.y = pid, ptype, radius, height, x, y
        self.place = None
        self.s = 0.0  # distance along the belt while on one
        self.body = self.shape = None  # the pymunk body and its disc (x, y mirror the body's position)
        self.cb = None  # the body's Chipmunk pointer (positions are read through it: 4x cheaper)
        self.joints = ()  # friction joints to the support, or the grip joints to the tool
        self.mass = self.friction = 0.0
        self.slot = None  # (x, y) of the slot it rests on
        self.pushed_by = None  # the last part that touched it


class _Robot:
    __slots__ = ("name", "spec", "x", "y", "z", "x0", "y0", "z0", "x1", "y1", "z1", "prof", "k", "moving",
                 "blocked", "holding", "closing", "armed", "faults_in", "tracking", "vel", "arrived", "body", "peak",
                 "last_v", "anchor", "coasting", "cruise_v", "aim")

    def __init__(self, name, spec):
        self.name, self.spec = name, spec
        self.x, self.y = spec["home"]
        self.z = spec["z"]["home"] if spec["z"] is not None else 0.0
        self.x0 = self.y0 = self.z0 = self.x1 = self.y1 = self.z1 = 0.0
        self.prof, self.k, self.moving, self.blocked = None, 0, False, False
        self.holding = None  # part id
        self.closing = None  # steps left while fingers close, or None
        self.armed = True  # False after a fault drop until the gripper is released
        self.faults_in: set = set()
        self.tracking = None  # id of the part the tool follows, or None
        self.vel = (0.0, 0.0)  # the tool's velocity while tracking
        self.arrived = False  # the last move ended at its target / the tracked part is under the tool
        self.body = None  # the kinematic pymunk body of the tool
        self.peak = 0.0  # the tool's largest acceleration (m/s^2) while it holds the part
        self.last_v = (0.0, 0.0)  # the tool's velocity in the last step
        self.anchor = (0.0, 0.0)  # where the held part's centre was, relative to the tool, when gripped
        self.coasting = False  # holding, in a move's constant-velocity phase: Chipmunk moves the tool body
        self.cruise_v = (0.0, 0.0)  # the tool's velocity in the constant-velocity phase of its move
        self.aim = None  # the one part the gripper may take (``World.aim``), or None: any part


class World:
    """The running scene: parts, belts, doors, robots; ``step()`` advances ``dt``."""

    def __init__(self, scene: Scene, seed: "int | None" = None):
        self.scene = scene
        self.dt = scene.dt
        self.seed = scene.seed if seed is None else int(seed)
        self.rng = random.Random(self.seed)
        self.steps = 0
        self.parts: list = []
        self.members: dict = {}  # Place -> [part ids], insertion-ordered
        self.log: list = []  # (time, part id, from, to)
        self.events: list = []  # (time, sensor, event name, part id, part type) raised, in order
        self.doors = {n: (1.0 if d["open"] else 0.0) for n, d in scene.doors.items()}  # openness 0..1
        self.door_goal = {n: (1.0 if d["open"] else 0.0) for n, d in scene.doors.items()}
        self.robots = {n: _Robot(n, spec) for n, spec in scene.robots.items()}
        self.inside: dict = {n: set() for n in scene.sensors}
        self.incidents: list = []  # (time, kind, part id, cause): what physics did that nobody commanded
        self._sensed_log = -1
        self.arrivals = {n: self._arrival_times(b) for n, b in scene.belts.items()}
        self.pending = {n: 0 for n in scene.belts}  # arrivals due but waiting for space
        self._spawned = {n: 0 for n in scene.belts}  # parts put on each belt so far
        self._build_space()
        self._next_arrival = -math.inf
        for name, a in scene.areas.items():
            self._fill(name, a)
        self._sense()
        self.events.clear()  # parts that start inside a sensor raise nothing

    # ---- physics: one pymunk space, seen from above (no gravity; z is kinematic)
    def _build_space(self) -> None:
        import pymunk

        self._pm = pymunk
        from pymunk._chipmunk import lib

        self._cp_step = lib.cpSpaceStep  # our collision callback never changes the space (see ``step``)
        self._cp_pos, self._cp_set_pos, self._cp_set_vel = lib.cpBodyGetPosition, lib.cpBodySetPosition, lib.cpBodySetVelocity
        self._cp_activate, self._cp_vel, self._cp_sleeping = lib.cpBodyActivate, lib.cpBodyGetVelocity, lib.cpBodyIsSleeping
        self._contact = False  # a contact callback ran (ends a batch of steps, see ``_coast``)
        self._wait = 1  # steps to take one at a time before ``_quiet`` looks again
        self._carriers: list = []  # robots whose tool and part a batch of steps drives every step
        self._calm_until = -1  # until this step no belt part can cross a sensor's or sink's edge (``_belt_horizon``)
        self._version = 0  # counts the commands and changes of place (``_quiet`` keeps a horizon while it stands)
        self._quiet_end, self._quiet_version = -1, -1  # the steps up to which the last horizon holds, and when found
        self._lookahead = max(2, int(round(1.0 / self.dt)))  # steps ``_quiet`` looks ahead (one second)
        self._top: "float | None" = None  # the highest top of a part that a cup could take (``_above_parts``)
        self._top_version = -1
        sc = self.scene
        space = self.space = pymunk.Space()
        space.iterations = 10
        space.collision_slop = 5e-4  # metres (pymunk's default assumes pixels)
        space.sleep_time_threshold = 0.5  # resting parts sleep: they cost nothing until touched
        space.idle_speed_threshold = 0.005
        self._static = space.static_body
        # collision layers: parts touch only parts (and walls) on the same support
        names = [FLOOR] + [Place("AREA", a) for a in sc.areas] + [Place("BELT", b) for b in sc.belts]
        self._layer = {pl: 1 << (i % 31) for i, pl in enumerate(names)}
        self._belt_body, self._belt_vel = {}, {}
        self._belt_places = [Place("BELT", b) for b in sc.belts]
        self._sensor_regions = [s["region"] for s in sc.sensors.values()]
        self._watched_regions = self._sensor_regions + list(sc.sinks.values())  # a belt part crossing an edge matters
        self._belt_rows = [(Place("BELT", n), *b["from"], (b["to"][0] - b["from"][0]) / b["length"],
                            (b["to"][1] - b["from"][1]) / b["length"], b["length"], b["width"] / 2, b["end"] == "lost")
                           for n, b in sc.belts.items()]
        for name, b in sc.belts.items():
            body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            (ax, ay), (bx, by), L = b["from"], b["to"], b["length"]
            body.velocity = self._belt_vel[name] = ((bx - ax) / L * b["speed"], (by - ay) / L * b["speed"])
            space.add(body)
            self._belt_body[name] = body
            if b["end"] == "stop":  # the end stop: a wall across the belt's end
                ux, uy = (bx - ax) / L, (by - ay) / L
                h = b["width"] / 2
                self._wall([(bx - uy * h, by + ux * h), (bx + uy * h, by - ux * h)], 0.0, self._layer[Place("BELT", name)])
        for w in sc.walls.values():
            pts = w["points"] + ([w["points"][0]] if w["closed"] else [])
            on = w["on"]
            mask = (0xFFFFFFFF if on is None else self._layer[FLOOR if on == "FLOOR" else
                                                               Place("AREA", on) if on in sc.areas else Place("BELT", on)])
            self._wall(pts, w["thickness"] / 2, mask)
        for r in self.robots.values():
            r.body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
            r.body.position = (r.x, r.y)
            space.add(r.body)
        self._added = True  # bodies added or shapes removed since the last step (see ``step``)
        self._disturbed: dict = {}  # part id -> None: resting parts that something touched (insertion-ordered)
        space.on_collision(_PART, _PART, begin=self._touch, pre_solve=self._pressed)
        space.on_collision(_PART, _WALL, pre_solve=self._pressed)

    def _wall(self, pts, radius, mask) -> None:
        pm = self._pm
        for a, b in zip(pts, pts[1:]):
            seg = pm.Segment(self._static, a, b, radius)
            seg.filter = pm.ShapeFilter(categories=mask, mask=mask)
            seg.friction, seg.collision_type = DEFAULT_FRICTION, _WALL
            self.space.add(seg)

    def _pressed(self, arbiter, space, data) -> None:
        """A part in contact (with a part or a wall) may move: watch it until it rests
        (every step of the contact: a sleeping group of touching parts wakes as a whole)."""
        self._contact, self._calm_until, self._quiet_end = True, -1, -1
        for s in arbiter.shapes:
            p = getattr(s.body, "part", None)
            if p is not None and p.place.kind != "BELT":
                self._disturbed[p.id] = None

    def _touch(self, arbiter, space, data) -> None:
        """Two parts touched: both may now move (they are watched until they rest)."""
        self._contact, self._calm_until, self._quiet_end = True, -1, -1
        a, b = (s.body.part for s in arbiter.shapes)
        for p, q in ((a, b), (b, a)):
            p.pushed_by = q.id
            if p.place.kind != "BELT":
                self._disturbed[p.id] = None
        if a.place.kind == "BELT" or b.place.kind == "BELT":
            self.incidents.append((round(self.time, 9), "collision", min(a.id, b.id),
                                   f"parts {min(a.id, b.id)} and {max(a.id, b.id)} collide on {a.place}"))

    def _support(self, part: _Part, place: Place) -> None:
        """Put the part's body on the physics of ``place``: friction joints to its support
        (the belt's moving body, or the ground), grip joints to a tool, out of the space when LOST."""
        pm, body = self._pm, part.body
        if part.joints:
            self.space.remove(*part.joints)
            part.joints = ()
        kind, name = place
        if kind == "LOST":
            self.space.remove(part.shape, body)
            self._added = True
            self._disturbed.pop(part.id, None)
            return
        if kind == "GRIPPER":
            r = self.robots[name]
            tool = r.body
            tool.position = (r.x, r.y)
            r.anchor = (body.position.x - r.x, body.position.y - r.y)
            pj = pm.PivotJoint(tool, body, r.anchor, (0, 0))
            gj = pm.GearJoint(tool, body, body.angle, 1.0)
            pj.max_force = r.spec["max_force"]
            gj.max_force = 0.05 * r.spec["max_force"]
            part.shape.filter = pm.ShapeFilter(categories=0, mask=0)  # a lifted part touches nothing
            self.space.add(pj, gj)
            part.joints = (pj, gj)
            r.peak, r.last_v = 0.0, None  # the tool's acceleration counts from its second step with the part
            r.coasting = False
            self._disturbed.pop(part.id, None)
            return
        if kind == "BELT":
            support, mu = self._belt_body[name], self.scene.belts[name]["friction"]
        else:
            support, mu = self._static, self.scene.areas[name]["friction"] if kind == "AREA" else None
        mu = part.friction if mu is None else float(mu)
        layer = self._layer[place]
        part.shape.filter = pm.ShapeFilter(categories=layer, mask=layer)
        body.velocity = support.velocity
        body.angular_velocity = 0.0
        f = mu * part.mass * G
        pj = pm.PivotJoint(support, body, support.world_to_local(body.position), (0, 0))
        gj = pm.GearJoint(support, body, body.angle - support.angle, 1.0)
        pj.max_bias = gj.max_bias = 0.0
        pj.max_force, gj.max_force = f, f * part.radius
        self.space.add(pj, gj)
        part.joints = (pj, gj)
        if kind != "BELT":  # watched until it rests: it may have landed on a wall or another part
            self._disturbed[part.id] = None

    @property
    def time(self) -> float:
        return self.steps * self.dt

    # ---- construction
    def _arrival_times(self, belt) -> list:
        arr = belt["arrivals"]
        if "schedule" in arr:
            return sorted(float(t) for t in arr["schedule"])
        limit = self.scene.time_limit
        count = arr.get("count")
        if count is not None and count > MAX_ARRIVALS:
            raise self.scene.error(f"belts.{belt['name']}.arrivals.count", f"at most {MAX_ARRIVALS:,} arrivals per belt")
        if "period" in arr:
            p, t0 = float(arr["period"]), float(arr.get("first", 0.0))
            n = count if count is not None else int(limit / p) + 1
            if n > MAX_ARRIVALS:
                raise self.scene.error(f"belts.{belt['name']}.arrivals.period", f"{n:,} arrivals within time_limit "
                                       f"{limit:g} s; at most {MAX_ARRIVALS:,} per belt (give a count or a longer period)")
            return [t0 + i * p for i in range(n)]
        if "random" in arr:
            r = arr["random"]
            mean, lo = float(r["mean_interval"]), float(r.get("min_interval", 0.0))
            out: list
            t, out = float(arr.get("first", 0.0)), []
            while (count is None and t <= limit) or (count is not None and len(out) < count):
                if len(out) >= MAX_ARRIVALS:
                    raise self.scene.error(f"belts.{belt['name']}.arrivals.random", f"more than {MAX_ARRIVALS:,} "
                                           f"arrivals within time_limit {limit:g} s (give a count or a longer mean_interval)")
                out.append(round(t, 6))
                t += lo + self.rng.expovariate(1.0 / max(mean - lo, _EPS))
            return out
        return []

    def _new_part(self, ptype, x, y, place) -> _Part:
        sc, pm = self.scene, self._pm
        part = _Part(len(self.parts), ptype, sc.part_types[ptype], x, y, sc.part_heights[ptype])
        part.mass, part.friction = sc.part_mass[ptype], sc.part_friction[ptype]
        body = pm.Body(part.mass, pm.moment_for_circle(part.mass, 0.0, part.radius))
        body.position = (x, y)
        body.part = part
        shape = pm.Circle(body, part.radius)
        shape.friction, shape.collision_type = part.friction, _PART
        self.space.add(body, shape)
        self._added = True
        part.body, part.shape, part.cb = body, shape, body._body
        self.parts.append(part)
        if place.kind == "AREA" and sc.areas[place.name]["slots"]:
            part.slot = (x, y)
        self._move(part, place)
        return part

    def _fill(self, name, a) -> None:
        x0, y0, x1, y1 = a["region"]
        kinds = [t for t, n in a["parts"].items() for _ in range(n)]
        if not kinds:
            return
        spots = list(a["slots"])
        if not spots:
            cols = max(1, math.ceil(math.sqrt(len(kinds) * (x1 - x0) / (y1 - y0))))
            rows = math.ceil(len(kinds) / cols)
            spots = [(x0 + (x1 - x0) * (c + 0.5) / cols, y1 - (y1 - y0) * (r + 0.5) / rows)
                     for r in range(rows) for c in range(cols)]
        for t, (x, y) in zip(kinds, spots):
            self._new_part(t, x, y, Place("AREA", name))

    # ---- place bookkeeping
    def _move(self, part: _Part, place: Place) -> None:
        old = part.place
        self._calm_until = -1
        self._version += 1
        if old is not None:
            self.members[old].remove(part.id)
            if old.kind == "BELT":  # the parts queued behind it may move on
                for pid in self.members[old]:
                    self.parts[pid].body.activate()
        self.members.setdefault(place, []).append(part.id)
        part.place = place
        if place.kind != "AREA" or not self.scene.areas[place.name]["slots"]:
            part.slot = None
        self.log.append((round(self.time, 9), part.id, old, place))
        self._support(part, place)

    def parts_in(self, place: Place) -> list:
        return list(self.members.get(place, ()))

    @staticmethod
    def area_place(area: str) -> Place:
        return Place("AREA", area)

    def count(self, area: str) -> int:
        return len(self.members.get(Place("AREA", area), ()))

    @property
    def lost(self) -> int:
        return len(self.members.get(LOST, ()))

    def landing(self, x: float, y: float) -> tuple:
        """(place, x, y, belt s) where a part let go at (x, y) comes to rest."""
        sc = self.scene
        for r in sc.sinks.values():
            if _inside(r, (x, y)):
                return LOST, x, y, 0.0
        for name, a in sc.areas.items():
            if not _inside(a["region"], (x, y)):
                continue
            if a["slots"]:
                best, bd = None, a["slot_tolerance"]
                taken = [(self.parts[i].x, self.parts[i].y) for i in self.members.get(Place("AREA", name), ())]
                for sx, sy in a["slots"]:
                    d = math.hypot(x - sx, y - sy)
                    if d <= bd and all(math.hypot(sx - tx, sy - ty) > _EPS for tx, ty in taken):
                        best, bd = (sx, sy), d
                if best is None:
                    return FLOOR, x, y, 0.0
                return Place("AREA", name), best[0], best[1], 0.0
            if a["capacity"] is not None and self.count(name) >= a["capacity"]:
                return FLOOR, x, y, 0.0
            return Place("AREA", name), x, y, 0.0
        for name, b in sc.belts.items():
            s, d = self._belt_coord(b, x, y)
            if d <= b["width"] / 2 and 0.0 <= s < b["length"]:
                return Place("BELT", name), x, y, s
        return FLOOR, x, y, 0.0

    @staticmethod
    def _belt_coord(b, x, y) -> tuple:
        (ax, ay), (bx, by), L = b["from"], b["to"], b["length"]
        ux, uy = (bx - ax) / L, (by - ay) / L
        s = (x - ax) * ux + (y - ay) * uy
        return s, abs(-(x - ax) * uy + (y - ay) * ux)

    def _let_go(self, part: _Part, cause: str = "released") -> None:
        """The part lands where it is (z is kinematic: on the surface under it), on the
        nearest free slot of a slotted area; a part let go where no area takes it (the
        floor, a full area, a slotted area away from a free slot) is an ``off_target``
        incident."""
        px, py = part.body.position
        place, x, y, s = self.landing(px, py)
        part.x, part.y, part.s = x, y, s
        part.body.position = (x, y)
        self._move(part, place)
        if place.kind == "AREA" and self.scene.areas[place.name]["slots"]:
            part.slot = (x, y)
        if place == FLOOR and cause == "released":
            where = next((f" in area {n} (no free slot within {a['slot_tolerance']:g} m, or full)"
                          for n, a in self.scene.areas.items() if _inside(a["region"], (px, py))), "")
            self.incidents.append((round(self.time, 9), "off_target", part.id,
                                   f"let go at ({px:.3f}, {py:.3f}){where}: it lies on the FLOOR"))

    def spawn(self, region) -> "int | None":
        """Put a new part where it will enter ``region`` (a replay makes a sensor fire):
        on a belt that crosses the region, just upstream of it, else on an area that
        holds the region's centre, else None. Returns the part id."""
        x0, y0, x1, y1 = region
        for name, b in self.scene.belts.items():
            (ax, ay), (bx, by), L = b["from"], b["to"], b["length"]
            n = max(2, int(L / 0.005))
            for i in range(n + 1):
                s = L * i / n
                px, py = ax + (bx - ax) * s / L, ay + (by - ay) * s / L
                if x0 <= px <= x1 and y0 <= py <= y1:
                    s = max(0.0, s - 0.01)
                    part = self._new_part(b["part_type"], ax + (bx - ax) * s / L, ay + (by - ay) * s / L,
                                          Place("BELT", name))
                    part.s = s
                    return part.id
        cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
        for name, a in self.scene.areas.items():
            if _inside(a["region"], (cx, cy)):
                return self._new_part(DEFAULT_PART, cx, cy, Place("AREA", name)).id
        return None

    # ---- robot commands (the primitive library calls these)
    def move_to(self, robot: str, p, speed: float = 1.0, z: "float | None" = None,
                acceleration: "float | None" = None) -> bool:
        """Start a straight rest-to-rest move to ``p`` (and height ``z`` for a robot with a z
        axis; None keeps its height); ``speed`` scales the velocity limits and
        ``acceleration`` (default: ``speed``) the acceleration limits. False when the
        target is behind a closed door."""
        r = self.robots[robot]
        r.tracking, r.arrived = None, False
        self._version += 1
        if self.door_at(p) is not None:
            r.moving, r.blocked = False, True
            return False
        spec = r.spec
        acc = speed if acceleration is None else acceleration
        r.x0, r.y0, r.x1, r.y1 = r.x, r.y, float(p[0]), float(p[1])
        if spec["z"] is None:
            r.prof = Profile(math.hypot(r.x1 - r.x0, r.y1 - r.y0), spec["speed"] * speed, spec["acceleration"] * acc)
        else:
            zs = spec["z"]
            r.z0, r.z1 = r.z, (r.z if z is None else float(z))
            if not zs["min"] <= r.z1 <= zs["max"]:
                raise ValueError(f"target height {r.z1:.3f} outside [{zs['min']:g}, {zs['max']:g}]")
            d_xy, d_z = math.hypot(r.x1 - r.x0, r.y1 - r.y0), abs(r.z1 - r.z0)
            v = a = math.inf  # one synchronised profile of the path fraction 0 -> 1
            if d_xy > 0.0:
                v, a = min(v, spec["speed"] / d_xy), min(a, spec["acceleration"] / d_xy)
            if d_z > 0.0:
                v, a = min(v, zs["speed"] / d_z), min(a, zs["acceleration"] / d_z)
            r.prof = Profile(1.0 if v != math.inf else 0.0, v * speed, a * acc)
        prof = r.prof
        r.cruise_v = ((r.x1 - r.x0) * prof.v / prof.dist, (r.y1 - r.y0) * prof.v / prof.dist) if prof.dist > 0.0 else (0.0, 0.0)
        r.k, r.moving, r.blocked, r.coasting = 0, True, False, False
        return True

    def track(self, robot: str, part_id: int, z: "float | None" = None) -> None:
        """Follow part ``part_id`` (on a belt or resting) with the tool: its velocity fed
        forward, the approach limited by the robot's speed and braking (twice its
        acceleration), the height moved to ``z`` on its own profile. ``arrived`` holds while
        the part is within ``track_tolerance`` under the tool and the height is reached."""
        r = self.robots[robot]
        self._version += 1
        if r.tracking is None:
            r.vel = (0.0, 0.0)
        r.tracking, r.moving, r.blocked, r.arrived, r.k, r.coasting = part_id, True, False, False, 0, False
        zs = r.spec["z"]
        r.z0, r.z1 = r.z, (r.z if z is None or zs is None else float(z))
        r.prof = Profile(abs(r.z1 - r.z0), zs["speed"], zs["acceleration"]) if zs else Profile(0.0, 1.0, 1.0)

    def stop(self, robot: str) -> None:
        r = self.robots[robot]
        r.moving, r.tracking, r.vel, r.arrived = False, None, (0.0, 0.0), False
        self._version += 1

    def door_at(self, p) -> "str | None":
        """The door (not fully open) whose region contains p, or None."""
        for name, d in self.scene.doors.items():
            if self.doors[name] < 1.0 and _inside(d["region"], p):
                return name
        return None

    def grip(self, robot: str) -> None:
        """Start gripping: vacuum attaches at the next step, fingers after close_time."""
        r = self.robots[robot]
        if r.holding is None and r.closing is None:
            r.closing = max(1, round(r.spec["close_time"] / self.dt)) if r.spec["close_time"] > 0 else 0
            r.armed = True
            self._version += 1

    def attach(self, robot: str) -> bool:
        """Attach the part under the tool now (a vacuum cup); False when there is none."""
        r = self.robots[robot]
        pid = self.part_under(robot) if r.holding is None else None
        if pid is None:
            return False
        r.holding, r.closing, r.armed = pid, None, True
        self._move(self.parts[pid], Place("GRIPPER", robot))
        return True

    def aim(self, robot: str, part_id: "int | None") -> None:
        """Let the gripper of ``robot`` take only part ``part_id`` (None: any part under it),
        and only when the tool is centred on it within the gripper's ``grasp_tolerance``,
        until it is released: a pick that passes over other parts, or over its own part's
        edge, on its way to its target does not take them."""
        r = self.robots[robot]
        if r.aim != part_id:
            r.aim = part_id
            self._version += 1

    def release(self, robot: str) -> None:
        r = self.robots[robot]
        r.closing, r.armed, r.aim = None, True, None
        self._version += 1
        if r.holding is not None:
            part = self.parts[r.holding]
            r.holding = None
            self._let_go(part)

    def _slip(self, r: _Robot, part: _Part) -> None:
        """The held part slid out of the gripper: the tool accelerated harder than the
        gripper's force can make the part follow."""
        F, m = r.spec["max_force"], part.mass
        r.holding, r.armed = None, False
        cause = (f"slipped from {r.name}'s gripper: the tool accelerated at up to {r.peak:.2f} m/s^2, "
                 f"which needs {m * r.peak:.1f} N on the {m:g} kg part; the gripper holds with at most {F:g} N")
        self.incidents.append((round(self.time, 9), "slip", part.id, cause))
        self._let_go(part, "slip")

    def gripping(self, robot: str) -> bool:
        """True while the gripper is closing (fingers) or waiting for a part (vacuum)."""
        return self.robots[robot].closing is not None

    def top(self, pid: int) -> float:
        """Height of a part's top: its support's height (area, belt; the floor is 0) plus its own."""
        p = self.parts[pid]
        kind, name = p.place
        base = (self.scene.areas[name]["height"] if kind == "AREA" else
                self.scene.belts[name]["height"] if kind == "BELT" else
                self.robots[name].z if kind == "GRIPPER" else 0.0)
        return base + p.height

    def part_under(self, robot: str) -> "int | None":
        r = self.robots[robot]
        best, bd = None, r.spec["radius"]
        zmax = None if r.spec["z"] is None else r.z - r.spec["grasp_tolerance"]
        if r.aim is not None:  # an aimed gripper: its part only, centred on it within the grasp tolerance
            p = self.parts[r.aim]
            if (p.place.kind in ("GRIPPER", "LOST") or math.hypot(p.x - r.x, p.y - r.y) > min(bd, r.spec["grasp_tolerance"])
                    or (zmax is not None and zmax > self.top(r.aim))):
                return None
            return r.aim
        for place, ids in self.members.items():
            if place.kind in ("GRIPPER", "LOST"):
                continue
            for pid in ids:
                p = self.parts[pid]
                d = math.hypot(p.x - r.x, p.y - r.y)
                if d > bd or (zmax is not None and zmax > self.top(pid)):
                    continue  # too far, or the cup is above the part
                if d < bd or (best is None and d <= bd) or (d == bd and best is not None and pid < best):
                    best, bd = pid, d
        return best

    def set_door(self, door: str, open_: bool) -> None:
        goal = 1.0 if open_ else 0.0
        if self.door_goal[door] != goal:
            self.door_goal[door] = goal
            self._version += 1

    def tool_in(self, region) -> bool:
        return any(_inside(region, (r.x, r.y)) for r in self.robots.values())

    def query(self, kind: str, name):
        """The world's value for a check: ``name`` is a name, or (name, part type) for
        ``count`` and ``sensor`` (only parts of that type)."""
        if isinstance(name, tuple):
            name, ptype = name
            ids = self.members.get(Place("AREA", name), ()) if kind == "count" else self.inside[name]
            return sum(1 for pid in ids if self.parts[pid].type == ptype)
        if kind == "holding":
            return self.robots[name].holding is not None
        if kind == "count":
            return self.count(name)
        if kind == "door":
            return self.doors[name] >= 1.0
        return len(self.inside[name])

    # ---- stepping
    def step(self, n: int = 1) -> None:
        """Advance ``n`` steps of ``dt``. A run of steps in which no Python-side check can
        fire (``_quiet``) goes to Chipmunk as one batch (``_coast``); its result is the one
        of stepping one at a time, bit for bit."""
        wait = 0  # steps to take one at a time before looking for a batch again
        while n > 0:
            if wait <= 0 and n > 1:
                m = self._quiet(n)
                if m > 1:
                    k = self._coast(m)
                    n -= k
                    if k < m:  # a contact ended the batch: one at a time for the rest of this call
                        wait = n
                    continue
                wait = self._wait
            j = min(n, max(wait, 1))
            self._steps(j)
            n -= j
            wait -= j

    def _steps(self, n: int) -> None:
        """``n`` steps one at a time."""
        space, dt, robots = self.space, self.dt, tuple(self.robots.values())
        cp_step, cp_space = self._cp_step, space._space
        doors, after = bool(self.doors), self._after_step
        for _ in range(n):
            self.steps += 1
            if self.steps * dt + _EPS >= self._next_arrival:
                self._arrive()
            if doors:
                self._doors()
            for r in robots:
                if r.holding is None:
                    self._drive(r)
                else:
                    self._robot(r)
            if self._added:  # pymunk's checks of new bodies and its bookkeeping of removed shapes
                space.step(dt)
                self._added = False
            else:
                cp_step(cp_space, dt)  # the same Chipmunk step without pymunk's per-call overhead
            after()

    def _after_step(self) -> None:
        for r in self.robots.values():
            if r.holding is not None:
                self._held(r)
        if self._belt_rows:
            self._belts()
        if self._disturbed:
            self._resting()
        if self.scene.sinks:
            self._sinks()
        if self._sensor_regions:
            self._sense()

    def _quiet(self, n: int) -> int:
        """How many of the next ``n`` steps (0 or 1: none) need no Python-side work
        between them but the robots that carry or track a part (``self._carriers``: their
        tool is driven and their part checked every step, as one at a time): no belt
        arrival is due, no door moves (nor a robot in a scene with doors), no fingers
        finish closing, no cup tracking a part is armed, and no part on a belt or watched
        resting part (``_disturbed``) can reach a belt's end or side, a sensor's, sink's
        or area's edge, a slot's tolerance or the reach of an armed cup: such a part rides
        a friction joint without bias, so while nothing touches it its speed relative to
        its support can only fall, and after ``j`` steps it lies within
        ``j * dt * (|v - v_support| + 1 mm/s)`` of where its support carries it
        (``_belt_horizon``, ``_rest_horizon``). A robot that carries a part at a constant
        velocity (at rest, in a vertical move or in the cruise phase of a move, the part settled under the
        tool) needs nothing at all (``_steady``). A contact or a change of place (a part
        slips) ends a batch (``_coast``). When it finds no batch, ``self._wait`` says how
        many steps to take one at a time before looking again (only a matter of speed:
        stepping one at a time is always right). It looks a second ahead (``_lookahead``
        steps, or ``n``): the horizon it finds holds for the calls that follow until a
        command or a change of place (``_version``) or a contact (``_coast``) ends it."""
        if self._quiet_version == self._version and self._quiet_end - self.steps > 1:
            return min(n, self._quiet_end - self.steps)  # the last horizon (and its carriers) still holds
        m = self._horizon_ahead(max(n, self._lookahead))
        if m > 1:
            self._quiet_end, self._quiet_version = self.steps + m, self._version
        return min(n, m)

    def _horizon_ahead(self, n: int) -> int:
        """``_quiet`` worked out afresh."""
        self._wait = 1
        self._carriers = carriers = []
        if self._added or (self._sensor_regions and len(self.log) != self._sensed_log):
            return 0
        dt, steps, m = self.dt, self.steps, n
        nxt = self._next_arrival
        if nxt != math.inf:
            if nxt == -math.inf:
                return 0
            m = min(m, int((nxt - _EPS) / dt) - steps + 1)
            while m > 1 and (steps + m) * dt + _EPS >= nxt:
                m -= 1
            if m < 2:
                return 0
        if self.doors and any(self.doors[d] != self.door_goal[d] for d in self.doors):
            self._wait = n
            return 0
        robots = self.robots.values()
        for r in robots:  # the robots' own limits first (cheap)
            if r.moving and self.doors:  # a moving tool stops short of a closed door
                self._wait = n
                return 0
            if r.tracking is not None:  # the tool follows its part step by step
                carriers.append(r)
                if r.closing == 0 and r.armed:  # a waiting cup: batched while it stays above every part
                    m = self._above_parts(r, m)
                elif r.closing is not None:
                    m = min(m, r.closing - 1)
            elif r.holding is not None:
                steady = self._steady(r, m)
                if steady > 1:
                    m = steady
                else:
                    carriers.append(r)
            elif r.closing is not None and r.closing > 0:
                m = min(m, r.closing - 1)
            if m < 2:
                return 0
        movers: dict = {}
        m = min(m, self._belt_horizon(movers))
        if m > 1 and self._disturbed:
            if carriers:  # a carrier's part may land by them (``landing``) or its tool follow them
                return 0
            m = min(m, self._rest_horizon(movers))
        if m < 2:
            return 0
        for r in robots:  # an armed vacuum cup attaches the first part that comes within its radius
            if r.holding is None and r.closing == 0 and r.armed and r.tracking is None:
                m = self._out_of_grip(r, m, movers)
                if m < 2:
                    self._wait = 4
                    return 0
        return m

    def _steady(self, r: _Robot, m: int) -> int:
        """``m`` or fewer steps (0 or 1: none) in which ``r``'s tool carries its part at a
        constant velocity (at rest, in a vertical move, or in the cruise phase of its move)
        with the part settled under it: the part cannot slip, and Chipmunk moves the tool
        body alone."""
        if self.scene.faults:
            return 0
        dt, prof = self.dt, r.prof
        if r.moving and (r.x0 != r.x1 or r.y0 != r.y1):
            if not r.coasting:
                return 0
            while m > 1 and (r.k + m) * dt > prof.total - prof.t_acc:  # the batch ends in the cruise phase
                m = min(m - 1, int((prof.total - prof.t_acc) / dt) - r.k + 1)
        elif r.last_v != (0.0, 0.0):  # at rest, or a vertical move (x-y stays put), since the last step
            return 0
        part = self.parts[r.holding]  # it sits well within the cup and moves with the tool
        ax, ay = r.anchor
        v = self._cp_vel(part.cb)
        tv = r.cruise_v if r.moving else (0.0, 0.0)
        if (math.hypot(part.x - r.x - ax, part.y - r.y - ay) > r.spec["radius"] / 2
                or math.hypot(v.x - tv[0], v.y - tv[1]) * m * dt > r.spec["radius"] / 4):
            return 0
        return min(m, int(0.5 * self.space.sleep_time_threshold / dt))  # the part is woken once per batch

    def _belt_horizon(self, movers: dict) -> int:
        """Steps (0 or 1: none) in which no belt part can reach a belt's end or side or a
        sensor's or sink's edge, while nothing touches it (see ``_quiet``); the checks
        after a step skip sensors and sinks until then (``_calm_until``; a contact or a
        change of place ends that). Appends ``(x, y, dx, dy, e)`` for each belt part to
        ``movers`` (part id -> ``(dx, dy, e)``): after ``j`` steps it lies within ``j * e``
        of where it is plus ``j`` times ``(dx, dy)``."""
        m, dt, parts, vel = 1 << 30, self.dt, self.parts, self._cp_vel
        for place, ax, ay, ux, uy, L, half, lost in self._belt_rows:
            ids = self.members.get(place)
            if not ids:
                continue
            bvx, bvy = self._belt_vel[place.name]
            for pid in ids:
                p = parts[pid]
                v = vel(p.cb)
                e = (math.hypot(v.x - bvx, v.y - bvy) + 1e-3) * dt
                dx, dy = bvx * dt, bvy * dt
                x, y = p.x, p.y
                movers[pid] = (dx, dy, e)
                s, ds = (x - ax) * ux + (y - ay) * uy, dx * ux + dy * uy
                q, dq = -(x - ax) * uy + (y - ay) * ux, -dx * uy + dy * ux
                m = _horizon(m, ((s, ds), (half - q, -dq), (half + q, dq)) + (((L - s, -ds),) if lost else ()), e)
                for rx0, ry0, rx1, ry1 in self._watched_regions:
                    m = _horizon(m, ((x - rx0, dx), (rx1 - x, -dx), (y - ry0, dy), (ry1 - y, -dy)), e)
                if m < 2:
                    self._calm_until = -1
                    return 0
        self._calm_until = self.steps + m
        return m

    def _rest_horizon(self, movers: dict) -> int:
        """Steps (0 or 1: none) in which no watched resting part (``_disturbed``) can leave
        its area or slot or cross a sensor's or sink's edge: held by friction to the ground
        and untouched, its speed can only fall. Adds them to ``movers``."""
        m, dt, parts, vel, areas = 1 << 30, self.dt, self.parts, self._cp_vel, self.scene.areas
        for pid in self._disturbed:
            p = parts[pid]
            v = vel(p.cb)
            e = (math.hypot(v.x, v.y) + 1e-3) * dt
            movers[pid] = (0.0, 0.0, e)
            x, y = p.x, p.y
            margins = []
            if p.place.kind == "AREA":
                rx0, ry0, rx1, ry1 = areas[p.place.name]["region"]
                margins += [(x - rx0, 0.0), (rx1 - x, 0.0), (y - ry0, 0.0), (ry1 - y, 0.0)]
                if p.slot is not None:
                    margins.append((areas[p.place.name]["slot_tolerance"] - math.hypot(x - p.slot[0], y - p.slot[1]), 0.0))
            for rx0, ry0, rx1, ry1 in self._watched_regions:
                margins += [(x - rx0, 0.0), (rx1 - x, 0.0), (y - ry0, 0.0), (ry1 - y, 0.0)]
            m = _horizon(m, margins, e)
            if m < 2:
                return 0
        return m

    def _above_parts(self, r: _Robot, m: int) -> int:
        """``m`` or fewer steps (0 or 1: none) in which the armed cup of ``r``, which tracks a
        part, stays more than its grasp tolerance above the top of every part it could take
        (``part_under`` finds none, wherever the tool goes in x-y): its height follows its
        own profile, monotone towards its target."""
        zs = r.spec["z"]
        if zs is None:
            return 0
        if self._top_version != self._version:  # the highest top changes only with a change of place
            self._top_version = self._version
            self._top = max((self.top(pid) for place, ids in self.members.items()
                             if place.kind not in ("GRIPPER", "LOST") for pid in ids), default=None)
        if self._top is None:
            return m
        floor = self._top + r.spec["grasp_tolerance"] + 1e-9  # the cup must stay above this
        prof, dt = r.prof, self.dt
        if r.z <= floor:
            return 0
        if r.z1 >= r.z0 or prof.dist <= 0.0:  # rising or level: never lower than now
            return m
        while m > 1:  # sinking: the height at the batch's last step bounds the ones before it
            if r.z0 + (r.z1 - r.z0) * prof.at((r.k + m) * dt) / prof.dist > floor:
                return m
            m //= 2
        return 0

    def _out_of_grip(self, r: _Robot, m: int, movers: dict) -> int:
        """``m`` or fewer steps in which no part comes under ``r``'s cup (``part_under``:
        within its radius, its top within the grasp tolerance of the cup's height). The
        tool moves along a straight line, its height monotone; belt parts move as
        ``movers`` says (``_belt_horizon``), other parts rest."""
        dt, radius, zs = self.dt, r.spec["radius"], r.spec["z"]
        while m > 1:
            tx, ty, tz = r.x, r.y, r.z
            if r.moving:
                prof = r.prof
                t = min((r.k + m) * dt, prof.total)
                f = 1.0 if prof.dist <= 0.0 else prof.at(t) / prof.dist
                tx, ty = r.x0 + (r.x1 - r.x0) * f, r.y0 + (r.y1 - r.y0) * f
                if zs is not None:
                    tz = r.z0 + (r.z1 - r.z0) * f
            reach = radius + math.hypot(tx - r.x, ty - r.y) + 1e-6
            zmax = None if zs is None else min(r.z, tz) - r.spec["grasp_tolerance"] - 1e-9
            ok = True
            for place, ids in self.members.items():
                if place.kind in ("GRIPPER", "LOST"):
                    continue
                for pid in ids:
                    if zmax is not None and zmax > self.top(pid):
                        continue  # the cup stays above it
                    p, mv = self.parts[pid], movers.get(pid)
                    far = reach + (0.0 if mv is None else m * (math.hypot(mv[0], mv[1]) + mv[2]))
                    if math.hypot(p.x - r.x, p.y - r.y) <= far:
                        ok = False
                        break
                if not ok:
                    break
            if ok:
                return m
            m //= 2
        return 0

    def _coast(self, m: int) -> int:
        """Up to ``m`` steps (``_quiet`` said they need nothing between them but the
        carriers' tools and parts) straight through Chipmunk; a contact callback or a
        change of place ends the batch after its step. The other robots then take those
        steps at once (their positions are functions of their step count; a coasting
        tool body was moved by Chipmunk at its constant velocity) and the checks after a
        step run once. Returns the steps taken."""
        cp_step, cp_space, dt = self._cp_step, self.space._space, self.dt
        carriers = self._carriers
        for r in self.robots.values():
            if r.holding is not None and r not in carriers:
                self._cp_activate(self.parts[r.holding].cb)
        self._contact = False
        k = 0
        one = carriers[0] if len(carriers) == 1 and not self.doors and not self.scene.faults else None
        if one is not None and one.tracking is None:
            k = self._carry(one, m)
        elif one is not None and one.holding is None and self.parts[one.tracking].place.kind not in ("GRIPPER", "LOST"):
            k = self._chase(one, m)
        elif carriers:
            log, n_log, parts, get_pos = self.log, len(self.log), self.parts, self._cp_pos
            while k < m:
                self.steps += 1
                k += 1
                for r in carriers:
                    if r.tracking is not None:  # the tracked part where the last step left it (``_belts``)
                        p = parts[r.tracking]
                        if p.place.kind == "BELT":
                            pos = get_pos(p.cb)
                            p.x, p.y = pos.x, pos.y
                    if r.holding is None:
                        self._drive(r)
                    else:
                        self._robot(r)
                cp_step(cp_space, dt)
                for r in carriers:
                    if r.holding is not None:
                        self._held(r)
                if self._contact or len(log) != n_log:
                    break
        else:
            while k < m:
                self.steps += 1
                k += 1
                cp_step(cp_space, dt)
                if self._contact:
                    break
        for r in self.robots.values():
            if r.moving and r not in carriers:
                prof = r.prof
                end = r.k + k
                if r.holding is None or r.x0 == r.x1 and r.y0 == r.y1:  # the step at which the move ends, if it
                    last = max(r.k + 1, math.ceil(prof.total / dt) - 1)  # ends within the batch (not in a cruise)
                    while last * dt < prof.total:
                        last += 1
                    while last - 1 > r.k and (last - 1) * dt >= prof.total:
                        last -= 1
                    end = min(end, last)
                r.k = end
                t = end * dt
                f = 1.0 if prof.dist <= 0.0 or t >= prof.total else prof.at(t) / prof.dist
                r.x, r.y = r.x0 + (r.x1 - r.x0) * f, r.y0 + (r.y1 - r.y0) * f
                if r.spec["z"] is not None:
                    r.z = r.z0 + (r.z1 - r.z0) * f
                if t >= prof.total:
                    r.moving, r.arrived = False, True
            if r.holding is None and r.closing is not None and r.closing > 0 and r not in carriers:
                r.closing -= k  # fingers closing (``_quiet``: they close after the batch)
        if self._contact or k < m:  # what touched may move: the horizon is to be found anew
            self._quiet_end = -1
        self._after_step()
        return k

    def _carry(self, r: _Robot, m: int) -> int:
        """The steps of a batch with one carrier and no doors or faults: ``_drive``
        (with ``Profile.at``), ``_robot`` and ``_held`` of the carrier inlined, on local
        variables (the same arithmetic in the same order: ``tests/test_physics.py``
        compares batches with steps one at a time)."""
        cp_step, cp_space, dt, hypot = self._cp_step, self.space._space, self.dt, math.hypot
        set_pos, set_vel, get_pos = self._cp_set_pos, self._cp_set_vel, self._cp_pos
        part = self.parts[r.holding]
        tb, pb, radius, (ax, ay) = r.body._body, part.cb, r.spec["radius"], r.anchor
        prof, zs = r.prof, r.spec["z"] is not None
        dist, total, t_acc, a, v = (prof.dist, prof.total, prof.t_acc, prof.a, prof.v) if prof else (0.0,) * 5
        cruise_end = total - t_acc
        x0, y0, z0, dx, dy, dz = r.x0, r.y0, r.z0, r.x1 - r.x0, r.y1 - r.y0, r.z1 - r.z0
        cvx, cvy = r.cruise_v
        x, y, z, rk, moving, coasting, peak = r.x, r.y, r.z, r.k, r.moving, r.coasting, r.peak
        lv = r.last_v is not None  # the tool's velocity in the last step is known: (lvx, lvy)
        lvx, lvy = r.last_v or (0.0, 0.0)
        moves = moving and not r.blocked
        steps, k, slipped = self.steps, 0, False
        cx = cy = svx = svy = math.nan  # the tool body's position after the last step, and velocity, when known
        while k < m:
            k += 1
            self.steps = steps + k  # a contact callback reads the time
            ox, oy = x, y
            if moving:  # _drive
                rk += 1
                t = rk * dt
                if dist <= 0.0 or t >= total:
                    f = 1.0
                elif t <= t_acc:
                    f = 0.5 * a * t * t / dist
                elif t <= cruise_end:
                    f = (0.5 * a * t_acc * t_acc + v * (t - t_acc)) / dist
                else:
                    rt = total - t
                    f = (dist - 0.5 * a * rt * rt) / dist
                x, y = x0 + dx * f, y0 + dy * f
                if zs:
                    z = z0 + dz * f
                if t >= total:
                    moving = False
            if moves and (rk - 1) * dt >= t_acc and rk * dt <= cruise_end:
                vx, vy = cvx, cvy  # _robot
                if not coasting:
                    coasting = True
                    set_pos(tb, (ox, oy))
                    set_vel(tb, (vx, vy))
                    cx = svx = math.nan  # Chipmunk moves the tool on (not followed here)
            else:
                moves = moving and moves
                coasting = False
                vx, vy = (x - ox) / dt, (y - oy) / dt
                if cx != ox or cy != oy or not (cx and cy):  # (a set to the same values changes nothing)
                    set_pos(tb, (ox, oy))
                if vx != svx or vy != svy:
                    set_vel(tb, (vx, vy))
                    svx, svy = vx, vy
                cx, cy = ox + (vx + 0.0) * dt, oy + (vy + 0.0) * dt  # where Chipmunk's step leaves the tool
            if lv:
                acc = hypot(vx - lvx, vy - lvy) / dt
                if acc > peak:
                    peak = acc
            lv, lvx, lvy = True, vx, vy
            cp_step(cp_space, dt)  # (Chipmunk keeps a body joined to a kinematic one awake)
            pos = get_pos(pb)  # _held
            px, py = pos.x, pos.y
            if hypot(px - x - ax, py - y - ay) > radius:
                slipped = True
                break
            if self._contact:
                break
        if r.moving and not moving:
            r.moving, r.arrived = False, True
        r.x, r.y, r.z, r.k, r.coasting, r.last_v, r.peak = x, y, z, rk, coasting, (lvx, lvy) if lv else None, peak
        part.x, part.y = px, py
        if slipped:
            self._slip(r, part)
        return k

    def _chase(self, r: _Robot, m: int) -> int:
        """The steps of a batch with one carrier that tracks a part and holds none, and no
        doors or faults: ``_drive`` of the carrier (``_track``, ``_velocity``, ``_pursuit``,
        ``Scene.clamp_to_reach``, ``Profile.at``) inlined on local variables, the same
        arithmetic in the same order (``tests/test_physics.py`` compares a trial in batches
        with one stepped one step at a time). Within a batch the tracked part keeps its
        place (a change of place ends the batch) and the fingers do not finish closing
        (``_quiet``)."""
        cp_step, cp_space, dt, hypot, sqrt = self._cp_step, self.space._space, self.dt, math.hypot, math.sqrt
        log, n_log, get_pos = self.log, len(self.log), self._cp_pos
        part = self.parts[r.tracking]
        on_belt, pb = part.place.kind == "BELT", part.cb
        pvx, pvy = self._velocity(part)
        spec, prof = r.spec, r.prof
        vmax, acc, tol = spec["speed"], spec["acceleration"], spec["track_tolerance"]
        dv_max = 2.0 * acc * dt
        (rax, ray), (rbx, rby) = self.scene.robots[r.name]["rail"]
        rdx, rdy = rbx - rax, rby - ray
        rl2, reach = rdx * rdx + rdy * rdy, self.scene.robots[r.name]["reach"]
        pdist, ptotal, pt_acc, pa, pv = prof.dist, prof.total, prof.t_acc, prof.a, prof.v
        z0, dz = r.z0, r.z1 - r.z0
        x, y, z, (wx, wy), rk, closing = r.x, r.y, r.z, r.vel, r.k, r.closing
        px, py, arrived = part.x, part.y, r.arrived
        steps, k = self.steps, 0
        r.faults_in.clear()
        while k < m:
            k += 1
            self.steps = steps + k  # a contact callback reads the time
            if on_belt:  # the tracked part where the last step left it (``_belts``)
                pos = get_pos(pb)
                px, py = pos.x, pos.y
            rk += 1  # _track
            t = rk * dt
            if pdist > 0.0:
                if t >= ptotal:
                    f = pdist
                elif t <= pt_acc:
                    f = 0.5 * pa * t * t
                elif t <= ptotal - pt_acc:
                    f = 0.5 * pa * pt_acc * pt_acc + pv * (t - pt_acc)
                else:
                    rt = ptotal - t
                    f = pdist - 0.5 * pa * rt * rt
                z = z0 + dz * f / pdist
            qx, qy = px + pvx * dt, py + pvy * dt
            if rl2 == 0.0:  # _pursuit: the reachable point nearest the target
                u = 0.0
            else:
                u = ((qx - rax) * rdx + (qy - ray) * rdy) / rl2
                u = u if u < 1.0 else 1.0
                u = u if u > 0.0 else 0.0
            cx, cy = rax + u * rdx, ray + u * rdy
            ex, ey = qx - cx, qy - cy
            d = hypot(ex, ey)
            if d <= reach:
                cx, cy, fx, fy = qx, qy, pvx, pvy
            else:
                cx, cy = cx + ex * reach / d, cy + ey * reach / d
                fx, fy = (pvx, pvy) if (cx, cy) == (qx, qy) else (0.0, 0.0)
            ex, ey = cx - x, cy - y
            dist = hypot(ex, ey)
            if dist == 0.0:
                vx, vy = fx, fy
            else:
                speed = min(vmax, sqrt(2.0 * acc * dist), dist / dt)
                vx, vy = fx + ex / dist * speed, fy + ey / dist * speed
            dvx, dvy = vx - wx, vy - wy
            dv = hypot(dvx, dvy)
            if dv > dv_max:  # acceleration limit
                vx, vy = wx + dvx * dv_max / dv, wy + dvy * dv_max / dv
            wx, wy = vx, vy
            x, y = x + vx * dt, y + vy * dt
            arrived = hypot(qx - x, qy - y) <= tol and t >= ptotal
            if closing is not None and closing > 0:  # fingers closing (they close after the batch)
                closing -= 1
            cp_step(cp_space, dt)
            if self._contact or len(log) != n_log:
                break
        r.x, r.y, r.z, r.vel, r.k, r.closing, r.arrived = x, y, z, (wx, wy), rk, closing, arrived
        part.x, part.y = px, py
        return k

    def _arrive(self) -> None:
        t = self.time + _EPS
        for name, times in self.arrivals.items():
            while times and times[0] <= t:
                times.pop(0)
                self.pending[name] += 1
            if self.pending[name]:
                b = self.scene.belts[name]
                types = b["part_types"]
                ptype = types[self._spawned[name] % len(types)]  # several types arrive in turn
                gap = 2 * max(self.scene.part_types[pt] for pt in types)
                if all(self.parts[i].s > gap for i in self.members.get(Place("BELT", name), ())):
                    self.pending[name] -= 1
                    self._spawned[name] += 1
                    x, y = b["from"]
                    self._new_part(ptype, x, y, Place("BELT", name))
        # the next step that has something to do here: now while a part waits for space, else the next arrival
        self._next_arrival = (-math.inf if any(self.pending.values()) else
                              min((ts[0] for ts in self.arrivals.values() if ts), default=math.inf))

    def _doors(self) -> None:
        for name, d in self.scene.doors.items():
            now, goal = self.doors[name], self.door_goal[name]
            if now != goal:
                rate = self.dt / d["open_time"] if d["open_time"] > 0 else 1.0
                self.doors[name] = min(goal, now + rate) if goal > now else max(goal, now - rate)

    def _robot(self, r: _Robot) -> None:
        ox, oy = r.x, r.y
        profiled = r.moving and r.tracking is None
        self._drive(r)
        if r.holding is not None:  # the tool (a kinematic body) drags the held part through the grip joint
            dt = self.dt
            prof = r.prof
            if profiled and not r.blocked and (r.k - 1) * dt >= prof.t_acc and r.k * dt <= prof.total - prof.t_acc:
                # the constant-velocity phase of the move: the tool body keeps the profile's velocity and
                # Chipmunk moves it (as a batch of steps does, ``_coast``: the same result either way)
                vx, vy = r.cruise_v
                if not r.coasting:
                    r.coasting = True
                    cb = r.body._body
                    self._cp_set_pos(cb, (ox, oy))
                    self._cp_set_vel(cb, (vx, vy))
            else:
                r.coasting = False
                vx, vy = (r.x - ox) / dt, (r.y - oy) / dt
                cb = r.body._body
                self._cp_set_pos(cb, (ox, oy))
                self._cp_set_vel(cb, (vx, vy))
            if r.last_v is not None:
                acc = math.hypot(vx - r.last_v[0], vy - r.last_v[1]) / dt
                if acc > r.peak:
                    r.peak = acc
            r.last_v = (vx, vy)
            self._cp_activate(self.parts[r.holding].cb)

    def _held(self, r: _Robot) -> None:
        """After the physics step: the held part's position; it slips when it slid more
        than the gripper's radius from where it was gripped."""
        part = self.parts[r.holding]
        pos = self._cp_pos(part.cb)
        part.x, part.y = pos.x, pos.y
        ax, ay = r.anchor
        if math.hypot(part.x - r.x - ax, part.y - r.y - ay) > r.spec["radius"]:
            self._slip(r, part)

    def _drive(self, r: _Robot) -> None:
        if r.tracking is not None:
            self._track(r)
        elif r.moving:
            r.k += 1
            t = r.k * self.dt
            prof = r.prof
            f = 1.0 if prof.dist <= 0.0 or t >= prof.total else prof.at(t) / prof.dist
            nx, ny = r.x0 + (r.x1 - r.x0) * f, r.y0 + (r.y1 - r.y0) * f
            if self.doors and self.door_at((nx, ny)) is not None:
                r.moving, r.blocked = False, True  # stop short of a closed door
            else:
                r.x, r.y = nx, ny
                if r.spec["z"] is not None:
                    r.z = r.z0 + (r.z1 - r.z0) * f
                if t >= prof.total:
                    r.moving, r.arrived = False, True
        if r.closing is not None and r.holding is None:
            if r.closing > 0:
                r.closing -= 1
            if r.closing == 0 and r.armed:
                pid = self.part_under(r.name)
                if pid is not None:
                    r.holding, r.closing = pid, None
                    self._move(self.parts[pid], Place("GRIPPER", r.name))
        if r.holding is not None:
            part = self.parts[r.holding]
            for name, f in self.scene.faults.items():
                inside = _inside(f["region"], (r.x, r.y))
                if inside and name not in r.faults_in:
                    r.faults_in.add(name)
                    if self.rng.random() < f["probability"]:
                        r.holding, r.armed = None, False
                        self.incidents.append((round(self.time, 9), "drop", part.id,
                                               f"fault region {name} (injected, probability {f['probability']:g})"))
                        self._let_go(part, "fault")
                        break
                elif not inside:
                    r.faults_in.discard(name)
        else:
            r.faults_in.clear()

    def _track(self, r: _Robot) -> None:
        part = self.parts[r.tracking]
        if part.place.kind in ("GRIPPER", "LOST"):
            self.stop(r.name)  # tracking ends when the part is taken or lost
            return
        dt = self.dt
        r.k += 1
        t = r.k * dt
        if r.prof.dist > 0.0:
            r.z = r.z0 + (r.z1 - r.z0) * r.prof.at(t) / r.prof.dist
        pv = self._velocity(part)
        px, py = part.x + pv[0] * dt, part.y + pv[1] * dt  # where the part is after this step (belts move after robots)
        vx, vy = self._pursuit(r, (px, py), pv)
        dvx, dvy = vx - r.vel[0], vy - r.vel[1]
        dv, dv_max = math.hypot(dvx, dvy), 2.0 * r.spec["acceleration"] * dt
        if dv > dv_max:  # acceleration limit
            vx, vy = r.vel[0] + dvx * dv_max / dv, r.vel[1] + dvy * dv_max / dv
        r.vel = (vx, vy)
        r.x, r.y = r.x + vx * dt, r.y + vy * dt
        r.arrived = math.hypot(px - r.x, py - r.y) <= r.spec["track_tolerance"] and t >= r.prof.total

    def _velocity(self, part: _Part) -> tuple:
        if part.place.kind != "BELT":
            return (0.0, 0.0)
        b = self.scene.belts[part.place.name]
        (ax, ay), (bx, by), L = b["from"], b["to"], b["length"]
        return ((bx - ax) / L * b["speed"], (by - ay) / L * b["speed"])

    def _pursuit(self, r: _Robot, target, velocity) -> tuple:
        """The target's ``velocity`` (feed-forward) plus a braking-limited approach to it
        (to the nearest reachable point, without feed-forward, when it is out of reach)."""
        px, py = target
        cx, cy = self.scene.clamp_to_reach(r.name, target)
        fx, fy = velocity if (cx, cy) == (px, py) else (0.0, 0.0)
        ex, ey = cx - r.x, cy - r.y
        dist = math.hypot(ex, ey)
        if dist == 0.0:
            return (fx, fy)
        speed = min(r.spec["speed"], math.sqrt(2.0 * r.spec["acceleration"] * dist), dist / self.dt)
        return (fx + ex / dist * speed, fy + ey / dist * speed)

    def _belts(self) -> None:
        """Belt parts ride the belt's body (friction joints) and push one another; a part
        past a ``lost`` end is lost, one pushed off the belt's side falls to the floor."""
        get, members = self._cp_pos, self.members
        for place, ax, ay, ux, uy, L, half, lost in self._belt_rows:
            ids = members.get(place)
            if not ids:
                continue
            for pid in list(ids):
                p = self.parts[pid]
                pos = get(p.cb)
                x, y = p.x, p.y = pos.x, pos.y
                s = p.s = (x - ax) * ux + (y - ay) * uy
                if lost and s >= L:
                    self._move(p, LOST)
                elif abs(-(x - ax) * uy + (y - ay) * ux) > half or s < 0.0:
                    self.incidents.append((round(self.time, 9), "fell_off", pid, f"pushed off belt {place.name}"
                                           + (f" by part {p.pushed_by}" if p.pushed_by is not None else "")))
                    p.s = min(max(s, 0.0), L)
                    self._let_go(p, "pushed")

    def _resting(self) -> None:
        """Resting parts that something touched: pushed out of their area or slot they
        leave it (to where they lie); once asleep they are no longer watched."""
        get, sleeping = self._cp_pos, self._cp_sleeping
        for pid in list(self._disturbed):
            p = self.parts[pid]
            pos = get(p.cb)
            p.x, p.y = pos.x, pos.y
            kind, name = p.place
            by = f" by part {p.pushed_by}" if p.pushed_by is not None else ""
            if kind == "AREA":
                a = self.scene.areas[name]
                if not _inside(a["region"], (p.x, p.y)):
                    self.incidents.append((round(self.time, 9), "pushed_off", pid, f"pushed out of area {name}{by}"))
                    self._let_go(p, "pushed")
                elif p.slot is not None and math.hypot(p.x - p.slot[0], p.y - p.slot[1]) > a["slot_tolerance"]:
                    self.incidents.append((round(self.time, 9), "pushed_out_of_slot", pid,
                                           f"pushed {math.hypot(p.x - p.slot[0], p.y - p.slot[1]):.3f} m out of its "
                                           f"slot in {name}{by} (tolerance {a['slot_tolerance']:g} m)"))
                    self._move(p, FLOOR)
            if p.place.kind in ("LOST", "GRIPPER", "BELT") or sleeping(p.cb):
                self._disturbed.pop(pid, None)
            elif any(_inside(r, (p.x, p.y)) for r in self.scene.sinks.values()):
                self._move(p, LOST)

    def _sinks(self) -> None:
        # resting parts were checked when they landed (``landing``): only belt parts move
        if not self.scene.sinks or self.steps <= self._calm_until:
            return
        sinks = tuple(self.scene.sinks.values())
        for name in self.scene.belts:
            for pid in list(self.members.get(Place("BELT", name), ())):
                p = self.parts[pid]
                if any(_inside(r, (p.x, p.y)) for r in sinks):
                    self._move(p, LOST)

    def _sense(self) -> None:
        # parts move only on belts; other changes go through ``_move`` (which logs them)
        if not self.scene.sensors:
            return
        full = len(self.log) != self._sensed_log  # places changed: look at every part
        if not full and not self._disturbed:
            if self.steps <= self._calm_until:
                return  # no belt part can have crossed a sensor's edge (and no other part moves)
            self._belt_horizon({})  # for the steps to come; this one is looked at below
        if full:
            self._sensed_log = len(self.log)
            movers = [pid for place, ids in self.members.items() if place.kind not in ("GRIPPER", "LOST") for pid in ids]
        else:  # else only the parts that move (on belts, pushed) can enter or leave a sensor
            movers = [pid for b in self._belt_places for pid in self.members.get(b, ())] + list(self._disturbed)
            if not movers:
                return
            if not any(self.inside.values()):  # the usual case: no sensor sees a part, and no mover entered one
                parts = self.parts
                for pid in movers:
                    p = parts[pid]
                    x, y = p.x, p.y
                    if any(x0 <= x <= x1 and y0 <= y <= y1 for x0, y0, x1, y1 in self._sensor_regions):
                        break
                else:
                    return
        parts = self.parts
        for name, s in self.scene.sensors.items():
            x0, y0, x1, y1 = s["region"]
            ptype = s["part_type"]
            old = self.inside[name]
            now = set() if full else set(old)
            for pid in movers:
                p = parts[pid]
                if x0 <= p.x <= x1 and y0 <= p.y <= y1 and (ptype is None or p.type == ptype):
                    now.add(pid)
                else:
                    now.discard(pid)
            if now == old:
                continue
            if s["on_enter"]:
                self.events.extend((self.time, name, s["on_enter"], pid, parts[pid].type) for pid in sorted(now - old))
            if s["on_exit"]:  # a part taken by a gripper does not "leave": it is taken
                self.events.extend((self.time, name, s["on_exit"], pid, parts[pid].type) for pid in sorted(old - now)
                                   if self.parts[pid].place.kind != "GRIPPER")
            self.inside[name] = now

    # ---- invariant, digest, snapshot
    def check_invariant(self) -> None:
        """Raise AssertionError unless every part is in exactly one consistent place."""
        seen: dict = {}
        for place, ids in self.members.items():
            for pid in ids:
                assert pid not in seen, f"part {pid} is in both {seen[pid]} and {place}"
                seen[pid] = place
                assert self.parts[pid].place == place, f"part {pid} listed in {place} records {self.parts[pid].place}"
        assert len(seen) == len(self.parts), f"parts without a place: {[p.id for p in self.parts if p.id not in seen]}"
        for r in self.robots.values():
            held = self.members.get(Place("GRIPPER", r.name), [])
            assert held == ([] if r.holding is None else [r.holding]), f"{r.name} holds {r.holding}, GRIPPER has {held}"
            assert self.scene.reachable(r.name, (r.x, r.y)), f"{r.name}'s tool left its reach"
        for p in self.parts:
            if p.place.kind == "AREA":
                a = self.scene.areas[p.place.name]
                assert _inside(a["region"], (p.x, p.y)), f"part {p.id} in {p.place} lies outside it"
                if a["capacity"] is not None:
                    assert self.count(p.place.name) <= a["capacity"], f"{p.place} holds more than its capacity"
            elif p.place.kind == "BELT":
                b = self.scene.belts[p.place.name]
                assert -_EPS <= p.s <= b["length"] + _EPS, f"part {p.id} is off the end of {p.place}"
            self._check_body(p)

    def _check_body(self, p: _Part) -> None:
        """The physics agrees with the place: a LOST part is out of the space; any other
        has two joints, to the tool of the robot holding it (colliding with nothing) or to
        its support (the belt's body or the ground); a resting part lies where it is recorded."""
        in_space = p.body.space is self.space
        assert in_space == (p.place != LOST), f"part {p.id} in {p.place} but in the space: {in_space}"
        if p.place == LOST:
            assert not p.joints, f"LOST part {p.id} still has joints"
            return
        assert len(p.joints) == 2, f"part {p.id} in {p.place} has {len(p.joints)} joints"
        kind, name = p.place
        want = (self.robots[name].body if kind == "GRIPPER" else self._belt_body[name] if kind == "BELT"
                else self._static)
        assert p.joints[0].a is want, f"part {p.id} in {p.place} is joined to the wrong body"
        if kind != "GRIPPER":
            bx, by = p.body.position
            assert math.hypot(bx - p.x, by - p.y) <= 1e-6, f"part {p.id} in {p.place} moved unrecorded"

    def digest(self) -> str:
        """sha256 over the step count, places and float.hex of every position."""
        h = hashlib.sha256()
        vals = []
        for r in self.robots.values():
            vals += [r.x, r.y] + ([r.z] if r.spec["z"] is not None else [])
            h.update(f"{r.name}:{r.holding}:{r.closing}|".encode())
        for p in self.parts:
            x, y = (p.x, p.y) if p.place == LOST else p.body.position
            vals += [x, y, p.s]
            h.update(f"{p.id}:{p.place}|".encode())
        vals += [self.doors[d] for d in sorted(self.doors)]
        h.update(f"{self.steps}|".encode() + ",".join(float(v).hex() for v in vals).encode())
        return h.hexdigest()

    def snapshot(self) -> dict:
        """Plain data of the world now (for pictures and logs)."""
        return {"time": self.time, "robots": {n: (r.x, r.y, r.holding) for n, r in self.robots.items()},
                "doors": dict(self.doors),
                "parts": [(p.id, p.type, p.radius, p.x, p.y, str(p.place)) for p in self.parts]}
