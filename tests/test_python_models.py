"""Models written in Python on the command line: FILE.py:FUNCTION and package.module:FUNCTION."""
import json
import os
import textwrap

import pytest

from btfsm.cli import main
from btfsm.errors import ModelError
from btfsm.files import load_model, python_model_ref

HERE = os.path.dirname(os.path.abspath(__file__))
TWO_AREA = os.path.join(HERE, "..", "models", "examples", "two_area.py")


def _run(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_file_function_loads_the_same_model_as_the_builtin():
    assert load_model(f"{TWO_AREA}:two_area") == load_model("two-area")


def test_module_function_loads():
    assert load_model("btfsm.models.pickplace:pickplace") == load_model("pickplace3")


def test_check_a_python_file_model(capsys):
    code, out, _ = _run(["check", f"{TWO_AREA}:two_area", "--property", "no-dead-states", "--json"], capsys)
    assert code == 0 and json.loads(out)["model"] == "two-area"


def test_sibling_imports_work_and_sys_path_is_restored(tmp_path):
    import sys

    (tmp_path / "helper_parts.py").write_text("N = 2\n")
    (tmp_path / "robot.py").write_text(textwrap.dedent("""
        from helper_parts import N
        from btfsm import Model, Int, ReactiveFallback, Condition, Action, success
        def build():
            return Model("robot", variables=[Int("n", 0, N)],
                         tree=ReactiveFallback("root", [Condition("full", "n == 2"),
                                                        Action("add", outcomes=[success(n="n + 1")])]))
        """))
    before = list(sys.path)
    assert load_model(f"{tmp_path / 'robot.py'}:build").name == "robot"
    assert sys.path == before


@pytest.mark.parametrize("source, ref, problem", [
    ("def f():\n    return 3\n", "f", "f() returned int, not a btfsm Model"),
    ("def f():\n    raise RuntimeError('boom')\n", "f", "f() raised RuntimeError: boom"),
    ("def f():\n    raise SystemExit(4)\n", "f", "f() raised SystemExit: 4"),
    ("x = 1\n", "f", "has no function 'f'"),
    ("raise ValueError('at import')\n", "f", "raised ValueError: at import"),
    ("def f(:\n", "f", "syntax error"),
])
def test_bad_python_models_are_one_line_errors(tmp_path, capsys, source, ref, problem):
    path = tmp_path / "m.py"
    path.write_text(source)
    code, out, err = _run(["check", f"{path}:{ref}"], capsys)
    assert code == 2 and "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert problem in err and f"{path}:{ref}" in err


@pytest.mark.parametrize("ref, problem", [
    ("missing_file.py:f", "no such Python file 'missing_file.py'"),
    ("no_such_pkg.mod:f", "cannot import 'no_such_pkg.mod': no module named 'no_such_pkg'"),
    ("model.py", "a model written in Python is named FILE.py:FUNCTION"),
])
def test_missing_python_models(capsys, ref, problem):
    code, _, err = _run(["validate", ref], capsys)
    assert code == 2 and problem in err


def test_refs_that_are_not_python_models(tmp_path):
    assert python_model_ref("a.yaml") is None
    assert python_model_ref("C:model") == ("C", "model")  # a module named C
    odd = tmp_path / "odd:name"
    odd.write_text("")
    assert python_model_ref(str(odd)) is None  # an existing file keeps its name
    with pytest.raises(ModelError):
        load_model(str(odd))
