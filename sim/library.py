"""The primitive library: what a robot in a scene can do, by name, and the binding that
maps a model's primitives onto it.

Each library primitive has parameters and a fixed set of outcomes it can produce (which
may depend on its arguments); the scene's ``bind`` section maps each model primitive,
per call site, to one of them::

    bind:
      move:    {primitive: move_to, args: {frame: "{area}_{pose}", speed: 0.5}}
      grasp:   {primitive: grip, args: {wait: true}}
      gripper: [{when: {"on": false}, primitive: release}, {when: {"on": true}, primitive: grip}]

``{name}`` in an argument is the model argument of that call site (a whole-string
``"{on}"`` keeps the argument's type). ``outcomes`` maps a library outcome to a model
outcome name; by default each library outcome maps to the site's only outcome with the
same status. Before a trial starts, ``bind_model`` refuses: an unknown library primitive,
an unknown or missing argument, an unknown frame/area/door/robot, a target out of reach,
a model primitive with several outcomes and no binding, and a library outcome the model
did not declare (``grip`` without ``wait`` can miss: the model's primitive must have a
failure outcome). Custom primitives come from ``python: package.module:function`` (an
explicit choice: the function is imported and called): ``function(world, robot, args)``
returns an object with ``tick() -> "running" | "success" | "failure"`` (optional
``halt()``); its ``outcomes`` attribute, if any, lists the statuses it can return.

The library (outcome names in brackets, status first):

================  ============================  ========================================
primitive         arguments                     outcomes
================  ============================  ========================================
move_to           frame, speed=1.0              running (moving), success (arrived),
                                                failure (blocked) when a door may be shut
carry_to          frame, speed=1.0              like move_to, and failure (dropped) when
                                                the part held at the start is lost
move_to_part      area, speed=1.0               running (moving), success (arrived): over
                                                the area's first part (its centre if empty)
grip              wait=false                    running (closing, fingers or wait),
                                                success (gripped), failure (missed)
                                                unless wait
release                                         success (released)
gripper           on                            grip (on) or release (off)
wait              seconds                       running (waiting), success (done)
detect            region                        success (seen), failure (nothing)
wait_for          region                        running (waiting), success (seen)
open_door         door                          running (opening), success (open)
close_door        door                          running (closing), success (closed)
succeed                                         success (done)
================  ============================  ========================================

A region argument names a sensor or an area. Sensor events are queued and given to the
model one per tick, oldest first, when the model's guard allows (later ones wait). An
environment choice (exactly one option each tick) must have exactly one option no sensor
raises: it is reported on every tick where no sensor event chose another option.
"""
from __future__ import annotations

import re

from btfsm.errors import DomainError, ModelError
from btfsm.status import FAILURE, RUNNING, SUCCESS

from .protocol import Binding
from .scene import incident_text

__all__ = ["LIBRARY", "bind_model", "SceneBinding"]

_R, _S, _F = int(RUNNING), int(SUCCESS), int(FAILURE)


class _Lib:
    """A library primitive: parameters {name: (kind, default)}; outcomes(scene, robot, args)
    -> [(status, name)]; start(world, robot, args) -> activity with tick() and halt()."""

    def __init__(self, name, params, outcomes, start):
        self.name, self.params, self.outcomes, self.start = name, params, outcomes, start


class _Act:
    __slots__ = ("tick", "halt")

    def __init__(self, tick, halt=None):
        self.tick, self.halt = tick, halt or (lambda: None)


def _move_out(scene, robot, a):
    p = a["frame"]
    outs = [(_R, "moving"), (_S, "arrived")]
    if any(_in(d["region"], p) for d in scene.doors.values()):
        outs.append((_F, "blocked"))
    return outs


def _in(r, p):
    return r[0] <= p[0] <= r[2] and r[1] <= p[1] <= r[3]


