"""Run btfsm from a source checkout that is not installed (the tests' fallback).

Installed (``pip install -e .``, what scripts/test.sh does), the folders verify/, models/
and sim/ are the packages ``btfsm.verify``, ``btfsm.models`` and ``btfsm.sim``
(``package-dir`` in pyproject.toml). Without an installation this finder gives the same
mapping. The root conftest.py loads this file into the test process and puts its folder
on PYTHONPATH, so that the processes the tests start (``python -m btfsm``, workers, a
second pytest) import the same modules: Python imports ``sitecustomize`` at start-up.
"""
import importlib.abc
import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
FOLDERS = {"btfsm.verify": ROOT / "verify", "btfsm.models": ROOT / "models", "btfsm.sim": ROOT / "sim"}


class SourceFolders(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        folder = FOLDERS.get(name)
        if folder is None:
            return None
        return importlib.util.spec_from_file_location(name, folder / "__init__.py",
                                                      submodule_search_locations=[str(folder)])


if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))
if not any(type(f).__name__ == "SourceFolders" for f in sys.meta_path):
    sys.meta_path.append(SourceFolders())
