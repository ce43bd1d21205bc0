"""A py_trees pick-and-place tree, checked by btfsm under py_trees' rules and under btfsm's.

Run: python docs/examples/pytrees_robot.py   (needs py_trees 2.6: pip install "btfsm[test]")
"""
import dataclasses

import py_trees

from btfsm.interop.pytrees import from_pytrees, to_pytrees
from btfsm.verify import check

# The robot's tree, as a py_trees user writes it: a conveyor part preempts placing on the AGV.
B = py_trees.behaviours
root = py_trees.composites.Selector("root", memory=False, children=[
    py_trees.composites.Sequence("conveyor_first", memory=False, children=[
        B.CheckBlackboardVariableExists(name="part_on_belt", variable_name="part"),
        B.Running(name="pick_from_conveyor"),
    ]),
    B.Running(name="place_on_agv"),
])

# What each leaf can return (py_trees' own leaves of other kinds map by themselves).
leaves = {"part_on_belt": ["success", "failure"],
          "pick_from_conveyor": ["running", "success", "failure"],
          "place_on_agv": ["running", "success"]}
model = from_pytrees(root, leaves, name="pytrees-robot")
# Both actions move the one arm: they must never run at once.
model = dataclasses.replace(model, resources={"arm": ["pick_from_conveyor", "place_on_agv"]})

for semantics in ("pytrees", "btfsm"):
    report = check(dataclasses.replace(model, semantics=semantics), ["exclusive-actions"])
    print(report.format_text(quiet=True))
    print()

# And back: the btfsm model as a py_trees tree, its leaves answering from a function.
answers = {"part_on_belt": ["failure", "success", "success"], "pick_from_conveyor": ["running"] * 3,
           "place_on_agv": ["running"] * 3}
tick = [0]
tree = to_pytrees(model, answer=lambda name: answers[name][tick[0]])
for tick[0] in range(3):
    tree.tick_once()
    print(f"tick {tick[0] + 1}: root {tree.status.name}; running:",
          [b.name for b in tree.iterate() if b.status == py_trees.common.Status.RUNNING and not b.children])
