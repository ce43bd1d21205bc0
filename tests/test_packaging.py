"""The wheel: one import name (btfsm), LICENSE and py.typed inside, declared dependencies.

Builds the wheel once (pip, with build isolation: setuptools comes from PyPI or pip's
cache) and imports from the unpacked wheel alone, outside the editable install.
"""
from __future__ import annotations

import os
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    out = tmp_path_factory.mktemp("wheel")
    r = subprocess.run([sys.executable, "-m", "pip", "wheel", "-v", "--no-deps", "-w", str(out), str(ROOT)],
                       capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot build the wheel here: {r.stderr.strip().splitlines()[-1:]}")
    (path,) = out.glob("btfsm-*.whl")
    unpacked = out / "unpacked"
    with zipfile.ZipFile(path) as z:
        z.extractall(unpacked)
        names = z.namelist()
    return names, unpacked, r.stdout + r.stderr


def test_build_declares_every_package(wheel):
    """setuptools warns "Package would be ignored" (about 70 lines) for a folder of data it
    installs without its being declared: btfsm.schema and btfsm.models.scenes are."""
    *_, log = wheel
    assert "would be ignored" not in log


def test_one_top_level_package(wheel):
    names, *_ = wheel
    tops = {n.split("/")[0] for n in names}
    assert tops == {"btfsm", "btfsm-0.1.0.dist-info"}
    for sub in ("btfsm/verify/explore.py", "btfsm/models/ariac.py", "btfsm/sim/scene.py", "btfsm/models/scenes/ariac.yaml",
                "btfsm/schema/model.schema.json", "btfsm/models/examples/two_area.yaml", "btfsm/viewer/viewer.js",
                "btfsm/viewer/viewer.css"):
        assert sub in names


def test_license_and_py_typed(wheel):
    names, unpacked, _ = wheel
    assert "btfsm/py.typed" in names
    assert any(n.endswith("licenses/LICENSE") for n in names)
    meta = next(unpacked.glob("btfsm-*.dist-info/METADATA")).read_text()
    assert "License-Expression: BSD-3-Clause" in meta
    assert "Provides-Extra: sim" in meta


def _run_isolated(unpacked, code):
    """Python without site processing (so no editable finder) and without PYTHONPATH (the
    source-checkout fallback of conftest.py), seeing only the unpacked wheel and the
    third-party packages of this environment."""
    site = sysconfig.get_paths()["purelib"]
    prog = f"import sys; sys.path[:0] = [{str(unpacked)!r}, {site!r}]\n{code}"
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    return subprocess.run([sys.executable, "-S", "-c", prog], capture_output=True, text=True, cwd=unpacked, env=env)


def test_only_btfsm_is_importable(wheel):
    _, unpacked, _ = wheel
    for name in ("verify", "models", "sim"):
        r = _run_isolated(unpacked, f"import {name}")
        assert r.returncode != 0 and "ModuleNotFoundError" in r.stderr, (name, r.stderr)
    r = _run_isolated(unpacked, "from btfsm.verify import check; from btfsm.files import load_model\n"
                                "import btfsm; assert btfsm.__file__.startswith(sys.path[0]), btfsm.__file__\n"
                                "print(check(load_model('two-area'), ['invariants']).exit_code)")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "0"


def test_checker_imports_no_simulator(wheel):
    """``pip install btfsm`` (no [sim] extra) is enough to check: checking never imports
    matplotlib, Pillow or the simulator."""
    _, unpacked, _ = wheel
    r = _run_isolated(unpacked, "from btfsm.verify import check; from btfsm.files import load_model\n"
                                "check(load_model('ariac-preemptive'))\n"
                                "print(sorted(m for m in ('matplotlib', 'PIL', 'btfsm.sim.scene') if m in sys.modules))")
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"
