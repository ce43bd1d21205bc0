"""Hostile model files and hostile names (issue 9, model files): one-line ModelErrors
instead of tracebacks, budgets that refuse bombs quickly, exports that never carry code.

Table tests per rule, hypothesis where the input space is large; the model-file fuzz
battery over mutated shipped files is tests/test_files_fuzz.py.
"""
from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import time
from pathlib import Path

import jsonschema
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from memo_strategies import st

from btfsm import ModelError
from btfsm.bt import Action, Condition, ReactiveFallback
from btfsm.expr import INT_LIMIT, MAX_DEPTH, MAX_LENGTH, Scope, check, compile_fn, parse, v
from btfsm.files import MAX_FILE_BYTES, dumps_model, load_model, loads_model, model_from_data
from btfsm.model import Model
from btfsm.primitives import Outcome
from btfsm.status import Status
from btfsm.world import Bool, Int

ROOT = Path(__file__).resolve().parent.parent
SHIPPED = sorted(p for p in (ROOT / "models").rglob("*.yaml")
                 if not p.name.endswith(".btfsm.yaml") and p.parent.name != "scenes")  # not XML side files, not scenes
SCHEMA = json.loads((ROOT / "btfsm" / "schema" / "model.schema.json").read_text())
VALIDATOR = jsonschema.Draft202012Validator(SCHEMA)

BASE = """\
name: counter
variables: {n: {int: [0, 3]}}
tree:
  ReactiveFallback: root
  children:
    - {Condition: full, expr: "EXPR"}
    - {Action: add, outcomes: [{success: {n: n + 1}}]}
"""


def _one_line_error(text, fmt="yaml", name="m.yaml") -> str:
    """The error of loading ``text``: a ModelError of one line naming the file."""
    with pytest.raises(ModelError) as info:
        loads_model(text, fmt, file_name=name)
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith(name + ": "), msg
    msg.encode("utf-8")  # printable everywhere
    return msg


def _with_expr(expr: str) -> str:
    return BASE.replace("EXPR", expr.replace('"', '\\"'))


# ---------------------------------------------------------------- 1. expressions: depth and length

@pytest.mark.parametrize("expr, expected", [
    ("(" * 300 + "n" + ")" * 300 + " == 3", "nested too deeply (limit 64)"),
    ("(" * 150 + "n" + ")" * 150 + " == 3", None),  # parentheses alone add no depth
    ("-" * 150 + "n == 3", "nested too deeply (limit 64)"),
    ("not " * 100 + "n == 3", "nested too deeply (limit 64)"),
    ("not " * 30000 + "n == 3", "characters long (limit 100000)"),
    ("n" + " + n" * 50000 + " == 3", "characters long (limit 100000)"),
    ("n" + " + n" * 100 + " > 3", "nested too deeply (limit 64)"),
    ("n" + " + 1" * 60 + " > 3", None),
    (" and ".join(["n > 0"] * 900), None),  # wide, not deep
    ("1 if n == 0 else " * 70 + "2 == 3", "nested too deeply"),
    ("n in (1, 2) in (3,)", "'in' cannot be chained"),
])
def test_expression_depth_and_length(expr, expected):
    if expected is None:
        loads_model(_with_expr(expr))
        return
    msg = _one_line_error(_with_expr(expr))
    assert "tree.children[0].expr" in msg and expected in msg, msg
    assert len(msg) < 400, "the expression is shortened in the message"


def test_python_api_deep_expression_is_a_model_error():
    e = v.n
    for _ in range(MAX_DEPTH + 5):
        e = -e
    scope = Scope.of([Int("n", 0, 3)])
    with pytest.raises(ModelError, match=r"^guard: expression nested too deeply \(limit 64\)$"):
        compile_fn((e > 0).node, scope, "guard")
    with pytest.raises(ModelError, match="nested too deeply"):
        Model("m", variables=[Int("n", 0, 3)], tree=Condition("c", e > 0))
    deep = v.n
    for _ in range(2000):  # far past the recursion limit: still one ModelError
        deep = deep + 1
    with pytest.raises(ModelError, match="nested too deeply"):
        Model("m", variables=[Int("n", 0, 3)], tree=Condition("c", deep > 0))


# ---------------------------------------------------------------- 4. int constants and ranges

