"""A 2D top-view ARIAC-2019-like kitting cell in pymunk 7 (one arm, bins 2-3, AGV2 tray).

Frame and units: ARIAC 2019 world frame seen from above (x across the cell, y along the
rail), metres, kilograms, seconds. Gravity is 0; heights (z) are plain numbers used only
for timing and for the grasp test, never simulated.

Layout (defaults of :class:`CellConfig`):

* conveyor along x = 1.21, 0.65 m wide, parts moving towards -y at 0.2 m/s. Parts appear
  at y = 4.3, a break-beam line at ``belt_y_detect`` (0.9) records each part once, and a
  deletion wall at ``belt_y_wall = belt_y_detect - belt_speed * pick_window_s`` (-2.3)
  removes it and marks it LOST. So a part is inside the arm's reach for exactly
  ``pick_window_s`` (16 s, 3.2 m of belt) after its detection.
* bins 2 and 3 (0.6 x 0.6 m at x = -0.3, y = -1.15 and -0.383), 9 parts each (3 x 3 grid);
* the AGV2 kit tray (0.5 m in x, 0.7 m in y) at (0.3, -3.3) with 18 slots (3 columns x 6
  rows; slot = row * 3 + column, row 0 is the +y end, column 0 the -x side);
* one arm on a rail at x = 0.3 whose carriage travels y in [-2.5, 0.26] (2.76 m).

Compromise with ARIAC (documented on purpose): one arm with 2.76 m of rail travel and
about 1.2 m of horizontal reach covers belt y in about [-3.2, 1.0] at x = 1.26. It cannot
reach both the tray at y = -3.3 and the belt near its spawn end (y ~ 4). The break beam
therefore sits at the upstream edge of the arm's reach (y = 0.9) instead of near the
spawn point, and the deletion wall moves from ARIAC's y = -4.1 to y = -2.3 so that it is
reached exactly ``pick_window_s`` after detection. Parts still spawn at y = 4.3 and ride
unseen for (4.3 - 0.9) / 0.2 = 17 s before detection (``Cell.detect_delay_s``).

Physics: every resting part has a friction joint pair (PivotJoint + GearJoint, max_bias 0,
max_force mu*m*g) to its support: the kinematic belt body for BELT parts, the static body
otherwise. Parts collide only with parts (and walls) of the same layer (belt, bins, tray,
floor), so parts at different heights never push each other; a held part collides with
nothing.

Arm: the tool centre point (TCP) is a kinematic body without shapes. ``Arm.move_to`` runs
one synchronised rest-to-rest trapezoidal profile along the straight line in (x, y, z)
(x/y share ``v_xy``/``a_xy``, z has ``v_z``/``a_z``); ``Arm.track`` pursues a part with
velocity feed-forward (speed limited by ``v_xy``, acceleration by ``2 * a_xy``) while z
follows its own profile. Moves always start from rest: switching from tracking to a move
makes a velocity step of at most the belt speed. The rail carriage is derived from the TCP
(``y = clamp(tcp.y, rail limits)``) and only drawn; the TCP must stay within ``arm_reach``
of it, which makes the reachable set a convex stadium, so straight moves between reachable
points stay reachable.

Gripper: while enabled and empty it attaches, after a step, to the part whose centre is
nearest the TCP within ``cup_radius`` among parts whose top is at most ``grasp_tol_z``
below the TCP height. Disabling releases the part where it is: on the nearest free tray
slot within ``slot_tolerance``, in a bin, on the belt, else on the FLOOR (a part released
on the tray away from a free slot counts as FLOOR: it is not a kit part). A landing part
takes its support's velocity (no sliding). Drop regions (faulty gripper): when the TCP
carries a part into one, the part falls to the FLOOR where it is, and the gripper stays
enabled but will not grasp again until it is re-enabled.

Accounting: every part is always in exactly one :class:`Place`: BIN(k), GRIPPER,
TRAY(slot), BELT, LOST or FLOOR. ``Cell.check_invariant`` verifies it and the physical
state that goes with it. Belt parts whose centre leaves the belt footprint fall to FLOOR.

Determinism: fixed dt, one thread, fixed construction order, all randomness (spawn
jitter in x and angle, part type choice) from one ``random.Random(seed)``, no wall clock,
decisions only from lists and insertion-ordered dicts. Same seed + same commands at the
same steps => bit-identical ``Cell.digest()``.
"""
from __future__ import annotations

import hashlib
import math
import random
from dataclasses import dataclass
from typing import NamedTuple, Sequence

import pymunk

__all__ = [
    "PartType", "PART_TYPES", "Place", "GRIPPER", "BELT", "LOST", "FLOOR",
    "BinSpec", "CellConfig", "Arm", "Gripper", "Cell", "periodic_arrivals",
    "RAIL_TRAVEL_LIMIT",
]

G = 9.81
RAIL_TRAVEL_LIMIT = 2.76  # ARIAC 2019: one arm's travel on the linear actuator
_EPS = 1e-9


# --------------------------------------------------------------------------- parts
class PartType(NamedTuple):
    """Footprint ("circle", (r,)) or ("box", (w, h)) and height in metres."""

    shape: str
    dims: tuple
    height: float


