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
        [--write-no-loss models/ariac_timing_no_loss.json]

``derive_scene(model, scene)`` (a scene with a ``bind`` table): every call site (FSM state
or Action) the table drives that can answer RUNNING gets its slowest run from the scene,
context-free: moves from the robot's profiles, grips from the gripper and where parts are,
waits and doors from their seconds; a wait the scene cannot bound is reported as such (the
model may declare it). ``btfsm check MODEL --timed [--scene S]`` checks the model so timed.

    python -m btfsm.sim.durations --scene FILE [MODEL] --trigger T --response R --within S

The module has more than 1,000 lines: the ARIAC derivation and the scene route share its
helpers (boxes, moves, the pursuit of a belt part).
"""
from __future__ import annotations

import math
from typing import NamedTuple, cast
from collections import defaultdict

from btfsm.errors import ModelError
from btfsm.status import Status

__all__ = ["measure", "declared", "derive", "derive_ariac", "Derivation", "Timing", "derive_scene", "timed_in_scene", "Derived", "print_scene_table", "measure_scene", "main"]


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
    p.add_argument("--write-no-loss", metavar="JSON", help="write the abstraction derived under 'no part lost yet' "
                   "(models/ariac_timing_no_loss.json)")
    args = p.parse_args(argv)
    from btfsm.models import ariac

    timing = derive_ariac()
    no_loss = derive_ariac(no_loss=True)
    for path, t in ((args.write, timing), (args.write_no_loss, no_loss)):
        if path:
            with open(path, "w", encoding="utf-8") as fh:
                json.dump(t.to_data(), fh, indent=1, sort_keys=True)
                fh.write("\n")
    slowest, slowest_nl = timing.slowest(), no_loss.slowest()
    specs = [TrialSpec(v, k) for v in VARIANTS for k in range(1, args.trials + 1)]
    maxima = measure(specs, args.workers) if specs else {}
    from btfsm.positions import base_state

    copies: dict = {}
    split = next(f for f in ariac.timed(ariac.preemptive(), timing=timing.to_data()).fsms if f.name == timing.fsm)
    for st in split.states:
        if st.duration is not None:
            copies[base_state(st.id)] = copies.get(base_state(st.id), 0) + 1
    print(f"derived from the scene: {sum(copies.values())} timed copies of {len(slowest)} states "
          f"({len(split.states)} states in the split FSM); measured: {len(specs)} trial(s)")
    print(f"{'state':22s} {'copies':>6s} {'derived s':>14s} {'no loss s':>10s} {'measured s':>10s} {'was declared':>12s}")
    for state in sorted(set(slowest) | set(maxima)):
        n = maxima.get(state)
        meas = "-" if n is None else f"{(n - 1) / 10:.1f}"
        have = ariac.ARM_DURATIONS.get(state)
        der = f"[0, {slowest[state]:.2f}]" if state in slowest else "-"
        nl = f"{slowest_nl[state]:.2f}" if state in slowest_nl else "-"
        print(f"{state:22s} {copies.get(state, 0):6d} {der:>14s} {nl:>10s} {meas:>10s} "
              f"{have if have is not None else '-':>12}")
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

    def track(self, start, z: float, age: float = 0.0) -> float:
        """The slowest sampled pursuit from the corners of box ``start`` to a belt part
        anywhere on the pick stretch, ending at height z (plus ``TRACK_MARGIN``); ``age``:
        only parts detected at least that many seconds before the pursuit starts."""
        key = (start, round(z, 6), age)
        if key not in self._tracks:
            corners = {(x, y, zz) for x in (start[0][0], start[1][0]) for y in (start[0][1], start[1][1])
                       for zz in (start[0][2], start[1][2])}
            (ax, ay), (bx, by) = self.g["spots"]["conveyor"]
            speed = self.scene.belts[self.b.belt]["speed"]
            stretch = math.hypot(bx - ax, by - ay)
            n = max(1, math.ceil(stretch / self.TRACK_PITCH))
            delays = [age] + [stretch * k / n / speed for k in range(n + 1) if stretch * k / n / speed > age]
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
    from the target of goal G at A; G ``*``: any target there, after the gripper let go;
    a fourth field names the bin copy's tag, ``above:bins:place_bins:bin2``: the target is
    in those bins); ``guards``: ``{goal copy: {tag: guard}}``, the place copies split by
    which bin their target is in (``split_by_guard``); ``ages``: ``{goal copy: {tag:
    guard}}``, the belt pursuits split by the part's age (``since(arrive)``); ``deep``:
    ``{copy u@w: {entry w@v: [group, {successor: max}]}}``, the third state of history
    (``split_deeper``); ``requested``: the goals the derived model's skill requests ask for
    (a copy runs only for those: a model that asks for another goal needs its own
    derivation)."""

    def __init__(self, fsm, classes, table, where, history=(), assume=None, guards=None, ages=None, deep=None,
                 requested=None):
        self.fsm, self.classes, self.table, self.where = fsm, classes, table, where
        self.deep = dict(deep or {})  # {copy: {entry: [group, {successor: max}]}}: ``split_deeper``
        self.requested = sorted(requested or ())
        self.history = list(history)
        self.guards = dict(guards or {})  # {goal copy: {tag: guard}}: ``split_by_guard`` (the bins a place goes to)
        self.assume = assume  # None, or "no_loss": derived under "no part lost yet" (``derive``)
        self.ages = dict(ages or {})  # {goal copy: {tag: guard}}: ``split_by_guard`` by a belt part's age

    def to_data(self) -> dict:
        """The JSON form (``models/ariac_timing.json``): classes, history, table and poses
        (and ``assume`` for a conditioned derivation, ``models/ariac_timing_no_loss.json``)."""
        out = {"fsm": self.fsm, "classes": {s: {c: list(g) for c, g in cl.items()} for s, cl in self.classes.items()},
               "history": self.history,
               "table": {s: {u: list(iv) for u, iv in rows.items()} for s, rows in self.table.items()},
               "where": self.where}
        if self.assume:
            out["assume"] = self.assume
        if self.guards:
            out["guards"] = self.guards
        if self.ages:
            out["ages"] = self.ages
        if self.deep:
            out["deep"] = self.deep
        if self.requested:
            out["requested"] = self.requested
        return out

    def apply(self, model):
        """``model`` split and timed (without guards; a timing with guards reads variables the
        model must track: ``btfsm.models.ariac.timed(m, timing=t.to_data())`` for ARIAC)."""
        from btfsm.positions import check_requests, split_by_entry, split_by_goal, split_deeper, split_history

        if self.guards or self.ages:
            raise ValueError("this timing splits by guards (the bins' occupancy, a belt part's age): apply it with "
                             "ariac.timed")
        check_requests(model, self.fsm, self.requested)
        split = split_history(split_by_goal(model, self.fsm, self.classes), self.fsm, self.history)
        split, table = split_deeper(split, self.fsm, self.table, self.deep)
        return split_by_entry(split, self.fsm, table)

    def slowest(self) -> dict:
        """{state: the slowest derived run over its copies and entries} (for the table)."""
        from btfsm.positions import base_state

        out: dict = {}
        for copy, rows in self.table.items():
            s = base_state(copy)
            out[s] = max([out.get(s, 0.0)] + [hi for _, hi in rows.values()])
        return out


