"""Trees in and out of other behavior-tree engines (issue 10).

* ``btfsm.interop.btcpp_export``: ``to_btcpp_xml(model)``, BehaviorTree.CPP XML v4.

The modules are imported on demand (``from btfsm.interop.btcpp_export import
to_btcpp_xml``): none of them is needed to load or check a model.
"""

__all__: list = []
