"""Let the tests run from a source checkout that is not installed.

Installed (``pip install -e .``, what scripts/test.sh does), the folders verify/, models/
and sim/ are the packages ``btfsm.verify``, ``btfsm.models`` and ``btfsm.sim``
(``package-dir`` in pyproject.toml). Without an installation, this finder gives the same
mapping, so ``python -m pytest`` from the repository root imports the same modules.
"""
from __future__ import annotations

import importlib.abc
import importlib.util
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent
FOLDERS = {"btfsm.verify": ROOT / "verify", "btfsm.models": ROOT / "models", "btfsm.sim": ROOT / "sim"}


class _SourceFolders(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        folder = FOLDERS.get(name)
        if folder is None:
            return None
        return importlib.util.spec_from_file_location(name, folder / "__init__.py",
                                                      submodule_search_locations=[str(folder)])


if importlib.util.find_spec("btfsm") is None or importlib.util.find_spec("btfsm.verify") is None:
    sys.path.insert(0, str(ROOT))
    sys.meta_path.append(_SourceFolders())