PART_TYPES = {
    "gear_part": PartType("circle", (0.039,), 0.012),
    "disk_part": PartType("circle", (0.0627,), 0.023),
    "gasket_part": PartType("box", (0.10, 0.10), 0.02),
    "piston_rod_part": PartType("box", (0.16, 0.05), 0.0075),
    "pulley_part": PartType("circle", (0.12,), 0.07),
}


class Place(NamedTuple):
    """Where a part is: kind in BIN, GRIPPER, TRAY, BELT, LOST, FLOOR; index for BIN/TRAY."""

    kind: str
    index: int = -1

    @classmethod
    def bin(cls, k: int) -> "Place":
        return cls("BIN", k)

    @classmethod
    def tray(cls, slot: int) -> "Place":
        return cls("TRAY", slot)

    def __str__(self) -> str:
        return self.kind if self.index < 0 else f"{self.kind}({self.index})"


GRIPPER = Place("GRIPPER")
BELT = Place("BELT")
LOST = Place("LOST")
FLOOR = Place("FLOOR")

# collision layers: parts only touch parts (and walls) of their own layer
_LAYER = {"BELT": 0x1, "BIN": 0x2, "TRAY": 0x4, "FLOOR": 0x8}
_HELD_FILTER = pymunk.ShapeFilter(categories=0, mask=0)


# --------------------------------------------------------------------------- config
@dataclass(frozen=True)
class BinSpec:
    """A bin: ARIAC index, centre, part type and initial count (3 x 3 grid, at most 9)."""

    index: int
    x: float
    y: float
    part_type: str = "gear_part"
    count: int = 9


@dataclass(frozen=True)
class CellConfig:
    """Every parameter of the cell (the seed is passed to :class:`Cell` separately)."""

    # time and solver
    dt: float = 1.0 / 240.0
    iterations: int = 10
    collision_slop: float = 5e-4
    sleep_time: float = 0.5  # seconds at rest before a body sleeps (0: never)
    idle_speed: float = 0.005  # m/s below which a body counts as resting
    # conveyor
    belt_x: float = 1.21
    belt_width: float = 0.65
    belt_speed: float = 0.2
    belt_y_spawn: float = 4.3
    belt_y_detect: float = 0.9
    pick_window_s: float = 16.0
    belt_part_types: tuple = ("gear_part",)
    spawn_jitter_x: float = 0.05
    mu_belt: float = 1.0
    mu_floor: float = 0.5
    part_mass: float = 0.5
    # bins and tray
    bins: tuple = (BinSpec(2, -0.3, -1.15, "gear_part"), BinSpec(3, -0.3, -0.383, "gasket_part"))
    bin_size: float = 0.6
    bin_pitch: float = 0.2
    tray_centre: tuple = (0.3, -3.3)
    tray_size: tuple = (0.5, 0.7)
    tray_grid: tuple = (3, 6)  # columns along x, rows along y
    slot_tolerance: float = 0.03
    # surface heights (z), approach clearance
    z_belt: float = 0.91
    z_bin: float = 0.72
    z_tray: float = 0.75
    z_floor: float = 0.0
    clearance: float = 0.2
    # arm
    rail_x: float = 0.3
    rail_y_min: float = -2.5
    rail_y_max: float = 0.26
    arm_reach: float = 1.2
    z_min: float = 0.0
    z_max: float = 1.6
    home: tuple = (0.6, -0.8, 1.1)
    v_xy: float = 1.4
    a_xy: float = 1.8
    v_z: float = 0.5
    a_z: float = 2.0
    track_tolerance: float = 0.005
    # gripper
    cup_radius: float = 0.05
    grasp_tol_z: float = 0.01
    grasp_max_force: float = 2000.0
    drop_regions: tuple = ()  # ((x_min, y_min, x_max, y_max), ...)

    @property
    def belt_y_wall(self) -> float:
        """y of the deletion wall: reached ``pick_window_s`` after detection."""
        return self.belt_y_detect - self.belt_speed * self.pick_window_s

    def slot_positions(self) -> list:
        """Centres (x, y) of the tray slots, in slot order."""
        cols, rows = self.tray_grid
        (cx, cy), (w, h) = self.tray_centre, self.tray_size
        px, py = w / cols, h / rows
        return [(cx - w / 2 + px * (c + 0.5), cy + h / 2 - py * (r + 0.5))
                for r in range(rows) for c in range(cols)]

    def bin_grid(self, spec: BinSpec) -> list:
        """Initial part centres of a bin, row by row from its +y side."""
        p = self.bin_pitch
        return [(spec.x + p * (c - 1), spec.y + p * (1 - r)) for r in range(3) for c in range(3)]


def periodic_arrivals(period: float, count: int, first: float = 0.0) -> list:
    """Spawn times ``first, first + period, ...`` (``count`` of them)."""
    return [first + i * period for i in range(count)]


