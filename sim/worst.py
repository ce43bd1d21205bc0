"""The cell's own worst reaction, found by search over the belt parts' arrival instants (issue 21).

A proof of the reaction time is tight when the cell itself can be driven into a run that
is nearly as slow. How slow can it be driven? The cell is deterministic, so its runs
differ only in when belt parts arrive: this module runs the ARIAC job of a kitting model
(``ariac-preemptive-timed``: 2 tray parts, arrivals at least 30 s apart and only while
the kit is incomplete, as the timed model assumes) with a belt part sent to the sensor at
every tick of the job (:func:`search_single`), and with two parts on a coarse grid of
pairs refined around the slowest second responses (:func:`search_pair`), and measures each part's response
exactly as the model defines it and as the counterexample replay does
(``replay.replay_in_cell``, ``pace="phase"``): from the part's detection to the start of
the arm's next grasp at the belt (a lost part counts: the next belt grasp answers it).

Every run starts afresh from the same seeded world (the replay's: ``TrialSpec("preemptive",
1)``) and differs from the others only in its arrival ticks, so the search is the same
whatever the number of worker processes (``workers``): the runs are split into chunks,
run in a process pool, and put back in grid order; the worst is the slowest response, the
earliest arrival on a tie. :func:`at_phase` gives the model's own worst response to an
arrival in the phase (the model's state) the cell's worst had.

The environment chooses outcomes too: the timed model lets any grasp miss. With
``misses=K`` the searches also force up to K of the cell's grasp attempts before the
ranked response to miss (:class:`_Misses`: the gripper lets the part go, on the cell's own
tick), every set of them (:func:`with_misses`), and report the worst with misses beside
the worst without (``Search.plain``).
"""
from __future__ import annotations

import dataclasses
import math
import sys
from dataclasses import dataclass, field
from typing import Any, cast

from .loop import Hooks, run_loop

__all__ = ["Phase", "Probe", "Search", "probe", "job_ticks", "run_probes", "search_single", "search_pair", "at_phase",
           "ModelAtPhase", "SPACING_TICKS", "CAP", "duration_refusals", "model_breakdown", "report"]

#: the timed ARIAC models' arrival spacing, 30 s, in ticks of 10 Hz
SPACING_TICKS = 300
#: seconds after a part's detection without a belt grasp after which its response counts as unbounded
CAP = 60.0


@dataclass(frozen=True)
class Phase:
    """Where the cell was when a part arrived: the arm FSM's state before the tick that
    told the model (the ``arrive`` event), the ticks it had been in that state, its goal,
    the model's variables then, and the whole program state (to find it in the model)."""

    state: str
    ticks: int
    goal: "str | None"
    values: tuple  # ((variable, value), ...) in the model's order
    program_state: tuple = field(repr=False, compare=False)

    def text(self) -> str:
        vals = ", ".join(f"{k} = {v}" for k, v in self.values)
        return f"'{self.state}', {self.ticks} tick(s) into the visit, goal {self.goal or '-'}; {vals}"