def derive(model, scene=None, no_loss: bool = False, place_spots: "dict | None" = None,
           bins: "dict | None" = None, track=None, ages: "dict | None" = None, third=()) -> Timing:
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
    every declared minimum is 0 (a restarted run may start next to its target).

    ``no_loss``: conditioned on "no detected part has left the belt ungrasped yet": a
    pursuit of the first belt part in the queue ends above it (the part is still on the
    belt), never at the belt's hub (no part there) nor where a part left the belt. Sound
    for runs up to the first lost part, so for the first late response's verdict when
    arrivals are spaced by more than the pick window (docs/verification.md 2.1), not for
    figures past the window.

    ``place_spots`` ({area: [(x, y)]}): a what-if for diagnosis, not a sound derivation
    unless the cell only ever chooses those spots: a place's target at that area (``above``
    and ``contact`` poses of its place goal) is limited to them (e.g. the first bin's
    spots: where a rescue goes when the first bin has a free spot, docs/verification.md 2.1).

    ``bins`` ({goal: {tag: {"guard": .., "bins": [bin, ..], "free": bool}}}, e.g.
    ``btfsm.models.ariac.BIN_COPIES`` on a model with ``ariac.with_bins``): the copies of
    a pick's or place's approach at the bins split by guard (``split_by_guard``), each
    copy's target in its bins (``free``: it has one there; else it may find none and stay at
    the hub); the poses that follow keep the tag (the grasp, the put, the release, the
    escape and the moves after them start in those bins). ``track``: a function giving the model split by goal class the
    variables the guards read (``ariac.with_bins``). ``ages`` ({goal copy: {tag: {"guard": ..,
    "age": seconds}}}, e.g. ``btfsm.models.ariac.AGE_COPIES``): goal copies that pursue a belt
    part split by guards on its age (``since(arrive) >= 90``: the copy chosen when the
    state is entered; the part pursued was detected no later than the last arrival), each
    copy's pursuit bounded over parts at least ``age`` seconds old only. A copy of ``bins``
    with ``slots`` (indices into the area's spots, ``ariac.TRAY_ROWS``) has its target among
    those slots.

    ``third`` (goal copies, e.g. ``("approach_bins#place_bins",)``): a third state of
    history where it pays (``Timing.deep``, ``btfsm.positions.split_deeper``): every copy
    the token leaves halted into one of their copies is split again by the copy it was
    entered from, so those copies' runs start where that one began, not anywhere its
    entries may have left the arm."""
    from btfsm.positions import entries_of, requested_goals, split_by_goal, split_by_guard, split_history

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
    guards: dict = {}
    for s, cl in classes.items():  # a pick's or place's approach (the bins, the tray): one copy per guard of ``bins``
        for c in cl:
            if bins and c in bins:
                guards[f"{s}#{c}"] = {tag: spec["guard"] for tag, spec in bins[c].items()}
    aged = {c: {tag: spec["guard"] for tag, spec in by.items()} for c, by in (ages or {}).items()}
    by_goal = split_by_goal(model, d.fsm, classes)
    # the goal copies split by their guards: the bins, the tray's rows, the ages
    tracked = track(by_goal) if track is not None and guards else by_goal
    guarded = split_by_guard(split_by_guard(tracked, d.fsm, guards), d.fsm, aged)
    f = next(x for x in guarded.fsms if x.name == d.fsm)
    base = {}
    for s in f.states:
        base[s.id] = s.id.split("#", 1)[0]
    # the goals a copy's runs serve: its class's, requested by the model (a SkillRequest), and
    # not left at once by a direct edge (docs/semantics.md 5, step 1: then nothing runs)
    requested = requested_goals(model, d.fsm)
    f1 = next(x for x in by_goal.fsms if x.name == d.fsm)
    leaves = {st.id: {g for e in f1.edges if e.source == st.id and e.direct and e.guard is None
                      for g in (f1.goals if "*" in e.goals else e.goals)} for st in f1.states}
    goals_of = {}
    for s in f.states:
        b, _, c = s.id.partition("#")
        goals = set(classes[b][c.split("%", 1)[0]]) if c else served(f0, b)
        goals_of[s.id] = {g for g in goals if g in requested and g not in leaves[s.id.split("%", 1)[0]]}

    def tag_of(sid):
        """The tag of a (history-split) copy of a bin or tray-row guard copy, or None (an age
        copy's tag names no target: ``age_of``)."""
        head, _, tag = sid.split("@", 1)[0].partition("%")
        return tag if tag and head not in aged else None

    def age_of(sid) -> float:
        """The least age (s) of the part a copy's runs pursue (0 but for an age copy)."""
        head, _, tag = sid.split("@", 1)[0].partition("%")
        return float(ages[head][tag]["age"]) if ages and head in ages else 0.0

    def tagged(p):
        return p[3] if len(p) > 3 else None

    # 2. poses: geometry and moves
    def boxes(points) -> tuple:
        """(contact box, above box: raised by the clearance) of contact ``points``."""
        c, h = _box(points), geo.g["clearance"]
        return c, ((c[0][0], c[0][1], c[0][2] + h), (c[1][0], c[1][1], c[1][2] + h))

    placed = {}  # area -> (contact box, above box) of the place targets limited by place_spots
    for a, xs in (place_spots or {}).items():
        placed[a] = boxes([(x, y, z) for x, y in xs for z in geo.g["contact"][a]])

    binbox = {}  # tag -> (contact box, above box) of its bins' spots, or of its tray slots
    for goal, copies in (bins or {}).items():
        for tag, spec in copies.items():
            if "slots" in spec:  # indices into the area's spots (the tray's slots; all of them past its last)
                sp = geo.g["spots"][d.goal(goal)[1]]
                xs = [sp[k] for k in spec["slots"] if k < len(sp)] or sp
                binbox[tag] = boxes([(x, y, z) for x, y in xs for z in geo.g["contact"][d.goal(goal)[1]]])
            else:
                binbox[tag] = boxes([(x, y, z) for b in spec["bins"] for x, y in geo.g["bin"][b][0]
                                     for z in geo.g["bin"][b][1]])

    def box(p):
        k, x = p[0], (p[1] if len(p) > 1 else None)
        if tagged(p) is not None and k in ("above", "contact", "lifted"):
            c, a = binbox[tagged(p)]
            if k == "lifted":
                hz = geo.hub[x][0][2]
                return ((c[0][0], c[0][1], hz), (c[1][0], c[1][1], hz))
            return a if k == "above" else c
        if k in ("above", "contact") and x in placed and len(p) > 2 and p[2] is not None \
                and p[2] == place_goal.get(x):
            return placed[x][k == "above"]
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
        return (len(p) >= 3 and len(q) >= 3 and p[1] == q[1] and p[2] is not None and p[2] == q[2]
                and tagged(p) == tagged(q) and "none" not in (p[0], q[0]))

    def rest(p, q) -> float:
        a, b = box(p), box(q)
        (_, dxy), (_, dz) = _distances(a, b)
        if same(p, q):
            dxy = 0.0
        return geo.rest_time(dxy, dz)

    def lifted(p, x):
        if p[0] in ("above", "contact", "lifted") and p[1] == x:
            return ("lifted", x, p[2]) + tuple(p[3:])
        return p  # at a hub or home: already at least that high

    def run(sid, g, p) -> tuple:
        """(slowest seconds, end poses) of a run of state sid for goal g starting at pose p."""
        s, x, k = base[sid], area(base[sid]), kind(base[sid])
        if k == "grasp":
            if p[0] == "none" or g != pick_goal.get(x):
                return 0.0, {p}  # nothing to grasp: it fails at once
            t: tuple = ("contact", x, pick_goal[x])
            if tagged(p) is not None and p[2] == t[2] and p[1] == x:
                t += (tagged(p),)  # the part the approach went above: in its bins
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
            if tagged(p) is not None and p[2] == t[2] and p[1] == x:
                t += (tagged(p),)  # back where it was taken: in its bins
            return rest(p, t), {t}
        if role == "put":
            if p[0] == "none":
                return 0.0, {p}  # nowhere to put it: done at once
            t = ("contact", x, place_goal.get(x))
            if tagged(p) is not None and p[2] == t[2] and p[1] == x:
                t += (tagged(p),)  # the spot the approach went above: in its bins
            return rest(p, t), {t, p}
        t = approach_target(x, g)
        sure = False
        age = age_of(sid)
        if t[0] == "above" and tag_of(sid) is not None:
            t += (tag_of(sid),)
            sure = bool((bins or {})[g][tag_of(sid)]["free"])
        if t[0] == "above" and x == "conveyor":
            if same(p, t):
                return geo.dt + geo.TRACK_MARGIN, {t}
            if no_loss:  # the part is on the belt until it is grasped: the pursuit reaches it
                return geo.track(box(p), box(t)[0][2], age), {t}
            # ended where the part left the belt (lost, or taken), or at the hub when none was there
            slow = max(geo.track(box(p), box(t)[0][2], age), rest(p, ("hub", x)))
            return slow, {t, ("hub", x), p}
        if t[0] == "above":
            if p == ("none", x, g) and not sure:
                return 0.0, {p}  # still no target: it stays at the hub
            if same(p, t):
                return 0.0, {t}  # already above it (the same target while nothing changed)
            if sure:  # the guard says there is one
                return rest(p, t), {t}
            # no target (no part, no free spot): the hub, until the gripper changes something
            return max(rest(p, t), rest(p, ("hub", x))), {t, ("none", x, g)}
        return rest(p, t), {t}

    def forget(ps, kinds=("pick", "place")):
        out = set()
        for p in ps:
            if len(p) >= 3 and p[2] is not None and d.goal(p[2])[0] in kinds:
                p = ("hub", p[1]) if p[0] == "none" else (p[0], p[1], None) + tuple(p[3:])
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
    f2 = next(x for x in split_history(guarded, d.fsm, timed_states).fsms
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
    # 5. a third state of history where it pays (``third``): a copy u@w that the token leaves
    # halted (a direct edge) into a copy of a goal copy of ``third``, split again by the copy it
    # is entered from (w@v: its runs from there start where w's runs from v's ends left the
    # arm), grouped by every duration that gives (its own, each successor's from it)
    deep: dict = {}
    halted = sorted({u for s2, ent in entries2.items() if s2.split("@", 1)[0].split("%", 1)[0] in third
                     for u, (direct, _) in ent.items() if u and direct and kind(base[u]) != "instant"})
    for u in halted:
        succ = [(y, ent[u]) for y, ent in entries2.items() if u in ent and kind(base[y]) != "instant"]
        sigs: dict = {}
        for w, (dw, gw) in entries2[u].items():
            su = {("home",)} if not w else leave(w, at[w], dw, gw)
            nxt = {}
            for y, (dy, gy) in succ:
                y1 = y.split("@", 1)[0]
                starts = leave(u, su, dy, gy)
                hi = max((run(y1, g, p)[0] for g in goals_of[y1] for p in starts), default=0.0)
                nxt[y] = round(hi + geo.dt + 1e-3, 3)
            sig = (table[u][w], tuple(sorted(nxt.items())))
            deep.setdefault(u, {})[w] = [sigs.setdefault(sig, len(sigs)), nxt]
    where = {s: sorted(":".join("*" if v is None else str(v) for v in p) for p in ps) for s, ps in where.items()}
    return Timing(d.fsm, classes, table, where, history=sorted(timed_states), assume="no_loss" if no_loss else None,
                  guards=guards, ages=aged, deep=deep, requested=requested)


def derive_ariac(scene=None, no_loss: bool = False) -> Timing:
    """``derive`` for the timed ARIAC models (``btfsm.models.ariac.timed``): the arm FSM of
    ``ariac.preemptive()``, its places at the bins split by which bin they go to
    (``ariac.PLACE_BINS``, read from the bins' occupancy ``ariac.with_bins`` gives the timed
    models), and its belt pursuits by the part's age (``ariac.AGE_COPIES``, read from the
    arrivals' spacing); ``models/ariac_timing.json``."""
    from btfsm.models import ariac

    return derive(ariac.spaced(ariac.preemptive()), scene, no_loss=no_loss,
                  bins={**ariac.BIN_COPIES, **ariac.TRAY_COPIES}, track=ariac.with_bins, ages=ariac.AGE_COPIES,
                  third=ariac.THIRD)


class Derived(NamedTuple):
    """One call site's duration in a scene: ``label`` (``fsm.state`` or the Action's
    name), ``call`` (the library primitive it runs), ``duration`` ``(min, max)`` seconds
    or None (unbounded: the scene gives no bound), ``how`` (where it comes from, or why
    there is none) and ``source``: ``derived``, ``declared`` (the model's own duration,
    kept) or ``unbounded``."""

    label: str
    call: str
    duration: "tuple | None"
    how: str
    source: str


_INSTANT = ("release", "detect", "succeed")
_STILL = ("grip", "release", "gripper", "wait", "detect", "wait_for", "open_door", "close_door", "succeed")


def _clip(box, a, b) -> "tuple | None":
    """(s0, s1): the stretch of segment a->b (arc length from a) inside the box, or None."""
    (ax, ay), (bx, by) = a, b
    length = math.hypot(bx - ax, by - ay)
    t0, t1 = 0.0, 1.0
    for d, lo, hi, p in ((bx - ax, box[0], box[2], ax), (by - ay, box[1], box[3], ay)):
        if abs(d) < 1e-12:
            if not lo <= p <= hi:
                return None
            continue
        u0, u1 = sorted(((lo - p) / d, (hi - p) / d))
        t0, t1 = max(t0, u0), min(t1, u1)
    return None if t0 > t1 else (t0 * length, t1 * length)


def _start_points(model, scene, calls) -> dict:
    """``{(fsm, state): set of (x, y) | None}``: where the robot is when a run of the
    state starts (None: somewhere not known, e.g. where a halted or blocked move stopped).
    A run starts where the run of the state it came from ended: the frame of a move that
    succeeded, the start of a run that does not move the robot (a grip, a wait), else
    not known; the initial state's first run starts at the robot's home, and a state's
    run may start again where its own last run ended (a new request)."""
    sites = {(s.fsm, s.state): s for s in model.program.sites if s.kind == "state"}
    out: dict = {}
    for f in model.fsms:
        def call(sid):
            site = sites.get((f.name, sid))
            return None if site is None else calls.get(site.index)

        def moves(sid):
            c = call(sid)
            return c is None or c[0] not in _STILL  # unbound or custom: may move

        start: dict = {s.id: set() for s in f.states}
        home = None
        for s in f.states:
            c = call(s.id)
            if c is not None:
                home = tuple(scene.robots[c[1]]["home"])
                break
        start[f.initial] = {home} if home is not None else {None}

        def end(sid):
            c = call(sid)
            if c is not None and c[0] in ("move_to", "carry_to"):
                return {tuple(c[2]["frame"])}
            return set(start[sid]) if not moves(sid) else {None}

        for _ in range(len(f.states) + 2):
            changed = False
            for s in f.states:
                new = set(start[s.id]) | end(s.id)
                for e in f.edges:
                    if e.target != s.id:
                        continue
                    if e.direct or e.on != Status.SUCCESS:
                        new |= set(start[e.source]) if not moves(e.source) else {None}
                    else:
                        new |= end(e.source)
                if new != start[s.id]:
                    start[s.id], changed = new, True
            if not changed:
                break
        for sid, pts in start.items():
            out[(f.name, sid)] = pts
    return out


def _part_wait(scene, robot, p, rate) -> tuple:
    """(seconds, how) until a part is under the tool at p, or (None, why not)."""
    spec = scene.robots[robot]
    close = spec["close_time"] if spec["gripper"] == "fingers" else 0.0
    for name, a in scene.areas.items():
        r = a["region"]
        if r[0] <= p[0] <= r[2] and r[1] <= p[1] <= r[3]:
            return close, f"the part rests in area {name}" + (f"; the fingers close in {close:g} s" if close else "")
    for sname, sen in scene.sensors.items():
        if not sen.get("on_enter"):
            continue
        for bname, b in scene.belts.items():
            stretch = _clip(sen["region"], b["from"], b["to"])
            if stretch is None:
                continue
            (ax, ay), (bx, by), length = b["from"], b["to"], b["length"]
            ux, uy = (bx - ax) / length, (by - ay) / length
            s_p = (p[0] - ax) * ux + (p[1] - ay) * uy
            lateral = abs(-(p[0] - ax) * uy + (p[1] - ay) * ux)
            radius = spec["radius"]
            stop = length - max(scene.part_types[t] for t in b["part_types"]) if b["end"] == "stop" else length
            if lateral > radius or s_p - radius > stop or s_p < stretch[0] - radius:
                continue
            travel = max(0.0, min(s_p, stop) - stretch[0])
            secs = travel / b["speed"] + close
            return secs, (f"a part sensor {sname} reported ('{sen['on_enter']}') rides belt {bname} "
                          f"{travel:.3f} m to the tool at {b['speed']:g} m/s" + (f", then the fingers close in {close:g} s"
                                                                                  if close else ""))
    return None, f"no part rests or is reported arriving at ({p[0]:g}, {p[1]:g})"


def derive_scene(model, scene) -> dict:
    """``{site index: Derived}``: a duration for every call site of ``model`` (FSM states and
    Actions) that a scene's ``bind`` table drives and that can answer RUNNING, from the
    scene (docs/verification.md 2.1). A site whose duration the model declares keeps it.

    * ``move_to``, ``carry_to``: the slowest rest-to-rest move of the robot (its velocity
      and acceleration limits at the call's speed scale) to the frame from the farthest
      of its home and the frames its moves go to (a halted move stops on a segment
      between those points, no farther); ``move_to_part``: to the farthest corner of the
      area;
    * ``grip``: the gripper's ``close_time`` (fingers; a vacuum attaches at once); with
      ``wait``, also until a part is under the tool at the points the robot can be when
      the run starts (``_start_points``): at once where parts rest (an area), or the belt
      travel from where a sensor reported the part to the tool. This assumes the model
      grips only where a part is (its tree's conditions: ``waiting > 0``); a run in which
      the part does not come is refused by the runtime (the declared maximum is
      exceeded), so trials test the assumption. Anywhere else: unbounded;
    * ``wait``: its seconds; ``open_door``/``close_door``: the door's ``open_time``
      (closing assumes the tool is out of the door: the door waits for it otherwise);
    * ``wait_for``, custom ``python:`` primitives: unbounded (the scene does not say when
      a part comes, or what the code does): declare ``duration:`` in the model.

    Every maximum adds one physics step and 1 ms; minimums are 0 (a halted run may
    restart next to its end), except ``wait``'s (its seconds less one tick)."""
    from .loop import start
    from .scene import Profile

    _world, binding, _rt = start(scene, model, 0, arrivals=False)
    calls = getattr(binding, "calls", None)
    if calls is None:
        raise ModelError("bind", f"scene {scene.name} binds the model through a Python binding: durations are "
                         "derived from a bind table's primitives (or, for the kitting binding, by derive())", scene.file)
    prog = model.program
    points: dict = {}
    for lib, robot, args in calls.values():
        pts = points.setdefault(robot, {tuple(scene.robots[robot]["home"])})
        if lib in ("move_to", "carry_to"):
            pts.add(tuple(args["frame"]))
        elif lib == "move_to_part":
            r = scene.areas[args["area"]]["region"]
            pts.update({(r[0], r[1]), (r[0], r[3]), (r[2], r[1]), (r[2], r[3])})
    starts = _start_points(model, scene, calls)
    pad = scene.dt + 1e-3
    out: dict = {}
    for site in prog.sites:
        label = site.label.replace("/", ".")
        if not any(o[0] == int(Status.RUNNING) for o in site.outcomes):
            continue  # answers at once: nothing to bound
        c = calls.get(site.index)
        if c is None:
            if site.index in binding.sites:  # a custom python: primitive
                dec = _declared(model, site)
                out[site.index] = (Derived(label, "python", dec, "declared in the model", "declared") if dec else
                                   Derived(label, "python", None, "custom python: the scene cannot bound it; declare "
                                           "duration: in the model", "unbounded"))
            continue
        lib, robot, args = c
        shown = lib + ("(" + ", ".join(f"{k}={v!r}" if not isinstance(v, tuple) else f"{k}=({v[0]:g}, {v[1]:g})"
                                       for k, v in args.items()) + ")" if args else "")
        declared = _declared(model, site)
        if declared is not None:
            out[site.index] = Derived(label, shown, declared, "declared in the model", "declared")
            continue
        spec = scene.robots[robot]
        lo, hi, how = 0.0, None, ""
        if lib in ("move_to", "carry_to", "move_to_part"):
            if lib == "move_to_part":
                r = scene.areas[args["area"]]["region"]
                targets = [(r[0], r[1]), (r[0], r[3]), (r[2], r[1]), (r[2], r[3])]
            else:
                targets = [tuple(args["frame"])]
            far = max(math.hypot(tx - x, ty - y) for tx, ty in targets for x, y in points[robot])
            s = float(args["speed"])
            hi = Profile(far, spec["speed"] * s, spec["acceleration"] * s).total
            how = f"rest-to-rest over {far:.3f} m (the farthest start) at speed scale {s:g}"
        elif lib in ("grip", "gripper"):
            close = spec["close_time"] if spec["gripper"] == "fingers" else 0.0
            if lib == "gripper" or not args.get("wait"):
                hi, how = close, f"the {spec['gripper']} gripper closes in {close:g} s"
            else:
                pts = starts.get((site.fsm, site.state), {None}) if site.kind == "state" else {None}
                waits = [(None, "where the robot is when it starts is not known (an Action, or a halted move "
                          "before it)")] if None in pts else [_part_wait(scene, robot, p, model.tick_rate)
                                                              for p in sorted(pts)]
                bad = [w for w in waits if w[0] is None]
                if bad:
                    hi, how = None, "grip waits for a part: " + bad[0][1]
                else:
                    hi = max(w[0] for w in waits)
                    how = "grip waits for a part: " + "; ".join(sorted({w[1] for w in waits}))
        elif lib == "wait":
            lo, hi = max(0.0, float(args["seconds"]) - 1.0 / model.tick_rate), float(args["seconds"])
            how = f"waits {args['seconds']:g} s"
        elif lib in ("open_door", "close_door"):
            d = scene.doors[args["door"]]
            hi = d["open_time"]
            how = f"door {args['door']} moves in {hi:g} s" + (" (with the tool out of it)" if lib == "close_door" else "")
        else:  # wait_for, and anything new
            how = (f"{lib} waits for a part in {args.get('region', '?')}: the scene does not say when one comes; "
                   "declare duration: in the model")
        if hi is None:
            out[site.index] = Derived(label, shown, None, how, "unbounded")
        else:
            out[site.index] = Derived(label, shown, (round(lo, 3), round(hi + pad, 3)), how, "derived")
    return out


def _declared(model, site) -> "tuple | None":
    """The duration the model itself declares for a site (state, Action or primitive)."""
    if site.kind == "state":
        st = next(s for s in next(f for f in model.fsms if f.name == site.fsm).states if s.id == site.state)
        if st.duration is not None:
            return st.duration
    else:
        node = next((n for n in model.nodes() if getattr(n, "name", None) == site.node), None)
        if node is not None and getattr(node, "duration", None) is not None:
            return node.duration
    prim = model.all_primitives().get(site.primitive)
    return getattr(prim, "duration", None)


def _with_durations(node, table: dict):
    """The tree with the Actions named in ``table`` given those durations."""
    import dataclasses

    from btfsm.bt import Action

    if isinstance(node, Action) and node.name in table:
        return dataclasses.replace(node, duration=table[node.name])
    kids = getattr(node, "children", None)
    if kids:
        return dataclasses.replace(node, children=tuple(_with_durations(k, table) for k in kids))
    child = getattr(node, "child", None)
    if child is not None:
        return dataclasses.replace(node, child=_with_durations(child, table))
    return node


def timed_in_scene(model, scene, responses=(), table: "dict | None" = None):
    """``model`` with the durations of ``derive_scene`` (or ``table``) on its FSM states and
    Actions, and ``responses`` added."""
    import dataclasses

    table = derive_scene(model, scene) if table is None else table
    sites = {s.index: s for s in model.program.sites}
    states: dict = {}
    actions: dict = {}
    for i, d in table.items():
        if d.source != "derived":
            continue
        s = sites[i]
        if s.kind == "state":
            states[(s.fsm, s.state)] = d.duration
        else:
            actions[s.node] = d.duration
    fsms = tuple(dataclasses.replace(f, states=tuple(
        dataclasses.replace(st, duration=states[(f.name, st.id)]) if (f.name, st.id) in states else st
        for st in f.states)) for f in model.fsms)
    tree = _with_durations(model.tree, actions) if model.tree is not None and actions else model.tree
    return dataclasses.replace(model, fsms=fsms, tree=tree, responses=tuple(model.responses) + tuple(responses))


def measure_scene(model, scene, seeds=(0,)) -> tuple:
    """``({site index: the longest run in seconds}, [mismatches])`` over runs of ``model`` in
    ``scene`` (one per seed, to the scene's ``terminal`` or time limit): a run of a site
    lasts from the tick that starts it to the tick it answers other than RUNNING, (n - 1)
    ticks of the model's rate (docs/semantics.md 6.1); a halted run is not counted. Run on
    the timed model (``timed_in_scene``), any run outside a declared duration is also a
    mismatch (the runtime refuses it)."""
    from .loop import Hooks, run_loop, start

    class _Done(Hooks):
        def done(self, rt, world, step) -> bool:
            term = model.program.terminal
            return term is not None and bool(term(list(step.state)))

    longest: dict = {}
    problems: list = []
    for seed in seeds:
        world, binding, rt = start(scene, model, seed)
        ticks: dict = {}
        tick_site = binding.tick_site

        def counted(call, tick_site=tick_site, ticks=ticks):
            i = call.site.index
            ticks[i] = 1 if call.first or i not in ticks else ticks[i] + 1
            out = tick_site(call)
            if i not in binding.active:  # the run answered: it is over
                longest[i] = max(longest.get(i, 0.0), (ticks.pop(i) - 1) / model.tick_rate)
            return out

        binding.tick_site = counted
        end = run_loop(rt, world, binding, scene.time_limit, _Done())
        if end.mismatch is not None:
            problems.append(f"seed {seed}: {end.mismatch}")
    return longest, problems


def print_scene_table(model, scene, table, file=None, measured: "dict | None" = None) -> None:
    """The derived durations, one line per site; the unbounded ones say why; ``measured``:
    ``{site index: seconds}`` (``measure_scene``), printed beside them."""
    print(f"{model.name} in scene {scene.name}: durations derived from the scene (context-free, per call site)", file=file)
    for i, d in table.items():
        iv = "unbounded" if d.duration is None else f"[{d.duration[0]:g}, {d.duration[1]:g}] s"
        tag = "" if d.source == "derived" else f" ({d.source})"
        meas = "" if measured is None else f" {('-' if i not in measured else format(measured[i], '.1f')):>5s}"
        print(f"  {d.label:24s} {iv:>16s}{meas}{tag}  {d.call}: {d.how}", file=file)


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
    p.add_argument("--trials", type=int, default=2, help="runs of the timed model in the scene (seeds 0..N-1) whose "
                   "longest run per site is printed beside the derived bound (0: none)")
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
        table = derive_scene(model, scene)
        timed = timed_in_scene(model, scene, reqs, table)
        timed.program  # the requirement's expressions are checked here
    except (ModelError, OSError) as exc:
        print(f"btfsm.sim.durations: {exc}", file=sys.stderr)
        return 2
    measured = None
    if args.trials > 0:
        measured, problems = measure_scene(timed_in_scene(model, scene, (), table), scene, range(args.trials))
        for problem in problems:
            print(f"measured: {problem}")
        print(f"(after the bound: the longest run in {args.trials} run(s) of the timed model in the scene, s; a run "
              "answers on the first tick at or after its bound, docs/semantics.md 6.1)")
    print_scene_table(model, scene, table, measured=measured)
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
