"""``request-latency``: a request whose goal or parameters differ from the held ones is
served in that same tick.

FSM level, for each FSM with parameters. By construction of the semantics a change of goal
alone is always served at once (the FSM steps toward the requested goal), so the property
examines parameter changes: for every reachable state and every request (goal, parameter
values, free inputs, environment), the possible results (next state, reply) must equal
those of the same request from the same state with the parameters already adopted, i.e.
of a tick that steps toward the requested goal. ``retarget: immediate`` satisfies this by
construction; ``retarget: withdraw`` (the authors' protocol) spends the tick on
``withdraw_goal`` and violates it whenever a withdraw is needed. Not applicable when no FSM
has parameters.
"""
from __future__ import annotations

from ..counterexample import path_counterexample
from ..retarget import late_requests
from .base import Result, budget_hit

__all__ = ["check", "late_requests"]


def check(ctx) -> Result:
    model = ctx.model
    notes, info, undecided, worst = [], {}, False, None
    for f in model.fsms:
        if not f.params:
            continue
        ts = ctx.fsm_ts(f.name)
        if not ts.complete:
            undecided = True
            notes.append(f"FSM {f.name}: {budget_hit(ts)}; not decided")
        for i in range(ts.n_states):
            late = late_requests(model, ts.open, ts.full_state(i))
            if late:
                d = len(ts.path_to(i))
                if worst is None or d < worst[0]:
                    worst = (d, ts, i, late[0])
                notes.append(f"FSM {f.name} (retarget: {f.retarget}): a request with new parameters is not served "
                             f"in the same tick")
                break
    checked = [f.name for f in model.fsms if f.params]
    info["fsms"] = checked
    if not checked:
        return Result("request-latency", True, None, notes, info, not_applicable="no FSM has parameters")
    if worst is None:
        return Result("request-latency", None if undecided else True, None, notes, info)
    _, ts, i, req = worst
    f = model.fsm(ts.fsm)
    goal = next(it[1] for it in req if it[0] == "goal")
    params = {it[1].split(".", 1)[1]: it[2] for it in req if it[0] == "param"}
    held = {p.name: v for p, v in zip(f.params, (ts.decode(i)[f"{f.name}.{p.name}"] for p in f.params))}
    how = (f"the tick goes to withdraw_goal '{f.withdraw_goal}' (retarget: withdraw); '{goal}' starts on a later tick"
           if f.retarget == "withdraw" else "the tick does not step toward the requested goal")
    viol = {"kind": "latency", "request": {"goal": goal, "params": params}, "held": held,
            "text": f"request '{goal}' with {_kv(params)} while {_kv(held)} is held: {how}"}
    ce = path_counterexample(ts, ts.path_to(i), "request-latency",
                             f"FSM {f.name}: a request with new parameters is not served in the same tick", viol)
    return Result("request-latency", False, ce, notes, info)


def _kv(d) -> str:
    return ", ".join(f"{k}={str(v).lower() if isinstance(v, bool) else v}" for k, v in d.items())