def _move(world, robot, a):
    if not world.move_to(robot, a["frame"], a["speed"]):
        return _Act(lambda: "blocked")
    r = world.robots[robot]
    return _Act(lambda: "blocked" if r.blocked else "moving" if r.moving else "arrived",
                lambda: world.stop(robot))


def _carry_out(scene, robot, a):
    return _move_out(scene, robot, a) + [(_F, "dropped")]


def _carry(world, robot, a):
    """``move_to`` that fails with ``dropped`` when the part held at its start is no longer
    held (it slipped, or a fault region took it): the model learns the drop."""
    r = world.robots[robot]
    held = r.holding
    move = _move(world, robot, a)

    def tick():
        if held is not None and r.holding != held:
            world.stop(robot)
            return "dropped"
        return move.tick()
    return _Act(tick, move.halt)


def _move_part(world, robot, a):
    ids = world.parts_in(world.area_place(a["area"]))
    if ids:
        p = world.parts[ids[0]]
        target = (p.x, p.y)
    else:
        r = world.scene.areas[a["area"]]["region"]
        target = ((r[0] + r[2]) / 2, (r[1] + r[3]) / 2)
    return _move(world, robot, {"frame": target, "speed": a["speed"]})


def _move_part_out(scene, robot, a):
    region = scene.areas[a["area"]]["region"]
    for corner in ((region[0], region[1]), (region[0], region[3]), (region[2], region[1]), (region[2], region[3])):
        if not scene.reachable(robot, corner):
            raise scene.error("", f"area '{a['area']}' is not entirely within the reach of robot '{robot}'")
    return _move_out(scene, robot, {"frame": ((region[0] + region[2]) / 2, (region[1] + region[3]) / 2)})


def _grip_out(scene, robot, a):
    closing = a["wait"] or scene.robots[robot]["gripper"] == "fingers"
    return ([(_R, "closing")] if closing else []) + [(_S, "gripped")] + ([] if a["wait"] else [(_F, "missed")])


def _grip(world, robot, a):
    r = world.robots[robot]
    if r.holding is not None:
        return _Act(lambda: "gripped")
    if r.spec["gripper"] == "vacuum":
        if world.attach(robot):
            return _Act(lambda: "gripped")
        if not a["wait"]:
            return _Act(lambda: "missed")
    world.grip(robot)  # fingers start closing; a waiting vacuum takes the next part under it

    def tick():
        if r.holding is not None:
            return "gripped"
        if r.closing == 0 and not a["wait"]:
            world.release(robot)
            return "missed"
        return "closing"

    return _Act(tick, lambda: world.release(robot) if r.holding is None else None)


def _release(world, robot, a):
    world.release(robot)
    return _Act(lambda: "released")


def _gripper_out(scene, robot, a):
    return _grip_out(scene, robot, {"wait": False}) if a["on"] else [(_S, "released")]


def _gripper(world, robot, a):
    return _grip(world, robot, {"wait": False}) if a["on"] else _release(world, robot, a)


def _wait(world, robot, a):
    end = world.time + a["seconds"] - 1e-9
    return _Act(lambda: "done" if world.time >= end else "waiting")


def _region(world, name):
    sc = world.scene
    if name in sc.sensors:
        return lambda: len(world.inside[name]) > 0
    return lambda: world.count(name) > 0


def _detect(world, robot, a):
    seen = _region(world, a["region"])
    return _Act(lambda: "seen" if seen() else "nothing")


def _wait_for(world, robot, a):
    seen = _region(world, a["region"])
    return _Act(lambda: "seen" if seen() else "waiting")


def _door(open_):
    def start(world, robot, a):
        d = a["door"]
        world.set_door(d, open_)
        want = 1.0 if open_ else 0.0
        region = world.scene.doors[d]["region"]

        def tick():
            if not open_ and world.tool_in(region):
                world.set_door(d, True)  # never close on the tool: hold it open and wait
                return "closing"
            world.set_door(d, open_)
            return ("open" if open_ else "closed") if world.doors[d] == want else ("opening" if open_ else "closing")
        return _Act(tick)
    return start


