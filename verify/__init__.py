"""verify: compile BT-FSM models to explicit transition systems and check them.

>>> from btfsm import Model, Int, Action, success
>>> import btfsm.verify
>>> m = Model("c", variables=[Int("n", 0, 3)], tree=Action("inc", outcomes=[success(n="min(n + 1, 3)")]))
>>> btfsm.verify.explore.explore(m).n_states
4
>>> btfsm.verify.check(m, ["invariants", "domain"]).exit_code
0
"""
from .counterexample import Counterexample, load_counterexample, replay_counterexample
from .determinism import analyse as determinism_analysis
from .explore import DEFAULT_MAX_STATES, OpenFSM, explore_fsm, open_fsm
from .properties import PROPERTIES, Context, Result
from .report import Report, check
from .system import TransitionSystem

# ``explore`` is not re-exported: the name would shadow the submodule ``btfsm.verify.explore``
# (``import btfsm.verify.explore`` must give the module); use ``from btfsm.verify.explore import explore``.
__all__ = ["explore_fsm", "open_fsm", "OpenFSM", "TransitionSystem", "DEFAULT_MAX_STATES",
           "check", "Report", "Result", "Context", "PROPERTIES", "Counterexample", "replay_counterexample",
           "load_counterexample", "determinism_analysis"]
