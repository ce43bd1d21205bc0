"""Run docs/examples/first_model_fixed.yaml with your own code bound to the btfsm Runtime.

The model says WHAT may happen (the outcomes of each primitive, the events of the world);
this file says what the robot DOES: one Python function (or object) per primitive, and a
sensor that reports environment events. Run it from the repository root:

    python docs/examples/first_model_robot.py

It prints one line per tick and writes the trace first_model_run.jsonl, which
`btfsm replay first_model_run.jsonl docs/examples/first_model_fixed.yaml` reproduces.
"""
import os

from btfsm.files import load_model
from btfsm.runtime import Runtime

HERE = os.path.dirname(os.path.abspath(__file__))


def reach(call):
    """A motion: a real robot starts it on the first tick (call.first) and polls it after.
    Here every motion takes two ticks: RUNNING, then SUCCESS."""
    return "running" if call.first else "success"


class Gripper:
    """The grasp primitive as an object: tick(call) answers, halt(call) is called if the
    tree or the FSM abandons the primitive while it runs. This one slips on its first try."""

    def __init__(self):
        self.tries = 0

    def tick(self, call):
        self.tries += 1
        return "failure" if self.tries == 1 else "success"

    def halt(self, call):
        print("  (grasp halted)")


def put_away(call):
    return "running" if call.first else "success"


class Camera:
    """A sensor: reports the event 'cup_appears' when it sees a cup (here: at ticks 2 and 14)."""

    def events(self, runtime):
        seen = runtime.clock.tick in (2, 14)
        return ["cup_appears"] if seen and not runtime.vars["cup_seen"] else []


def main():
    model = load_model(os.path.join(HERE, "first_model_fixed.yaml"))
    robot = {"reach": reach, "grasp": Gripper(), "put_away": put_away}   # by primitive name
    camera = Camera()
    rt = Runtime(model, robot, trace="first_model_run.jsonl")
    for _ in range(22):
        events = camera.events(rt)
        k = rt.clock.tick
        step = rt.tick(events)
        state, goal = rt.fsm_state("arm")
        world = ", ".join(f"{name}={value}" for name, value in rt.vars.items())
        print(f"tick {k:2d} {' '.join(events):11s} {step.status.name:7s}  arm: {state} (goal {goal}); {world}")
    rt.close()
    print("trace: first_model_run.jsonl")


if __name__ == "__main__":
    main()