@pytest.mark.parametrize("expr, expected", [
    ("n + 99999999999999999999999999999 > 0", "constant 99999999999999999999999999999: int values must stay within -2**53..2**53"),
    (f"n < {2 ** 53 + 1}", "constant"),
    (f"n > -{2 ** 53 + 1}", "constant"),
    (f"n * {2 ** 52} * 4 > 0", "can reach"),
    (f"n + {2 ** 53} > 0", "can reach"),
    (f"abs(n - {2 ** 53}) + 4 > 0", "can reach"),
    (f"n * {2 ** 50} > 0", None),
    (f"n + 0 < {2 ** 53}", None),
    (f"n % {2 ** 53} == 0", None),
    (f"n // {2 ** 53} == 0", None),
])
def test_int_constants_and_intermediate_ranges(expr, expected):
    if expected is None:
        loads_model(_with_expr(expr))
        return
    msg = _one_line_error(_with_expr(expr))
    assert "tree.children[0].expr" in msg and expected in msg, msg


def test_int_range_from_variable_bounds():
    text = BASE.replace("EXPR", "n * m * m > 3").replace("{n: {int: [0, 3]}}", "{n: {int: [0, 3]}, m: {int: [0, 4000000000]}}")
    assert "'n * m * m' can reach 48000000000000000000" in _one_line_error(text)
    text = BASE.replace("EXPR", "n > 0").replace("{n: {int: [0, 3]}}", "{n: {int: [0, 3]}, m: {int: [0, 1152921504606846976]}}")
    assert "variables.m: int m has bounds 0..1152921504606846976" in _one_line_error(text)


def test_int_limit_in_the_python_api_and_effects():
    with pytest.raises(ModelError, match=r"^guard: constant .* in 'n \+ 99999999999999999999 > 0'"):
        check(parse("n + 99999999999999999999 > 0"), Scope.of([Int("n", 0, 3)]), "guard")
    with pytest.raises(ModelError, match="tree.a.*can reach"):
        Model("m", variables=[Int("n", 0, 3), Int("k", 0, 2 ** 40)],
              tree=Action("a", outcomes=[Outcome(Status.SUCCESS, {"n": "min(k * k, 3)"})]))


@settings(max_examples=60, deadline=None)
@given(st.integers(-(2 ** 70), 2 ** 70), st.integers(0, 3))
def test_in_range_constants_compute_exactly_on_the_default_engine(c, n):
    """A guard with a constant either is refused (|c| > 2**53) or gives the exact answer."""
    from btfsm.verify.explore import explore

    guard = f"n + {c} > 0" if c >= 0 else f"n - {-c} > 0"
    text = BASE.replace("EXPR", guard).replace("{n: {int: [0, 3]}}", f"{{n: {{int: [0, 3], init: {n}}}}}")
    if abs(c) > INT_LIMIT - 3:
        with pytest.raises(ModelError):
            loads_model(text)
        return
    m = loads_model(text)
    ts = explore(m, max_states=100)
    assert ts.complete
    assert bool(compile_fn(parse(guard), Scope.of(m.variables), "g")([n])) == (n + c > 0)


# ---------------------------------------------------------------- 2. alias and template bombs

LAUGHS = "name: x\na: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n" + "".join(
    f"{b}: &{b} [{', '.join(['*' + a] * 9)}]\n" for a, b in zip("abcdefgh", "bcdefghi"))


def _template_bomb(levels=7, fan=10):
    lines = ["name: x", "templates:", "  t0: {params: [], states: [a, b, c, d, e, f, g, h, i, j]}"]
    lines += [f"  t{k}: {{params: [], states: [{', '.join(['{use: t%d}' % (k - 1)] * fan)}]}}" for k in range(1, levels + 1)]
    lines += ["fsms:", f"  f: {{goals: [g], states: [{{use: t{levels}}}]}}"]
    return "\n".join(lines) + "\n"


def _value_bomb():
    """Few items, each a big parameter value: counted by values, not by items."""
    big = "[" + ", ".join(["[1, 2, 3, 4, 5, 6, 7, 8, 9, 10]"] * 500) + "]"
    row = "{X: *big}"
    rows = ", ".join([f"{{X: &big {big}}}"] + [row] * 7)
    inner = ", ".join(['{X: "${X}"}'] * 8)
    return f"""name: x
templates:
  t0: {{params: [X], states: [{{id: a, args: {{k: "${{X}}"}}}}]}}
  t1: {{params: [X], states: [{{use: t0, for_each: [{inner}]}}]}}
  t2: {{params: [X], states: [{{use: t1, for_each: [{inner}]}}]}}
fsms:
  f: {{goals: [g], states: [{{use: t2, for_each: [{rows}]}}]}}
"""


