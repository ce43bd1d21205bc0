"""Replay a model checker's counterexample in the kitting cell (the ARIAC scene) or in a scene.

A counterexample says which environment events happened in which FSM state (a belt part
arrives while the arm is at ``release on agv``). The cell cannot follow its scripted
primitive outcomes (motions take the time physics gives them), so the replay re-creates
the counterexample's *situation*: it runs the same model in the cell and makes each of the
counterexample's events happen physically (a part reaches the belt sensor) as soon as the
arm's FSM is in the state where the counterexample had it. Then it watches what the robot
does: for the authors' original, it stays frozen while the part rides past and is lost.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any, cast

from .loop import Hooks, run_loop, start

__all__ = ["CellReplay", "cell_window", "wrap_answers", "triggers_of", "phases_of", "replay_in_cell", "SceneReplay", "scene_triggers", "replay_in_scene",
           "replay_for_cli"]


def triggers_of(ce: dict, fsm: str) -> list:
    """[(FSM state before the step, event name)] for every environment event of ``ce``."""
    state = ce["initial"].get(f"{fsm}.state")
    out = []
    for step in ce["steps"]:
        for ev in step.get("env", ()):
            out.append((state, ev))
        state = step.get("state", {}).get(f"{fsm}.state", state)
    return out


@dataclass
class CellReplay:
    model: str
    triggers: list
    injected: list = field(default_factory=list)  # (time, FSM state, part id)
    lost: list = field(default_factory=list)  # (time, part id)
    frozen: "tuple | None" = None  # (FSM state, from time, to time) longest time the arm did not move on
    kind: str = ""  # the counterexample's violation kind
    timeline: list = field(default_factory=list)  # (time, FSM state, goal) changes
    end_time: float = 0.0
    picture: "str | None" = None
    paced: int = 0  # ticks of the counterexample the replay was paced to (0: not paced)
    held: int = 0  # ticks a primitive that had finished in the cell was held RUNNING to follow it
    diverged: "tuple | None" = None  # (tick, counterexample's FSM state, the cell's) where pacing stopped
    mismatch: "str | None" = None  # the runtime refused a tick of the cell: the replay stopped there
    reaches: list = field(default_factory=list)  # (part id, s from its detection to the arm starting its grasp)
    at_ticks: bool = False  # the parts were sent at the counterexample's ticks (the arm unpaced)
    at_phase: bool = False  # the parts were sent at the counterexample's FSM phase (state, ticks into its visit)
    too_soon: list = field(default_factory=list)  # (time, FSM state): a phase the cell reached before the spacing allowed
    forced: list = field(default_factory=list)  # (time, site, outcome): the counterexample's failures forced on the cell
    skipped: list = field(default_factory=list)  # (time or None, site, outcome, why): its failures the cell did not follow
    responses: list = field(default_factory=list)  # (part id, s from its detection to the next belt grasp's start)
    grasp_states: set = field(default_factory=set)  # the FSM states that grasp on the belt
    decomposition: list = field(default_factory=list)  # (state, counterexample s, cell s): see ``decomposition``

    def text(self) -> str:
        lines = [f"cell replay of a counterexample on {self.model}: {len(self.triggers)} environment event(s)"]
        if self.paced:
            lines.append(f"  paced to the counterexample's {self.paced} ticks: each FSM state lasts at least as long as "
                         f"there (a primitive the cell finished earlier was held running {self.held} tick(s) in all)")
            if self.diverged:
                t, want, got = self.diverged
                lines.append(f"  pacing stopped at tick {t}: the counterexample is at '{want}', the cell at '{got}'")
        for t, st in self.too_soon:
            lines.append(f"  t = {t:6.1f} s: the arm FSM is at the counterexample's phase of '{st}' before the "
                         "arrivals' minimum interval allows a part: not sent yet (it waits while the phase lasts, "
                         "or for its next visit)")
        for t, st, pid in self.injected:
            how = ("at the counterexample's tick" if self.at_ticks else
                   "at the counterexample's phase: its state, as many ticks into the visit, the model's variables "
                   "as there" if self.at_phase else
                   "as in the counterexample")
            lines.append(f"  t = {t:6.1f} s: belt part {pid} sent to the sensor (arm FSM at '{st}', {how})")
        for t, site, outcome in self.forced:
            lines.append(f"  t = {t:6.1f} s: '{site}' answered '{outcome}' as in the counterexample "
                         "(the gripper let the part go)")
        for t, site, outcome, why in self.skipped:
            when = "" if t is None else f"t = {t:6.1f} s: "
            lines.append(f"  {when}the counterexample's '{outcome}' at '{site}' NOT forced: {why}")
        if self.at_phase and len(self.injected) < len(self.triggers):
            for k, (st, _ev) in enumerate(self.triggers[len(self.injected):], start=len(self.injected) + 1):
                lines.append(f"  part {k} of {len(self.triggers)} NOT sent: the cell did not reach the "
                             f"counterexample's phase at '{st}' (it did not follow the counterexample there)")
        for t, pid in self.lost:
            lines.append(f"  t = {t:6.1f} s: belt part {pid} reached the end of the belt: LOST")
        if self.frozen:
            st, t0, t1 = self.frozen
            lines.append(f"  the arm stayed in '{st}' from t = {t0:.1f} s to t = {t1:.1f} s ({t1 - t0:.1f} s without a move)")
        lines.append("  last FSM states: " + "; ".join(f"{t:.1f} s {s} ({g or '-'})" for t, s, g in self.timeline[-4:]))
        if self.mismatch:
            lines.append(f"  stopped: {self.mismatch}")
        for pid, r in self.reaches:
            lines.append(f"  belt part {pid} reached (the grasp starts) {r:.1f} s after its detection")
        reached = {pid for pid, _ in self.reaches}
        for pid, r in self.responses:
            if pid not in reached:
                lines.append(f"  belt part {pid}: the arm starts a belt grasp (the model's response) {r:.1f} s after "
                             "its detection")
        if self.decomposition:
            ce_total = sum(c for _, c, _x in self.decomposition)
            cell_total = sum(x for _, _c, x in self.decomposition)
            lines.append(f"  where the response time went, per FSM state (counterexample {ce_total:.1f} s, "
                         f"cell {cell_total:.1f} s):")
            for st, c, x in self.decomposition:
                lines.append(f"    {st:24s} {c:6.1f} s {x:6.1f} s {c - x:+6.1f} s")
        if self.kind == "response":  # a late response loses the belt part in the cell, or it does not
            belt_misses = any(site.split("/", 1)[-1] in self.grasp_states for _t, site, _o in self.forced)
            given_up = [pid for _, pid in self.lost if pid in reached and belt_misses]
            lines.append("  the cell shows the late response: a belt part was lost" if len(given_up) < len(self.lost)
                         else "  the cell does not show the late response: no belt part was lost" if not given_up else
                         "  the cell does not show the late response: no belt part was lost unreached (belt part(s) "
                         + ", ".join(map(str, given_up)) + " reached, then given up after forced misses, as in the "
                         "counterexample)")
        if self.picture:
            lines.append(f"  picture: {self.picture}")
        return "\n".join(lines)

    @property
    def shows_loss_while_frozen(self) -> bool:
        """A part was lost while the arm sat in one state for the whole pick window."""
        if not self.frozen:
            return False
        _, t0, t1 = self.frozen
        return any(t0 <= t <= t1 for t, _ in self.lost)


def _by_state(visits) -> dict:
    """{state the copies were split from: seconds} summed over ``visits`` [(state, seconds)], in order."""
    from btfsm.positions import base_state

    out: dict = {}
    for st, sec in visits:
        out[base_state(st)] = out.get(base_state(st), 0.0) + sec
    return out


def decomposition(ce: dict, fsm: str, result: "CellReplay", rate: float) -> list:
    """[(state, counterexample s, cell s)]: where the response time of a ``response``
    counterexample (from its trigger to the response) and the cell's (from the last part's
    detection to its next belt grasp) went, per FSM state (copies summed), in the
    counterexample's order; empty unless both are known."""
    v = ce.get("violation") or {}
    last = result.injected[-1][2] if result.injected and len(result.injected) == len(result.triggers) else None
    cell_r = dict(result.responses).get(last)
    if v.get("kind") != "response" or v.get("trigger_step") is None or cell_r is None:
        return []
    states = fsm_states_of(ce, fsm)
    k0 = int(v["trigger_step"])  # states[k0]: the state the trigger's tick reached
    k1 = next((k for k in range(k0, len(states)) if states[k] in result.grasp_states), len(states))
    ce_side = _by_state((states[k], 1.0 / rate) for k in range(k0, k1))
    tl = result.timeline
    end = next(t for t, st, _g in tl if t > 0 and st in result.grasp_states and t >= result.injected[-1][0])
    cell_side = cell_window(tl, end - cell_r, end, result.end_time)
    return [(st, round(ce_side.get(st, 0.0), 2), round(cell_side.get(st, 0.0), 2))
            for st in list(ce_side) + [x for x in cell_side if x not in ce_side]]


