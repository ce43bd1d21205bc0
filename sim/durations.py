"""How long the ARIAC arm's FSM states take in the kitting cell: derived from the scene,
and measured in trials as a check.

``derive(model)`` derives, for every state of the arm FSM that moves the arm, the slowest
run from the scene's geometry and the arm's motion profiles, per goal class and per
entry, two states deep (the position abstraction of ``btfsm.positions``; ``Timing``, docs/verification.md
2.1); ``btfsm.models.ariac.timed`` declares them (``models/ariac_timing.json``).

``measure(specs)`` runs trials of the experiment (``btfsm.sim.trial.run_trial``) and records,
for every visit of the arm FSM's token to a state, the ticks it stayed there; the maxima
are what ``btfsm.models.ariac.ARM_DURATIONS`` declares (with a margin), so that the
checker can bound the reaction time (property ``response``, docs/verification.md 2.1).
Declared durations are enforced in every run: the runtime refuses a primitive answer
outside them (a conformance error), so a trial whose motions take longer than declared
fails instead of passing silently.

``ARM_DURATIONS`` (the former context-free declaration: the measured maxima plus 10 %)
stays for ``timed(model, durations="measured")``.

    python -m btfsm.sim.durations [--trials N] [--write models/ariac_timing.json]

``derive_scene(model, scene)`` (a scene with a ``bind`` table): each FSM state bound to a
library move gets its slowest rest-to-rest run, context-free; other states no duration.

    python -m btfsm.sim.durations --scene FILE [MODEL] --trigger T --response R --within S
"""
from __future__ import annotations

import math
from typing import cast
from collections import defaultdict

from btfsm.errors import ModelError

__all__ = ["measure", "declared", "derive", "Derivation", "Timing", "derive_scene", "timed_in_scene", "main"]


def _visits(spec) -> dict:
    from .trial import run_trial

    runs: dict = defaultdict(int)
    cur = {"state": None, "n": 0}

    def on_tick(rt, world):
        from btfsm.positions import base_state

        state = base_state(rt.fsm_state("arm")[0])
        if state == cur["state"]:
            cur["n"] += 1
            return
        if cur["state"] is not None:
            runs[cur["state"]] = max(runs[cur["state"]], cur["n"])
        cur["state"], cur["n"] = state, 1

    run_trial(spec, on_tick=on_tick)
    return dict(runs)


def measure(specs, workers: int = 1) -> dict:
    """``{state: the most ticks a visit lasted}`` over the trials ``specs``."""
    if workers > 1 and len(specs) > 1:
        import multiprocessing as mp

        with mp.get_context("fork").Pool(workers) as pool:
            parts = pool.map(_visits, specs)
    else:
        parts = [_visits(s) for s in specs]
    out: dict = {}
    for p in parts:
        for state, n in p.items():
            out[state] = max(out.get(state, 0), n)
    return dict(sorted(out.items()))


def declared(maxima: dict, rate: float = 10.0, margin: float = 0.1) -> dict:
    """Seconds to declare per state: a visit of n ticks ends on the n-th tick of its run,
    i.e. after (n - 1) / rate seconds (docs/semantics.md 6.1), plus ``margin``, rounded up
    to a tick.

    >>> declared({"put_agv": 14, "conveyor_to_agv": 61})
    {'put_agv': 1.5, 'conveyor_to_agv': 6.6}
    """
    return {s: math.ceil((n - 1) * (1 + margin) - 1e-9) / rate for s, n in maxima.items()}


