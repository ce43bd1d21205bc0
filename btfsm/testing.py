"""Model checking and cell conformance as assertions, for your own pytest suite.

``assert_holds`` checks a model (a ``Model``, a model file, ``file.py:function`` or a
built-in name) and raises ``AssertionError`` whose text is the verdicts and each
counterexample, exactly as ``btfsm check`` prints them. ``assert_conforms`` runs seeded
random scenarios in the simulated cell under the conformance monitor and raises with the
first mismatch and its tick. The pytest plugin (``btfsm.pytest_plugin``, registered
through the ``pytest11`` entry point) hands both to tests as the ``btfsm`` fixture and
collects model files into one test item per property.

>>> report = assert_holds("pickplace3", ["no-dead-states"])
>>> report.exit_code
0
>>> try:
...     assert_holds("defect-dead-state", ["no-dead-states"])
... except AssertionError as exc:
...     print(str(exc).splitlines()[0])
model defect-dead-state: no-dead-states VIOLATED
"""
from __future__ import annotations

__all__ = ["assert_holds", "assert_conforms", "as_model", "failure_text"]


def as_model(model, semantics: "str | None" = None):
    """A ``Model`` from a Model or anything ``btfsm.files.load_model`` takes, under
    ``semantics`` when given."""
    import dataclasses

    from .files import load_model
    from .model import Model

    if isinstance(model, Model):
        return model if semantics in (None, model.semantics) else dataclasses.replace(model, semantics=semantics)
    return load_model(model, semantics=semantics)


def failure_text(report) -> str:
    """A one-line summary of what failed, then the report as ``btfsm check`` prints it."""
    bad = [r for r in report.results if r.holds is not True]
    summary = ", ".join(f"{r.name} {'VIOLATED' if r.holds is False else 'undecided'}" for r in bad)
    return f"model {report.model}: {summary}\n\n{report.format_text(quiet=True)}"


def assert_holds(model, properties=None, *, semantics: "str | None" = None, goal_level: str = "open",
                 max_states: "int | None" = None, max_transitions: "int | None" = None,
                 max_seconds: "float | None" = None):
    """Check ``properties`` (default: all) and return the ``Report``; AssertionError with
    the counterexamples when one is violated or undecided (a budget was hit)."""
    from btfsm.verify.report import check
    from btfsm.verify.search import DEFAULT_MAX_STATES, DEFAULT_MAX_TRANSITIONS

    m = as_model(model, semantics)
    report = check(m, properties, goal_level=goal_level,
                   max_states=DEFAULT_MAX_STATES if max_states is None else max_states,
                   max_transitions=DEFAULT_MAX_TRANSITIONS if max_transitions is None else max_transitions,
                   max_seconds=max_seconds)
    if report.exit_code != 0:
        raise AssertionError(failure_text(report))
    return report


def assert_conforms(model, *, scenarios: int = 10, seed: int = 0, time_limit: float = 700.0,
                    drops: bool = False, path: bool = True, max_states: "int | None" = 2_000_000,
                    semantics: "str | None" = None, scene=None):
    """Run ``scenarios`` seeded scenarios in the cell (``btfsm conform``) and return the
    ``Conformance``; AssertionError naming the first mismatch, its scenario and tick.
    ``scene``: a scene file or Scene to run in (docs/cell.md); a model the kitting cell
    cannot run uses its default scene."""
    from btfsm.sim.conformance import conform

    m = as_model(model, semantics)
    out = conform(m, scenarios, seed, time_limit, drops, path=path, max_states=max_states, scene=scene)
    if out.incomplete:
        raise AssertionError(f"{m.name}: exploring the model for the path check hit max_states={max_states:,}")
    first = out.first_mismatch()
    if first is not None:
        i, mismatch = first
        sc = out.scenarios[i]
        where = "in its scene" if sc.variant == "scene" else f"belt parts at {list(sc.detections)}"
        raise AssertionError(f"{m.name}: scenario {i} (seed {sc.seed}, {where}) "
                             f"does not conform: first mismatch at {mismatch}; {len(out.failed)} of "
                             f"{len(out.results)} scenarios failed")
    return out
