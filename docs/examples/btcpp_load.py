"""Load a BehaviorTree.CPP XML file in the real BehaviorTree.CPP 4 (the behaviortreepy
bindings) and tick it: every leaf its TreeNodesModel declares is registered as a stub
(actions run for two ticks and succeed, conditions succeed). The Python bindings cannot
declare a node's ports, so the leaves' port attributes are removed before loading; control
nodes, SubTrees and their remapping are loaded as written.

Run: python docs/examples/btcpp_load.py TREE.xml   (needs: pip install behaviortreepy)
"""
import sys
import xml.etree.ElementTree as ET

import behaviortreepy as bt

path = sys.argv[1]
text = open(path, encoding="utf-8").read()
model = ET.fromstring(text).find("TreeNodesModel")
factory = bt.BehaviorTreeFactory()
ticks = {}
for decl in model if model is not None else []:
    ident = decl.get("ID")
    if decl.tag == "Condition":
        factory.register_simple_condition(ident, lambda node: bt.NodeStatus.SUCCESS)
    elif decl.tag == "Action":
        def start(node, ident=ident):
            ticks[ident] = 1
            return bt.NodeStatus.RUNNING

        def running(node, ident=ident):
            ticks[ident] += 1
            return bt.NodeStatus.SUCCESS if ticks[ident] >= 2 else bt.NodeStatus.RUNNING
        factory.register_simple_stateful_action(ident, start, running, lambda node: None)
root = ET.fromstring(text)
leaf_ids = {d.get("ID") for d in (model if model is not None else []) if d.tag in ("Action", "Condition")}
for tree_el in root.iter("BehaviorTree"):
    for el in tree_el.iter():
        if el.tag in leaf_ids:
            for key in [k for k in el.attrib if k != "name"]:
                del el.attrib[key]
tree = factory.create_tree_from_text(ET.tostring(root, encoding="unicode"))
print(f"BehaviorTree.CPP loaded {path}")
for i in range(1, 4):
    print(f"tick {i}: {tree.tick_exactly_once().name}")