@dataclass(frozen=True)
class Probe:
    """One run of the cell with belt parts sent at ``ticks`` (before those ticks of the
    runtime; each is detected in the world steps after it and told the next tick)."""

    ticks: tuple
    detections: tuple = ()  # the parts' detection times (s)
    responses: tuple = ()  # per part: s from its detection to the start of the next belt grasp; None: none within CAP
    lost: tuple = ()  # indices (into ticks) of the parts that reached the end of the belt
    phases: tuple = ()  # Phase per part told to the model
    breakdown: tuple = ()  # ((state split from, s), ...): where the slowest response went, in order
    refused: "str | None" = None  # the runtime refused a tick (an arrival the model does not allow, a duration)
    end_tick: "int | None" = None  # with ``to_end``: the first tick after which the kit is complete
    ranked: "int | None" = None  # the part whose response ranks the run (None: the slowest part's)
    misses: tuple = ()  # ordinals of the cell's grasp attempts (every area, in the order they end) forced to miss
    forced: tuple = ()  # ((attempt, time, site label, its runs before), ...): attempts the cell made succeed, forced to miss
    attempts: int = 0  # the grasp attempts that ended before the ranked (else slowest) part's response (all of them
    # with ``to_end``, or when no response ranks the run)

    @property
    def worst(self) -> float:
        """The ranked part's response, else the slowest (inf: none within CAP); -inf for a refused run."""
        if self.refused is not None or len(self.responses) < len(self.ticks):
            return -math.inf
        rs = [math.inf if r is None else r for r in self.responses]
        return rs[self.ranked] if self.ranked is not None else max(rs)

    @property
    def worst_part(self) -> int:
        if self.ranked is not None:
            return self.ranked
        rs = [math.inf if r is None else r for r in self.responses]
        return rs.index(max(rs))


class _Misses:
    """The cell's grasp attempts numbered in ``misses`` (0-based: every run of the grasp
    primitive, any area, counted as it ends) miss: an attempt the cell made succeed
    answers the site's failure outcome (``missed``) on the cell's own tick, so within the
    declared duration, and the gripper lets the part go (the vacuum did not hold); one
    the cell missed by itself stays missed. Every grasp site of the ARIAC models offers
    that outcome, so the model's environment may choose it there (the runtime, which
    steps the model on the cell's answers, refuses any other)."""

    def __init__(self, grasp: str, misses):
        self.grasp, self.misses = grasp, frozenset(misses)
        self.ends: list = []  # the time each grasp attempt ended
        self.forced: list = []  # (attempt ordinal, time, site label, the site's runs before this one)
        self.runs: dict = {}  # site label -> its runs ended so far
        self.world: Any = None
        self.robot: Any = None

    def wrap(self, impl):
        from .replay import wrap_answers

        return wrap_answers(impl, self._answer)

    def _answer(self, call, answer):
        site = call.site
        status = {o[2]: o[0] for o in site.outcomes}
        if site.primitive != self.grasp or status.get(answer, 0) == 0:
            return answer
        n = len(self.ends)
        self.ends.append(call.time)
        run = self.runs.get(site.label, 0)
        self.runs[site.label] = run + 1
        fail = next((o[2] for o in site.outcomes if o[0] == 2), None)
        if n in self.misses and status.get(answer) == 1 and fail is not None:
            self.world.release(self.robot)
            self.forced.append((n, round(call.time, 2), site.label, run))
            return fail
        return answer