def _string_bomb(in_key=False):
    """One item, one value, but a text that doubles eightfold per template level (8**15
    times its start): refused by its length, computed before the text is built."""
    lines = ["name: x", "templates:"]
    for k in range(15):
        lines.append(f"  t{k}: {{params: [X], states: [{{use: t{k + 1}, with: {{X: \"{'${X}' * 8}\"}}}}]}}")
    last = "{id: s, args: {\"${X}\": 1}}" if in_key else "\"s_${X}\""
    lines += [f"  t15: {{params: [X], states: [{last}]}}", "fsms:", "  f: {goals: [g], states: [{use: t0, with: {X: ab}}]}"]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("text, expected", [
    (LAUGHS, "more than 200000 values (aliases expanded)"),
    (_template_bomb(), "templates produce more than 100000 items"),
    (_value_bomb(), "templates produce more than 200000 values"),
    (_string_bomb(), "templates produce more than 8388608 characters of text"),
    (_string_bomb(in_key=True), "templates produce more than 8388608 characters of text"),
], ids=["billion-laughs", "template-items", "template-values", "template-string", "template-key-string"])
def test_bombs_are_refused_quickly(text, expected):
    t0 = time.process_time()
    msg = _one_line_error(text)
    assert expected in msg, msg
    assert time.process_time() - t0 < 20  # seconds of CPU; about 1 s today


def test_python_data_with_shared_values_is_counted():
    leaf = list(range(10))
    for _ in range(8):
        leaf = [leaf] * 10  # 10**9 values when expanded, a few objects in memory
    with pytest.raises(ModelError, match="more than 200000 values"):
        model_from_data({"name": "x", "description": leaf})


# ---------------------------------------------------------------- 3. labels: printable, one line

HOSTILE_LABELS = ["a\ud800b", "new\nline", "tab\there", "nul\x00", "bell\x07", "zero\u200bwidth", "ls\u2028", "", "x" * 300]


@pytest.mark.parametrize("label", HOSTILE_LABELS, ids=lambda s: repr(s)[:20])
@pytest.mark.parametrize("where", ["name", "state", "goal", "node", "invariant", "enum", "outcome", "edge id"])
def test_non_printable_labels_are_refused_at_load(label, where):
    data = {"name": "m", "variables": {"n": {"int": [0, 1]}, "e": {"enum": ["a", "b"]}},
            "fsms": {"f": {"goals": ["g"], "states": ["s", {"id": "t", "outcomes": [{"success": {}, "name": "ok"}]}],
                           "edges": [{"from": "s", "to": "t"}]}},
            "tree": {"Condition": "c", "expr": "n == 0"}, "invariants": {"inv": "n >= 0"}}
    f = data["fsms"]["f"]
    if where == "name":
        data["name"] = label
    elif where == "state":
        f["states"][0] = label
        f["edges"][0]["from"] = label
    elif where == "goal":
        f["goals"] = ["g", label]
    elif where == "node":
        data["tree"]["Condition"] = label
    elif where == "invariant":
        data["invariants"] = {label: "n >= 0"}
    elif where == "enum":
        data["variables"]["e"]["enum"] = ["a", label]
    elif where == "outcome":
        f["states"][1]["outcomes"][0]["name"] = label
    else:
        if not label:  # an empty id means "the default id"
            return
        if len(label) > 256:
            f["edges"][0]["id"] = label  # ids have no length limit
            loads_model(json.dumps(data), "json")
            return
        f["edges"][0]["id"] = label
    msg = _one_line_error(json.dumps(data), "json", "m.json")
    assert re.search(r"non-printable|characters long|non-empty|cannot be empty|expected", msg), msg


def test_surrogate_names_never_reach_a_printer(capsys):
    from btfsm.cli import main

    path = ROOT / "tests" / "_tmp_surrogate.json"
    try:
        path.write_text('{"name": "a\\ud800b", "tree": {"Condition": "c\\ud800", "expr": "true"}}')
        for cmd in ("validate", "check", "show"):
            try:
                code = main([cmd, str(path)])
            except SystemExit as exc:
                code = exc.code
            out = capsys.readouterr()
            assert code == 2 and "non-printable character U+D800" in out.err, (cmd, out)
            assert "Traceback" not in out.err
    finally:
        path.unlink(missing_ok=True)


