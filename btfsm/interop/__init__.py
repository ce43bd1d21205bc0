"""Interoperability with other behavior-tree engines (BehaviorTree.CPP, py_trees).

Each engine has its own module; optional dependencies are imported there, not here.
"""

__all__: list = []
