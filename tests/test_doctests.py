"""Run every module's doctests, imported by its installed name (btfsm, btfsm.verify, ...).

pytest's ``--doctest-modules`` would import verify/, models/ and sim/ a second time under
their folder names; walking the installed package imports each module once, as users do.
"""
from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import btfsm


def _modules():
    names = ["btfsm"]
    for info in pkgutil.walk_packages(btfsm.__path__, "btfsm."):
        names.append(info.name)
    for sub in ("btfsm.verify", "btfsm.models", "btfsm.sim"):
        pkg = importlib.import_module(sub) if _importable(sub) else None
        if pkg is None:
            continue
        names.append(sub)
        names += [i.name for i in pkgutil.walk_packages(pkg.__path__, sub + ".")]
    return sorted(set(names))


def _importable(name):
    try:
        importlib.import_module(name)
    except ImportError:
        return False
    return True


MODULES = _modules()


def test_every_package_is_walked():
    for sub in ("btfsm.verify.explore", "btfsm.verify.properties.dead", "btfsm.models.ariac", "btfsm.sim.scene"):
        assert sub in MODULES


@pytest.mark.parametrize("name", MODULES)
def test_doctests(name):
    try:
        module = importlib.import_module(name)
    except ImportError as exc:  # an optional extra that is not installed
        pytest.skip(f"{name}: {exc}")
    finder = doctest.DocTestFinder(exclude_empty=True)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    for test in finder.find(module, name):
        runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{result.failed} doctest(s) failed in {name}"