LIBRARY = {lib.name: lib for lib in (
    _Lib("move_to", {"frame": ("point", None), "speed": ("number", 1.0)}, _move_out, _move),
    _Lib("carry_to", {"frame": ("point", None), "speed": ("number", 1.0)}, _carry_out, _carry),
    _Lib("move_to_part", {"area": ("area", None), "speed": ("number", 1.0)}, _move_part_out, _move_part),
    _Lib("grip", {"wait": ("bool", False)}, _grip_out, _grip),
    _Lib("release", {}, lambda s, r, a: [(_S, "released")], _release),
    _Lib("gripper", {"on": ("bool", None)}, _gripper_out, _gripper),
    _Lib("wait", {"seconds": ("number", None)}, lambda s, r, a: [(_R, "waiting"), (_S, "done")], _wait),
    _Lib("detect", {"region": ("region", None)}, lambda s, r, a: [(_S, "seen"), (_F, "nothing")], _detect),
    _Lib("wait_for", {"region": ("region", None)}, lambda s, r, a: [(_R, "waiting"), (_S, "seen")], _wait_for),
    _Lib("open_door", {"door": ("door", None)}, lambda s, r, a: [(_R, "opening"), (_S, "open")], _door(True)),
    _Lib("close_door", {"door": ("door", None)}, lambda s, r, a: [(_R, "closing"), (_S, "closed")], _door(False)),
    _Lib("succeed", {}, lambda s, r, a: [(_S, "done")], lambda w, r, a: _Act(lambda: "done")),
)}

_STATUS_NAME = {_R: "running", _S: "success", _F: "failure"}
_PLACEHOLDER = re.compile(r"\{([A-Za-z_][A-Za-z0-9_]*)\}")


def _fill(value, site_args, where, scene):
    """Substitute ``{arg}`` placeholders with the call site's model arguments."""
    if not isinstance(value, str):
        return value
    m = _PLACEHOLDER.fullmatch(value)
    if m:
        if m.group(1) not in site_args:
            raise scene.error(where, f"'{{{m.group(1)}}}' is not an argument of this call site (it has: "
                                     f"{', '.join(sorted(site_args)) or 'none'})")
        return site_args[m.group(1)]

    def sub(mm):
        if mm.group(1) not in site_args:
            raise scene.error(where, f"'{{{mm.group(1)}}}' is not an argument of this call site (it has: "
                                     f"{', '.join(sorted(site_args)) or 'none'})")
        return str(site_args[mm.group(1)])
    return _PLACEHOLDER.sub(sub, value)


def _coerce(scene, robot, kind, value, where):
    if kind == "point":
        p = scene.point(value, where) if isinstance(value, str) else (
            scene.point(value, where) if isinstance(value, (list, tuple)) and len(value) == 2 else None)
        if p is None:
            raise scene.error(where, f"expected a frame name or [x, y], got {value!r}")
        if not scene.reachable(robot, p):
            what = f"frame '{value}' at" if isinstance(value, str) else "point"
            raise scene.error(where, f"{what} ({p[0]:g}, {p[1]:g}) is out of the reach of robot '{robot}'")
        return p
    if kind == "number":
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
            raise scene.error(where, f"expected a number > 0, got {value!r}")
        return float(value)
    if kind == "bool":
        if not isinstance(value, bool):
            raise scene.error(where, f"expected true or false, got {value!r}")
        return value
    table = {"region": {**scene.sensors, **scene.areas}, "door": scene.doors, "area": scene.areas}[kind]
    if value not in table:
        raise scene.error(where, f"no {'sensor or area' if kind == 'region' else kind} named {value!r} "
                                 f"(known: {', '.join(sorted(table)) or 'none'})")
    return value