# --------------------------------------------------------------------------- motion
class _Ramp:
    """Rest-to-rest trapezoidal (or triangular) profile from x0 to x1."""

    __slots__ = ("x0", "x1", "dist", "sign", "a", "t_acc", "t_total", "v_peak")

    def __init__(self, x0: float, x1: float, v: float, a: float):
        self.x0, self.x1 = x0, x1
        self.dist = abs(x1 - x0)
        self.sign = 1.0 if x1 >= x0 else -1.0
        self.a = a
        if self.dist == 0.0:
            self.t_acc = self.t_total = self.v_peak = 0.0
        elif v * v / a >= self.dist:  # never reaches v
            self.t_acc = math.sqrt(self.dist / a)
            self.t_total, self.v_peak = 2.0 * self.t_acc, a * self.t_acc
        else:
            self.t_acc = v / a
            self.t_total, self.v_peak = self.dist / v + self.t_acc, v

    def at(self, t: float) -> float:
        if t >= self.t_total:
            return self.x1
        if t <= self.t_acc:
            s = 0.5 * self.a * t * t
        elif t <= self.t_total - self.t_acc:
            s = 0.5 * self.a * self.t_acc * self.t_acc + self.v_peak * (t - self.t_acc)
        else:
            r = self.t_total - t
            s = self.dist - 0.5 * self.a * r * r
        return self.x0 + self.sign * s


def _path_ramp(p0, p1, cfg: CellConfig, scale: float) -> _Ramp:
    """Normalised ramp s: 0 -> 1 for a synchronised straight move from p0 to p1."""
    d_xy = math.hypot(p1[0] - p0[0], p1[1] - p0[1])
    d_z = abs(p1[2] - p0[2])
    v = a = math.inf
    if d_xy > 0.0:
        v, a = min(v, cfg.v_xy / d_xy), min(a, cfg.a_xy / d_xy)
    if d_z > 0.0:
        v, a = min(v, cfg.v_z / d_z), min(a, cfg.a_z / d_z)
    if v == math.inf:
        return _Ramp(0.0, 0.0, 1.0, 1.0)
    return _Ramp(0.0, 1.0, v * scale, a * scale * scale)


