"""The named properties ``btfsm check`` decides, one module per topic.

Each property is a function ``prop(ctx) -> Result``; ``ctx`` (a ``Context``) explores the
model and each FSM at most once, with one state budget. A ``Result`` says whether the
property holds (``True``/``False``, or ``None`` when it could not be decided because the
state budget was hit), carries a counterexample when it is violated, and notes.

===========================  =======  ==================================================
name                         level    meaning
===========================  =======  ==================================================
``workable-reachability``    model    AG EF workable
``goal-reachability``        fsm      every requestable goal can still succeed
``determinism``              static   no two guards of one firing point overlap (z3)
``no-dead-states``           both     no stuck state; no non-progress cycle (FSM level)
``request-latency``          fsm      a retargeted request is served in the same tick
``invariants``               model    every invariant holds in every reachable state
``contracts``                model    no SUCCESS with post false; no two requests on one FSM
``domain``                   both     no effect writes outside its variable's domain
``exclusive-actions``        model    no two leaves of one declared resource run at once
``response``                 model    each declared trigger is answered within its bound
``lints``                    both     warnings only (never fails)
===========================  =======  ==================================================
"""
from __future__ import annotations

import time

from .base import Context, Result, columns_of, evaluate

__all__ = ["Result", "Context", "PROPERTIES", "property_names", "evaluate", "columns_of", "not_applicable"]


def _registry() -> dict:
    from . import dead, exclusive, goals, latency, lints, response, safety, workable

    return {
        "workable-reachability": workable.check,
        "goal-reachability": goals.check,
        "determinism": _determinism,
        "no-dead-states": dead.check,
        "request-latency": latency.check,
        "invariants": safety.check_invariants,
        "contracts": safety.check_contracts,
        "domain": safety.check_domain,
        "exclusive-actions": exclusive.check,
        "response": response.check,
        "lints": lints.check,
    }


def _determinism(ctx) -> Result:
    from ..counterexample import static_counterexample
    from ..determinism import analyse, describe_gap, describe_overlap

    overlaps, gaps = analyse(ctx.model)
    notes = [f"gap (information): {describe_gap(g)}" for g in gaps]
    info = {"overlaps": overlaps, "gaps": gaps}
    if not overlaps:
        return Result("determinism", True, None, notes, info)
    o = overlaps[0]
    text = "\n".join(describe_overlap(x) for x in overlaps[:10])
    if len(overlaps) > 10:
        text += f"\n... and {len(overlaps) - 10} more"
    ce = static_counterexample(ctx.model, "determinism",
                               f"{len(overlaps)} pair(s) of guards can be true together",
                               dict(o, kind=o["kind"], text=text), fsm=o["fsm"])
    return Result("determinism", False, ce, notes, info)


PROPERTIES = ("workable-reachability", "goal-reachability", "determinism", "no-dead-states", "request-latency",
              "invariants", "contracts", "domain", "exclusive-actions", "response", "lints")


def property_names() -> tuple:
    return PROPERTIES


def not_applicable(model, name: str) -> "str | None":
    """Why property ``name`` has nothing to check in ``model`` (None: it applies).

    A property that does not apply is reported as "not applicable" with this reason, not
    as "holds" (``Result.not_applicable``; it never fails a check).

    >>> from btfsm import Model, Action, success
    >>> m = Model("t", tree=Action("a", outcomes=[success()]))
    >>> not_applicable(m, "goal-reachability")
    'no skill FSM'
    >>> not_applicable(m, "no-dead-states") is None
    True
    """
    fsms = bool(model.fsms)
    if name in ("goal-reachability", "determinism") and not fsms:
        return "no skill FSM"
    if name == "contracts" and not fsms and model.program.wake is None:
        return "no skill FSM and no tickOnce wake-up"  # a tickOnce loop is a contract breach
    if name == "workable-reachability" and not fsms and model.workable is None:
        return "no skill FSM and no 'workable' expression"
    if name == "request-latency" and not any(f.params for f in model.fsms):
        return "no FSM has parameters" if fsms else "no skill FSM"
    if name == "invariants" and not model.invariants:
        return "no invariant declared"
    if name == "domain" and not fsms and not any(v.kind == "int" for v in model.variables):
        return "no int variable and no skill FSM"
    if name == "exclusive-actions" and not model.resources:
        return "no 'resources:' declared"
    if name == "response" and not model.responses:
        return "no 'responses:' declared"
    return None


def run_property(ctx, name: str) -> Result:
    """Decide one property by name (KeyError for an unknown name); a property with
    nothing to check in the model (``not_applicable``) is not run."""
    fn = _registry()[name]
    t0 = time.perf_counter()
    why = not_applicable(ctx.model, name)
    if why is not None:
        res = Result(name, True, None, [], {}, not_applicable=why)
    else:
        res = fn(ctx)
    res.seconds = time.perf_counter() - t0
    return res
