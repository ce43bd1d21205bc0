"""Let the tests run from a source checkout that is not installed.

Installed, nothing happens here. Otherwise ``tests/source_checkout/sitecustomize.py``
maps verify/, models/ and sim/ to ``btfsm.verify``, ``btfsm.models`` and ``btfsm.sim`` as
pyproject's ``package-dir`` does, in this process and (through PYTHONPATH) in every
process the tests start; and the pytest plugin (``btfsm.pytest_plugin``) is loaded by
name instead of by its entry point. What needs a real installation (the ``btfsm``
console script, the plugin in a project outside this repository) says so and is skipped.
"""
from __future__ import annotations

import importlib.util
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent
SOURCE_CHECKOUT = ROOT / "tests" / "source_checkout"

if importlib.util.find_spec("btfsm") is None or importlib.util.find_spec("btfsm.verify") is None:
    spec = importlib.util.spec_from_file_location("btfsm_source_checkout", SOURCE_CHECKOUT / "sitecustomize.py")
    spec.loader.exec_module(importlib.util.module_from_spec(spec))
    os.environ["PYTHONPATH"] = os.pathsep.join(
        [str(SOURCE_CHECKOUT), str(ROOT)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p])
    # installed, the plugin comes from its pytest11 entry point (also visible when a build
    # left btfsm.egg-info in the checkout); otherwise it is named here
    from importlib.metadata import entry_points

    if not any(ep.name == "btfsm" for ep in entry_points(group="pytest11")):
        pytest_plugins = ["btfsm.pytest_plugin"]