class Arm:
    """Kinematic TCP on the rail: ``move_to``, ``track``, ``stop``; the caller steps the cell."""

    def __init__(self, cell: "Cell"):
        self._cell = cell
        cfg = self._cfg = cell.config
        self.body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        self.body.position = cfg.home[0], cfg.home[1]
        self.z = float(cfg.home[2])
        self._mode = "idle"  # idle | move | track
        self._k = 0  # steps since the motion (or z ramp) started
        self._ramp = None
        self._p0 = self._p1 = (0.0, 0.0, 0.0)
        self._track_pid = None
        self._z_ramp = None
        self._vel = (0.0, 0.0)
        self._finishing = False
        self._arrived = False

    # ---- commands
    def move_to(self, x: float, y: float, z: float, speed_scale: float = 1.0) -> float:
        """Start a synchronised move to (x, y, z); return its duration in seconds."""
        cfg = self._cfg
        if not self._cell.reachable(x, y):
            raise ValueError(f"target ({x:.3f}, {y:.3f}) is out of the arm's reach")
        if not cfg.z_min <= z <= cfg.z_max:
            raise ValueError(f"target z {z:.3f} outside [{cfg.z_min}, {cfg.z_max}]")
        if speed_scale <= 0.0:
            raise ValueError("speed_scale must be > 0")
        self._p0 = self.pose
        self._p1 = (float(x), float(y), float(z))
        self._ramp = _path_ramp(self._p0, self._p1, cfg, speed_scale)
        self._track_pid = None
        self._start("move")
        return self._ramp.t_total

    def track(self, part_id: int, z: float | None = None) -> None:
        """Follow part ``part_id`` in (x, y) every step; move z to ``z`` (None: keep target)."""
        if self._cell.place_of(part_id) in (GRIPPER, LOST):
            raise ValueError(f"part {part_id} cannot be tracked from {self._cell.place_of(part_id)}")
        z_goal = self._z_goal() if z is None else float(z)
        if not self._cfg.z_min <= z_goal <= self._cfg.z_max:
            raise ValueError(f"target z {z_goal:.3f} outside [{self._cfg.z_min}, {self._cfg.z_max}]")
        if self._mode != "track":
            self._vel = (0.0, 0.0)
        self._track_pid = part_id
        self._z_ramp = _Ramp(self.z, z_goal, self._cfg.v_z, self._cfg.a_z)
        self._start("track")

    def stop(self) -> None:
        """Stop at once and hold the current pose (the target is abandoned)."""
        self._mode = "idle"
        self._track_pid = None
        self._finishing = False
        self._vel = (0.0, 0.0)
        self.body.velocity = (0.0, 0.0)
        self._arrived = False

    # ---- state
    @property
    def pose(self) -> tuple:
        p = self.body.position
        return (p.x, p.y, self.z)

    @property
    def arrived(self) -> bool:
        """True once the last move finished, or while the tracked part is under the TCP."""
        return self._arrived

    @property
    def moving(self) -> bool:
        """True while a move runs or a part is tracked."""
        return self._mode != "idle"

    @property
    def tracking(self) -> int | None:
        """Id of the tracked part, or None."""
        return self._track_pid

    @property
    def carriage_y(self) -> float:
        return min(max(self.body.position.y, self._cfg.rail_y_min), self._cfg.rail_y_max)

    @property
    def time_remaining(self) -> float:
        """Seconds left in the current move (0 when idle or tracking)."""
        if self._mode != "move":
            return 0.0
        return max(0.0, self._ramp.t_total - self._k * self._cfg.dt)

    def duration(self, p0, p1, speed_scale: float = 1.0) -> float:
        """Duration of a rest-to-rest move from pose p0 to pose p1 (for planning)."""
        return _path_ramp(p0, p1, self._cfg, speed_scale).t_total

    # ---- stepping (called by Cell)
    def _start(self, mode: str) -> None:
        self._mode = mode
        self._k = 0
        self._finishing = False
        self._arrived = False

    def _z_goal(self) -> float:
        if self._mode == "move":
            return self._p1[2]
        if self._mode == "track":
            return self._z_ramp.x1
        return self.z

    def _pre_step(self, dt: float) -> None:
        if self._mode == "move":
            self._pre_move(dt)
        elif self._mode == "track":
            self._pre_track(dt)

    def _pre_move(self, dt: float) -> None:
        self._k += 1
        t = self._k * dt
        s = self._ramp.at(t)
        (x0, y0, z0), (x1, y1, z1) = self._p0, self._p1
        p = self.body.position
        self.body.velocity = ((x0 + (x1 - x0) * s - p.x) / dt, (y0 + (y1 - y0) * s - p.y) / dt)
        self.z = z0 + (z1 - z0) * s
        self._finishing = t >= self._ramp.t_total

    def _pre_track(self, dt: float) -> None:
        self._k += 1
        self.z = self._z_ramp.at(self._k * dt)
        vx, vy = self._pursuit_velocity(dt)
        dvx, dvy = vx - self._vel[0], vy - self._vel[1]
        dv, dv_max = math.hypot(dvx, dvy), 2.0 * self._cfg.a_xy * dt
        if dv > dv_max:  # acceleration limit
            vx, vy = self._vel[0] + dvx * dv_max / dv, self._vel[1] + dvy * dv_max / dv
        self._vel = (vx, vy)
        self.body.velocity = self._vel

    def _pursuit_velocity(self, dt: float) -> tuple:
        """Part velocity (feed-forward) plus a braking-limited approach to its position."""
        part = self._cell._parts[self._track_pid].body
        pp, pv = part.position, part.velocity
        cx, cy = self._cell.clamp_to_reach(pp.x, pp.y)
        fx, fy = (pv.x, pv.y) if (cx, cy) == (pp.x, pp.y) else (0.0, 0.0)
        p = self.body.position
        ex, ey = cx - p.x, cy - p.y
        dist = math.hypot(ex, ey)
        if dist == 0.0:
            return (fx, fy)
        speed = min(self._cfg.v_xy, math.sqrt(2.0 * self._cfg.a_xy * dist), dist / dt)
        return (fx + ex / dist * speed, fy + ey / dist * speed)

    def _post_step(self) -> None:
        if self._mode == "move" and self._finishing:
            self.body.position = self._p1[0], self._p1[1]
            self.body.velocity = (0.0, 0.0)
            self.z = self._p1[2]
            self._mode = "idle"
            self._arrived = True
        elif self._mode == "track":
            self._post_track()

    def _post_track(self) -> None:
        place = self._cell.place_of(self._track_pid)
        if place == GRIPPER or place == LOST:
            self.stop()  # tracking ends when the part is grasped or deleted
            return
        pp = self._cell._parts[self._track_pid].body.position
        p = self.body.position
        self._arrived = (math.hypot(pp.x - p.x, pp.y - p.y) <= self._cfg.track_tolerance
                        and self._k * self._cfg.dt >= self._z_ramp.t_total)


class Gripper:
    """Vacuum gripper on the TCP: ``enable``/``disable``; ``attached_part`` is an id or None."""

    def __init__(self, cell: "Cell"):
        self._cell = cell
        self.enabled = False
        self.attached_part = None
        self.drops = 0
        self._armed = False  # False after a drop until the next enable()

    def enable(self) -> None:
        self.enabled = True
        self._armed = True

    def disable(self) -> None:
        """Switch suction off; a held part is released onto whatever is under it."""
        self.enabled = False
        self._armed = False
        if self.attached_part is not None:
            self._cell._release(self._cell._parts[self.attached_part])

    def _post_step(self) -> None:
        cell = self._cell
        if self.attached_part is not None:
            if cell.config.drop_regions and cell._in_drop_region():
                self.drops += 1
                self._armed = False
                cell._release(cell._parts[self.attached_part], FLOOR)
        elif self.enabled and self._armed and cell.arm.z <= cell._max_grasp_z:
            x, y, z = cell.arm.pose
            part = cell._part_under_cup(x, y, z)
            if part is not None:
                cell._attach(part)


# --------------------------------------------------------------------------- cell
class _Part:
    __slots__ = ("id", "ptype", "type_name", "body", "shape", "place", "joints", "detected")

    def __init__(self, pid, type_name, body, shape):
        self.id, self.type_name, self.ptype = pid, type_name, PART_TYPES[type_name]
        self.body, self.shape = body, shape
        self.place = None
        self.joints = ()
        self.detected = False


