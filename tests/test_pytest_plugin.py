"""The pytest plugin, used the way docs/testing.md shows it, in a project outside this repository."""
import os
import shutil
import subprocess
import sys
import textwrap

import pytest

HERE = os.path.dirname(os.path.abspath(__file__))
GOOD = os.path.join(HERE, "..", "docs", "examples", "first_model_fixed.yaml")
BROKEN = os.path.join(HERE, "..", "docs", "examples", "first_model.yaml")

USER_TEST = textwrap.dedent('''
    def test_my_robot_is_checked(btfsm):
        report = btfsm.check("robot/cell.yaml", ["workable-reachability", "no-dead-states"])
        assert report.states > 0

    def test_a_builtin_model(btfsm):
        btfsm.check("pickplace3", ["no-dead-states", "invariants"])
''')


def _installed() -> bool:
    """btfsm is installed (not mapped from the source folders by the root conftest.py)."""
    return not any(type(f).__name__ == "SourceFolders" for f in sys.meta_path)


# a project outside this repository finds the plugin through its entry point only
needs_install = pytest.mark.skipif(not _installed(), reason="the plugin's pytest11 entry point needs "
                                                            "btfsm installed (pip install -e .; CI does)")


def _project(tmp_path, model_source, ini_extra=""):
    (tmp_path / "robot").mkdir()
    shutil.copy(model_source, tmp_path / "robot" / "cell.yaml")
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests" / "test_my_robot.py").write_text(USER_TEST)
    (tmp_path / "pytest.ini").write_text("[pytest]\nbtfsm_models = robot/*.yaml\n" + ini_extra)
    return tmp_path


def _pytest(folder, *args):
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTEST_")}
    return subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-rA", *args],
                          cwd=folder, capture_output=True, text=True, timeout=300, env=env)


@needs_install
def test_a_good_model_passes_every_item(tmp_path):
    done = _pytest(_project(tmp_path, GOOD), "robot", "tests")
    assert done.returncode == 0, done.stdout
    assert "PASSED robot/cell.yaml::no-dead-states" in done.stdout
    assert "PASSED tests/test_my_robot.py::test_my_robot_is_checked" in done.stdout
    # a property with nothing to check in the model is skipped with its reason
    assert "SKIPPED" in done.stdout and "response: not applicable (no 'responses:' declared)" in done.stdout


@needs_install
def test_a_broken_model_fails_with_its_counterexample(tmp_path):
    done = _pytest(_project(tmp_path, BROKEN), "robot", "tests")
    assert done.returncode == 1
    assert "FAILED robot/cell.yaml::no-dead-states" in done.stdout
    assert "FAILED tests/test_my_robot.py::test_my_robot_is_checked" in done.stdout
    assert "non-progress cycle requesting 'fetch'" in done.stdout  # the counterexample text
    assert "-- cycle starts here --" in done.stdout
    assert "PASSED robot/cell.yaml::workable-reachability" in done.stdout


@needs_install
def test_properties_ini_option_and_unloadable_files(tmp_path):
    # properties on one line separated by spaces (docs/testing.md writes them so) or one per line
    project = _project(tmp_path, GOOD, "btfsm_properties = contracts workable-reachability\n    goal-reachability\n")
    (project / "robot" / "bad.yaml").write_text("name: bad\ntree: {type: Nope}\n")
    # a scene and a side file beside the model match robot/*.yaml but are not models
    (project / "robot" / "cell.scene.yaml").write_text("robots: {}\n")
    (project / "robot" / "tree.btfsm.yaml").write_text("nodes: {}\n")
    done = _pytest(project, "robot")
    assert done.returncode == 1
    assert "PASSED robot/cell.yaml::contracts" in done.stdout and "no-dead-states" not in done.stdout
    assert "PASSED robot/cell.yaml::workable-reachability" in done.stdout
    assert "PASSED robot/cell.yaml::goal-reachability" in done.stdout
    assert "scene" not in done.stdout and "btfsm.yaml" not in done.stdout
    assert "FAILED robot/bad.yaml::load" in done.stdout and "bad.yaml: tree: a node needs a type" in done.stdout


@needs_install
def test_without_the_ini_option_model_files_are_not_collected(tmp_path):
    project = _project(tmp_path, BROKEN)
    (project / "pytest.ini").write_text("[pytest]\n")
    done = _pytest(project, "robot")
    assert done.returncode == 5  # no tests collected


def test_fixture_check_on_built_in_models(btfsm):
    for name in ("ariac-preemptive", "ariac-baseline"):
        report = btfsm.check(name, ["workable-reachability", "no-dead-states", "invariants", "contracts"])
        assert report.exit_code == 0


def test_fixture_check_raises_with_the_counterexample(btfsm):
    with pytest.raises(AssertionError, match="no tick can happen here"):
        btfsm.check("defect-dead-state", ["no-dead-states"])


def test_fixture_conform_in_the_cell(btfsm):
    out = btfsm.conform("ariac-preemptive", scenarios=1, seed=3, time_limit=60.0)
    assert out.conforms and len(out.results) == 1