def _import(path, where, scene):
    import importlib

    mod, _, fn = path.partition(":")
    if not mod or not fn:
        raise scene.error(where, f"expected package.module:function, got '{path}'")
    try:
        obj = getattr(importlib.import_module(mod), fn)
    except Exception as exc:  # the user's code: any error becomes one line
        raise scene.error(where, f"cannot import '{path}': {type(exc).__name__}: {exc}") from None
    if not callable(obj):
        raise scene.error(where, f"'{path}' is not callable")
    return obj


class SceneBinding(Binding):
    """Per call site: the library primitive, its arguments and the outcome map; the
    runtime implementations; the sensor events queued for the model; the checks."""

    def __init__(self, scene, model, world):
        self.scene, self.model, self.world = scene, model, world
        self.sites: dict = {}  # site index -> (start(world), {library outcome: model outcome})
        self.calls: dict = {}  # site index -> (library primitive, robot, its arguments): what the site runs
        self.active: dict = {}  # site index -> activity
        self.backlog: list = []  # events raised by sensors, not yet given to the model
        self._seen = 0
        self.env = {}  # event name -> guard
        self.idle_of = {}  # choice name -> its quiet option (no sensor raises it)
        self.prog_env = model.program.env
        self.checks = []
        self._incidents = 0  # world incidents seen by after_tick

    # ---- runtime glue
    def implementations(self) -> dict:
        impls = {}
        for name in {s.primitive for s in self.model.program.sites if s.index in self.sites}:
            impls[name] = _Impl(self)
        return impls

    def tick_site(self, call):
        idx = call.site.index
        start, omap = self.sites[idx]
        if call.first or idx not in self.active:
            self.active[idx] = start(self.world)
        answer = self.active[idx].tick()
        if answer not in omap:
            raise ModelError(f"bind.{call.site.primitive}", f"returned '{answer}', which the binding does not map")
        out = omap[answer]
        if out[0] != _R:
            self.active.pop(idx, None)
        return out[1]

    def halt_site(self, call):
        act = self.active.pop(call.site.index, None)
        if act is not None:
            act.halt()

    def events(self, state) -> list:
        """Sensor events for the next tick: one per tick, oldest first, when the model's
        guard allows it (later ones wait their turn); plus, for each environment choice
        that no sensor event decides, its quiet option when enabled. Guards are evaluated
        in the model's order, each after the effects of the events before it, as the
        step function does."""
        w = self.world
        while self._seen < len(w.events):
            self.backlog.append(w.events[self._seen][2])
            self._seen += 1
        head = self.backlog[0] if self.backlog else None
        s = list(state)
        out = []
        try:
            for name, guard, eff, options in self.prog_env:
                if options is None:
                    if name == head and (guard is None or guard(s)):
                        out.append(self.backlog.pop(0))
                        if eff is not None:
                            eff(s)
                    continue
                enabled = [o for o in options if o[1] is None or o[1](s)]
                chosen = next((o for o in enabled if o[0] == head), None)
                if chosen is not None:
                    out.append(self.backlog.pop(0))
                else:
                    quiet = self.idle_of[name]
                    chosen = next((o for o in enabled if o[0] == quiet), None)
                    if chosen is not None:
                        out.append(quiet)
                    elif len(enabled) == 1:
                        chosen = enabled[0]  # the runtime takes the only enabled option unasked
                if chosen is not None and chosen[2] is not None:
                    chosen[2](s)
        except DomainError:  # an effect out of its domain: the runtime's tick reports it
            pass
        return out

    def after_tick(self, rt) -> list:
        """The scene's checks after a tick: what disagrees (empty when all agree), each
        disagreement followed by what physics did since the last tick (its incidents:
        a slip, a part pushed out of its slot, ... with their causes)."""
        out = self.check(rt.vars) if self.checks else []
        new = self.world.incidents[self._incidents:]
        self._incidents = len(self.world.incidents)
        if out and new:
            out.append("physics: " + "; ".join(map(incident_text, new)))
        return out

    def check(self, vars: dict) -> list:
        out = []
        for var, kind, name, lo, hi in self.checks:
            have, want = vars[var], self.world.query(kind, name)
            diff = int(want) - int(have)
            if not lo <= diff <= hi:
                out.append(f"{var} is {have} but {kind}({', '.join(name) if isinstance(name, tuple) else name}) is {want}")
        return out


