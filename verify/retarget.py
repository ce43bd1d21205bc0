"""Requests with new parameters to an FSM as an open system: which are not served in the
tick they are made (``request-latency``; its counterexamples are confirmed with it too).

A request is late when its possible results (next state, reply) differ from those of the
same request made with the parameters already adopted, i.e. of a tick toward that goal.
"""
from __future__ import annotations

from btfsm.errors import DomainError

from .labels import readable
from .search import EnumOracle

__all__ = ["late_requests"]


def _results(op, state, adopt) -> dict:
    """request (readable, without outcomes) -> set of (next state, reply)."""
    prog = op.program
    out: dict = {}
    stack = [()]
    while stack:
        script = stack.pop()
        o = EnumOracle(script)
        try:
            st = op.run(state, o, False, adopt)
            res = None if st is None else (st.state, st.status)
        except DomainError as exc:
            res = ("domain", exc.var)
        for k in range(len(script), len(o.arities)):
            for c in range(1, o.arities[k]):
                stack.append(tuple(o.taken[:k]) + (c,))
        if res is None:
            continue
        request = tuple(it for it in readable(prog, tuple(o.picks), op)[0] if it[0] != "outcome")
        out.setdefault(request, set()).add(res)
    return out


def late_requests(model, op, state) -> list:
    """Requests from ``state`` whose results differ from the adopted-parameters reference."""
    actual = _results(op, state, False)
    ref = _results(op, state, True)
    return [req for req in actual if actual[req] != ref.get(req)]
