"""Readable transition labels, shared by the exploration engines and what re-runs
their transitions: a transition's picks (``EnumOracle.picks``) become a tuple of
``("env", name)``, ``("choice", entry, option)``, ``("goal", name)``, ``("input"|"param",
variable, value)`` and ``("outcome", site, outcome, status)`` items.
"""
from __future__ import annotations

__all__ = ["readable", "STATUS"]

STATUS = ("RUNNING", "SUCCESS", "FAILURE")


def readable(prog, key, op) -> tuple:
    """(hashable readable label, requested goal index or -1) of a picks key."""
    out: list = []
    goal = -1
    env = prog.env
    for p in key:
        head = p[0]
        if head == "env":
            if p[2]:
                out.append(("env", env[p[1]][0]))
        elif head == "choice":
            tag, val = p[1], p[2]
            if isinstance(tag, int):
                out.append(("choice", env[tag][0], env[tag][3][val][0]))
            elif tag[0] == "goal":
                goal = val
                f = prog.fsm_info[op.index][0]
                out.append(("goal", f.goals[val]))
            else:  # ("input", slot) or ("param", slot)
                out.append((tag[0], prog.slots[tag[1]].name, prog.decode_slot(tag[1], val)))
        else:  # (site, outcome index)
            site, k = p
            status, _, oname = site.outcomes[k]
            out.append(("outcome", site.label, oname, STATUS[status]))
    return tuple(out), goal
