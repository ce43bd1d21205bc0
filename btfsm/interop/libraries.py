"""Node libraries by name (``--node-library NAME``, ``node_library: NAME`` in a side file).

A node library tells the BehaviorTree.CPP importer how a family of custom nodes is
modelled: their node models (ports, kinds, from a Groot2 ``TreeNodesModel`` file shipped
with btfsm) and the tick rule of each control, decorator and leaf. The one library so far
is ``nav2`` (``btfsm.interop.nav2``).

>>> sorted(LIBRARIES)
['nav2']
>>> load_library("nav2").models["RecoveryNode"].kind
'Control'
"""
from __future__ import annotations

from importlib import resources

from ..errors import ModelError

__all__ = ["LIBRARIES", "load_library"]

#: name -> the node model file shipped in btfsm/interop/data/
LIBRARIES = {"nav2": "nav2_tree_nodes.xml"}
_CACHE: dict = {}


def load_library(name: str):
    """The node library called ``name`` (a ModelError naming the choices otherwise)."""
    if name not in LIBRARIES:
        raise ModelError("node_library", f"unknown node library {name!r} (one of: {', '.join(sorted(LIBRARIES))})")
    if name not in _CACHE:
        from . import nav2
        from .btcpp_import import parse_xml
        from .groot import models_of_document

        data = resources.files("btfsm.interop").joinpath("data", LIBRARIES[name]).read_bytes()
        models = models_of_document(parse_xml(data, LIBRARIES[name]), LIBRARIES[name])
        _CACHE[name] = nav2.NodeLibrary(name, models)
    return _CACHE[name]