def cell_window(timeline, start: float, end: float, end_time: float) -> dict:
    """{state the copies were split from: seconds} the cell's FSM spent in each state
    between ``start`` and ``end`` (``timeline``: [(time, state, goal)] of its visits, the
    last one lasting until ``end_time``), in order."""
    segs = []
    for j, (t, st, _g) in enumerate(timeline):
        t1 = timeline[j + 1][0] if j + 1 < len(timeline) else end_time
        lo, hi = max(t, start), min(t1, end)
        if hi > lo + 1e-9:
            segs.append((st, hi - lo))
    return _by_state(segs)


def phases_of(ce: dict, fsm: str, event: str = "arrive", variables=()) -> list:
    """[(FSM state, ticks the FSM had been in it, {variable: value})] before each step of
    ``ce`` with ``event``; the values of the model's ``variables`` (names) then."""
    states = fsm_states_of(ce, fsm)
    out = []
    values = {k: ce["initial"].get(k) for k in variables}
    for i, step in enumerate(ce["steps"]):
        if event in step.get("env", ()):
            c = 0
            while c < i and states[i - c - 1] == states[i]:
                c += 1
            out.append((states[i], c, dict(values)))
        values.update({k: v for k, v in step.get("state", {}).items() if k in values})
    return out


def fsm_states_of(ce: dict, fsm: str) -> list:
    """The FSM's state before the first step of ``ce`` and after each step (index i: after step i)."""
    state = ce["initial"].get(f"{fsm}.state")
    out = [state]
    for step in ce["steps"]:
        state = step.get("state", {}).get(f"{fsm}.state", state)
        out.append(state)
    return out