class Cell:
    """The kitting cell. ``Cell(config, seed)``, then command ``arm``/``gripper`` and ``step``."""

    def __init__(self, config: CellConfig | None = None, seed: int = 0,
                 arrivals: Sequence[float] = ()):
        self.config = cfg = config or CellConfig()
        self.rng = random.Random(seed)
        self._check_geometry()
        self.space = pymunk.Space()
        self.space.iterations = cfg.iterations
        self.space.collision_slop = cfg.collision_slop
        if cfg.sleep_time > 0:  # resting bin and tray parts sleep (about half the physics cost)
            self.space.sleep_time_threshold = cfg.sleep_time
            self.space.idle_speed_threshold = cfg.idle_speed
        self.space.gravity = (0.0, 0.0)
        self._steps = 0
        self._parts: dict[int, _Part] = {}
        self._members: dict[Place, list] = {}
        self._slots = cfg.slot_positions()
        self._pending: list = []
        self._next_arrival = 0
        self.detections: list = []  # (part_id, time)
        self.events: list = []  # (time, part_id, from_place, to_place)
        self._layout = None
        self._belt = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        self._belt.velocity = (0.0, -cfg.belt_speed)
        self.space.add(self._belt)
        self.arm = Arm(self)
        self.gripper = Gripper(self)
        self.space.add(self.arm.body)
        self._max_grasp_z = max(cfg.z_belt, cfg.z_bin, cfg.z_tray, cfg.z_floor) + max(
            t.height for t in PART_TYPES.values()) + cfg.grasp_tol_z
        self._build_bins()
        self.schedule_arrivals(arrivals)

    # ---- construction
    def _check_geometry(self) -> None:
        cfg = self.config
        if cfg.rail_y_max - cfg.rail_y_min > RAIL_TRAVEL_LIMIT + _EPS:
            raise ValueError(f"rail travel {cfg.rail_y_max - cfg.rail_y_min:.3f} m exceeds "
                             f"ARIAC's {RAIL_TRAVEL_LIMIT} m")
        points = cfg.slot_positions() + [cfg.home[:2]]
        for spec in cfg.bins:
            points += cfg.bin_grid(spec)
        for x in (cfg.belt_x - cfg.spawn_jitter_x, cfg.belt_x + cfg.spawn_jitter_x):
            points += [(x, cfg.belt_y_detect), (x, cfg.belt_y_wall)]
        for x, y in points:
            if not self.reachable(x, y):
                raise ValueError(f"({x:.3f}, {y:.3f}) is out of the arm's reach: "
                                 "move the rail limits, the pick window or the layout")

    def _build_bins(self) -> None:
        cfg = self.config
        for spec in cfg.bins:
            if spec.count > 9:
                raise ValueError(f"bin {spec.index} holds at most 9 parts")
            self._add_walls(spec.x, spec.y, cfg.bin_size, cfg.bin_size, _LAYER["BIN"])
            for x, y in cfg.bin_grid(spec)[:spec.count]:
                self._new_part(spec.part_type, x, y, 0.0, Place.bin(spec.index))

    def _add_walls(self, cx, cy, w, h, layer) -> None:
        x0, x1, y0, y1 = cx - w / 2, cx + w / 2, cy - h / 2, cy + h / 2
        corners = [(x0, y0), (x1, y0), (x1, y1), (x0, y1)]
        for i in range(4):
            seg = pymunk.Segment(self.space.static_body, corners[i], corners[(i + 1) % 4], 0.005)
            seg.filter = pymunk.ShapeFilter(categories=layer, mask=layer)
            self.space.add(seg)

    def _new_part(self, type_name: str, x: float, y: float, angle: float, place: Place) -> int:
        ptype = PART_TYPES[type_name]
        body = pymunk.Body()
        body.position = (x, y)
        body.angle = angle
        if ptype.shape == "circle":
            shape = pymunk.Circle(body, ptype.dims[0])
        else:
            shape = pymunk.Poly.create_box(body, ptype.dims, 0.001)
        shape.mass = self.config.part_mass
        shape.friction = 0.5
        self.space.add(body, shape)
        part = _Part(len(self._parts), type_name, body, shape)
        self._parts[part.id] = part
        self._land(part, place)
        return part.id

    # ---- arrivals
    def schedule_arrivals(self, times: Sequence[float]) -> None:
        """Add conveyor spawn times (seconds of simulated time)."""
        rest = self._pending[self._next_arrival:] + [float(t) for t in times]
        self._pending = sorted(rest)
        self._next_arrival = 0

    def spawn_conveyor_part(self, part_type: str | None = None, y: float | None = None) -> int:
        """Put a new part on the belt at ``y`` (default ``belt_y_spawn``) now; return its id."""
        cfg = self.config
        types = cfg.belt_part_types
        chosen = types[self.rng.randrange(len(types))]
        x = cfg.belt_x + self.rng.uniform(-cfg.spawn_jitter_x, cfg.spawn_jitter_x)
        angle = self.rng.uniform(0.0, 2.0 * math.pi)
        return self._new_part(part_type or chosen, x, cfg.belt_y_spawn if y is None else y, angle, BELT)

    # ---- stepping
    @property
    def time(self) -> float:
        return self._steps * self.config.dt

    @property
    def steps(self) -> int:
        return self._steps

    def step(self, n: int = 1) -> None:
        """Advance ``n`` fixed steps of ``config.dt``."""
        dt = self.config.dt
        space_step = self.space.step
        arm, gripper = self.arm, self.gripper
        for _ in range(n):
            while (self._next_arrival < len(self._pending)
                   and self._pending[self._next_arrival] <= self._steps * dt):
                self._next_arrival += 1
                self.spawn_conveyor_part()
            arm._pre_step(dt)
            space_step(dt)
            self._steps += 1
            arm._post_step()
            gripper._post_step()
            self._belt_bookkeeping()

    def _belt_bookkeeping(self) -> None:
        belt = self._members.get(BELT)
        if not belt:
            return
        cfg = self.config
        half = cfg.belt_width / 2
        for pid in list(belt):
            part = self._parts[pid]
            pos = part.body.position
            if not part.detected and pos.y <= cfg.belt_y_detect:
                part.detected = True
                self.detections.append((pid, self.time))
            if pos.y <= cfg.belt_y_wall:
                self._delete(part)
            elif abs(pos.x - cfg.belt_x) > half:
                self._land(part, FLOOR)  # pushed off the side of the belt

    # ---- place changes
    def _set_place(self, part: _Part, place: Place) -> None:
        old = part.place
        if old is not None:
            self._members[old].remove(part.id)
        self._members.setdefault(place, []).append(part.id)
        part.place = place
        self.events.append((self.time, part.id, old, place))

    def _unsupport(self, part: _Part) -> None:
        if part.joints:
            self.space.remove(*part.joints)
            part.joints = ()

    def _support(self, part: _Part, support: pymunk.Body, mu: float) -> None:
        f = mu * self.config.part_mass * G
        pj = pymunk.PivotJoint(support, part.body, support.world_to_local(part.body.position), (0, 0))
        gj = pymunk.GearJoint(support, part.body, part.body.angle - support.angle, 1.0)
        pj.max_bias = gj.max_bias = 0.0
        pj.max_force, gj.max_force = f, f * 0.03  # torque ~ friction over a 3 cm lever
        self.space.add(pj, gj)
        part.joints = (pj, gj)

    def _land(self, part: _Part, place: Place) -> None:
        """Rest ``part`` on the support of ``place`` (BIN, TRAY, BELT or FLOOR)."""
        self._unsupport(part)
        on_belt = place == BELT
        support = self._belt if on_belt else self.space.static_body
        layer = _LAYER[place.kind]
        part.shape.filter = pymunk.ShapeFilter(categories=layer, mask=layer)
        part.body.velocity = support.velocity
        part.body.angular_velocity = 0.0
        self._support(part, support, self.config.mu_belt if on_belt else self.config.mu_floor)
        self._set_place(part, place)

    def _attach(self, part: _Part) -> None:
        self._unsupport(part)
        tcp = self.arm.body
        offset = part.body.position - tcp.position
        pj = pymunk.PivotJoint(tcp, part.body, offset, (0, 0))
        gj = pymunk.GearJoint(tcp, part.body, part.body.angle - tcp.angle, 1.0)
        pj.max_force = self.config.grasp_max_force
        gj.max_force = 0.05 * self.config.grasp_max_force
        part.shape.filter = _HELD_FILTER
        self.space.add(pj, gj)
        part.joints = (pj, gj)
        self.gripper.attached_part = part.id
        self._set_place(part, GRIPPER)

    def _release(self, part: _Part, place: Place | None = None) -> None:
        self.gripper.attached_part = None
        pos = part.body.position
        self._land(part, place or self.landing_place(pos.x, pos.y))

    def _delete(self, part: _Part) -> None:
        self._unsupport(part)
        self.space.remove(part.shape, part.body)
        self._set_place(part, LOST)

    # ---- geometry queries
    def reachable(self, x: float, y: float) -> bool:
        """True if the TCP can be at (x, y) from some carriage position."""
        cfg = self.config
        cy = min(max(y, cfg.rail_y_min), cfg.rail_y_max)
        return math.hypot(x - cfg.rail_x, y - cy) <= cfg.arm_reach + _EPS

    def clamp_to_reach(self, x: float, y: float) -> tuple:
        """The nearest reachable point to (x, y) (itself if reachable)."""
        cfg = self.config
        cy = min(max(y, cfg.rail_y_min), cfg.rail_y_max)
        dx, dy = x - cfg.rail_x, y - cy
        d = math.hypot(dx, dy)
        if d <= cfg.arm_reach:
            return (x, y)
        k = cfg.arm_reach / d
        return (cfg.rail_x + dx * k, cy + dy * k)

    def landing_place(self, x: float, y: float) -> Place:
        """Where a part released with its centre at (x, y) would end up."""
        cfg = self.config
        (tx, ty), (tw, th) = cfg.tray_centre, cfg.tray_size
        if abs(x - tx) <= tw / 2 and abs(y - ty) <= th / 2:
            slot = self._free_slot_near(x, y)
            return FLOOR if slot is None else Place.tray(slot)
        half = cfg.bin_size / 2
        for spec in cfg.bins:
            if abs(x - spec.x) <= half and abs(y - spec.y) <= half:
                return Place.bin(spec.index)
        if abs(x - cfg.belt_x) <= cfg.belt_width / 2 and cfg.belt_y_wall < y <= cfg.belt_y_spawn + 0.5:
            return BELT
        return FLOOR

    def _free_slot_near(self, x: float, y: float) -> int | None:
        best, best_d = None, self.config.slot_tolerance
        for slot, (sx, sy) in enumerate(self._slots):
            d = math.hypot(x - sx, y - sy)
            if d <= best_d and not self._members.get(Place.tray(slot)):
                best, best_d = slot, d
        return best

    def _in_drop_region(self) -> bool:
        p = self.arm.body.position
        return any(x0 <= p.x <= x1 and y0 <= p.y <= y1 for x0, y0, x1, y1 in self.config.drop_regions)

    def _top_z(self, part: _Part) -> float:
        cfg = self.config
        if part.place == GRIPPER:
            return self.arm.z
        base = {"BELT": cfg.z_belt, "BIN": cfg.z_bin, "TRAY": cfg.z_tray}.get(part.place.kind, cfg.z_floor)
        return base + part.ptype.height

    def _part_under_cup(self, x: float, y: float, z: float) -> _Part | None:
        cfg = self.config
        best, best_d = None, cfg.cup_radius
        for part in self._parts.values():
            if part.place == LOST or part.place == GRIPPER or z > self._top_z(part) + cfg.grasp_tol_z:
                continue
            pos = part.body.position
            d = math.hypot(pos.x - x, pos.y - y)
            if d < best_d or (best is None and d <= best_d):
                best, best_d = part, d
        return best

    # ---- observations
    @property
    def detect_delay_s(self) -> float:
        """Belt travel time from spawn to detection."""
        cfg = self.config
        return (cfg.belt_y_spawn - cfg.belt_y_detect) / cfg.belt_speed

    @property
    def part_ids(self) -> list:
        return list(self._parts)

    def place_of(self, part_id: int) -> Place:
        return self._parts[part_id].place

    def part_type(self, part_id: int) -> str:
        return self._parts[part_id].type_name

    def position(self, part_id: int) -> tuple:
        """(x, y, angle) of a part (LOST parts keep their last pose)."""
        b = self._parts[part_id].body
        return (b.position.x, b.position.y, b.angle)

    def parts_in(self, place: Place) -> list:
        return list(self._members.get(place, ()))

    def belt_parts(self) -> list:
        """[(part_id, x, y)] of BELT parts, the next to reach the wall first."""
        rows = [(pid,) + self.position(pid)[:2] for pid in self._members.get(BELT, ())]
        return sorted(rows, key=lambda r: (r[2], r[0]))

    def time_to_wall(self, part_id: int) -> float:
        """Seconds until a BELT part reaches the deletion wall (at belt speed)."""
        cfg = self.config
        return (self.position(part_id)[1] - cfg.belt_y_wall) / cfg.belt_speed

    @property
    def lost_parts(self) -> list:
        return self.parts_in(LOST)

    @property
    def tray_count(self) -> int:
        return sum(len(self._members.get(Place.tray(s), ())) for s in range(len(self._slots)))

    def bin_count(self, k: int) -> int:
        return len(self._members.get(Place.bin(k), ()))

    def next_bin_part(self, k: int) -> int | None:
        """The first part (in insertion order) in bin k, or None."""
        ids = self._members.get(Place.bin(k))
        return ids[0] if ids else None

    def free_slots(self) -> list:
        return [s for s in range(len(self._slots)) if not self._members.get(Place.tray(s))]

    def slot_position(self, slot: int) -> tuple:
        return self._slots[slot]

    # ---- named poses (x, y, z) for the controller
    def _held_height(self) -> float:
        pid = self.gripper.attached_part
        return 0.0 if pid is None else self._parts[pid].ptype.height

    def pose_at(self, target) -> tuple:
        """Contact pose: on top of a part (id), or a held part touching tray slot / bin (Place)."""
        cfg = self.config
        if isinstance(target, Place):
            if target.kind == "TRAY":
                x, y = self._slots[target.index]
                return (x, y, cfg.z_tray + self._held_height())
            if target.kind == "BIN":
                spec = self._bin_spec(target.index)
                return (spec.x, spec.y, cfg.z_bin + self._held_height())
            raise ValueError(f"no pose for {target}")
        part = self._parts[target]
        x, y, _ = self.position(target)
        return (x, y, self._top_z(part))

    def pose_above(self, target, clearance: float | None = None) -> tuple:
        """``pose_at(target)`` raised by ``clearance`` (default ``config.clearance``)."""
        x, y, z = self.pose_at(target)
        return (x, y, z + (self.config.clearance if clearance is None else clearance))

    def bin_approach(self, k: int) -> tuple:
        spec = self._bin_spec(k)
        return (spec.x, spec.y, self.config.z_bin + 0.05 + self.config.clearance)

    def tray_approach(self) -> tuple:
        cfg = self.config
        return (cfg.tray_centre[0], cfg.tray_centre[1], cfg.z_tray + 0.05 + cfg.clearance)

    def conveyor_approach(self, y: float | None = None) -> tuple:
        """Above the belt centre line at ``y`` (default: middle of the pick window)."""
        cfg = self.config
        if y is None:
            y = 0.5 * (cfg.belt_y_detect + cfg.belt_y_wall)
        x, y = self.clamp_to_reach(cfg.belt_x, y)
        return (x, y, cfg.z_belt + 0.05 + cfg.clearance)

    def _bin_spec(self, k: int) -> BinSpec:
        for spec in self.config.bins:
            if spec.index == k:
                return spec
        raise KeyError(f"no bin {k} in this cell")

    # ---- invariant, digest, snapshot
    def check_invariant(self) -> None:
        """Raise AssertionError if a part is not in exactly one consistent place."""
        seen = {}
        for place, ids in self._members.items():
            for pid in ids:
                assert pid not in seen, f"part {pid} is in both {seen[pid]} and {place}"
                seen[pid] = place
                assert self._parts[pid].place == place, (
                    f"part {pid} is listed in {place} but records {self._parts[pid].place}")
        assert len(seen) == len(self._parts), (
            f"parts without a place: {[p for p in self._parts if p not in seen]}")
        held = self._members.get(GRIPPER, [])
        assert held == ([] if self.gripper.attached_part is None else [self.gripper.attached_part]), (
            f"GRIPPER holds {held} but the gripper reports {self.gripper.attached_part}")
        for part in self._parts.values():
            self._check_part(part)

    def _check_part(self, part: _Part) -> None:
        cfg, place, pid = self.config, part.place, part.id
        in_space = part.body.space is self.space
        assert in_space == (place != LOST), f"part {pid} in {place} but in_space={in_space}"
        if place == LOST:
            assert not part.joints, f"LOST part {pid} still has joints"
            return
        assert len(part.joints) == 2, f"part {pid} in {place} has {len(part.joints)} joints"
        support = part.joints[0].a
        if place == GRIPPER:
            assert support is self.arm.body and part.shape.filter.mask == 0, (
                f"held part {pid} is not jointed to the TCP with collisions off")
            return
        want = self._belt if place == BELT else self.space.static_body
        assert support is want, f"part {pid} in {place} rests on the wrong support"
        pos = part.body.position
        if place.kind == "TRAY":
            assert len(self._members[place]) == 1, f"tray slot {place.index} holds several parts"
        elif place.kind == "BIN":
            spec, lim = self._bin_spec(place.index), cfg.bin_size / 2 + 0.01
            assert abs(pos.x - spec.x) <= lim and abs(pos.y - spec.y) <= lim, (
                f"part {pid} in {place} is outside the bin at ({pos.x:.3f}, {pos.y:.3f})")
        elif place == BELT:
            assert abs(pos.x - cfg.belt_x) <= cfg.belt_width / 2 and pos.y > cfg.belt_y_wall, (
                f"BELT part {pid} is off the belt at ({pos.x:.3f}, {pos.y:.3f})")

    def digest(self) -> str:
        """sha256 over float.hex of the arm pose and of every part's pose, velocity and place."""
        h = hashlib.sha256()
        b = self.arm.body
        vals = [b.position.x, b.position.y, b.velocity.x, b.velocity.y, self.arm.z]
        h.update(f"{self._steps}|{self.gripper.enabled}|{self.gripper.attached_part}|".encode())
        for part in self._parts.values():
            pb = part.body
            vals += [pb.position.x, pb.position.y, pb.angle, pb.velocity.x, pb.velocity.y]
            h.update(f"{part.id}:{part.place}|".encode())
        h.update(",".join(float(v).hex() for v in vals).encode())
        return h.hexdigest()

    def layout(self) -> dict:
        """Static geometry for drawing (belt, bins, tray slots, rail, drop regions, part types)."""
        cfg = self.config
        return {
            "belt": {"x": cfg.belt_x, "width": cfg.belt_width, "y_spawn": cfg.belt_y_spawn,
                     "y_detect": cfg.belt_y_detect, "y_wall": cfg.belt_y_wall},
            "bins": [(s.index, s.x, s.y, cfg.bin_size) for s in cfg.bins],
            "tray": {"centre": cfg.tray_centre, "size": cfg.tray_size, "grid": cfg.tray_grid,
                     "slots": list(self._slots)},
            "rail": {"x": cfg.rail_x, "y_min": cfg.rail_y_min, "y_max": cfg.rail_y_max,
                     "reach": cfg.arm_reach},
            "cup_radius": cfg.cup_radius,
            "drop_regions": list(cfg.drop_regions),
            "part_types": {k: (v.shape, v.dims) for k, v in PART_TYPES.items()},
        }

    def snapshot(self) -> dict:
        """Plain-data picture of the cell now (for rendering and logs)."""
        if self._layout is None:
            self._layout = self.layout()
        x, y, z = self.arm.pose
        return {
            "time": self.time, "step": self._steps, "layout": self._layout,
            "tcp": (x, y, z), "carriage_y": self.arm.carriage_y,
            "gripper_enabled": self.gripper.enabled, "attached": self.gripper.attached_part,
            "parts": [(p.id, p.type_name) + self.position(p.id) + (str(p.place),)
                      for p in self._parts.values()],
            "tray_count": self.tray_count, "lost_count": len(self.lost_parts),
            "detections": len(self.detections),
        }