class _ArrivalHooks(Hooks):
    """Sends a belt part before each of ``ticks``; records the arm FSM's timeline, each
    part's phase and response; ends once every part was answered and left the belt (or,
    with ``to_end``, once the kit is complete too), or CAP s after the last detection."""

    def __init__(self, binding, ticks, to_end: bool):
        d = binding.d
        self.b, self.fsm, self.ticks, self.to_end = binding, d.fsm, list(ticks), to_end
        self.beam = binding.scene.sensors[binding.sensor]["region"]
        f = next(x for x in binding.model.fsms if x.name == d.fsm)
        self.grasps = {st.id for st in f.states if st.primitive == d.grasp and d.area(dict(st.args)) == binding.belt_area}
        self.tray_slot = binding.model.program.scope[d.tray_var].index
        self.n_tray = binding.n_tray
        self.pids: list = []
        self.timeline: list = []  # (time, state, goal) changes
        self.last: Any = None
        self.in_state = 0
        self.pre: Any = None  # (state, ticks in it, goal, program state) before this tick
        self.told = 0
        self.phases: list = []
        self.responses: dict = {}  # part id -> s
        self.grasp_at: dict = {}  # part id -> the time the belt grasp answering it begins (the timeline's)
        self.end_tick: "int | None" = None

    def before(self, rt, world) -> None:
        st, goal = rt.fsm_state(self.fsm)
        if (st, goal) != self.last:
            if self.last is not None and st != self.last[0]:
                self.in_state = 0
            self.timeline.append((round(world.time, 2), st, goal))
            self.last = (st, goal)
        self.pre = (st, self.in_state, goal, rt.state)
        if self.ticks and rt.clock.tick == self.ticks[0]:
            self.ticks.pop(0)
            self.pids.append(world.spawn(self.beam))

    def after(self, rt, world, step, before) -> None:
        b = self.b
        st = rt.fsm_state(self.fsm)[0]
        self.in_state = self.in_state + 1 if st == self.pre[0] else 0
        told = len(b.detections) - len(b.backlog)
        if told > self.told:  # this tick told the model of a part: its phase is the state before it
            self.told = told
            pst, c, goal, state = self.pre
            values = tuple((v.name, rt.program.decode_slot(rt.program.scope[v.name].index,
                                                            state[rt.program.scope[v.name].index]))
                           for v in rt.model.variables)
            self.phases.append(Phase(pst, c, goal, values, tuple(state)))
        if st in self.grasps:  # the model's response: a belt grasp starts (``replay._CellHooks.after``)
            for pid, t in b.detections:
                if pid not in self.responses:
                    self.responses[pid] = round(world.time - t - 1.0 / rt.model.tick_rate, 2)
                    self.grasp_at[pid] = world.time + 1.0 / rt.model.tick_rate  # the grasp's visit begins
        if self.end_tick is None and step.state[self.tray_slot] >= self.n_tray:
            self.end_tick = rt.clock.tick - 1

    def done(self, rt, world, step) -> bool:
        if self.ticks or len(self.b.detections) < len(self.pids):
            return False
        answered = all(pid in self.responses for pid, _ in self.b.detections)
        left = all(world.parts[p].place.kind != "BELT" for p in self.pids)
        if answered and left and (not self.to_end or self.end_tick is not None):
            return True
        return bool(self.b.detections) and world.time > self.b.detections[-1][1] + CAP


def _breakdown(timeline, end: float, response: float) -> tuple:
    """((state split from, s), ...): the cell's response window split per FSM state, copies
    summed (the cell side of ``replay.decomposition``: the window ends when the belt grasp's
    visit begins, ``end``, and lasts ``response`` s)."""
    from .replay import cell_window

    return tuple((st, round(sec, 2)) for st, sec in cell_window(timeline, end - response, end, end).items())


def probe(model, ticks, *, to_end: bool = False, time_limit: "float | None" = None, last: bool = False,
          misses=()) -> Probe:
    """Run ``model`` in the ARIAC cell (the replay's cell) with a belt part sent before each
    of ``ticks`` (runtime ticks, ascending); see :class:`Probe`. ``to_end``: run on until the
    kit is complete (``Probe.end_tick``); ``last``: the last part's response ranks the run;
    ``misses``: the ordinals of the grasp attempts forced to miss (:class:`_Misses`)."""
    from .binding import Dialect, dialect_of
    from .protocol import TrialSpec
    from .scene import LOST
    from .trial import build_trial

    ticks = tuple(int(t) for t in ticks)
    misses = tuple(sorted(int(j) for j in misses))
    rate = model.tick_rate
    limit = time_limit if time_limit is not None else (max(ticks, default=0) / rate + CAP + 1.0)
    if to_end and time_limit is None:
        limit += 120.0
    spec = TrialSpec("preemptive", 1, time_limit=limit)
    forcing = _Misses(cast(Dialect, dialect_of(model)).grasp, misses)
    model, world, binding, rt = build_trial(spec, model, detections=(), wrap=forcing.wrap)
    forcing.world, forcing.robot = world, binding.robot
    hooks = _ArrivalHooks(binding, ticks, to_end)
    end = run_loop(rt, world, binding, limit, hooks, stop_at_mismatch=False)
    refused = str(end.ended_by) if end.ended_by is not None else None
    detected = list(binding.detections)
    responses = tuple(hooks.responses.get(pid) for pid, _ in detected)
    lost_ids = set(world.parts_in(LOST))
    lost = tuple(i for i, pid in enumerate(hooks.pids) if pid in lost_ids)
    p = Probe(ticks, tuple(round(t, 3) for _, t in detected), responses, lost, tuple(hooks.phases), (), refused,
              hooks.end_tick, len(ticks) - 1 if last and ticks else None, misses, tuple(forcing.forced))
    ends = forcing.ends
    if refused is None and responses and len(responses) == len(ticks) and p.worst not in (math.inf, -math.inf):
        i = p.worst_part
        at = hooks.grasp_at[detected[i][0]]
        bd = _breakdown(hooks.timeline, at, cast(float, responses[i]))
        p = dataclasses.replace(p, breakdown=bd)
        if not to_end:
            p = dataclasses.replace(p, attempts=sum(1 for t in ends if t < at - 1e-9))
    if refused is None and (to_end or not p.attempts and p.worst in (math.inf, -math.inf)):
        p = dataclasses.replace(p, attempts=len(ends))
    return p