class _Pacer:
    """Replays the counterexample's FSM visits with their durations as lower bounds: while
    the cell's FSM is in the counterexample's v-th visit (state s, n ticks), a primitive
    that would leave s before its n-th tick there is held RUNNING (the arm waits where its
    move ended); a visit the cell makes longer stays longer (the cell's arm cannot be made
    faster). Each visit thus lasts at least as long as in the counterexample, so a
    response it makes late is at least as late in the cell. Pacing stops at the first
    visit whose state differs from the counterexample's (``diverged``)."""

    def __init__(self, states: list):
        runs: list = []  # [state, ticks] of each visit; states[0] is the state before the first tick
        for st in states:
            if runs and runs[-1][0] == st:
                runs[-1][1] += 1
            else:
                runs.append([st, 1])
        self.visits = runs
        self.ticks = len(states) - 1
        self.v = self.c = 0  # the current visit, and the ticks the cell spent in it so far
        self.diverged: "tuple | None"
        self.now, self.held, self.diverged = None, 0, None
        self.tick = 0

    def active(self) -> bool:
        return self.diverged is None and self.v < len(self.visits)

    def at(self, v: int, c: int) -> bool:
        return self.active() and (self.v, self.c) == (v, c)

    def hold(self) -> bool:
        return self.active() and self.c + 1 < self.visits[self.v][1]

    def after(self, state) -> None:
        self.tick += 1
        if not self.active():
            return
        if state == self.visits[self.v][0]:
            self.c += 1
            return
        self.v, self.c = self.v + 1, 0
        if self.v < len(self.visits) and state != self.visits[self.v][0]:
            self.diverged = (self.tick, self.visits[self.v][0], state)

    def position(self, step: int) -> tuple:
        """(visit, ticks into it) of the counterexample's tick ``step`` (1-based)."""
        done = 0
        for v, (_, n) in enumerate(self.visits):
            if step - 1 < done + n:
                return v, step - 1 - done
            done += n
        return len(self.visits) - 1, 0

    def wrap(self, impl):
        return wrap_answers(impl, self._answer)

    def _answer(self, call, answer):
        if self.hold():
            running = [o[2] for o in call.site.outcomes if o[0] == 0]
            if running and answer not in running:
                self.held += 1
                return running[0]
        return answer


def wrap_answers(impl, change):
    """``impl`` (a primitive's implementation) answering ``change(call, its answer)``."""
    tick = impl if callable(impl) else impl.tick

    class Wrapped:
        halt = getattr(impl, "halt", None)

        def tick(self, call):
            return change(call, tick(call))
    return Wrapped()


