"""btfsm: preemptive robot skills as Behavior Trees driving goal-driven FSMs.

The public modelling API. See docs/semantics.md for the tick rules.
"""
from .bt import (Action, Condition, Effects, FailureIsRunning, ForceFailure, ForceSuccess, Guard, IfThenElse,
                 Inverter, KeepRunningUntilFailure, RunningIsFailure, RunningIsSuccess, MemoryFallback, MemorySequence, Parallel, ParallelAll,
                 ReactiveFallback, ReactiveSequence, Repeat, Retry, RunOnce, SequenceWithMemory,
                 SkillRequest, SubTree, WhileDoElse, walk)
from .errors import ConformanceError, DomainError, ModelError
from .expr import E, as_expr, parse, to_text, v
from .fsm import FSM, Edge, Marker, State
from .model import EnvChoice, EnvEvent, Model
from .primitives import Outcome, Primitive, failure, running, success
from .status import FAILURE, RUNNING, SUCCESS, Status
from .world import Bool, Enum, Int, Var

__version__ = "0.1.0"

__all__ = [
    "Action", "Condition", "Effects", "ForceFailure", "ForceSuccess", "Guard", "Inverter",
    "MemoryFallback", "MemorySequence", "Parallel", "ReactiveFallback", "ReactiveSequence",
    "Repeat", "Retry", "SkillRequest", "walk",
    "IfThenElse", "KeepRunningUntilFailure", "ParallelAll", "RunOnce", "SequenceWithMemory", "SubTree", "WhileDoElse",
    "FailureIsRunning", "RunningIsFailure", "RunningIsSuccess",
    "ConformanceError", "DomainError", "ModelError",
    "E", "as_expr", "parse", "to_text", "v",
    "FSM", "Edge", "Marker", "State", "EnvChoice", "EnvEvent", "Model",
    "Outcome", "Primitive", "failure", "running", "success",
    "FAILURE", "RUNNING", "SUCCESS", "Status", "Bool", "Enum", "Int", "Var",
]
