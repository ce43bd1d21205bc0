"""Trees in and out of other behavior-tree engines (issue 10).

* ``btfsm.interop.btcpp_export``: ``to_btcpp_xml(model)``, BehaviorTree.CPP XML v4.
* ``btfsm.interop.btcpp_import``: ``xml_to_data(...)``, BehaviorTree.CPP XML v4 in
  (``btfsm.files.load_xml_model`` loads a ``.xml`` file with its side file).
* ``btfsm.interop.pytrees``: ``from_pytrees(root, leaves=...)`` and ``to_pytrees(model)``
  (needs py_trees 2.6).

The modules are imported on demand: none of them is needed to load or check a model, and
optional dependencies are imported there, not here.
"""