class _Forced:
    """The counterexample's failures, forced on the cell, before and after its arrivals:
    the n-th run of a site (an FSM state's copy: its two states of history) that ends in
    the cell ends as the counterexample's n-th run there did, when that was a failure (a
    grasp's ``missed``: the only failures the ARIAC models let the environment choose) and
    the cell's answer a success, and the model's variables are the counterexample's then
    (the phase: the tray's count, the gripper, the queue, the retries); the gripper lets
    the part go (a grasp that missed: the vacuum did not hold). The answer comes on the
    cell's own tick, so it is inside the declared duration. A failure the cell does not
    follow is listed (``skipped``): the variables differ there, the cell failed where the
    counterexample succeeded, or the cell never ran the site that often (``finish``). A
    variable the counterexample does not give (None) is not compared."""

    def __init__(self, ce: dict, model, grasp: "str | None" = None):
        sites = {site.label: site for site in model.program.sites}
        names = [v.name for v in model.variables]
        values = {k: ce["initial"].get(k) for k in names}
        self.skipped: list = []  # (time or None, site label, outcome, why): a failure of the counterexample not forced
        self.ends: dict = {}  # site label -> [(outcome, the model's variables before that tick)] of each run's end
        for step in ce["steps"]:
            for label, outcome in step.get("outcomes", ()):
                site = sites.get(label)
                if site is None:
                    continue
                status = {o[2]: o[0] for o in site.outcomes}
                if status.get(outcome, 0) == 0 or 2 not in status.values():
                    continue
                if grasp is None or site.primitive == grasp:
                    self.ends.setdefault(label, []).append((outcome, dict(values)))
                elif status[outcome] == 2:
                    self.skipped.append((None, label, outcome, "not a grasp: the cell has no way to make it fail"))
            values.update({k: v for k, v in step.get("state", {}).items() if k in values})
        self.fails = {label: {o[2] for o in sites[label].outcomes if o[0] == 2} for label in self.ends}
        self.seen: dict = {}  # site label -> runs ended in the cell
        self.forced: list = []  # (time, site label, outcome) forced on the cell
        self.world: Any = None
        self.robot: Any = None

    def wrap(self, impl):
        return wrap_answers(impl, self._answer)

    def _answer(self, call, answer):
        label = call.site.label
        runs = self.ends.get(label)
        status = {o[2]: o[0] for o in call.site.outcomes}
        if runs is None or status.get(answer, 0) == 0:
            return answer
        n = self.seen.get(label, 0)
        self.seen[label] = n + 1
        if n >= len(runs):
            return answer
        want, values = runs[n]
        if status.get(want) != 2 or status.get(answer) == 2:
            if status.get(want) == 1 and status.get(answer) == 2:
                self.skipped.append((round(call.time, 2), label, want, f"the cell answered '{answer}' (run {n + 1})"))
            return answer
        differ = {k: call.vars[k] for k, v in values.items() if v is not None and call.vars[k] != v}
        if differ:
            self.skipped.append((round(call.time, 2), label, want, f"run {n + 1} there, but "
                                 + ", ".join(f"{k} = {v} (counterexample: {values[k]})" for k, v in differ.items())))
            return answer
        self.world.release(self.robot)
        self.forced.append((round(call.time, 2), label, want))
        return want

    def finish(self) -> None:
        """List the counterexample's failures at runs the cell never made."""
        for label, runs in self.ends.items():
            for n in range(self.seen.get(label, 0), len(runs)):
                if runs[n][0] in self.fails[label]:
                    self.skipped.append((None, label, runs[n][0], f"the cell ran it {self.seen.get(label, 0)} "
                                         f"time(s); the counterexample's failure was its run {n + 1}"))