def main(argv=None) -> int:
    import argparse
    import json
    import sys

    argv = sys.argv[1:] if argv is None else list(argv)
    if any(a == "--scene" or a.startswith("--scene=") for a in argv):
        return scene_main(argv)

    from .protocol import VARIANTS, TrialSpec

    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--trials", type=int, default=2, help="trials per variant measured beside the derived bounds "
                   "(k = 1..N; 40 for the whole experiment; 0: none)")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--write", metavar="JSON", help="write the derived abstraction (models/ariac_timing.json)")
    args = p.parse_args(argv)
    from btfsm.models import ariac

    timing = derive(ariac.preemptive())
    if args.write:
        with open(args.write, "w", encoding="utf-8") as fh:
            json.dump(timing.to_data(), fh, indent=1, sort_keys=True)
            fh.write("\n")
    slowest = timing.slowest()
    specs = [TrialSpec(v, k) for v in VARIANTS for k in range(1, args.trials + 1)]
    maxima = measure(specs, args.workers) if specs else {}
    from btfsm.positions import base_state

    copies: dict = {}
    split = next(f for f in timing.apply(ariac.preemptive()).fsms if f.name == timing.fsm)
    for st in split.states:
        if st.duration is not None:
            copies[base_state(st.id)] = copies.get(base_state(st.id), 0) + 1
    print(f"derived from the scene: {sum(copies.values())} timed copies of {len(slowest)} states "
          f"({len(split.states)} states in the split FSM); measured: {len(specs)} trial(s)")
    print(f"{'state':22s} {'copies':>6s} {'derived s':>14s} {'measured s':>10s} {'was declared':>12s}")
    for state in sorted(set(slowest) | set(maxima)):
        n = maxima.get(state)
        meas = "-" if n is None else f"{(n - 1) / 10:.1f}"
        have = ariac.ARM_DURATIONS.get(state)
        der = f"[0, {slowest[state]:.2f}]" if state in slowest else "-"
        print(f"{state:22s} {copies.get(state, 0):6d} {der:>14s} {meas:>10s} {have if have is not None else '-':>12}")
    return 0




# ============================================================== derivation from the scene
# Boxes: ((x0, y0, z0), (x1, y1, z1)), axis-aligned sets of arm poses.

def _box(points) -> tuple:
    pts = list(points)
    return (tuple(min(p[k] for p in pts) for k in range(3)), tuple(max(p[k] for p in pts) for k in range(3)))


def _gaps(a, b, k) -> tuple:
    """(least, greatest) |p[k] - q[k]| for p in a, q in b."""
    lo = max(0.0, b[0][k] - a[1][k], a[0][k] - b[1][k])
    return lo, max(abs(a[1][k] - b[0][k]), abs(b[1][k] - a[0][k]))


def _distances(a, b) -> tuple:
    """((least, greatest) x-y distance, (least, greatest) z distance) between boxes a and b."""
    (x0, x1), (y0, y1), (z0, z1) = (_gaps(a, b, k) for k in range(3))
    return (math.hypot(x0, y0), math.hypot(x1, y1)), (z0, z1)


class Derivation:
    """The arm's moves in a kitting scene (``KittingBinding.geometry``) as boxes of poses,
    and the time each move takes between two boxes: the scene's rest-to-rest profile
    (``World.move_to``: one profile of the path fraction, synchronised in x-y and z, at
    the binding's velocity scale and its square for accelerations) bounded at the boxes'
    least and greatest distances (the time grows with both distances), and for belt
    tracking the scene's own pursuit run in a ``World`` from the box's corners to a part
    at every 0.2 m of the pick stretch (sampled, plus ``TRACK_MARGIN``)."""

    TRACK_MARGIN = 0.2  # s added to the slowest sampled pursuit
    TRACK_PITCH = 0.2  # m between sampled part positions on the pick stretch

    def __init__(self, scene, binding):
        self.scene, self.b = scene, binding
        g = binding.geometry()
        self.g = g
        self.robot = binding.robot
        self.spec = scene.robots[self.robot]
        self.dt = scene.dt
        self.hub = {a: _box([p]) for a, p in g["hub"].items()}
        c = g["clearance"]
        self.contact = {}
        for a, zs in g["contact"].items():
            xs = g["spots"][a]
            self.contact[a] = _box([(x, y, z) for x, y in xs for z in zs])
        self.above = {a: ((b[0][0], b[0][1], b[0][2] + c), (b[1][0], b[1][1], b[1][2] + c))
                      for a, b in self.contact.items()}
        self.home = _box([g["home"]])
        self._tracks: dict = {}

    # ---- one move
    def rest_time(self, dxy: float, dz: float) -> float:
        """Seconds of ``World.move_to`` over dxy (x-y) and dz at the binding's scale."""
        from .scene import Profile

        s, zs = self.g["speed"], self.spec["z"]
        v = a = math.inf
        if dxy > 0.0:
            v, a = min(v, self.spec["speed"] / dxy), min(a, self.spec["acceleration"] / dxy)
        if dz > 0.0:
            v, a = min(v, zs["speed"] / dz), min(a, zs["acceleration"] / dz)
        return Profile(1.0 if v != math.inf else 0.0, v * s, a * s * s).total

    def track(self, start, z: float) -> float:
        """The slowest sampled pursuit from the corners of box ``start`` to a belt part
        anywhere on the pick stretch, ending at height z (plus ``TRACK_MARGIN``)."""
        key = (start, round(z, 6))
        if key not in self._tracks:
            corners = {(x, y, zz) for x in (start[0][0], start[1][0]) for y in (start[0][1], start[1][1])
                       for zz in (start[0][2], start[1][2])}
            (ax, ay), (bx, by) = self.g["spots"]["conveyor"]
            speed = self.scene.belts[self.b.belt]["speed"]
            stretch = math.hypot(bx - ax, by - ay)
            n = max(1, math.ceil(stretch / self.TRACK_PITCH))
            delays = [stretch * k / n / speed for k in range(n + 1)]
            worst = max(self._pursuit(p, d, z) for p in sorted(corners) for d in delays)
            self._tracks[key] = worst + self.TRACK_MARGIN
        return self._tracks[key]

    def _pursuit(self, start, delay: float, z: float) -> float:
        from .scene import World

        w = World(self.scene, 0)
        for name in w.arrivals:
            w.arrivals[name] = []
        pid = cast(int, w.spawn(self.scene.sensors[self.b.sensor]["region"]))  # an empty belt: room for it
        w.step(round(delay / w.dt))
        part = w.parts[pid]
        if part.place.kind != "BELT":
            return 0.0
        r = w.robots[self.robot]
        r.x, r.y, r.z = start
        w.track(self.robot, pid, z)
        n = 0
        while not r.arrived and part.place.kind == "BELT":
            w.step()
            n += 1
        return n * w.dt


