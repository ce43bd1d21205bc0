"""One trial of the experiment: the checked ARIAC model driving the pymunk cell.

The BT ticks at the model's ``tick_rate`` (10 Hz) through ``btfsm.runtime.Runtime``; between two
ticks the cell takes ``physics_rate / tick_rate`` fixed steps (240 Hz physics). After
every tick the binding's abstraction check compares the model's variables with the cell.
"""
from __future__ import annotations

from btfsm.signals import check as check_signals

from btfsm.bt import SkillRequest
from btfsm.runtime import Runtime

from .binding import CellBinding
from .cell import BELT, GRIPPER, Cell, CellConfig
from .protocol import TrialResult, TrialSpec

__all__ = ["run_trial", "build_trial"]


def build_model(spec: TrialSpec):
    from btfsm.models import ariac

    make = {"preemptive": ariac.preemptive, "baseline": ariac.baseline}[spec.variant]
    return make(n_tray=spec.parts)


def build_trial(spec: TrialSpec, model=None, config: "CellConfig | None" = None, *,
                seed: "int | None" = None, detections=None):
    """(model, cell, binding, runtime) for a trial, ready to run. Belt parts reach the
    sensor every dTa(k) seconds, or at the given ``detections`` times."""
    model = model or build_model(spec)
    config = config or CellConfig(dt=1.0 / spec.physics_rate, pick_window_s=spec.pick_window,
                                  belt_speed=spec.belt_speed)
    cell = Cell(config, seed=spec.seed if seed is None else seed)
    delay = cell.detect_delay_s
    if detections is None:
        period = spec.arrival_period
        detections = [j * period for j in range(1, int(spec.time_limit / period) + 2)]
    cell.schedule_arrivals([t - delay for t in detections if t >= delay])
    binding = CellBinding(cell, model, speed_scale=spec.speed_scale)
    runtime = Runtime(model, binding.implementations(), record=True)
    return model, cell, binding, runtime


def run_trial(spec: TrialSpec, model=None, on_tick=None) -> TrialResult:
    """Run one trial to completion (``parts`` on the tray) or to the time limit."""
    model, cell, binding, rt = build_trial(spec, model)
    prog = model.program
    q_slot, tray_slot = prog.scope["queue"].index, prog.scope[binding.d.tray_var].index
    skills = {n.name: prog.nodes[n.name].flag for n in model.nodes() if isinstance(n, SkillRequest)}
    steps_per_tick = max(1, round(spec.physics_rate / model.tick_rate))  # the BT's rate is the model's
    starts = halts = ticks = 0
    error = ""
    while cell.time < spec.time_limit:
        check_signals()  # an interrupt swallowed in a destructor still stops the trial
        before = rt.state
        step = rt.tick(binding.events(before[q_slot]))
        ticks += 1
        binding.after_tick(step.state[q_slot])
        for ev in step.events:
            if ev[0] == "status" and ev[1] in skills and not before[skills[ev[1]]]:
                starts += 1
            elif ev[0] == "halt" and ev[1] in skills:
                halts += 1
        if not error:
            problems = binding.abstraction_errors(rt.vars, *rt.fsm_state(binding.d.fsm))
            if problems:
                error = f"t={cell.time:.2f}s tick {ticks}: " + "; ".join(problems)
        if on_tick is not None:
            on_tick(rt, cell)
        if step.state[tray_slot] >= spec.parts and cell.tray_count >= spec.parts:
            break
        cell.step(steps_per_tick)
    detected = {pid: t for pid, t in cell.detections}
    reactions = [t - detected[pid] for t, pid, src, dst in cell.events
                 if src == BELT and dst == GRIPPER and pid in detected]
    lost = sum(1 for pid in cell.lost_parts if pid in detected)
    return TrialResult(spec.variant, spec.k, spec.seed, cell.tray_count >= spec.parts, round(cell.time, 6),
                       cell.tray_count, starts, halts, len(detected), len(reactions), lost,
                       [round(r, 4) for r in reactions], ticks, error)
