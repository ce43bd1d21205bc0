"""The paper's trial protocol as data (a trial's parameters and its result), and the
interface every binding of a model to a scene world implements (:class:`Binding`).

dTa for trial k is 30 + 0.2 k seconds; each trial is seeded from (variant, k) only.

>>> arrival_period(40)
38.0
>>> TrialSpec("baseline", 3).seed
3001
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

if TYPE_CHECKING:
    from btfsm.runtime import Runtime

__all__ = ["VARIANTS", "arrival_period", "TrialSpec", "TrialResult", "Mismatch", "Binding"]

VARIANTS = ("preemptive", "baseline")

def arrival_period(k: int) -> float:
    """dTa for trial k: 30 + 0.2 k seconds."""
    return 30.0 + 0.2 * k


@dataclass(frozen=True)
class TrialSpec:
    variant: str
    k: int
    parts: int = 18
    pick_window: float = 16.0
    time_limit: float = 1500.0
    physics_rate: float = 240.0  # the BT ticks at the model's tick_rate (10 Hz for ARIAC)
    # cell parameters a sweep varies (the defaults are the paper's cell)
    belt_speed: float = 0.2  # m/s
    speed_scale: float = 0.5  # the arm's move_to velocity scaling (the authors' default 0.5)
    period: "float | None" = None  # seconds between belt parts; None: dTa(k) = 30 + 0.2 k

    @property
    def seed(self) -> int:
        return 1000 * self.k + VARIANTS.index(self.variant)

    @property
    def arrival_period(self) -> float:
        """Seconds between two belt parts: ``period`` if given, else dTa(k)."""
        return arrival_period(self.k) if self.period is None else self.period


@dataclass
class TrialResult:
    variant: str
    k: int
    seed: int
    completed: bool
    sim_time: float
    tray: int
    skills: int
    preemptions: int
    conveyor_arrivals: int
    conveyor_picks: int
    lost: int
    reaction_times: list = field(default_factory=list)
    ticks: int = 0
    conformance_error: str = ""




@dataclass
class Mismatch:
    """The first disagreement of a conformance run: its tick (0-based, the runtime's
    ``clock.tick`` when it ran; ``btfsm.sim.loop``), the world's time, kind and what."""

    tick: int
    time: float
    kind: str  # "path" | "abstraction" | "conformance" | "accounting"
    what: str

    def __str__(self) -> str:
        return f"tick {self.tick} (t = {self.time:.2f} s): {self.kind} mismatch: {self.what}"


@runtime_checkable
class Binding(Protocol):
    """What the tick loop (``btfsm.sim.loop``) needs of a binding of a model to a scene
    world: a scene's ``bind`` table (``library.SceneBinding``, built by
    ``library.bind_model``) or a Python class named by the scene's ``binding`` section
    (``binding.KittingBinding``). Such a class is constructed as ``Class(scene, model,
    world, **args)`` and raises ``ModelError`` for a model it cannot run."""

    def implementations(self) -> dict[str, Any]:
        """Primitive name -> implementation (a callable or an object with ``tick(call)``
        and optionally ``halt(call)``), as ``btfsm.runtime.Runtime`` takes them."""
        ...

    def events(self, state: tuple[int, ...]) -> list[str]:
        """The environment events (names) of the next tick, given the model's state
        before it; an event is given once."""
        ...

    def after_tick(self, rt: Runtime) -> list[str]:
        """Bookkeeping after a tick, then the disagreements between the model's variables
        and the world (empty when they agree)."""
        ...