def _kitting(model, scene=None):
    """(scene, binding) of the kitting cell for ``model`` (the ARIAC scene by default)."""
    from .loop import start
    from .protocol import TrialSpec
    from .trial import ariac_scene

    scene = scene if scene is not None else ariac_scene(TrialSpec("preemptive", 1))
    _world, binding, _rt = start(scene, model, 0, arrivals=False)
    if not hasattr(binding, "geometry"):
        raise ModelError("binding", f"scene {scene.name}'s binding gives no geometry to derive durations from "
                         "(only the kitting binding does)", scene.file)
    return scene, binding


class Timing:
    """The derived position abstraction of a kitting model's arm FSM.

    ``classes``: ``{state: {class: goals}}``, the states whose runs go to different
    targets for different goals (``btfsm.positions.split_by_goal``); ``history``: the
    states (instants too), each split into one copy per entry (``split_history``);
    ``table``: ``{copy s@u: {entry copy u@w: (min, max)}}`` for those copies, split again
    by the copy they are entered from (``split_by_entry``: two states of history);
    ``where``: ``{state: sorted poses}``, where the arm can be when
    a run of the copy starts (the fixed point). Poses: ``home``, ``hub:A`` (area A's
    approach pose), ``above:A:G`` / ``contact:A:G`` / ``lifted:A:G`` (above, at, or lifted
    from the target of goal G at A; G ``*``: any target there, after the gripper let go)."""

    def __init__(self, fsm, classes, table, where, history=()):
        self.fsm, self.classes, self.table, self.where = fsm, classes, table, where
        self.history = list(history)

    def to_data(self) -> dict:
        """The JSON form (``models/ariac_timing.json``): classes, history, table and poses."""
        return {"fsm": self.fsm, "classes": {s: {c: list(g) for c, g in cl.items()} for s, cl in self.classes.items()},
                "history": self.history,
                "table": {s: {u: list(iv) for u, iv in rows.items()} for s, rows in self.table.items()},
                "where": self.where}

    def apply(self, model):
        from btfsm.positions import split_by_entry, split_by_goal, split_history

        split = split_history(split_by_goal(model, self.fsm, self.classes), self.fsm, self.history)
        return split_by_entry(split, self.fsm, self.table)

    def slowest(self) -> dict:
        """{state: the slowest derived run over its copies and entries} (for the table)."""
        from btfsm.positions import base_state

        out: dict = {}
        for copy, rows in self.table.items():
            s = base_state(copy)
            out[s] = max([out.get(s, 0.0)] + [hi for _, hi in rows.values()])
        return out


