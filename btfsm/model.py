"""A BT-FSM model: world variables, primitives, skill FSMs, the tree and its environment.

Models are immutable and check themselves when built (automata-lib style): every name,
type, id and reference is resolved, every expression type-checked, and the compiled
program (``model.program``) is ready to run. Structural doubts that do not make the model
unusable (unreachable states, edges that never fire) are kept in ``model.warnings``.

>>> from btfsm import *
>>> m = Model("counter", variables=[Int("n", 0, 3)],
...           tree=ReactiveFallback("root", [Condition("full", "n == 3"),
...                                          Action("add", outcomes=[success(n="n + 1")])]))
>>> m.program.initial
(0,)
>>> from btfsm.oracles import FirstOracle
>>> m.program.step(m.program.initial, FirstOracle()).state
(1,)
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Iterable, Mapping, Sequence, TypeVar, cast

from .bt import Action, Node, SkillRequest, walk
from .errors import ModelError
from .expr import Expr, ExprLike, as_expr
from .fsm import FSM
from .positions import widen_to_copies
from .profiles import PROFILES, TICKS
from .primitives import PASS, EffectsLike, Outcome, Primitive, effects_of
from .timing import responses_of
from .world import Var, check_label, check_name, check_text

if TYPE_CHECKING:
    from .semantics import Program

_T = TypeVar("_T")

__all__ = ["EnvEvent", "EnvChoice", "Model"]


@dataclass(frozen=True)
class EnvEvent:
    """Something the environment may do before any tick while ``guard`` holds (a part
    arrives, a sensor flips). Each enabled event independently happens or not."""

    name: str
    guard: "ExprLike | None" = None  # an Expr once built
    effects: EffectsLike = ()  # a tuple of (var, Expr) once built
    min_interval: "float | None" = None  # seconds after it happened before it is enabled again

    def __post_init__(self) -> None:
        object.__setattr__(self, "guard", None if self.guard is None else as_expr(self.guard))
        object.__setattr__(self, "effects", effects_of(self.effects))
        m = self.min_interval
        if m is not None and (isinstance(m, bool) or not isinstance(m, (int, float)) or not 0 <= m < float("inf")):
            raise ModelError(f"environment.{self.name}.min_interval", f"expected a finite number of seconds >= 0, got {m!r}")


@dataclass(frozen=True)
class EnvChoice:
    """The environment takes exactly one of the enabled ``options`` (EnvEvents) each tick,
    like a Promela ``if``. With no option enabled the tick cannot happen (a dead state)."""

    name: str
    options: Sequence[EnvEvent] = ()  # a tuple once built

    def __post_init__(self) -> None:
        object.__setattr__(self, "options", tuple(self.options))


@dataclass(frozen=True)
class Model:
    """The whole model. ``tree`` may be None for a model of FSMs alone.

    ``workable``: the predicate of states from which work can go on (default: every FSM
    token on its initial state). ``invariants``: ``(name, expr)`` that must hold in every
    reachable state. ``terminal``: states where stopping is intended. ``tick_rate`` in Hz.
    ``semantics``: the engine whose tick rules apply (``btfsm.profiles``: btfsm, btcpp, pytrees).
    ``resources``: ``(resource name, (node names...))`` pairs (or a mapping): Action and
    SkillRequest nodes that share a physical resource (an arm, a gripper); two of one
    resource must never run at once (property ``exclusive-actions``, docs/semantics.md
    rule 'Exclusive resources'). ``responses``: ``btfsm.timing.Response`` requirements (or a
    mapping name -> {trigger, response, within}) that property ``response`` decides.
    ``tick``: how a BehaviorTree.CPP main loop ticks the tree under ``semantics="btcpp"``:
    ``once`` (``tickOnce()``, the default: wake-up re-ticks) or ``exactly-once``
    (``btfsm.profiles.TICKS``; docs/semantics.md section 8.1).
    """

    name: str
    # each sequence is a tuple once built; invariants ((name, Expr), ...), workable and
    # terminal Exprs, resources ((name, (node, ...)), ...), responses (Response, ...)
    variables: Sequence[Var] = ()
    primitives: Sequence[Primitive] = ()
    fsms: Sequence[FSM] = ()
    tree: "Node | None" = None
    environment: "Sequence[EnvEvent | EnvChoice]" = ()
    invariants: "Mapping[str, ExprLike] | Sequence[tuple[str, ExprLike]]" = ()
    workable: "ExprLike | None" = None
    terminal: "ExprLike | None" = None
    tick_rate: float = 10.0
    description: str = ""
    semantics: str = "btfsm"
    resources: "Mapping[str, Any] | Sequence[Any]" = ()
    responses: "Mapping[str, Any] | Sequence[Any]" = ()
    tick: str = "once"
    warnings: "tuple[tuple[str, str], ...]" = field(default=(), compare=False, repr=False)

    def __post_init__(self) -> None:
        for f in ("variables", "primitives", "fsms", "environment"):
            object.__setattr__(self, f, tuple(getattr(self, f)))
        object.__setattr__(self, "invariants", tuple((str(k), as_expr(x)) for k, x in
                                                      (self.invariants.items() if hasattr(self.invariants, "items") else self.invariants)))
        for f in ("workable", "terminal"):
            val = getattr(self, f)
            object.__setattr__(self, f, None if val is None else as_expr(val))
        object.__setattr__(self, "resources", _resources(self.resources))
        object.__setattr__(self, "responses", responses_of(self.responses))
        object.__setattr__(self, "warnings", tuple(self._validate()))

    # ------------------------------------------------------------------ lookups
    def fsm(self, name: str) -> FSM:
        return self._index("_fsm_index", self.fsms)[name]

    def var(self, name: str) -> Var:
        return self._index("_var_index", self.variables)[name]

    def _index(self, attr: str, items: Iterable[_T]) -> dict[str, _T]:
        """name -> item (the first with that name), built once: lookups stay O(1), so
        building a model with many variables is linear, not quadratic."""
        idx: "dict[str, _T] | None" = self.__dict__.get(attr)
        if idx is None:
            idx = {}
            for x in items:
                idx.setdefault(getattr(x, "name"), x)
            object.__setattr__(self, attr, idx)
        return idx

    def all_primitives(self) -> dict[str, Primitive]:
        """Every primitive by name: declared ones plus those declared inline."""
        prims = {p.name: p for p in self.primitives}
        for node in self.nodes():
            if isinstance(node, Action) and node.outcomes is not None:
                prims[node.primitive] = Primitive(node.primitive, node.outcomes)
        for f in self.fsms:
            for st in f.states:
                if st.outcomes is not None:
                    prims[st.primitive or st.id] = Primitive(st.primitive or st.id, st.outcomes)
        prims.setdefault(PASS.name, PASS)
        return prims

    def roots(self) -> list[tuple[str, Node]]:
        """``(element path, subtree)`` for the tree and every FSM state's subtree."""
        out = [("tree", self.tree)] if self.tree is not None else []
        for f in self.fsms:
            for st in f.states:
                if st.subtree is not None:
                    out.append((f"fsms.{f.name}.states.{st.id}.subtree", st.subtree))
        return out

    def nodes(self) -> list[Node]:
        return [n for _, root in self.roots() for n in walk(root)]

    def requests_of(self, fsm: str) -> list[SkillRequest]:
        """The SkillRequest nodes (anywhere in the model) that request FSM ``fsm``."""
        return [n for n in self.nodes() if isinstance(n, SkillRequest) and n.fsm == fsm]

    @property
    def program(self) -> Program:
        """The compiled program (``btfsm.semantics.Program``), built once."""
        prog: "Program | None" = self.__dict__.get("_program")
        if prog is None:
            from .semantics import Program

            prog = Program(self)
            object.__setattr__(self, "_program", prog)
        return prog

    # ------------------------------------------------------------------ validation
    def _validate(self) -> list[tuple[str, str]]:
        if not isinstance(self.name, str) or not self.name:
            raise ModelError("name", "a model needs a non-empty name")
        check_label(self.name, "name", "model name")
        check_text(self.description, "description", "the description")
        if self.semantics not in PROFILES:
            raise ModelError("semantics", f"unknown semantics {self.semantics!r} (one of: {', '.join(PROFILES)})")
        if self.tick not in TICKS:
            raise ModelError("tick", f"unknown tick {self.tick!r} (one of: {', '.join(TICKS)})")
        names: set[str] = set()
        for i, var in enumerate(self.variables):
            if not isinstance(var, Var):
                raise ModelError(f"variables[{i}]", "not a variable declaration")
            var.validated(f"variables.{var.name}")
            if var.name in names:
                raise ModelError(f"variables.{var.name}", f"duplicate variable '{var.name}'")
            names.add(var.name)
        fsm_names: set[str] = set()
        for f in self.fsms:
            if f.name in fsm_names or f.name in names:
                raise ModelError(f"fsms.{f.name}", f"name '{f.name}' is used twice")
            fsm_names.add(f.name)
        declared: set[str] = set()
        for p in self.primitives:
            if not isinstance(p.name, str) or not p.name:
                raise ModelError("primitives", "a primitive needs a non-empty name")
            check_label(p.name, "primitives", "primitive name")
            if p.name in declared:
                raise ModelError(f"primitives.{p.name}", f"duplicate primitive '{p.name}'")
            declared.add(p.name)
            if not p.outcomes:
                raise ModelError(f"primitives.{p.name}", "declares no outcome")
            _unique_outcomes(p.outcomes, f"primitives.{p.name}")
        inline = self._check_nodes(declared)
        resource_warnings = self._check_resources()
        for f in self.fsms:
            for st in f.states:
                if st.outcomes is None:
                    continue
                name, where = st.primitive or st.id, f"fsms.{f.name}.states.{st.id}"
                if not st.outcomes:
                    raise ModelError(where, "declares no outcome")
                _unique_outcomes(st.outcomes, where)
                if name in declared or (name in inline and inline[name] != st.outcomes):
                    raise ModelError(where, f"primitive '{name}' is declared twice with different outcomes")
                inline[name] = st.outcomes
        env_names = []
        for i, ev in enumerate(self.environment):
            if not isinstance(ev, (EnvEvent, EnvChoice)):
                raise ModelError(f"environment[{i}]", "not an event or a choice")
            check_name(ev.name, f"environment[{i}]", "event name")
            env_names.append(ev.name)
            if isinstance(ev, EnvChoice):
                if not ev.options:
                    raise ModelError(f"environment.{ev.name}", "a choice needs options")
                for k, opt in enumerate(ev.options):
                    if not isinstance(opt, EnvEvent):
                        raise ModelError(f"environment.{ev.name}.options[{k}]", "not an option (EnvEvent)")
                    check_name(opt.name, f"environment.{ev.name}.options[{k}]", "option name")
                    env_names.append(opt.name)
        _no_dup_names(env_names, "environment")
        invariants = cast("tuple[tuple[str, Expr], ...]", self.invariants)
        for inv, _ in invariants:
            check_label(inv, "invariants", "invariant name")
        _no_dup_names([k for k, _ in invariants], "invariants")
        if not isinstance(self.tick_rate, (int, float)) or not 0 < self.tick_rate < float("inf"):
            raise ModelError("tick_rate", "must be a positive number of ticks per second")
        prims = self.all_primitives()
        warnings: list[tuple[str, str]] = []
        for f in self.fsms:
            for st in f.states:
                if st.primitive and st.outcomes is None and st.primitive not in prims:
                    raise ModelError(f"fsms.{f.name}.states.{st.id}.primitive", f"unknown primitive '{st.primitive}'")
            statuses = {name: p.statuses() for name, p in prims.items()}
            warnings += f.validate(statuses)
        if self.responses:  # a split state named in a requirement names its copies, on every route
            object.__setattr__(self, "responses", widen_to_copies(self.responses, self))
        self._check_reentrant_requests()
        self.program  # compiles and type-checks every expression
        return warnings + resource_warnings

    def _check_resources(self) -> list[tuple[str, str]]:
        """Each resource names distinct Action or SkillRequest nodes of the model."""
        nodes = {n.name: n for n in self.nodes()}
        seen: set[str] = set()
        warnings: list[tuple[str, str]] = []
        for name, members in cast("tuple[tuple[str, tuple[Any, ...]], ...]", self.resources):
            check_label(name, "resources", "resource name")
            where = f"resources.{name}"
            if name in seen:
                raise ModelError(where, f"resource '{name}' is declared twice")
            seen.add(name)
            if not members:
                raise ModelError(where, "lists no node")
            for k, m in enumerate(members):
                if not isinstance(m, str):
                    raise ModelError(f"{where}[{k}]", f"expected a node name, got {type(m).__name__}")
                node = nodes.get(m)
                if node is None:
                    raise ModelError(f"{where}[{k}]", f"unknown node '{m}'")
                if not isinstance(node, (Action, SkillRequest)):
                    raise ModelError(f"{where}[{k}]", f"'{m}' is a {type(node).__name__}; a resource lists Action and SkillRequest nodes")
                if m in members[:k]:
                    raise ModelError(f"{where}[{k}]", f"'{m}' is listed twice")
            if len(members) == 1:
                warnings.append((where, f"only '{members[0]}' uses it: nothing can run beside it"))
        return warnings

    def _check_reentrant_requests(self) -> None:
        """An FSM state's subtree may request other FSMs, but never (through others) its own."""
        calls = {f.name: {(n.fsm, st.id) for st in f.states if st.subtree is not None
                          for n in walk(st.subtree) if isinstance(n, SkillRequest)} for f in self.fsms}
        for start in calls:
            todo, seen = [start], set[str]()
            while todo:
                f = todo.pop()
                for g, via in calls.get(f, ()):
                    if g == start:
                        raise ModelError(f"fsms.{f}.states.{via}.subtree",
                                         f"requests FSM '{g}' while '{start}' is being ticked (a re-entrant request)")
                    if g not in seen:
                        seen.add(g)
                        todo.append(g)

    def _check_nodes(self, declared: set[str]) -> dict[str, Sequence[Outcome]]:
        seen: dict[str, str] = {}
        inline: dict[str, Sequence[Outcome]] = {}
        for path, root in self.roots():
            for node in walk(root):
                if not isinstance(node, Node):
                    raise ModelError(path, f"{node!r} is not a tree node")
                where = f"{path}.{node.name}" if isinstance(node.name, str) else path
                if not isinstance(node.name, str) or not node.name:
                    raise ModelError(path, "every node needs a non-empty name")
                check_label(node.name, path, "node name")
                if node.name in seen:
                    raise ModelError(where, f"duplicate node name '{node.name}' (node names are trace ids)")
                seen[node.name] = where
                for k, child in enumerate(node.children_of()):
                    if not isinstance(child, Node):
                        raise ModelError(f"{where}.children[{k}]", "missing or not a node")
                if isinstance(node, Action):
                    if node.outcomes is not None:
                        if not node.outcomes:
                            raise ModelError(where, "declares no outcome")
                        _unique_outcomes(node.outcomes, where)
                        if node.primitive in declared or (node.primitive in inline and inline[node.primitive] != node.outcomes):
                            raise ModelError(where, f"primitive '{node.primitive}' is declared twice")
                        inline[node.primitive] = node.outcomes
                    elif node.primitive not in declared and node.primitive not in inline:
                        raise ModelError(where, f"unknown primitive '{node.primitive}' (declare it, or give outcomes)")
                if isinstance(node, SkillRequest):
                    try:
                        f = self.fsm(node.fsm)
                    except KeyError:
                        raise ModelError(f"{where}.fsm", f"unknown FSM '{node.fsm}'") from None
                    if node.goal not in f.goals:
                        raise ModelError(f"{where}.goal", f"'{node.goal}' is not a goal of {f.name} ({', '.join(f.goals)})")
                    pnames = {p.name for p in f.params}
                    given = {k for k, _ in cast("tuple[tuple[str, Expr], ...]", node.params)}
                    if given != pnames:
                        raise ModelError(f"{where}.params", f"{f.name} takes parameters {sorted(pnames)}, got {sorted(given)}")
        return inline


def _resources(x: "Mapping[str, Any] | Sequence[Any]") -> tuple[tuple[str, tuple[Any, ...]], ...]:
    """``((name, (node, ...)), ...)`` from a mapping or pairs; a lone node name is a list of one."""
    items: Iterable[Any] = cast(Any, x).items() if hasattr(x, "items") else x
    try:
        out = []
        for pair in items:
            name, members = pair
            out.append((name, (members,) if isinstance(members, str) else tuple(members)))
        return tuple(out)
    except (TypeError, ValueError):
        raise ModelError("resources", "expected a mapping of resource names to lists of node names") from None


def _unique_outcomes(outcomes: Iterable[Outcome], where: str) -> None:
    for o in outcomes:
        check_label(o.name, f"{where}.outcomes", "outcome name")
    _no_dup_names([o.name for o in outcomes], f"{where}.outcomes")


def _no_dup_names(names: Iterable[str], where: str) -> None:
    seen: set[str] = set()
    for n in names:
        if n in seen:
            raise ModelError(where, f"duplicate name '{n}'")
        seen.add(n)
