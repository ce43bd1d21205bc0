"""The example model files, as built-in models (they are loaded, never executed)."""
from __future__ import annotations

import os

__all__ = ["two_area_file", "templated"]

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