def derive(model, scene=None) -> Timing:
    """The position abstraction of a kitting model's arm FSM with each state's duration
    derived from the scene, per goal class and per entry, two states deep: a copy's
    duration depends on the copy it was entered from, and on the state that one was
    entered from (docs/verification.md 2.1).

    A pose is symbolic and relational: ``above:bins:pick_bins`` is above *the* part the
    pick goes for, so the grasp from there descends ``clearance`` and nothing else, while
    a pose whose target is not known (``*``) is any point of its area's box. A run of a
    copy starts where its entry left the arm: the end of the entry's run (its target), or
    anywhere on its path when the entry was left by a direct edge (halted); a halted run
    of the copy itself restarts on its own path toward the same target, which is no
    farther. The slowest run is the longest move from those poses (``Derivation``);
    every declared minimum is 0 (a restarted run may start next to its target)."""
    from btfsm.positions import entries_of, split_by_goal, split_history

    scene, binding = _kitting(model, scene)
    d = binding.d
    geo = Derivation(scene, binding)
    f0 = next(x for x in model.fsms if x.name == d.fsm)
    by_id = {s.id: s for s in f0.states}
    pick_goal = {d.goal(g)[1]: g for g in f0.goals if d.goal(g)[0] == "pick"}
    place_goal = {d.goal(g)[1]: g for g in f0.goals if d.goal(g)[0] == "place"}

    def kind(sid):
        prim = by_id[sid].primitive
        return "move" if prim == d.move else "grasp" if prim == d.grasp else "instant"

    def area(sid):
        return d.area(dict(by_id[sid].args))

    def served(f, sid):
        out = set()
        for e in f.edges:
            if e.source == sid:
                out.update(f.goals if "*" in e.goals else e.goals)
        for m in f.markers:
            if m.state == sid:
                out.update(f.goals if "*" in m.goals else m.goals)
        return out

    def approach_target(x, g):
        gk, ga = d.goal(g)
        if ga == x and (gk, x) in (("pick", "bins"), ("place", "bins"), ("place", "agv"), ("pick", "conveyor")):
            return ("above", x, g)
        return ("hub", x)

    # 1. goal classes: the approach-role moves, by the pose their run goes to
    classes = {}
    for s in f0.states:
        if kind(s.id) == "move" and d.role(s.id) == "approach":
            groups: dict = {}
            for g in sorted(served(f0, s.id)):
                t = approach_target(area(s.id), g)
                groups.setdefault("hub" if t[0] == "hub" else g, []).append(g)
            if len(groups) > 1:
                classes[s.id] = {c: tuple(gs) for c, gs in groups.items()}
    f = next(x for x in split_by_goal(model, d.fsm, classes).fsms if x.name == d.fsm)
    base = {}
    for s in f.states:
        base[s.id] = s.id.split("#", 1)[0]
    goals_of = {}  # the goals a copy's runs serve: its class's
    for s in f.states:
        b, _, c = s.id.partition("#")
        goals_of[s.id] = set(classes[b][c]) if c else served(f0, b)

    # 2. poses: geometry and moves
    def box(p):
        k, x = p[0], (p[1] if len(p) > 1 else None)
        if k == "home":
            return geo.home
        if k in ("hub", "none"):
            return geo.hub[x]
        if k == "above":
            return geo.above[x]
        if k == "contact":
            return geo.contact[x]
        hz = geo.hub[x][0][2]
        c = geo.contact[x]
        return ((c[0][0], c[0][1], hz), (c[1][0], c[1][1], hz))

    def same(p, q):
        return (len(p) == 3 and len(q) == 3 and p[1] == q[1] and p[2] is not None and p[2] == q[2]
                and "none" not in (p[0], q[0]))

    def rest(p, q) -> float:
        a, b = box(p), box(q)
        (_, dxy), (_, dz) = _distances(a, b)
        if same(p, q):
            dxy = 0.0
        return geo.rest_time(dxy, dz)

    def lifted(p, x):
        if p[0] in ("above", "contact", "lifted") and p[1] == x:
            return ("lifted", x, p[2])
        return p  # at a hub or home: already at least that high

    def run(sid, g, p) -> tuple:
        """(slowest seconds, end poses) of a run of state sid for goal g starting at pose p."""
        s, x, k = base[sid], area(base[sid]), kind(base[sid])
        if k == "grasp":
            if p[0] == "none" or g != pick_goal.get(x):
                return 0.0, {p}  # nothing to grasp: it fails at once
            t = ("contact", x, pick_goal[x])
            if x == "conveyor":
                zs = geo.spec["z"]
                if same(p, t) or (p[0] == "above" and same(("contact",) + p[1:], t)):
                    (_, _), (_, dz) = _distances(box(p), box(t))
                    from .scene import Profile

                    return Profile(dz, zs["speed"], zs["acceleration"]).total + geo.TRACK_MARGIN, {t}
                return geo.track(box(p), box(t)[0][2]), {t}
            return rest(p, t), {t}
        role = d.role(s)
        if role == "lift":
            q = lifted(p, x)
            hz = geo.hub[x][0][2]
            return geo.rest_time(0.0, max(0.0, hz - box(p)[0][2])), {q}
        if role == "put_back":
            t = ("contact", x, pick_goal.get(x))
            return rest(p, t), {t}
        if role == "put":
            if p[0] == "none":
                return 0.0, {p}  # nowhere to put it: done at once
            t = ("contact", x, place_goal.get(x))
            return rest(p, t), {t, p}
        t = approach_target(x, g)
        if t[0] == "above" and x == "conveyor":
            if same(p, t):
                return geo.dt + geo.TRACK_MARGIN, {t}
            # ended where the part left the belt (lost, or taken), or at the hub when none was there
            slow = max(geo.track(box(p), box(t)[0][2]), rest(p, ("hub", x)))
            return slow, {t, ("hub", x), p}
        if t[0] == "above":
            if p == ("none", x, g):
                return 0.0, {p}  # still no target: it stays at the hub
            if same(p, t):
                return 0.0, {t}  # already above it (the same target while nothing changed)
            # no target (no part, no free spot): the hub, until the gripper changes something
            return max(rest(p, t), rest(p, ("hub", x))), {t, ("none", x, g)}
        return rest(p, t), {t}

    def forget(ps, kinds=("pick", "place")):
        out = set()
        for p in ps:
            if len(p) == 3 and p[2] is not None and d.goal(p[2])[0] in kinds:
                p = ("hub", p[1]) if p[0] == "none" else (p[0], p[1], None)
            out.add(p)
        return out

    def leave(u, poses, direct, goals) -> set:
        """Where the arm can be when the token leaves copy u whose runs start at ``poses``."""
        k = kind(base[u])
        if k == "instant":
            st = by_id[base[u]]
            if st.primitive == d.gripper and not dict(st.args).get("on", True):
                return forget(poses)  # a part was let go: the targets are chosen anew
            return set(poses)
        out = set(poses) if direct else set()
        for g in goals_of[u]:
            if not direct and goals and g not in goals:
                continue
            for p in poses:
                out |= run(u, g, p)[1]
        if k == "grasp" and not direct:
            out = forget(out, ("place",))  # a part left the bins: the free spots change
        return out

    # 3. where runs start: the fixed point on the FSM split by every entry (two states of
    # history: a copy s@u's runs start where u's own runs, from u's entries, left the arm)
    entries = entries_of(f)
    timed_states = list(entries)  # instants too: a state after an instant knows what preceded it
    f2 = next(x for x in split_history(split_by_goal(model, d.fsm, classes), d.fsm, timed_states).fsms
              if x.name == d.fsm)
    for s2 in f2.states:
        b1 = s2.id.split("@", 1)[0]
        base[s2.id] = base[b1]
        goals_of.setdefault(s2.id, goals_of[b1])
    entries2 = entries_of(f2)
    at: dict = {s.id: set() for s in f2.states}
    at[f2.initial] = {("home",)}
    for _ in range(500):
        changed = False
        for s, ent in entries2.items():
            new = set(at[s])
            for u, (direct, goals) in ent.items():
                if u:
                    new |= leave(u, at[u], direct, goals)
            if new != at[s]:
                at[s], changed = new, True
        if not changed:
            break
    else:
        raise RuntimeError("the position fixed point did not converge")

    # 4. a copy's duration by its entry in that split: two states of history (the copy of
    # s entered from u@w starts where u's runs from w's ends left the arm)
    table: dict = {}
    where: dict = {}
    for s2, ent in entries2.items():
        if kind(base[s2]) == "instant":
            continue
        s1 = s2.split("@", 1)[0]
        for u, (direct, goals) in ent.items():
            starts = {("home",)} if not u else leave(u, at[u], direct, goals)
            hi = max((run(s1, g, p)[0] for g in goals_of[s1] for p in starts), default=0.0)
            table.setdefault(s2, {})[u] = (0.0, round(hi + geo.dt + 1e-3, 3))
            where.setdefault(s1, set()).update(starts)
    where = {s: sorted(":".join("*" if v is None else str(v) for v in p) for p in ps) for s, ps in where.items()}
    return Timing(d.fsm, classes, table, where, history=sorted(timed_states))