class _CellHooks(Hooks):
    """The cell replay's counts: the arm FSM's timeline and longest stay, the injections
    (at the counterexample's FSM states, or paced to its ticks), the animation frames, and
    the end ``settle`` seconds after the last injected part left the belt."""

    def __init__(self, fsm, beam, result, pending, pacer, arrive_at, frames, settle, on_tick=None, binding=None,
                 arrive_ticks=None, phases=None, spacing=0.0):
        self.fsm, self.beam, self.result, self.pending, self.pacer = fsm, beam, result, pending, pacer
        self.arrive_at, self.frames, self.settle, self.on_tick = arrive_at, frames, settle, on_tick
        self.last, self.since, self.done_at = None, 0.0, None
        self.binding, self.arrive_ticks = binding, arrive_ticks
        self.phases, self.spacing = phases, spacing  # [(state, ticks into its visit, variables)], the arrivals' minimum interval
        self.in_state = 0  # ticks the FSM has been in its current state (before this tick)
        self.vars: dict = {}  # the model's variables before this tick (phases)
        self.missed = False  # the cell left the phase's state before its tick: send on the next tick
        self.refused: "float | None" = None  # the visit (its start time) whose phase came too soon
        self.reached: set = set()
        self.responded: set = set()
        self.grasps: set = set()  # the arm FSM's states that grasp on the belt
        if binding is not None:
            d = binding.d
            f = next(x for x in binding.model.fsms if x.name == d.fsm)
            self.grasps = {st.id for st in f.states if st.primitive == d.grasp and d.area(dict(st.args)) == binding.belt_area}

    def _stay(self, st, world) -> None:
        """The FSM stayed in ``st`` from ``since`` until now: keep the longest stay."""
        frozen = self.result.frozen
        if frozen is None or world.time - self.since > frozen[2] - frozen[1]:
            self.result.frozen = (st, round(self.since, 2), round(world.time, 2))

    def before(self, rt, world) -> None:
        result, pacer, pending = self.result, self.pacer, self.pending
        st, goal = rt.fsm_state(self.fsm)
        if (st, goal) != self.last:
            result.timeline.append((round(world.time, 2), st, goal))
            if self.last is None or st != self.last[0]:
                if self.last is not None:
                    self._stay(self.last[0], world)
                self.since = world.time
            self.last = (st, goal)
        if self.phases is not None:  # at the counterexample's phase, the arm at its own speed
            self.vars = rt.vars
            due = self._phase_due(st, world)
        elif self.arrive_ticks is not None:  # at the counterexample's ticks, the arm at its own speed
            due = bool(pending) and rt.clock.tick >= self.arrive_ticks[len(result.injected)]
        else:
            due = (pending and (pacer.at(*self.arrive_at[len(result.injected)]) if pacer is not None and pacer.active()
                                else pending[0][0] == st))
        if due:
            pid = world.spawn(self.beam)
            result.injected.append((round(world.time, 2), st, pid))
            pending.pop(0)
        if pacer is not None:
            pacer.now = st

    def _values_are(self, values: dict) -> bool:
        """The model's variables hold the counterexample's values (the phase's other half:
        the nth visit of a state is told from the first by the tray's count, say)."""
        return all(self.vars.get(k) == v for k, v in values.items())

    def _phase_due(self, st, world) -> bool:
        """A part is due: the FSM is in the next phase's state, as many ticks into its visit
        as in the counterexample (or it has just left that state before that tick), and
        the arrivals' minimum interval since the last part sent has passed."""
        result = self.result
        if not self.pending:
            return False
        want, c, values = self.phases[len(result.injected)]
        here = st == want and self.in_state >= c and self._values_are(values)
        left = self.missed and st != want
        self.missed = st == want and self.in_state < c and self._values_are(values)
        if not (here or left):
            return False
        if result.injected and world.time - result.injected[-1][0] < self.spacing - 1e-9:
            if self.refused != self.since:  # once per visit
                self.refused = self.since
                result.too_soon.append((round(world.time, 2), want))
            return False
        return True

    def after(self, rt, world, step, before) -> None:
        st_now = rt.fsm_state(self.fsm)[0]
        self.in_state = self.in_state + 1 if self.last is not None and st_now == self.last[0] else 0
        if self.pacer is not None:
            self.pacer.after(rt.fsm_state(self.fsm)[0])
        b = self.binding
        if b is not None and rt.fsm_state(self.fsm)[0] in self.grasps:
            pid = b.targets.get(b.belt)
            detected = dict(b.detections)
            if pid in detected and pid not in self.reached:  # the grasp of this belt part starts
                self.reached.add(pid)
                self.result.reaches.append((pid, round(world.time - detected[pid] - 1.0 / rt.model.tick_rate, 2)))
            for pid, t in b.detections:  # the model's response: a belt grasp starts after the detection
                if pid not in self.responded:
                    self.responded.add(pid)
                    self.result.responses.append((pid, round(world.time - t - 1.0 / rt.model.tick_rate, 2)))
        if self.on_tick is not None:
            self.on_tick(rt, world)
        if self.frames is not None and rt.clock.tick % 5 == 0 and len(self.frames) < 2000:
            self.frames.append(world.snapshot())
        injected = [pid for _, _, pid in self.result.injected]
        if (not self.pending and injected and self.done_at is None
                and all(world.parts[p].place.kind != "BELT" for p in injected)):
            self.done_at = world.time

    def done(self, rt, world, step) -> bool:
        return self.done_at is not None and world.time >= self.done_at + self.settle

    def finish(self, world) -> None:
        if self.last is not None:
            self._stay(self.last[0], world)
        injected = [pid for _, _, pid in self.result.injected]
        self.result.lost = [(round(t, 2), pid) for t, pid, _src, dst in world.log
                            if pid in injected and dst.kind == "LOST"]


