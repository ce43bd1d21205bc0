"""The example model files, as built-in models (they are loaded, never executed)."""
from __future__ import annotations

import os

__all__ = ["two_area_file", "templated", "bt_cpp_1031"]

_HERE = os.path.dirname(os.path.abspath(__file__))


def _load(name: str):
    from btfsm.files import load_model

    return load_model(os.path.join(_HERE, name))


def two_area_file():
    """models/examples/two_area.yaml: the file-format tour (most features in one file)."""
    return _load("two_area.yaml")


def templated():
    """models/examples/templated.yaml: a 3-area FSM generated from one template."""
    return _load("templated.yaml")


def bt_cpp_1031():
    """models/examples/bt_cpp_1031.yaml: BehaviorTree.CPP issue #1031 (semantics: btcpp),
    a reactive fallback over two async actions on one arm (property exclusive-actions)."""
    return _load("bt_cpp_1031.yaml")