def derive_scene(model, scene) -> dict:
    """``{fsm: {state: (0, max) seconds}}`` for the FSM states of a model run in a scene
    with a ``bind`` table whose call is a library move (``move_to``, ``carry_to``): the
    slowest rest-to-rest move of the scene's robot to the state's frame from the robot's
    home or any frame its moves go to (context-free: no position abstraction; the
    farthest of those points bounds every start on the segments between them). Other
    states get no duration (a grip that waits for a part, a wait for a sensor, have no
    bound the geometry gives)."""
    from .loop import start
    from .scene import Profile

    _world, binding, _rt = start(scene, model, 0, arrivals=False)
    calls = getattr(binding, "calls", None)
    if calls is None:
        raise ModelError("bind", f"scene {scene.name} binds the model through a Python binding: durations are "
                         "derived from a bind table's moves (or, for the kitting binding, by derive())", scene.file)
    prog = model.program
    moves = {i: c for i, c in calls.items() if c[0] in ("move_to", "carry_to")}
    points: dict = {}
    for lib, robot, args in moves.values():
        points.setdefault(robot, {tuple(scene.robots[robot]["home"])}).add(tuple(args["frame"]))
    out: dict = {}
    for site in prog.sites:
        if site.index not in moves or not site.fsm or not site.state:
            continue
        lib, robot, args = moves[site.index]
        spec, (tx, ty) = scene.robots[robot], args["frame"]
        far = max(math.hypot(tx - x, ty - y) for x, y in points[robot])
        s = float(args["speed"])
        slow = Profile(far, spec["speed"] * s, spec["acceleration"] * s).total
        row = out.setdefault(site.fsm, {})
        row[site.state] = (0.0, round(max(row.get(site.state, (0, 0))[1], slow + scene.dt + 1e-3), 3))
    return out