def replay_in_cell(model, ce, *, time_limit: float = 120.0, render: "str | None" = None, gif: "str | None" = None,
                   settle: float = 20.0, pace: "bool | str | None" = None, on_tick=None,
                   lift_spacing: bool = False) -> CellReplay:
    """Run ``model`` in the ARIAC scene, raising the counterexample's events in its FSM states.

    ``pace`` (default: for a ``response`` counterexample, whose timing is the point): the
    events happen at the counterexample's ticks and a primitive the cell finishes before
    the counterexample does is held running until the counterexample's tick (the arm waits
    where its move ended); the cell's arm cannot be made faster than it is. ``pace="times"``:
    the parts are sent at the counterexample's ticks, its failures forced as below, the arm unpaced; ``pace="phase"``: a
    part is sent when the cell's FSM is in the state the counterexample had at that
    arrival, as many ticks into the visit (on the next tick when the cell leaves the state
    sooner) with the model's variables as there (the tray's count, the gripper, the queue), the arm
    unpaced; a phase reached before the arrivals' minimum interval allows
    a part is listed in ``too_soon`` and the part waits for the phase's next visit; the
    counterexample's failures, before and after its arrivals, are forced on the cell at
    their phases (``_Forced``: a grasp's n-th run there, the model's variables as there),
    and ``decomposition`` says where the response time went, per FSM state, there and in
    the cell. ``lift_spacing``: the model's environment events lose their minimum interval
    (durations stay enforced), to put the cell in a phase that it reaches sooner than the
    spacing allows: a diagnosis of the bound, not a run of the model. Stops
    ``settle`` seconds after the last injected part was lost or picked, at ``time_limit``,
    or when the runtime refuses a tick (``mismatch``). ``on_tick(rt, world)``: called after
    each tick (``cell_view.CellView``)."""
    from .experiment import TrialSpec
    from .trial import build_trial

    if isinstance(ce, str):
        with open(ce, encoding="utf-8") as fh:
            ce = json.load(fh)
    if "counterexample" in ce:
        ce = ce["counterexample"]
    kind = (ce.get("violation") or {}).get("kind", "")
    spec = TrialSpec("preemptive", 1, time_limit=time_limit)
    if lift_spacing:
        import dataclasses

        model = dataclasses.replace(model, environment=tuple(
            dataclasses.replace(e, min_interval=None) if getattr(e, "min_interval", None) else e
            for e in model.environment))
    pacer = arrive_at = None
    arrive_ticks = phases = None
    forced = None
    from .binding import Dialect, dialect_of

    dialect = cast(Dialect, dialect_of(model))  # the kitting vocabulary: the arm FSM, the grasp primitive
    if pace == "phase":  # the counterexample's FSM phase at each arrival, its failures, the arm unpaced
        phases = phases_of(ce, dialect.fsm, variables=[v.name for v in model.variables])
        forced = _Forced(ce, model, dialect.grasp)
    elif pace == "times":  # the counterexample's arrival ticks and failures, the arm unpaced
        arrive_ticks = [i - 1 for i, step in enumerate(ce["steps"], start=1) for ev in step.get("env", ()) if ev == "arrive"]
        forced = _Forced(ce, model, dialect.grasp)
    elif pace if pace is not None else kind == "response":
        pacer = _Pacer(fsm_states_of(ce, dialect.fsm))
        # a part for the counterexample's tick i reaches the sensor in the world steps before
        # the cell's tick at the same point of the same visit
        arrive_at = [pacer.position(i) for i, step in enumerate(ce["steps"], start=1)
                     for ev in step.get("env", ()) if ev == "arrive"]
        arrive_at = [(v, max(0, c - 1)) for v, c in arrive_at]
    model, world, binding, rt = build_trial(spec, model, detections=(),
                                            wrap=pacer.wrap if pacer else forced.wrap if forced else None)
    d = binding.d
    pending = [t for t in triggers_of(ce, d.fsm) if t[1] == "arrive"]
    result = CellReplay(model.name, list(pending), kind=kind, paced=pacer.ticks if pacer else 0,
                        at_ticks=arrive_ticks is not None, at_phase=phases is not None)
    frames: "list | None" = [] if gif else None
    spacing = max([e.min_interval or 0.0 for e in model.environment if getattr(e, "name", None) == "arrive"],
                  default=0.0)
    hooks = _CellHooks(d.fsm, world.scene.sensors[binding.sensor]["region"], result, pending, pacer, arrive_at,
                       frames, settle, on_tick, binding, arrive_ticks, phases, spacing)
    if forced is not None:
        forced.world, forced.robot = world, binding.robot
    end = run_loop(rt, world, binding, time_limit, hooks, stop_at_mismatch=False)
    hooks.finish(world)
    if end.ended_by is not None:
        result.mismatch = str(end.ended_by)
    if pacer is not None:
        result.held, result.diverged = pacer.held, pacer.diverged
    if forced is not None:
        forced.finish()
        result.forced, result.skipped = forced.forced, forced.skipped
    result.end_time = round(world.time, 2)
    result.grasp_states = set(hooks.grasps)
    if phases is not None:
        result.decomposition = decomposition(ce, d.fsm, result, model.tick_rate)
    if render:
        from .scene_render import render_scene

        st, goal = rt.fsm_state(d.fsm)
        result.picture = render_scene(world.scene, world.snapshot(), render,
                                      title=f"{model.name}: counterexample in the cell ({d.fsm}: {st}, goal {goal or '-'})")
    if frames is not None:
        from .scene_render import write_gif

        write_gif(world.scene, frames, gif, fps=10, title=f"{model.name}: counterexample in the cell")
    return result