class _Impl:
    __slots__ = ("b",)

    def __init__(self, b):
        self.b = b

    def tick(self, call):
        return self.b.tick_site(call)

    def halt(self, call):
        self.b.halt_site(call)


def bind_model(scene, model, world):
    """Check the scene's ``bind`` and ``checks`` against ``model``; ModelError before any
    trial when something does not fit. A scene with a ``binding`` section (``python:
    package.module:Class`` and ``args``) is bound by that class instead:
    ``Class(scene, model, world, **args)``, an object with ``implementations()``,
    ``events(state)`` and ``after_tick(runtime) -> [problem]`` (``protocol.Binding``;
    it raises ModelError for a model it cannot run)."""
    if scene.binding is not None:
        cls = _import(scene.binding["python"], "binding.python", scene)
        try:
            b = cls(scene, model, world, **scene.binding.get("args", {}))
        except TypeError as exc:
            raise scene.error("binding.args", str(exc)) from None
        if not isinstance(b, Binding):
            missing = [m for m in ("implementations", "events", "after_tick") if not callable(getattr(b, m, None))]
            raise scene.error("binding.python", f"'{scene.binding['python']}' made an object without "
                                                f"{', '.join(missing)} (a binding needs implementations(), "
                                                "events(state) and after_tick(runtime))")
        return b
    b = SceneBinding(scene, model, world)
    prog = model.program
    prims = model.all_primitives()
    robots = sorted(scene.robots)
    for name in scene.bind:
        if name not in prims:
            raise scene.error(f"bind.{name}", f"the model has no primitive '{name}' (it has: {', '.join(sorted(prims))})")
    for site in prog.sites:
        spec = scene.bind.get(site.primitive)
        where = f"bind.{site.primitive}"
        if spec is None:
            if len(site.outcomes) > 1:
                raise scene.error("bind", f"model primitive '{site.primitive}' (used at {site.label}) has "
                                          f"{len(site.outcomes)} outcomes and no binding")
            continue
        cases = spec if isinstance(spec, list) else [spec]
        chosen = None
        for i, case in enumerate(cases):
            when = case.get("when", {})
            if all(site.args.get(k) == v for k, v in when.items()):
                chosen, where = case, (f"{where}[{i}]" if isinstance(spec, list) else where)
                break
        if chosen is None:
            raise scene.error(where, f"no case matches the call at {site.label} (args {site.args})")
        robot = chosen.get("robot", robots[0])
        if robot not in scene.robots:
            raise scene.error(f"{where}.robot", f"no robot named '{robot}' (robots: {', '.join(robots)})")
        args = {k: _fill(v, site.args, f"{where}.args.{k}", scene) for k, v in chosen.get("args", {}).items()}
        if ("primitive" in chosen) == ("python" in chosen):
            raise scene.error(where, "give exactly one of 'primitive' (the library) or 'python' (module:function)")
        if "python" in chosen:
            fn = _import(chosen["python"], f"{where}.python", scene)
            statuses = getattr(fn, "outcomes", ("running", "success", "failure"))
            lib_outs = [(int({"running": RUNNING, "success": SUCCESS, "failure": FAILURE}[s]), s) for s in statuses]

            def start(world, fn=fn, robot=robot, args=args):
                obj = fn(world, robot, dict(args))
                return _Act(obj.tick, getattr(obj, "halt", None))
        else:
            lib = LIBRARY.get(chosen["primitive"])
            if lib is None:
                raise scene.error(f"{where}.primitive", f"unknown library primitive '{chosen['primitive']}' "
                                                        f"(library: {', '.join(sorted(LIBRARY))})")
            for k in args:
                if k not in lib.params:
                    raise scene.error(f"{where}.args.{k}", f"'{lib.name}' takes no argument '{k}' "
                                                           f"(it takes: {', '.join(lib.params) or 'none'})")
            full = {}
            for k, (kind, default) in lib.params.items():
                if k not in args and default is None:
                    raise scene.error(f"{where}.args", f"'{lib.name}' needs argument '{k}'")
                full[k] = _coerce(scene, robot, kind, args.get(k, default), f"{where}.args.{k}")
            try:
                lib_outs = lib.outcomes(scene, robot, full)
            except ModelError as exc:
                raise scene.error(f"{where}.args", exc.problem) from None

            def start(world, lib=lib, robot=robot, full=full):
                return lib.start(world, robot, full)
            b.calls[site.index] = (lib.name, robot, dict(full))
        explicit = chosen.get("outcomes", {})
        omap = {}
        for status, lname in lib_outs:
            if lname in explicit:
                match = [o for o in site.outcomes if o[2] == explicit[lname]]
                if not match:
                    raise scene.error(f"{where}.outcomes.{lname}", f"model primitive '{site.primitive}' has no "
                                                                   f"outcome '{explicit[lname]}'")
                if match[0][0] != status:
                    raise scene.error(f"{where}.outcomes.{lname}", f"'{lname}' is {_STATUS_NAME[status]} but "
                                                                   f"'{explicit[lname]}' is {_STATUS_NAME[match[0][0]]}")
            else:
                match = [o for o in site.outcomes if o[0] == status]
                if len(match) != 1:
                    what = (f"declares no {_STATUS_NAME[status]} outcome" if not match else
                            f"has several {_STATUS_NAME[status]} outcomes; name one in {where}.outcomes")
                    raise scene.error(where, f"'{chosen.get('primitive') or chosen.get('python')}' can answer "
                                             f"{_STATUS_NAME[status]} ({lname}) but model primitive "
                                             f"'{site.primitive}' at {site.label} {what}")
            omap[lname] = (status, match[0][2])
        b.sites[site.index] = (start, omap)
    # sensor events must be model environment events (or options of a choice)
    env = {}
    raised = {s.get(k) for s in scene.sensors.values() for k in ("on_enter", "on_exit")} - {None}
    for name, guard, _eff, options in prog.env:
        if options is None:
            env[name] = guard
            continue
        for oname, oguard, _e, _o in options:
            env[oname] = oguard
        quiet = [o for o in options if o[0] not in raised]
        if len(quiet) != 1:
            raise scene.error("sensors", f"environment choice '{name}' needs exactly one option that no sensor "
                                         f"raises (reported on every tick no sensor chose another); "
                                         f"{len(quiet)} of its options ({', '.join(o[0] for o in options)}) are")
        b.idle_of[name] = quiet[0][0]
    for sname, s in scene.sensors.items():
        for key in ("on_enter", "on_exit"):
            ev = s.get(key)
            if ev is not None and ev not in env:
                raise scene.error(f"sensors.{sname}.{key}", f"the model has no environment event '{ev}' "
                                                            f"(it has: {', '.join(sorted(env)) or 'none'})")
    b.env = env
    names = {v.name for v in model.variables}
    for i, c in enumerate(scene.checks):
        if c["var"] not in names:
            raise scene.error(f"checks[{i}].var", f"the model has no variable '{c['var']}'")
        var = model.var(c["var"])
        if var.kind == "enum":
            raise scene.error(f"checks[{i}].var", f"'{c['var']}' is an enum ({var.describe_domain()}): a check compares "
                                                  "a bool or int variable with a count of the world")
        kind, nm = scene.world_query(c["world"], f"checks[{i}].world")
        lo, hi = c.get("slack", [0, 0])
        b.checks.append((c["var"], kind, nm, lo, hi))
    return b
