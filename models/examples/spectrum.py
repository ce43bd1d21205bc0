"""The paper's preemption spectrum: one model per way a preempted skill can give way.

Same cell, same tree, same environment in all three: an arm does a three-step routine job
(skill ``work``: ``w1 -> w2 -> w3``) and an urgent call (environment event ``call``)
must be served (skill ``serve``: ``go -> act -> back``). The tree checks the call on every
tick, so ``serve`` preempts ``work``. Only the FSM's ``serve`` edges inside the work
chain differ:

* ``continue_()``: the preempted job runs on to its safe point (the end of the job) and
  only then does the arm serve: the slowest reaction, nothing is lost;
* ``hold()``: the arm parks where it is (``park``), keeping the job's progress in
  ``stage``; the next ``work`` request resumes at the next step;
* ``reverse()``: the arm undoes the steps it did (``u3 -> u2 -> u1``) and the job later
  starts over.

``reaction(model)`` measures, for each work step, how many ticks pass from the first
``serve`` request until the serve chain starts (the token reaches ``go``) when every
primitive succeeds at once.

>>> reaction(continue_()), reaction(hold()), reaction(reverse())
({'w1': 4, 'w2': 3, 'w3': 2}, {'w1': 2, 'w2': 2, 'w3': 2}, {'w1': 2, 'w2': 3, 'w3': 4})
"""
from __future__ import annotations

from btfsm.oracles import SucceedOracle
from btfsm import (FSM, Bool, Condition, Edge, Effects, EnvEvent, Int, Marker, Model, Primitive,
                   ReactiveFallback, ReactiveSequence, SkillRequest, State, running, success)

__all__ = ["continue_", "hold", "reverse", "spectrum_fsm", "reaction", "MODES", "WORK"]

MODES = ("continue", "hold", "reverse")
WORK = ("w1", "w2", "w3")


def spectrum_fsm(mode: str) -> FSM:
    """The arm FSM for one point of the spectrum."""
    if mode not in MODES:
        raise ValueError(f"unknown mode {mode!r} ({', '.join(MODES)})")
    states = [State("home", "move", {"pose": "home"})]
    states += [State(w, "tool", {"step": k + 1}) for k, w in enumerate(WORK)]
    states += [State("go", "move", {"pose": "call"}), State("act", "tool", {"step": "serve"}),
               State("back", "move", {"pose": "home"})]
    edges = [
        Edge("go", "act"), Edge("act", "back"), Edge("back", "home"),  # serve runs to its end for any goal
        Edge("home", "go", ["serve"]),
        Edge("w1", "w2", ["work"]), Edge("w2", "w3", ["work"]), Edge("w3", "home", ["work"]),
    ]
    if mode == "continue":
        edges += [Edge("w1", "w2", ["serve"], id="w1->w2 (serve)"), Edge("w2", "w3", ["serve"], id="w2->w3 (serve)"),
                  Edge("w3", "home", ["serve"], id="w3->home (serve)"), Edge("home", "w1", ["work"])]
    elif mode == "hold":
        states.append(State("park", "move", {"pose": "park"}))
        edges[4:7] = [Edge("w1", "w2", ["work"], effects={"stage": 1}), Edge("w2", "w3", ["work"], effects={"stage": 2}),
                      Edge("w3", "home", ["work"], effects={"stage": 0})]
        edges += [Edge(w, "park", ["serve"], direct=True) for w in WORK]
        edges += [Edge("park", "home"),
                  Edge("home", "w1", ["work"], guard="stage == 0"), Edge("home", "w2", ["work"], guard="stage == 1"),
                  Edge("home", "w3", ["work"], guard="stage == 2")]
    else:
        states += [State(f"u{k + 1}", "undo", {"step": k + 1}) for k in range(len(WORK))]
        edges += [Edge(w, f"u{k + 1}", ["serve"], direct=True) for k, w in enumerate(WORK)]
        edges += [Edge("u3", "u2"), Edge("u2", "u1"), Edge("u1", "home"), Edge("home", "w1", ["work"])]
    markers = [Marker("w3", ["work"]), Marker("back", ["serve"])]
    return FSM("arm", states=states, initial="home", goals=["work", "serve"], edges=edges, markers=markers)


def _model(mode: str) -> Model:
    tree = ReactiveFallback("root", [
        ReactiveSequence("urgent", [
            Condition("called", "call"),
            Effects("answer", child=SkillRequest("serve_call", fsm="arm", goal="serve"), on_success={"call": False})]),
        SkillRequest("do_work", fsm="arm", goal="work"),
    ])
    variables = [Bool("call")] + ([Int("stage", 0, 2)] if mode == "hold" else [])
    return Model(
        f"spectrum-{mode}",
        variables=variables,
        primitives=[Primitive("move", (running("moving"), success("arrived"))),
                    Primitive("tool", (running("working"), success("done"))),
                    Primitive("undo", (running("working"), success("done")))],
        fsms=[spectrum_fsm(mode)],
        tree=tree,
        environment=[EnvEvent("call", "not call", {"call": True})],
        description=f"preemption spectrum: a preempted job {'runs on to its end' if mode == 'continue' else 'is parked and resumed' if mode == 'hold' else 'is undone'}",
    )


def continue_() -> Model:
    """The preempted job runs on to its safe point first."""
    return _model("continue")


def hold() -> Model:
    """The preempted job is parked and resumed later."""
    return _model("hold")


def reverse() -> Model:
    """The preempted job is undone."""
    return _model("reverse")



def reaction(model) -> dict:
    """Ticks from a call to the serve chain (the token reaches ``go``), per work step the arm was in
    when ``serve`` was first requested (every primitive succeeding at once)."""
    prog = model.program
    tok = next(i for i, s in enumerate(prog.slots) if s.name == "arm.state")
    ids = [s.id for s in model.fsm("arm").states]
    out = {}
    for w in WORK:
        first = list(prog.initial)
        first[tok] = ids.index(w)
        state = tuple(first)
        for k in range(1, 4 * len(ids)):
            state = prog.fsm_step(state, "arm", "serve", (), SucceedOracle()).state
            if ids[state[tok]] == "go":
                out[w] = k
                break
    return out