def timed_in_scene(model, scene, responses=()):
    """``model`` with the durations of ``derive_scene`` on its FSM states and ``responses``."""
    import dataclasses

    table = derive_scene(model, scene)
    fsms = tuple(dataclasses.replace(f, states=tuple(
        dataclasses.replace(st, duration=table[f.name][st.id]) if st.id in table.get(f.name, {}) else st
        for st in f.states)) for f in model.fsms)
    return dataclasses.replace(model, fsms=fsms, responses=tuple(model.responses) + tuple(responses))


def scene_main(argv) -> int:
    """``python -m btfsm.sim.durations --scene FILE [MODEL] [--trigger T --response R --within S]``."""
    import argparse
    import sys

    from btfsm.files import load_model
    from btfsm.timing import Response
    from btfsm.verify.report import check

    from .scene import load_scene

    p = argparse.ArgumentParser(prog="python -m btfsm.sim.durations --scene")
    p.add_argument("--scene", required=True)
    p.add_argument("model", nargs="?", help="the model (default: the scene's model)")
    p.add_argument("--trigger")
    p.add_argument("--response")
    p.add_argument("--within", type=float)
    args = p.parse_args(argv)
    try:
        scene = load_scene(args.scene)
        name = args.model or scene.model
        if not name:
            raise ModelError("model", f"scene {scene.name} names no model: give one")
        model = load_model(name)
        reqs: tuple = ()
        if args.trigger or args.response:
            if not (args.trigger and args.response):
                raise ModelError("requirement", "give both --trigger and --response")
            reqs = (Response("requirement", args.trigger, args.response, args.within),)
        timed = timed_in_scene(model, scene, reqs)
        timed.program  # the requirement's expressions are checked here
        table = derive_scene(model, scene)
    except (ModelError, OSError) as exc:
        print(f"btfsm.sim.durations: {exc}", file=sys.stderr)
        return 2
    print(f"{model.name} in scene {scene.name}: durations derived from the bind table's moves (context-free)")
    for fsm, rows in table.items():
        for st, (lo, hi) in rows.items():
            print(f"  {fsm}.{st:24s} [{lo:g}, {hi:g}] s")
    if not timed.responses:
        print("no requirement: give --trigger, --response and --within (or declare responses: in the model)")
        return 0
    r = check(timed, ["response"])
    res = r.results[0]
    for note in res.notes:
        print("  " + note)
    print("response: " + ("holds" if res.holds else "violated" if res.holds is False else "not decided"))
    return r.exit_code


if __name__ == "__main__":
    raise SystemExit(main())
