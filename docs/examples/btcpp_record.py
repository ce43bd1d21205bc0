"""Run the pick-and-place tree (models/examples/pick_place_btcpp.xml) in the real
BehaviorTree.CPP 4 (behaviortreepy) and record the run with its FileLogger2 (a .btlog file,
the format Groot2 replays), for ``btfsm conform --log``.

The leaves are stubs over a small simulated cell, seeded: a part arrives on the belt now
and then, the pick takes two ticks and may fail, the place takes two ticks. With
``--stuck-sensor`` the IsHolding condition always answers SUCCESS (a faulty sensor), which
no run of the model does. As in docs/examples/btcpp_load.py, the leaves' port attributes
are removed before loading (the bindings cannot declare ports).

Run: python docs/examples/btcpp_record.py OUT.btlog [--ticks N] [--seed S] [--stuck-sensor]
(needs: pip install behaviortreepy)
"""
import argparse
import os
import random
import time
import xml.etree.ElementTree as ET

import behaviortreepy as bt

TREE = os.path.join(os.path.dirname(__file__), "..", "..", "models", "examples", "pick_place_btcpp.xml")

ap = argparse.ArgumentParser()
ap.add_argument("out")
ap.add_argument("--ticks", type=int, default=40)
ap.add_argument("--seed", type=int, default=1)
ap.add_argument("--stuck-sensor", action="store_true")
args = ap.parse_args()

rng = random.Random(args.seed)
cell = {"part_on_belt": False, "holding": False, "placed": 0}
S, F, R = bt.NodeStatus.SUCCESS, bt.NodeStatus.FAILURE, bt.NodeStatus.RUNNING


def pick_running(node):
    if rng.random() < 0.2:
        return F
    cell.update(part_on_belt=False, holding=True)
    return S


def place_running(node):
    cell.update(placed=min(cell["placed"] + 1, 3), holding=False)
    return S


factory = bt.BehaviorTreeFactory()
factory.register_simple_condition("IsPartOnConveyor", lambda node: S if cell["part_on_belt"] else F)
factory.register_simple_condition("IsHolding", lambda node: S if cell["holding"] or args.stuck_sensor else F)
factory.register_simple_stateful_action("PickPart", lambda node: R, pick_running, lambda node: None)
factory.register_simple_stateful_action("PlaceOnAGV", lambda node: R, place_running, lambda node: None)

root = ET.parse(TREE).getroot()
for el in root.iter():
    if el.tag in ("IsPartOnConveyor", "IsHolding", "PickPart", "PlaceOnAGV"):
        for key in [k for k in el.attrib if k != "name"]:
            del el.attrib[key]
tree = factory.create_tree_from_text(ET.tostring(root, encoding="unicode"))
logger = bt.FileLogger(tree, args.out)
for _ in range(args.ticks):
    if not cell["part_on_belt"] and rng.random() < 0.3:  # the environment, before the tick
        cell["part_on_belt"] = True
    tree.tick_exactly_once()
# FileLogger2 writes from its own thread and drops what it has not written when it is
# destroyed: wait until the file has stopped growing for 0.2 s
size, still = -1, 0
while still < 10:
    time.sleep(0.02)
    now = os.path.getsize(args.out)
    size, still = now, still + 1 if now == size else 0
logger.flush()
del logger
print(f"{args.out}: {args.ticks} ticks of PickPlace recorded")