def test_labels_in_the_python_api():
    from btfsm.fsm import FSM, State

    with pytest.raises(ModelError, match=r"^name: model name 'a\\nb' holds the non-printable character U\+000A"):
        Model("a\nb", tree=Condition("c", "true"))
    with pytest.raises(ModelError, match="state id"):
        Model("m", fsms=[FSM("f", [State("s\x1b[31m")], goals=["g"])])
    Model("m \u00e9\u4e2d */ {x} \"q\" \\", tree=Condition("c", "true"))  # printable: fine


# ---------------------------------------------------------------- 5. exports carry no code

PAYLOAD_MARK = "PWNED_BY_EXPORT"


def _hostile_model(name: str, everywhere: bool):
    h = name if everywhere else "x"
    data = {"name": name, "variables": {"n": {"int": [0, 2]}, "e": {"enum": ["a", "b" + h]}},
            "fsms": {"arm": {"goals": ["go", "g" + h], "initial": "s" + h,
                             "states": ["s" + h, {"id": "t", "outcomes": [{"success": {"n": "min(n + 1, 2)"}, "name": "ok" + h}]}],
                             "edges": [{"from": "s" + h, "to": "t", "goals": "*", "when": "direct", "id": "edge" + h},
                                       {"from": "t", "to": "s" + h, "goals": "*"}],
                             "markers": [{"state": "t", "id": "mk" + h, "when": "direct", "goals": ["g" + h]}]}},
            "invariants": {"inv" + h: "n <= 2"}}
    return loads_model(json.dumps(data), "json")


def _promela_comments_balanced(text: str) -> bool:
    """Outside comments there is no ``*/``; inside there is no ``/*``; every comment ends."""
    i, n = 0, len(text)
    while i < n:
        start, stray = text.find("/*", i), text.find("*/", i)
        if stray != -1 and (start == -1 or stray < start):
            return False
        if start == -1:
            return True
        end = text.find("*/", start + 2)
        if end == -1 or "/*" in text[start + 2:end]:
            return False
        i = end + 2
    return True


_HOSTILE_PIECES = ["*/", "/*", "\n", '"', "'", "\\", "c_code", "{", "}", "system(\"touch X\")", "#include", "--", "\u00e9", ";", "//"]


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.sampled_from(_HOSTILE_PIECES) | st.text(max_size=4), min_size=1, max_size=8).map("".join),
       st.booleans())
def test_exports_of_hostile_names_are_inert(name, everywhere):
    from btfsm.verify.export import export

    try:
        model = _hostile_model(name, everywhere)
    except ModelError as exc:  # a label that is not printable text is refused with one line
        assert "\n" not in str(exc)
        assert not name.isprintable() or not name or len(name) + 4 > 256 or "non-printable" in str(exc) or "not an identifier" in str(exc)
        return
    pml = export(model, "promela", "arm")
    assert _promela_comments_balanced(pml)
    assert not re.search(r"\bc_code\b", _strip_comments(pml))
    assert pml.isascii()
    smv = export(model, "smv", "arm")
    for line in smv.splitlines():
        code = line.split("--", 1)[0]
        assert not re.search(r"\bc_code\b", code) and "\\" not in code
    dot = export(model, "dot", "arm")
    _check_dot_quoting(dot)


def _strip_comments(text):
    return re.sub(r"/\*.*?\*/", "", text, flags=re.S)


def _check_dot_quoting(dot: str):
    """Every line is a statement whose quoted strings close (no raw newline inside)."""
    for line in dot.splitlines():
        stripped = re.sub(r'"(?:[^"\\]|\\.)*"', 'Q', line)
        assert '"' not in stripped, line
        assert line.isprintable() or all(c.isprintable() or c == "\t" for c in line)


def _spin_missing():
    for tool in ("spin", "gcc"):
        if shutil.which(tool) is None:
            return f"{tool} not found"
    return None