@dataclass
class SceneReplay:
    model: str
    scene: str
    triggers: list
    injected: list = field(default_factory=list)  # (time, FSM states, event, part id, "world" or None)
    lost: list = field(default_factory=list)  # (time, part id)
    taken: list = field(default_factory=list)  # (time, part id): injected parts a gripper took
    mismatch: "str | None" = None
    timeline: list = field(default_factory=list)  # (time, {fsm: (state, goal)}) changes
    end_time: float = 0.0
    picture: "str | None" = None

    def text(self) -> str:
        lines = [f"scene replay of a counterexample on {self.model} in scene {self.scene}: "
                 f"{len(self.triggers)} environment event(s)"]
        events = []  # (time, kind order, text): printed in time order, injections first at a tie
        for t, states, ev, pid in self.injected:
            how = ("left to the world: raised when a part leaves a sensor's region untaken" if pid == "world" else
                   f"part {pid} put where a sensor will see it" if pid is not None else
                   "no sensor raises it: given directly")
            events.append((t, 0, f"'{ev}' ({how}; FSMs at {_states_text(states)}, as in the counterexample)"))
        events += [(t, 1, f"part {pid} taken by the gripper") for t, pid in self.taken]
        events += [(t, 2, f"part {pid} LOST") for t, pid in self.lost]
        for t, _, text in sorted(events, key=lambda e: (e[0], e[1])):
            lines.append(f"  t = {t:6.1f} s: {text}")
        if len(self.injected) < len(self.triggers):
            lines.append(f"  {len(self.triggers) - len(self.injected)} event(s) never injected: the FSMs did not reach "
                         "the counterexample's state(s)")
        if self.mismatch:
            lines.append(f"  stopped: {self.mismatch}")
        lines.append("  last FSM states: " + "; ".join(f"{t:.1f} s {_states_text(st)}" for t, st in self.timeline[-4:]))
        if self.picture:
            lines.append(f"  picture: {self.picture}")
        return "\n".join(lines)


def _states_text(states: dict) -> str:
    return ", ".join(f"{f}={s}" for f, s in states.items())


def scene_triggers(ce: dict, fsms) -> list:
    """[({fsm: state} before the step, event name)] for every environment event of ``ce``."""
    now = {f: ce["initial"].get(f"{f}.state") for f in fsms}
    out = []
    for step in ce["steps"]:
        for ev in step.get("env", ()):
            out.append((dict(now), ev))
        for f in fsms:
            now[f] = step.get("state", {}).get(f"{f}.state", now[f])
    return out


class _SceneReplayHooks(Hooks):
    """The scene replay's counts: the FSMs' timeline, the injections at the
    counterexample's FSM states, and the end ``settle`` seconds after the last one."""

    def __init__(self, scene, binding, fsms, result, pending, settle, on_tick=None):
        self.binding, self.fsms, self.result, self.pending, self.settle = binding, fsms, result, pending, settle
        self.on_tick = on_tick
        self.sensors, self.exits = {}, set()
        for s in scene.sensors.values():
            if s.get("on_enter"):
                self.sensors.setdefault(s["on_enter"], s["region"])
            if s.get("on_exit"):
                self.exits.add(s["on_exit"])
        self.last, self.done_at, self.injected = None, None, []

    def before(self, rt, world) -> None:
        now = {f: rt.fsm_state(f)[0] for f in self.fsms}
        if now != self.last:
            self.result.timeline.append((round(world.time, 2), dict(now)))
            self.last = now
        pending = self.pending
        if pending and all(now.get(f) == s for f, s in pending[0][0].items() if s is not None):
            states, ev = pending.pop(0)
            pid: "str | None"
            if ev in self.exits and ev not in self.sensors:
                pid = "world"  # a part leaving: it happens in the world, or it does not
            else:
                pid = world.spawn(self.sensors[ev]) if ev in self.sensors else None
                if pid is None:
                    self.binding.backlog.append(ev)
                else:
                    self.injected.append(pid)
            self.result.injected.append((round(world.time, 2), states, ev, pid))
            if not pending:
                self.done_at = world.time

    def after(self, rt, world, step, before) -> None:
        if self.on_tick is not None:
            self.on_tick(rt, world)

    def done(self, rt, world, step) -> bool:
        return self.done_at is not None and world.time >= self.done_at + self.settle


