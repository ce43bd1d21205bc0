"""Built-in models by name: ``BUILTIN[name]`` is ``"module:function"`` returning a Model.

Only these fixed, shipped entries are ever imported (``btfsm.files.load_model`` resolves
names through this table; ``load_builtin`` here does the same without the file loader).

>>> load_builtin("spectrum-reverse").name
'spectrum-reverse'
>>> sorted(n for n in BUILTIN if n.startswith("ariac"))
['ariac-baseline', 'ariac-baseline-timed', 'ariac-baseline-timed-no-loss', 'ariac-preemptive', 'ariac-preemptive-timed', 'ariac-preemptive-timed-no-loss']
"""
from __future__ import annotations

import importlib

from btfsm.errors import ModelError

__all__ = ["BUILTIN", "CONDITIONED", "DEFECTS", "HEAVY", "SAME_FORM", "load_builtin", "names"]

BUILTIN: dict = {
    # the paper's ARIAC cell, corrected design (models/ariac.py)
    "ariac-preemptive": "btfsm.models.ariac:preemptive",
    "ariac-baseline": "btfsm.models.ariac:baseline",
    # the same with time: measured durations, arrivals >= 30 s apart, requirement 'reach'
    "ariac-preemptive-timed": "btfsm.models.ariac:preemptive_timed",
    "ariac-baseline-timed": "btfsm.models.ariac:baseline_timed",
    # the same with the durations derived under "no part lost yet" (sound up to the first late response)
    "ariac-preemptive-timed-no-loss": "btfsm.models.ariac:preemptive_timed_no_loss",
    "ariac-baseline-timed-no-loss": "btfsm.models.ariac:baseline_timed_no_loss",
    # the authors' original FSM and executive, defects kept (models/original.py)
    "original": "btfsm.models.original:original",
    "original-preemptive": "btfsm.models.original:original_preemptive",
    "original-narrow": "btfsm.models.original:original_narrow",  # narrower primitive declarations
    # teaching examples (models/examples/)
    "two-area": "btfsm.models.examples.two_area:two_area",
    "two-area-file": "btfsm.models.examples.files:two_area_file",
    "templated": "btfsm.models.examples.files:templated",
    "bt-cpp-1031": "btfsm.models.examples.files:bt_cpp_1031",  # BehaviorTree.CPP #1031 (semantics btcpp)
    "spectrum-continue": "btfsm.models.examples.spectrum:continue_",
    "spectrum-hold": "btfsm.models.examples.spectrum:hold",
    "spectrum-reverse": "btfsm.models.examples.spectrum:reverse",
    # the SPIN pick/place benchmark model at Q=D=B=3 (models/pickplace.py)
    "pickplace3": "btfsm.models.pickplace:pickplace",
    "pickplace3-dead": "btfsm.models.pickplace:pickplace_dead",
    "pickplace3-bug": "btfsm.models.pickplace:pickplace_bug",
    # the seeded-defect catalogue: one model per property (models/examples/defects.py)
    "defect-trap": "btfsm.models.examples.defects:trap",
    "defect-unreachable-goal": "btfsm.models.examples.defects:unreachable_goal",
    "defect-nondeterminism": "btfsm.models.examples.defects:nondeterminism",
    "defect-dead-state": "btfsm.models.examples.defects:dead_state",
    "defect-nonprogress": "btfsm.models.examples.defects:nonprogress",
    "defect-latency": "btfsm.models.examples.defects:latency",
    "defect-invariant": "btfsm.models.examples.defects:invariant",
    "defect-contract": "btfsm.models.examples.defects:contract",
    "defect-domain": "btfsm.models.examples.defects:domain",
    "defect-shadowed-marker": "btfsm.models.examples.defects:shadowed_marker",
    "defect-exclusive": "btfsm.models.examples.defects:exclusive",
}

# models whose whole state space takes tens of seconds to explore (about a million states):
# the test suite's loops over every built-in model leave them to their own tests
HEAVY = frozenset({"ariac-preemptive-timed", "ariac-baseline-timed", "ariac-preemptive-timed-no-loss",
                   "ariac-baseline-timed-no-loss"})

# timed model -> (the same model with durations conditioned on an assumption that holds in
# every run up to its first late response, the assumption, the longest --within it covers in
# seconds): `btfsm bound MODEL --within S` also prints the conditioned model's worst first
# late response, which decides the requirement (docs/verification.md 2.1)
CONDITIONED: dict = {
    "ariac-preemptive-timed": ("ariac-preemptive-timed-no-loss", "no part lost yet", 16.0),
    "ariac-baseline-timed": ("ariac-baseline-timed-no-loss", "no part lost yet", 16.0),
}
# the conditioned models differ from theirs only in declared numbers (the same states): loops
# over the built-in models that test the file format leave them out
SAME_FORM: frozenset = frozenset(c[0] for c in CONDITIONED.values())

# defect model -> the property it is seeded to violate (the catalogue's table)
DEFECTS: dict = {
    "defect-trap": "workable-reachability",
    "defect-unreachable-goal": "goal-reachability",
    "defect-nondeterminism": "determinism",
    "defect-dead-state": "no-dead-states",
    "defect-nonprogress": "no-dead-states",
    "defect-latency": "request-latency",
    "defect-invariant": "invariants",
    "defect-contract": "contracts",
    "defect-domain": "domain",
    "defect-shadowed-marker": "lints",
    "defect-exclusive": "exclusive-actions",
}


def names() -> list:
    """The built-in model names, sorted."""
    return sorted(BUILTIN)


def load_builtin(name: str):
    """Build the built-in model ``name``; ModelError (listing the names) when unknown."""
    entry = BUILTIN.get(name)
    if entry is None:
        raise ModelError("", f"'{name}' is neither a model file nor a built-in model ({', '.join(names())})")
    module, func = entry.split(":")
    return getattr(importlib.import_module(module), func)()
