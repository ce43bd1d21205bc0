"""``check(model)``: decide the named properties and gather them in a ``Report``.

The report prints as text for people (``format_text``) and as one JSON object for tools
(``to_json``: ``model``, ``states``, ``transitions``, ``seconds``, ``complete``,
``systems`` and ``properties``, each ``{name, holds, verdict, counterexample, notes, info}``;
``holds`` is null when the property could not be decided within the state budget;
``verdict`` is ``holds``, ``violated``, ``undecided`` or ``not-applicable``, the last with
``why``: the model gives the property nothing to check, and ``holds`` is then true).

>>> from btfsm import Model, Int, Action, success
>>> m = Model("c", variables=[Int("n", 0, 2)], tree=Action("inc", outcomes=[success(n="n + 1")]))
>>> r = check(m, ["domain"])
>>> r.results[0].holds, r.exit_code
(False, 1)
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

from .search import DEFAULT_MAX_STATES, DEFAULT_MAX_TRANSITIONS, HIT_WORDS, describe_hit
from .properties import PROPERTIES, Context, run_property

__all__ = ["Report", "check", "exit_code_of", "lint_kind", "lint_summary"]



@dataclass
class Report:
    model: str
    results: list
    systems: list = field(default_factory=list)
    seconds: float = 0.0
    semantics: str = "btfsm"

    @property
    def complete(self) -> bool:
        return all(s["complete"] for s in self.systems)

    @property
    def states(self) -> int:
        return sum(s["states"] for s in self.systems)

    @property
    def transitions(self) -> int:
        return sum(s["transitions"] for s in self.systems)

    @property
    def exit_code(self) -> int:
        return exit_code_of(self.results)

    def result(self, name: str):
        for r in self.results:
            if r.name == name:
                return r
        raise KeyError(name)

    def to_json(self) -> dict:
        return {"model": self.model, "semantics": self.semantics, "states": self.states, "transitions": self.transitions,
                "seconds": round(self.seconds, 6), "complete": self.complete, "systems": self.systems,
                "properties": [r.to_json() for r in self.results]}

    def format_text(self, quiet: bool = False, verbose: bool = False) -> str:
        """The verdicts, counterexamples and notes of failing properties. Lints are grouped
        by kind with counts and information lines (determinism gaps, notes of holding
        properties) are summed up in one line; ``verbose`` lists them all, ``quiet``
        leaves out lints and information entirely."""
        explored = "; ".join(_system_text(s) for s in self.systems) or "nothing to explore"
        under = "" if self.semantics == "btfsm" else f" under {self.semantics} semantics"
        lines = [f"model {self.model}{under}: {explored} ({self.seconds:.2f} s)"]
        if not self.complete:
            hit = sorted({describe_hit(s.get("budget")) or "a budget" for s in self.systems if not s["complete"]})
            lines.append(f"INCOMPLETE: the {' and the '.join(hit)} was hit; undecided properties say so")
        width = max((len(r.name) for r in self.results), default=0)
        for r in self.results:
            verdict = {True: "holds", False: "VIOLATED", None: "undecided"}[r.holds]
            if r.name == "lints":
                verdict = f"{len(r.notes)} warning(s)"
            elif r.not_applicable is not None:
                verdict = f"not applicable ({r.not_applicable})"
            elif r.holds is True and r.info.get("vacuous"):
                verdict = "holds (vacuously: the model has no tree)"
            lines.append(f"  {r.name.ljust(width)}  {verdict}")
        for r in self.results:
            if r.counterexample is not None:
                lines += ["", r.counterexample.format_text()]
        for r in self.results:
            notes = [n for n in r.notes if r.name not in ("lints", "determinism")]
            if notes and (r.holds is not True or (verbose and not quiet) or r.info.get("vacuous")):
                lines += ["", f"{r.name}:"] + [f"  {n}" for n in notes]
        if quiet:
            return "\n".join(lines)
        gaps = [n for r in self.results if r.name == "determinism" for n in r.notes]
        if gaps and verbose:
            lines += ["", "determinism (information, not failures):"] + [f"  {n}" for n in gaps]
        elif gaps:
            lines += ["", f"determinism: {len(gaps)} gap(s), information only (--verbose lists them)"]
        lint = next((r for r in self.results if r.name == "lints"), None)
        if lint is not None and lint.notes:
            warns = lint.info.get("warnings") or [{"element": n, "text": ""} for n in lint.notes]
            lines += ["", f"{len(lint.notes)} warning(s): {lint_summary(warns)}"
                      + ("" if verbose else " (--verbose lists them)")]
            if verbose:
                lines += [f"  {n}" for n in lint.notes]
        return "\n".join(lines)


_KINDS = (("states", "state(s) never reached"), ("edges", "edge(s) never fire"),
          ("markers", "marker(s) never fire"), ("goals", "goal(s) never requested"))


def lint_kind(element: str) -> str:
    """The group of a lint by its element path: ``fsms.arm.edges.e1`` -> "edges"."""
    parts = element.split(".")
    if parts[0] == "tree":
        return "tree"
    if parts[0] == "fsms" and len(parts) >= 3 and parts[2] in ("states", "edges", "markers", "goals"):
        return parts[2]
    return "other"


def lint_summary(warnings) -> str:
    """``41 edge(s) never fire, 12 state(s) never reached`` for lint dicts (element, text),
    most frequent kind first.

    >>> lint_summary([{"element": "fsms.a.edges.x"}, {"element": "fsms.a.states.p"}, {"element": "fsms.a.edges.y"}])
    '2 edge(s) never fire, 1 state(s) never reached'
    """
    from collections import Counter

    names = dict(_KINDS, tree="tree warning(s)", other="other warning(s)")
    counts = Counter(lint_kind(w["element"]) for w in warnings)
    return ", ".join(f"{n} {names[k]}" for k, n in sorted(counts.items(), key=lambda kv: (-kv[1], kv[0])))


def _system_text(s: dict) -> str:
    what = "model" if s["kind"] == "model" else f"FSM {s['fsm']}"
    inc = "" if s["complete"] else f", incomplete ({HIT_WORDS.get(s.get('budget') or '', 'a')} budget hit)"
    return f"{what} {s['states']} states, {s['transitions']} transitions{inc}"


def exit_code_of(results) -> int:
    """0 all hold, 1 some property violated, 3 some property undecided (budget hit)."""
    if any(r.holds is False for r in results):
        return 1
    if any(r.holds is None for r in results):
        return 3
    return 0


def check(model, properties=None, *, max_states: "int | None" = DEFAULT_MAX_STATES,
          max_transitions: "int | None" = DEFAULT_MAX_TRANSITIONS, max_seconds: "float | None" = None, progress=None,
          engine: str = "auto", goal_level: str = "open") -> Report:
    """Decide ``properties`` (names; default: all of ``btfsm.verify.properties.PROPERTIES``).
    ``progress(what, states, transitions, seconds)`` is called during long explorations;
    ``engine``: the model-level exploration engine (``btfsm.verify.explore.explore``);
    ``goal_level``: ``open`` or ``tree`` (``btfsm.verify.properties.goals``).
    Budgets: ``max_states`` and ``max_transitions`` per explored system, ``max_seconds``
    for the whole check (``btfsm.verify.search.Budget``); a system that hits one is
    incomplete and the properties it leaves undecided say so (exit code 3)."""
    names = list(PROPERTIES) if not properties else list(dict.fromkeys(properties))
    unknown = [n for n in names if n not in PROPERTIES]
    if unknown:
        raise ValueError(f"unknown propert{'y' if len(unknown) == 1 else 'ies'} {', '.join(unknown)} "
                         f"(known: {', '.join(PROPERTIES)})")
    t0 = time.perf_counter()
    ctx = Context(model, max_states=max_states, max_transitions=max_transitions, max_seconds=max_seconds,
                  progress=progress, engine=engine, goal_level=goal_level)
    done = {}
    for n, during, after in _schedule(ctx, names):
        ctx.model_needed = during
        done[n] = run_property(ctx, n)
        ctx.model_needed = after
        ctx.done_with_model()
    results = [done[n] for n in names]
    fsms = [f.name for f in model.fsms]
    order = sorted(ctx.systems, key=lambda ts: -1 if ts.kind == "model" else fsms.index(ts.fsm))
    systems = [{"kind": ts.kind, "fsm": ts.fsm, "states": ts.n_states, "transitions": ts.n_transitions,
                "complete": ts.complete, "seconds": round(ts.seconds, 6),
                **({} if ts.complete else {"budget": ts.stopped})} for ts in order]
    return Report(model.name, results, systems, time.perf_counter() - t0, model.semantics)


# properties that read the model-level system (``lints`` and tree-level ``goal-reachability``: see ``_schedule``)
_MODEL = ("workable-reachability", "invariants", "contracts", "domain", "exclusive-actions", "response")


def _schedule(ctx, names):
    """``(name, during, after)`` in the order to decide ``names`` (the report keeps the
    given order): first what reads only the model-level system, then ``no-dead-states``
    (its model part, then the FSMs), then what reads only FSM systems. ``during`` and
    ``after`` say whether the model-level system is still needed while the property runs
    and once it is done: ``Context.done_with_model`` lets the system go when it is not, so
    the model's system is gone before the FSMs are explored and the check holds one large
    system at a time (``no-dead-states`` lets it go between its two parts)."""
    from .properties import lints, not_applicable

    def reads_model(n):
        if not_applicable(ctx.model, n) is not None:
            return False
        if n == "goal-reachability":
            return ctx.goal_level == "tree" and ctx.model.tree is not None
        if n == "lints":
            return lints.uses_model(ctx)  # explores the model when it has a tree (lints needs its size)
        return n in _MODEL or n == "no-dead-states"

    first = [n for n in names if n == "determinism" or (n not in ("no-dead-states", "lints") and reads_model(n))]
    rest = [n for n in names if n not in first]
    order = first + [n for n in rest if n == "lints" and reads_model(n)] + [n for n in rest if n == "no-dead-states"]
    order += [n for n in names if n not in order]
    for k, n in enumerate(order):
        after = any(reads_model(m) for m in order[k + 1:])
        yield n, after or (reads_model(n) and n != "no-dead-states"), after