def replay_in_scene(model, ce, scene, *, time_limit: float = 120.0, seed: "int | None" = None,
                    render: "str | None" = None, settle: float = 20.0, on_tick=None) -> SceneReplay:
    """Run ``model`` in ``scene`` with the scene's own arrivals switched off, and make
    each of the counterexample's environment events happen in the FSM states where the
    counterexample had it: a part is put where the sensor that raises the event will
    see it (upstream on a belt crossing its region, or in the area under it); an event
    no sensor raises is given to the model directly. Stops ``settle`` seconds after the
    last injection, at the first conformance error, or at ``time_limit``. ``on_tick(rt,
    world)``: called after each tick (``cell_view.CellView``)."""
    if isinstance(ce, str):
        with open(ce, encoding="utf-8") as fh:
            ce = json.load(fh)
    if "counterexample" in ce:
        ce = ce["counterexample"]
    fsms = [f.name for f in model.fsms]
    world, binding, rt = start(scene, model, seed, arrivals=False, record=on_tick is not None)
    pending = scene_triggers(ce, fsms)
    result = SceneReplay(model.name, scene.name, list(pending))
    hooks = _SceneReplayHooks(scene, binding, fsms, result, pending, settle, on_tick)
    end = run_loop(rt, world, binding, time_limit, hooks, stop_at_mismatch=False)
    if end.ended_by is not None:
        result.mismatch = str(end.ended_by)
    injected = hooks.injected
    result.lost = [(round(t, 2), pid) for t, pid, _src, dst in world.log if pid in injected and dst is not None
                   and dst.kind == "LOST"]
    result.taken = [(round(t, 2), pid) for t, pid, _src, dst in world.log if pid in injected and dst is not None
                    and dst.kind == "GRIPPER"]
    result.end_time = round(world.time, 2)
    if render:
        from .scene_render import render_scene

        result.picture = render_scene(scene, world.snapshot(), render,
                                      title=f"{model.name}: counterexample in {scene.name}")
    return result


def replay_for_cli(model, ce_json: dict, args, record: bool = False):
    """``btfsm replay CE.json MODEL --cell [--scene FILE]``: the kitting cell for the
    paper's models, else the scene (``--scene`` or the model's default scene). Returns the
    text; with ``record`` (``--html``), ``(text, run)``: the cell run as a view run
    (``cell_view.CellView``), pictures included."""
    from btfsm.errors import UsageError

    from .binding import dialect_of, unsupported
    from .scene import load_scene
    from .scene_trial import scene_for

    path = args.scene
    view: Any = None
    out: Any
    if path is None and dialect_of(model) is not None:
        if record:
            from .cell_view import CellView

            view = CellView(model, f"{model.name} in the kitting cell")
        pace = {None: None, "paced": True, "ticks": "times", "phase": "phase"}[args.pace]
        out = replay_in_cell(model, ce_json, time_limit=args.time, render=args.render, gif=args.gif, on_tick=view,
                             pace=pace)
    else:
        path = path or scene_for(model, args.model)
        if path is None:
            why = unsupported(model)
            raise UsageError(f"{model.name}: the kitting cell cannot run this model ({why}) and it has no scene: "
                             "give --scene FILE (docs/cell.md)")
        if args.gif:
            raise UsageError("--gif is not available for a scene replay yet (use --render)")
        if args.pace:
            raise UsageError("--pace is for the kitting cell (a scene replay raises each event in its FSM state)")
        scene = load_scene(path)
        if record:
            from .cell_view import CellView

            view = CellView(model, f"{model.name} in scene {scene.name}")
        out = replay_in_scene(model, ce_json, scene, time_limit=args.time, render=args.render, on_tick=view)
    if not record:
        return out.text()
    return out.text(), view.run(summary=out.text().splitlines()[0])