def job_ticks(model) -> list:
    """The ticks before which a belt part may be sent in the job without arrivals: those
    after which the kit is still incomplete (the part is told the model on the next tick,
    and the timed model's arrivals need ``tray < n``)."""
    p = probe(model, (), to_end=True, time_limit=3600.0)
    if p.end_tick is None:
        raise ValueError(f"{model.name}: the job does not complete within an hour of simulated time")
    return list(range(0, p.end_tick))


# ---------------------------------------------------------------- parallel runs

_MODEL: Any = None


def _init(model) -> None:
    import signal

    global _MODEL
    _MODEL = model
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _run_chunk(item) -> list:
    chunk, to_end, last = item
    return [probe(_MODEL, t, to_end=to_end, last=last, misses=m) for t, m in chunk]


def run_probes(model, grid, *, workers: int = 1, to_end: bool = False, last: bool = False, misses=None) -> list:
    """``probe(model, ticks, to_end=, last=, misses=)`` for every ``ticks`` of ``grid`` (and the
    ``misses`` at the same index of that list, if given), in grid order, in ``workers``
    processes (the same list whatever their number: each run depends on its ticks and
    misses alone; chunks of up to 8 runs, at least two per worker)."""
    grid = [tuple(t) for t in grid]
    runs = list(zip(grid, [tuple(m) for m in misses] if misses is not None else [()] * len(grid)))
    chunk = max(1, min(8, len(runs) // (2 * max(workers, 1))))
    items = [(runs[i:i + chunk], to_end, last) for i in range(0, len(runs), chunk)]
    if workers <= 1 or len(items) <= 1:
        return [probe(model, t, to_end=to_end, last=last, misses=m) for t, m in runs]
    import multiprocessing as mp

    ctx = mp.get_context("fork" if sys.platform.startswith("linux") else "spawn")
    with ctx.Pool(min(workers, len(items)), initializer=_init, initargs=(model,)) as pool:
        return [p for part in pool.map(_run_chunk, items) for p in part]


@dataclass
class Search:
    """A search's result: the worst run found, how many runs it took, and how."""

    model: str
    arrivals: int
    worst: "Probe | None"
    runs: int
    refused: int  # runs the runtime refused (a pair whose second part came after the kit was complete)
    how: str
    refusals: list = field(default_factory=list)  # why each refused run was refused
    grid: list = field(default_factory=list, repr=False)  # (ticks, worst response) of every run, grid order
    top: list = field(default_factory=list)  # the slowest runs (Probe), slowest first
    clean: "Probe | None" = None  # the slowest run in which no part was lost
    misses: int = 0  # up to this many grasp attempts forced to miss per run
    plain: "Probe | None" = None  # with misses: the slowest run without a forced miss (arrivals only)

    def text(self, rate: float = 10.0) -> str:
        lines = [f"{self.model}: the cell's worst response to {self.arrivals} belt part(s), by search: "
                 f"{self.runs} runs ({self.how})"]
        late = sum("not enabled" in why for why in self.refusals)
        if late:
            lines.append(f"  {late} run(s) refused by the model: a part came once the kit was complete (the timed "
                         "model's arrivals need tray < n): no scenario of the model, left out")
        if self.refused > late:
            lines.append(f"  {self.refused - late} run(s) refused by the runtime for a declared duration or another "
                         "conformance error: the model's durations do not hold in the cell")
        w = self.worst
        if w is None:
            lines.append("  no run answered")
            return "\n".join(lines)
        r = w.responses[w.worst_part]
        lines.append(f"  worst: {'unbounded (no belt grasp within %g s)' % CAP if r is None else f'{r:.2f} s'}, "
                     f"part {w.worst_part + 1} of {len(w.ticks)}, sent at t0 = "
                     + ", ".join(f"{t / rate:.1f}" for t in w.ticks) + " s (detected at "
                     + ", ".join(f"{t:.2f}" for t in w.detections) + " s)")
        if self.misses:
            lines.append("  forced misses: " + ("; ".join(
                f"grasp attempt {j + 1} at t = {t:.1f} s ('{site}': the gripper let the part go)"
                for j, t, site, _n in w.forced) if w.forced else "none"))
        for i, ph in enumerate(w.phases):
            lines.append(f"  part {i + 1}'s phase: {ph.text()}")
        c = self.clean
        if c is not None and c is not w:
            lines.append(f"  worst without a lost part: {c.worst:.2f} s (sent at t0 = "
                         + ", ".join(f"{t / rate:.1f}" for t in c.ticks) + " s"
                         + (f"; {len(c.forced)} forced miss(es)" if self.misses else "") + ")")
        q = self.plain
        if self.misses and q is not None:
            lines.append(f"  worst without a forced miss (arrivals only): {q.worst:.2f} s (sent at t0 = "
                         + ", ".join(f"{t / rate:.1f}" for t in q.ticks) + " s"
                         + (", part lost" if q.lost else "") + ")")
        resp = ", ".join("none" if x is None else f"{x:.2f} s" for x in w.responses)
        lines.append(f"  responses: {resp}; lost: " + (", ".join(f"part {i + 1}" for i in w.lost) or "none"))
        if w.breakdown:
            lines.append(f"  where the worst response went, per FSM state (cell, {sum(s for _, s in w.breakdown):.1f} s):")
            for st, s in w.breakdown:
                lines.append(f"    {st:24s} {s:6.1f} s")
        return "\n".join(lines)


def _rank(p: Probe) -> tuple:
    """The search's order: slowest first, then the earliest arrival ticks, the fewest misses."""
    return (-p.worst, p.ticks, len(p.misses), p.misses)


def _found(model, arrivals: int, probes: list, runs: int, how: str, misses: int = 0) -> Search:
    """The worst run is the slowest (its ranked part's response, else its slowest), the
    earliest arrival ticks on a tie (then the fewest forced misses); refused runs are left out."""
    ok = sorted((p for p in probes if p.worst != -math.inf), key=_rank)
    refusals = [p.refused for p in probes if p.refused is not None]
    grid = [((p.ticks, p.misses) if misses else p.ticks, p.worst) for p in probes]
    return Search(model.name, arrivals, ok[0] if ok else None, runs, len(refusals), how, refusals,
                  grid, ok[:5], next((p for p in ok if not p.lost), None), misses,
                  next((p for p in ok if not p.misses), None) if misses else None)


def with_misses(model, grid, misses: int, *, workers: int = 1, last: bool = False, to_end: bool = False) -> list:
    """Every run of ``grid`` (arrival ticks) with every set of up to ``misses`` forced misses
    among its grasp attempts that end before the ranked response (an attempt ending
    after it cannot change it; with ``to_end``, among all of them), level by level: the
    runs with k misses, then each run's set extended by one attempt after its last forced
    one and before its response (``Probe.attempts``; a run up to attempt j is the same with
    or without a miss after it, so every set is run once). Refused runs are not extended.
    In grid order, level after level: the same list for any ``workers``."""
    level = [(tuple(t), ()) for t in grid]
    out: list = []
    for k in range(misses + 1):
        probes = run_probes(model, [t for t, _m in level], workers=workers, last=last, to_end=to_end,
                            misses=[m for _t, m in level])
        out += probes
        level = [(p.ticks, p.misses + (j,)) for p in probes if p.refused is None
                 for j in range(max(p.misses, default=-1) + 1, p.attempts)]
        if not level:
            break
    return out


def _job_end(model, misses: int, workers: int = 1) -> int:
    """The first tick after which the kit is complete in the job without arrivals, the
    latest over every set of up to ``misses`` forced misses among its grasp attempts (a
    forced miss may delay the kit's completion)."""
    end = _ends(model, [()], misses, workers)[()]
    if end is None:
        raise ValueError(f"{model.name}: the job does not complete within an hour of simulated time")
    return end


def _ends(model, grid, misses: int, workers: int) -> dict:
    """{ticks: the latest tick after which the kit is complete (None: never)} over the runs
    with parts at each ``ticks`` of ``grid`` to the kit's completion, with every set of up
    to ``misses`` forced misses among all their grasp attempts; and how many runs it took
    (the key ``None``)."""
    out: dict = {tuple(t): None for t in grid}
    probes = with_misses(model, grid, misses, workers=workers, to_end=True)
    for p in probes:
        if p.end_tick is not None:
            out[p.ticks] = max(p.end_tick, out[p.ticks] if out[p.ticks] is not None else -1)
    out[None] = len(probes)
    return out


def search_single(model, *, workers: int = 1, step: int = 1, ticks=None, misses: int = 0) -> Search:
    """One belt part sent before every ``step``-th tick of the job (``job_ticks``; or the
    given ``ticks``): the slowest response over them. ``misses``: each instant also with
    every set of up to that many forced grasp misses before the part's response
    (:func:`with_misses`); the job then runs to its latest end over the misses of the run
    without arrivals (an instant after the kit is complete is refused by the model and left out)."""
    if ticks is None:
        ticks = job_ticks(model) if not misses else list(range(0, _job_end(model, misses, workers)))
        ticks, every = ticks[::step], "every tick" if step == 1 else f"every {step}th tick"
    else:
        every = "the given ticks"
    grid = [(t,) for t in ticks]
    probes = with_misses(model, grid, misses, workers=workers)
    how = (f"one part before {every} of the job, t0 = {grid[0][0] / model.tick_rate:.1f}.."
           f"{grid[-1][0] / model.tick_rate:.1f} s" if grid else "no tick")
    if misses:
        how += (f", each with every set of up to {misses} forced grasp miss(es) before its response "
                f"({len(probes) - len(grid)} runs with misses)")
    return _found(model, 1, probes, len(probes), how, misses)


def search_pair(model, *, workers: int = 1, coarse: int = 10, keep: int = 3, spacing: int = SPACING_TICKS,
                misses: int = 0) -> Search:
    """Two belt parts, the second at least ``spacing`` ticks after the first and while the
    kit is incomplete, ranked by the second part's response (the first's is the one-part
    search's whenever it comes before the second part). Coarse: the first part before every ``coarse``-th tick of the job,
    the job's end with it (a run to the kit's completion), the second before every
    ``coarse``-th tick from ``spacing`` after the first to that end. Refined: around each of
    the ``keep`` slowest coarse pairs, every pair of ticks less than ``coarse`` from it
    (kept at least ``spacing`` apart; a pair whose second part comes after the kit is
    complete is refused by the model and left out). ``misses``: every coarse pair also
    with every set of up to that many forced grasp misses before the second part's
    response (:func:`with_misses`), its second part up to the latest end of the job over
    the first part's run's misses; refined around the ``keep`` slowest coarse runs with
    misses and the ``keep`` slowest without, each with its own misses."""
    firsts = job_ticks(model)[::coarse] if not misses else list(range(0, _job_end(model, misses, workers), coarse))
    grid = []
    ends = _ends(model, [(t,) for t in firsts], misses, workers)
    runs = ends[None]
    for t0 in firsts:
        end = ends[(t0,)]
        if end is not None:
            grid += [(t0, t1) for t1 in range(t0 + spacing, end, coarse)]
    probes = with_misses(model, grid, misses, workers=workers, last=True)
    runs += len(probes)
    ok = sorted((p for p in probes if p.worst != -math.inf), key=_rank)
    best = ok[:keep]
    if misses:
        best += [p for p in ok if not p.misses][:keep]
    fine: set = set()
    for p in best:
        a, b = p.ticks
        fine |= {((x, y), p.misses) for x in range(max(0, a - coarse + 1), a + coarse)
                 for y in range(b - coarse + 1, b + coarse) if y - x >= spacing}
    fine -= {(p.ticks, p.misses) for p in probes}
    fine_runs = sorted(fine)
    fprobes = run_probes(model, [t for t, _m in fine_runs], workers=workers, last=True,
                         misses=[m for _t, m in fine_runs])
    runs += len(fprobes)
    every = probes + fprobes
    how = (f"coarse: the first part every {coarse} ticks, the second every {coarse} ticks from {spacing} ticks after "
           f"it to the job's end ({runs - len(every)} runs to the end, {len(grid)} pairs"
           + (f", {len(probes) - len(grid)} more runs with up to {misses} forced grasp miss(es) before the second "
              f"part's response" if misses else "")
           + f"); refined: every tick within {coarse - 1} of the {len(best)} slowest "
           + ("runs (with and without misses, each with its misses)" if misses else "pairs")
           + f" ({len(fprobes)} {'runs' if misses else 'pairs'})")
    return _found(model, 2, every, runs, how, misses)


# ---------------------------------------------------------------- the model at the cell's phase

@dataclass
class ModelAtPhase:
    """The model's worst response to an arrival in a given state (the cell's phase)."""

    found: bool
    worst: "float | None" = None  # s
    counterexample: "dict | None" = None  # its run (``btfsm replay ... --cell --pace phase`` replays it)
    states: int = 0


def at_phase(model, phase: Phase, ts=None) -> ModelAtPhase:
    """The worst response of ``model`` (its first requirement) over the runs in which the
    arrival comes in ``phase.program_state`` (the model's state before the arrival tick,
    the cell's exact state there), and that run as a counterexample (the shortest path to
    that state, the arrival, then a longest path without the response)."""
    import numpy as np

    from btfsm.verify.explore import explore
    from btfsm.verify.properties.response import INF, ResponseBound, counterexample

    ts = explore(model) if ts is None else ts
    req = model.responses[0]
    rb = ResponseBound(ts, req)
    mask = np.ones(ts.n_states, bool)
    for slot in ts.slots:
        mask &= ts.column(slot) == phase.program_state[slot]
    src = np.flatnonzero(mask)
    if not src.size:
        return ModelAtPhase(False, states=ts.n_states)
    edges = rb.trigger_edges[np.isin(ts.src[rb.trigger_edges], src)]
    if not edges.size:
        return ModelAtPhase(False, states=ts.n_states)
    w = int(rb.worst_at[ts.dst[edges]].max())
    witness = rb.witness_from(edges)
    if witness is None:  # unbounded through states a budget left unexplored (not with a full exploration)
        return ModelAtPhase(True, math.inf, None, ts.n_states)
    path, k, loop = witness
    bound = rb.bound_ticks()
    ce = counterexample(rb, path, k, loop, f"the worst response to an arrival at the cell's phase '{phase.state}'",
                        bound).to_json()
    return ModelAtPhase(True, math.inf if w == INF else w / rb.rate, ce, ts.n_states)


def duration_refusals(search: Search) -> list:
    """The refusals of ``search``'s runs that were not about an arrival after the kit was
    complete: an answer outside a declared duration (the model's durations do not hold in
    the cell), or another conformance error."""
    return [why for why in search.refusals if "not enabled" not in why]


def model_breakdown(ce: dict, fsm: str) -> tuple:
    """((state split from, s), ...): where a ``response`` counterexample's response time
    went, from its trigger to its last state (the response), per FSM state, copies summed
    (the counterexample side of ``replay.decomposition``)."""
    from btfsm.positions import base_state

    from .replay import fsm_states_of

    v = ce.get("violation") or {}
    states = fsm_states_of(ce, fsm)
    rate = float(v.get("tick_rate") or 10.0)
    out: dict = {}
    for st in states[int(v["trigger_step"]):-1]:
        out[base_state(st)] = round(out.get(base_state(st), 0.0) + 1.0 / rate, 2)
    return tuple(out.items())


def report(model, search: Search, *, phase_models: bool = False) -> "tuple[str, int]":
    """``btfsm sim MODEL --worst N``'s text and exit code (1 when a run was refused for a
    declared duration: the model's durations do not hold in the cell). With
    ``phase_models``: the model's worst response to an arrival at the cell's worst phase
    (:func:`at_phase`), and its conditioned twin's (``registry.CONDITIONED``), each with
    where its time went beside the cell's, per FSM state."""
    from btfsm.models.registry import CONDITIONED, load_builtin

    from .binding import Dialect, dialect_of

    lines = [search.text(model.tick_rate)]
    bad = duration_refusals(search)
    for why in bad[:3]:
        lines.append(f"  REFUSED: {why}")
    w = search.worst
    if phase_models and not model.responses:
        lines.append(f"  --at-phase: {model.name} declares no response requirement (a timed model does: "
                     "ariac-*-timed)")
    elif phase_models and w is not None and w.phases and w.responses[w.worst_part] is not None:
        ph = w.phases[w.worst_part]
        cell = w.responses[w.worst_part]
        fsm = cast(Dialect, dialect_of(model)).fsm
        twins = [(model, "")]
        if model.name in CONDITIONED:
            name, what, _within = CONDITIONED[model.name]
            twins.append((load_builtin(name), what))
        lines.append("  the model's worst response to an arrival at that phase (the cell's state before the "
                     "arrival's tick, among the model's states):")
        for m, what in twins:
            r = at_phase(m, ph)
            if not r.found or r.worst is None:
                lines.append(f"    {m.name}: the phase is not a state of this model")
                continue
            cond = f", durations conditioned on {what}" if what else ""
            lines.append(f"    {m.name} ({r.states:,} states{cond}): {r.worst:.1f} s, {r.worst / cell:.2f} times "
                         f"the cell's {cell:.2f} s")
            if r.worst == math.inf or r.counterexample is None:
                continue
            mine, theirs = dict(model_breakdown(r.counterexample, fsm)), dict(w.breakdown)
            lines.append("      per FSM state (model, cell, model - cell):")
            for st in list(mine) + [x for x in theirs if x not in mine]:
                a, b = mine.get(st, 0.0), theirs.get(st, 0.0)
                lines.append(f"        {st:24s} {a:6.1f} s {b:6.1f} s {a - b:+6.1f} s")
    return "\n".join(lines), (1 if bad else 0)