@pytest.mark.skipif(_spin_missing() is not None, reason=f"needs spin and gcc: {_spin_missing()}")
@pytest.mark.parametrize("everywhere", [False, True], ids=["name-only", "every-label"])
def test_spin_runs_exported_hostile_model_without_running_its_payload(tmp_path, everywhere):
    """The issue's attack: a model name that closes the comment and adds a c_code block
    whose constructor touches a file. Following the export's own Verify recipe must not
    create the file (with the old export it did)."""
    from btfsm.verify.export import export

    marker = tmp_path / PAYLOAD_MARK
    name = (f'*/ c_code {{ __attribute__((constructor)) static void pw(void) {{ system("touch {marker}"); }} }} '
            f'/* x')
    pml = export(_hostile_model(name, everywhere), "promela", "arm")
    (tmp_path / "m.pml").write_text(pml)
    spin = subprocess.run(["spin", "-o2", "-a", "m.pml"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert spin.returncode == 0 and "rror" not in spin.stdout, spin.stdout + spin.stderr
    cc = subprocess.run(["gcc", "-O2", "-DSAFETY", "-DNOCLAIM", "-o", "pan", "pan.c"], cwd=tmp_path,
                        capture_output=True, text=True, timeout=300)
    assert cc.returncode == 0, cc.stderr[-2000:]
    pan = subprocess.run(["./pan", "-m100000"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert "errors: 0" in pan.stdout, pan.stdout
    assert not marker.exists()
    assert not (ROOT / PAYLOAD_MARK).exists()


# ---------------------------------------------------------------- 6. export errors name the file

@pytest.mark.parametrize("args, expected", [
    (["--format", "promela"], r"^btfsm export: error: \S*m\.yaml: tree: whole-model export"),
    (["--format", "smv", "--fsm", "nope"], r"^btfsm export: error: \S*m\.yaml: --fsm: no FSM named 'nope'"),
])
def test_export_errors_name_the_file(tmp_path, capsys, args, expected):
    from btfsm.cli import main

    path = tmp_path / "m.yaml"
    path.write_text(_with_expr("n == 3"))
    try:
        code = main(["export", str(path), *args])
    except SystemExit as exc:
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and re.search(expected, err), err


def test_export_api_errors_name_the_model_or_source():
    from btfsm.verify.export import export

    m = loads_model(_with_expr("n == 3"))
    with pytest.raises(ModelError, match=r"^counter: tree: "):
        export(m, "promela")
    with pytest.raises(ModelError, match=r"^f\.yaml: format: unknown export format"):
        export(m, "nope", source="f.yaml")
    path = ROOT / "models" / "examples" / "two_area.yaml"
    with pytest.raises(ModelError, match=r"two_area\.yaml: format: unknown export format"):
        export(load_model(path), "nope")  # load_model records the source


# ---------------------------------------------------------------- 7. not a regular file, too big

@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="needs FIFOs")
def test_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "m.yaml"
    os.mkfifo(fifo)
    t0 = time.monotonic()
    with pytest.raises(ModelError, match=r"m\.yaml: is a FIFO, not a regular model file$"):
        load_model(fifo)
    assert time.monotonic() - t0 < 10


@pytest.mark.parametrize("path, expected", [
    ("/dev/zero.yaml", "cannot read"),
    ("/dev/null", "unknown model file extension"),
])
def test_special_paths(path, expected):
    with pytest.raises(ModelError, match=expected):
        load_model(path)


def test_device_with_a_model_extension_is_refused(tmp_path):
    link = tmp_path / "zero.yaml"
    link.symlink_to("/dev/zero")
    with pytest.raises(ModelError, match="is a device, not a regular model file"):
        load_model(link)


def test_huge_file_is_refused_before_reading(tmp_path):
    big = tmp_path / "big.yaml"
    with open(big, "wb") as fh:
        fh.truncate(MAX_FILE_BYTES + 1)  # sparse: nothing written
    with pytest.raises(ModelError, match=f"is {MAX_FILE_BYTES + 1} bytes; model files are at most {MAX_FILE_BYTES} bytes"):
        load_model(big)


# ---------------------------------------------------------------- 8. validation is linear in variables

def _model_with(n: int) -> Model:
    vs = [Bool(f"v{i}") for i in range(n)]
    tree = ReactiveFallback("root", [Condition("c", "v0"), Action("a", outcomes=[Outcome(Status.SUCCESS, {"v1": "true"})])])
    return Model("many", variables=vs, tree=tree)


def _lookups(n: int) -> int:
    """Variables compared by name while building, validating and compiling an n-variable
    model (the old lookup scanned the list: about n*n/2 comparisons)."""
    count = 0

    class CountingName(str):
        def __eq__(self, other):
            nonlocal count
            count += 1
            return str.__eq__(self, other)

        __hash__ = str.__hash__

    vs = [Bool(CountingName(f"v{i}")) for i in range(n)]
    tree = ReactiveFallback("root", [Condition("c", "v0"), Action("a", outcomes=[Outcome(Status.SUCCESS, {"v1": "true"})])])
    m = Model("many", variables=vs, tree=tree)
    m.program  # noqa: B018 - compiles
    return count


def test_validation_does_linear_work_in_the_number_of_variables():
    small, large = _lookups(1000), _lookups(4000)
    assert large <= 6 * max(small, 1), (small, large)  # quadratic would be ~16x
    assert large < 4000 * 20, large


def test_twenty_thousand_variables_validate():
    t0 = time.process_time()
    m = _model_with(20_000)
    m.program  # noqa: B018
    assert len(m.variables) == 20_000
    assert time.process_time() - t0 < 60  # about 1 s; the old lookup needed minutes


# ---------------------------------------------------------------- 9. the trigger key: when (on still read)

def test_shipped_files_validate_with_plain_pyyaml_and_jsonschema():
    assert SHIPPED, "no shipped model files found"
    for path in SHIPPED:
        data = yaml.safe_load(path.read_text())  # a YAML 1.1 reader: on: would become True
        errors = [e.message for e in VALIDATOR.iter_errors(data)]
        assert not errors, (path, errors[:3])
        assert not re.search(r"\bon:", re.sub(r"#.*", "", path.read_text())), path


@pytest.mark.parametrize("spelling", ["when", "on", "yaml11"])
def test_trigger_spellings(spelling):
    base = {"name": "m", "fsms": {"f": {"goals": ["g"], "states": ["a", "b"],
                                        "edges": [{"from": "a", "to": "b"}], "markers": [{"state": "b"}]}}}
    edge, marker = base["fsms"]["f"]["edges"][0], base["fsms"]["f"]["markers"][0]
    key = True if spelling == "yaml11" else spelling
    edge[key], marker[key] = "failure", "direct"
    m = model_from_data(base)
    e, mk = m.fsms[0].edges[0], m.fsms[0].markers[0]
    assert e.on == Status.FAILURE and mk.direct
    text = dumps_model(m)
    assert "when: failure" in text and "when: direct" in text and "on:" not in text
    assert loads_model(text) == m
    assert not list(VALIDATOR.iter_errors(yaml.safe_load(text)))


def test_trigger_given_twice_or_wrong():
    two = "name: m\nfsms:\n  f:\n    goals: [g]\n    states: [a, b]\n    edges: [{from: a, to: b, when: failure, on: direct}]\n"
    assert "give the trigger once" in _one_line_error(two)
    bad = two.replace(", on: direct", "").replace("failure", "later")
    assert "fsms.f.edges[0].when: expected success, failure, running or direct, got 'later'" in _one_line_error(bad)
    data = {"name": "m", "fsms": {"f": {"goals": ["g"], "states": ["a", "b"], "edges": [{"from": "a", "to": "b", True: "nope"}]}}}
    with pytest.raises(ModelError, match=r"edges\[0\]\.on: expected success"):
        model_from_data(data)
    data["fsms"]["f"]["edges"][0] = {"from": "a", "to": "b", 1: "x"}
    with pytest.raises(ModelError, match="field names are strings"):
        model_from_data(data)
    assert list(VALIDATOR.iter_errors({"name": "m", "fsms": {"f": {"goals": ["g"], "states": ["a"],
                                                                   "edges": [{"from": "a", "to": "a", "when": "direct", "on": "direct"}]}}}))


# ---------------------------------------------------------------- 1. the parser and compiler never crash

from btfsm.expr import (BinOp, BoolOp, Call, Compare, Const, IfElse, Name, Unary, names_in,  # noqa: E402
                        to_numpy_source, to_text)

_EXPR_SCOPE_VARS = [Bool("p"), Int("n", -3, 4), Int("big", -(2 ** 40), 2 ** 40), Int("m", 0, 5)]
_EXPR_SCOPE = Scope.of(_EXPR_SCOPE_VARS)
_TOKENS = ["n", "m", "p", "big", "q", "(", ")", " and ", " or ", "not ", " + ", " - ", " * ", " // ", " % ", " == ",
           " < ", " >= ", " != ", "min(", "max(", "abs(", ", ", " if ", " else ", " in ", "('a', 'b')", "true",
           "false", "0", "1", "3", "-", str(2 ** 53), str(2 ** 63), "99999999999999999999", "'x'", "arm.state",
           "**", "lambda", "[", "]", "{", "}", "@", ":", ";", "\n", "\\", "\x00", "\ud800", "é", "#", "f'", "'", '"']


def _try_compile(e, expected=None):
    """check + every translation: a value, or a ModelError; never another exception."""
    try:
        t = check(e, _EXPR_SCOPE, "x", expected)
    except ModelError as exc:
        assert "\n" not in str(exc)
        return None
    fn = compile_fn(e, _EXPR_SCOPE, "x", t)
    src = to_numpy_source(e, _EXPR_SCOPE, expected=t)
    to_text(e)
    names_in(e)
    return t, fn, src


@settings(max_examples=300, deadline=None, suppress_health_check=list(HealthCheck))
@given(st.lists(st.sampled_from(_TOKENS), max_size=30).map("".join) | st.text(max_size=60))
def test_random_strings_parse_or_fail_cleanly(text):
    try:
        e = parse(text)
    except ModelError as exc:
        assert "\n" not in str(exc) and len(str(exc)) < 400
        return
    _try_compile(e)


_NAMES = st.sampled_from(["n", "m", "p", "big", "nope", "arm.state", ""])
_CONSTS = st.one_of(st.booleans(), st.integers(-(2 ** 70), 2 ** 70), st.sampled_from(["a", "x", ""]),
                    st.sampled_from([None, 1.5, b"n", (1,)]))


def _asts():
    leaves = st.one_of(_CONSTS.map(Const), _NAMES.map(Name))
    ops = st.sampled_from(["not", "-", "and", "or", "==", "<", "+", "*", "//", "%", "**", "", "min"])
    return st.recursive(leaves, lambda kids: st.one_of(
        st.builds(Unary, ops, kids),
        st.builds(BoolOp, ops, st.lists(kids, max_size=3).map(tuple)),
        st.builds(Compare, ops, kids, kids),
        st.builds(BinOp, ops, kids, kids),
        st.builds(Call, st.sampled_from(["min", "max", "abs", "pow", "eval"]), st.lists(kids, max_size=3).map(tuple)),
        st.builds(IfElse, kids, kids, kids),
    ), max_leaves=25)


@settings(max_examples=400, deadline=None, suppress_health_check=list(HealthCheck))
@given(_asts(), st.sampled_from([None, "bool", "int"]),
       st.tuples(st.integers(0, 1), st.integers(-3, 4), st.sampled_from([-(2 ** 40), 0, 2 ** 40]), st.integers(0, 5)))
def test_random_asts_compile_or_fail_cleanly(e, kind, state):
    """Hand-built trees (unknown operators, wrong arities, odd constants): a ModelError or
    a closure whose value the numpy translation reproduces exactly on int64 columns."""
    import numpy as np

    from btfsm.expr import BOOL, INT

    got = _try_compile(e, {"bool": BOOL, "int": INT}.get(kind))
    if got is None:
        return
    t, fn, src = got
    value = fn(list(state))
    cols = np.array([state], dtype=np.int64).T
    vec = np.asarray(eval(src, {"np": np, "c": cols}))  # noqa: S307 - generated from a checked AST
    vec = np.broadcast_to(vec, (1,)).item()
    if t == BOOL:
        assert bool(vec) == bool(value)
    else:
        assert int(vec) == int(value), (to_text(e), vec, value)  # no int64 overflow


@settings(max_examples=300, deadline=None, suppress_health_check=list(HealthCheck))
@given(st.data())
def test_well_typed_expressions_over_big_bounds_are_exact_or_refused(data):
    """With variables near 2**40, products leave int64 unless refused: a checked
    expression gives the same value in Python (exact) and numpy (int64)."""
    import numpy as np

    from core_strategies import expr_env, typed_exprs

    e, t = data.draw(typed_exprs(expr_env(_EXPR_SCOPE_VARS), max_depth=4))
    state = data.draw(st.tuples(st.integers(0, 1), st.integers(-3, 4), st.sampled_from([-(2 ** 40), -1, 2 ** 40]), st.integers(0, 5)))
    got = _try_compile(e, t)
    if got is None:
        return
    _, fn, src = got
    value = fn(list(state))
    vec = np.broadcast_to(np.asarray(eval(src, {"np": np, "c": np.array([state], dtype=np.int64).T})), (1,)).item()  # noqa: S307
    assert (bool(vec) == bool(value)) if t.kind == "bool" else (int(vec) == int(value)), to_text(e)
