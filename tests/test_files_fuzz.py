"""Model-file fuzz battery: mutations of the shipped valid model files.

Sources: ``models/examples/*.yaml`` and the dumps (``btfsm.files.dumps_model``) of the
built-in models. Mutations: delete keys and list items, retype values, insert hostile
strings (comment breakers, lone surrogates, line breaks, deep and huge expressions),
huge numbers, deep nesting, duplicated names and list items, renamed keys, values moved
elsewhere in the document, and edits of the YAML text itself (lines deleted, duplicated,
cut, random characters). Every input must load into a Model or raise one ``ModelError``
of one printable line; ``btfsm validate FILE`` (in-process) must exit 0, 1 or 2 and never
print a traceback. Each test counts its inputs and asserts the count (printed with
``-s``); together they run well over 800 generated inputs.
"""
from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from memo_strategies import st

from btfsm import ModelError
from btfsm.files import builtin_models, dumps_model, load_model, loads_data, loads_model, model_from_data
from btfsm.models.registry import SAME_FORM
from btfsm.model import Model

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = sorted(p for p in (ROOT / "models" / "examples").glob("*.yaml") if not p.name.endswith(".btfsm.yaml"))  # not side files of XML models
SMALL = 8000  # characters: bigger dumps load in ~0.3 s and get fewer inputs


def _sources():
    out = [(p.name, p.read_text()) for p in EXAMPLES]
    for name in sorted(set(builtin_models()) - SAME_FORM):  # SAME_FORM: another model's states, other numbers
        out.append((f"builtin:{name}", dumps_model(load_model(name))))
    return out


SOURCES = _sources()
SMALL_SOURCES = [s for s in SOURCES if len(s[1]) <= SMALL]
LARGE_SOURCES = [s for s in SOURCES if len(s[1]) > SMALL]

HOSTILE_STRINGS = [
    "", " ", "*/ c_code { system(\"touch X\") } /* x", "a\ud800b", "\udfff", "x\ny", "tab\t", "nul\x00",
    "\u2028", "\u200b", "é中", "(" * 300 + "n" + ")" * 300, "not " * 70 + "true", "n" + " + n" * 80 + " > 0",
    "x" * 20_000, "n + 99999999999999999999999999999 > 0", "-99999999999999999999999999", "1 // 0", "n % -3 == 0",
    "__import__('os').system('touch X')", "().__class__", "lambda: 0", "f'{x}'", "a.b.c", "x[0]", "${X}", "${",
    "'busy'", "*", "direct", "on", "yes", "true", "null", "0x10", "1e400", ".nan", "min(1)", "abs(1, 2)", "1 if true",
    "arm.state == 'nope'", "arm.goal", "holding == 3", "'a' < 'b'", "true + 1", "x in ()", "x in y",
]
HOSTILE_VALUES = [None, True, False, 0, -1, 1, 2 ** 53 + 1, 2 ** 70, -(2 ** 70), 10 ** 400, 1.5, math.inf, -math.inf, math.nan,
                  [], {}, [None], {"use": "nope"}, {"use": 3}, {"": None}, [[[]]], {"Condition": "c", "expr": "true"}]
HOSTILE_KEYS = ["", "on", "when", "use", "id", "a\ud800", "x\ny", "Condition", "children", "templates", "*/", "${X}", "name"]


class Counter:
    def __init__(self):
        self.n = 0
        self.models = 0
        self.errors = 0


def _check_load(load, counter: Counter):
    """``load()`` gives a Model or a one-line ModelError; anything else fails the test."""
    counter.n += 1
    try:
        m = load()
    except ModelError as exc:
        counter.errors += 1
        msg = str(exc)
        assert "\n" not in msg and "\r" not in msg, msg
        msg.encode("utf-8")
        assert len(msg) < 2000, msg[:200]
        return None
    assert isinstance(m, Model)
    counter.models += 1
    return m


def _plain(x):
    """Loaded data (dict/list subclasses with positions) as plain dicts and lists."""
    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_plain(v) for v in x]
    return x


def _paths(x, prefix=()):
    out = [prefix]
    if isinstance(x, dict):
        for k, v in x.items():
            out += _paths(v, prefix + (k,))
    elif isinstance(x, list):
        for i, v in enumerate(x):
            out += _paths(v, prefix + (i,))
    return out


def _get(x, path):
    for k in path:
        x = x[k]
    return x


def _deep(depth, leaf):
    for k in range(depth):
        leaf = [leaf] if k % 2 else {"k": leaf}
    return leaf


MUTATIONS = ("delete", "retype", "hostile", "rename", "duplicate", "nest", "move", "huge")


def _mutate(draw, data):
    """One mutation at a random place of ``data`` (changed in place); returns its name."""
    paths = [p for p in _paths(data) if p]
    path = draw(st.sampled_from(paths))
    parent, key = _get(data, path[:-1]), path[-1]
    kind = draw(st.sampled_from(MUTATIONS))
    if kind == "delete":
        del parent[key]
    elif kind == "retype":
        parent[key] = copy.deepcopy(draw(st.sampled_from(HOSTILE_VALUES)))
    elif kind == "hostile":
        parent[key] = draw(st.sampled_from(HOSTILE_STRINGS))
    elif kind == "rename" and isinstance(parent, dict):
        new = draw(st.sampled_from(HOSTILE_KEYS + list(parent)))
        value = parent.pop(key)
        parent[new] = value
    elif kind == "duplicate" and isinstance(parent, list):
        parent.insert(key, copy.deepcopy(parent[key]))
    elif kind == "duplicate":  # a sibling mapping entry gets this one's value (duplicated names)
        other = draw(st.sampled_from(list(parent)))
        parent[other] = copy.deepcopy(parent[key])
    elif kind == "nest":
        parent[key] = _deep(draw(st.sampled_from([3, 50, 99, 101, 150, 400])), parent[key])
    elif kind == "move":
        src = draw(st.sampled_from(paths))
        parent[key] = copy.deepcopy(_get(data, src)) if src[:len(path)] != path else None
    else:
        parent[key] = draw(st.sampled_from([2 ** 31, 2 ** 53, 2 ** 63, 2 ** 64 + 1, -(2 ** 63) - 1, 10 ** 30, 10 ** 4000]))
    return kind


def _as_text(data, fmt, ascii_only=False):
    if fmt == "json":
        return json.dumps(data, ensure_ascii=ascii_only)
    return yaml.safe_dump(data, allow_unicode=True, sort_keys=False)


def _data_battery(sources, n_examples, label):
    counter = Counter()
    parsed = [(name, _plain(loads_data(text))) for name, text in sources]

    @settings(max_examples=n_examples, deadline=None, derandomize=True, database=None,
              suppress_health_check=list(HealthCheck))
    @given(st.data())
    def run(data):
        name, base = data.draw(st.sampled_from(parsed))
        doc = copy.deepcopy(base)
        for _ in range(data.draw(st.integers(1, 3))):
            if isinstance(doc, dict) and len(_paths(doc)) > 1:
                _mutate(data.draw, doc)
        route = data.draw(st.sampled_from(["data", "json", "yaml"]))
        if route == "data":
            _check_load(lambda: model_from_data(doc, name), counter)
            return
        try:
            text = _as_text(doc, route, data.draw(st.booleans()))
        except (ValueError, yaml.YAMLError, RecursionError, OverflowError):
            counter.n += 1  # not representable in that format: the data route covers it
            _check_load(lambda: model_from_data(doc, name), counter)
            return
        _check_load(lambda: loads_model(text, route, f"{name}.{route}"), counter)

    run()
    print(f"\n{label}: {counter.n} inputs, {counter.models} models, {counter.errors} ModelErrors")
    return counter


def test_mutated_data_of_small_model_files_500_inputs():
    c = _data_battery(SMALL_SOURCES, 500, "data mutations (small files)")
    assert c.n >= 500 and c.errors > 50 and c.models > 10


def test_mutated_data_of_large_model_files_40_inputs():
    c = _data_battery(LARGE_SOURCES, 40, "data mutations (large files)")
    assert c.n >= 40


TEXT_CHARS = list(":{}[]&*!|>'\"#%@`,-?\t\n\\ ") + ["\ud800", "\u2028", "\x00", "é", "on", "- ", ": ", "&a ", "*a", "!!python/object:os.system ", "<<: "]


def test_mutated_yaml_text_300_inputs():
    counter = Counter()

    @settings(max_examples=300, deadline=None, derandomize=True, database=None, suppress_health_check=list(HealthCheck))
    @given(st.data())
    def run(data):
        name, text = data.draw(st.sampled_from(SMALL_SOURCES))
        lines = text.split("\n")
        for _ in range(data.draw(st.integers(1, 4))):
            op = data.draw(st.sampled_from(["delete", "duplicate", "insert", "cut", "indent", "swap"]))
            i = data.draw(st.integers(0, max(len(lines) - 1, 0)))
            if op == "delete" and lines:
                del lines[i]
            elif op == "duplicate" and lines:
                lines.insert(i, lines[i])
            elif op == "insert" and lines:
                pos = data.draw(st.integers(0, len(lines[i])))
                ins = "".join(data.draw(st.lists(st.sampled_from(TEXT_CHARS), min_size=1, max_size=4)))
                lines[i] = lines[i][:pos] + ins + lines[i][pos:]
            elif op == "cut":
                joined = "\n".join(lines)
                lines = joined[:data.draw(st.integers(0, len(joined)))].split("\n")
            elif op == "indent" and lines:
                lines[i] = " " * data.draw(st.integers(1, 3)) + lines[i]
            elif op == "swap" and len(lines) > 1:
                j = data.draw(st.integers(0, len(lines) - 1))
                lines[i], lines[j] = lines[j], lines[i]
        mutated = "\n".join(lines)
        as_bytes = data.draw(st.booleans())
        payload = mutated.encode("utf-8", "surrogatepass") if as_bytes else mutated
        _check_load(lambda: loads_model(payload, "yaml", name), counter)

    run()
    print(f"\ntext mutations: {counter.n} inputs, {counter.models} models, {counter.errors} ModelErrors")
    assert counter.n >= 300 and counter.errors > 30


def test_cli_validate_on_mutated_files_120_inputs(tmp_path, capsys):
    from btfsm.cli import main

    counter = Counter()
    codes = {}
    parsed = [(name, _plain(loads_data(text))) for name, text in SMALL_SOURCES]

    @settings(max_examples=120, deadline=None, derandomize=True, database=None, suppress_health_check=list(HealthCheck))
    @given(st.data())
    def run(data):
        name, base = data.draw(st.sampled_from(parsed))
        doc = copy.deepcopy(base)
        _mutate(data.draw, doc)
        fmt = data.draw(st.sampled_from(["json", "yaml"]))
        try:
            text = _as_text(doc, fmt)
        except (ValueError, yaml.YAMLError, RecursionError, OverflowError):
            text = "{" + json.dumps(str(doc)[:50])  # broken on purpose
        path = tmp_path / f"m.{fmt}"
        path.write_text(text, encoding="utf-8", errors="surrogatepass")
        args = ["validate", str(path)] + (["--strict"] if data.draw(st.booleans()) else [])
        try:
            code = main(args)
        except SystemExit as exc:
            code = exc.code
        out = capsys.readouterr()
        counter.n += 1
        codes[code] = codes.get(code, 0) + 1
        assert code in (0, 1, 2), (code, out.err[-500:])
        assert "Traceback" not in out.out + out.err
        if code == 2:  # one line per problem found (and then their count)
            lines = out.err.splitlines()
            problems = lines if len(lines) == 1 else lines[:-1]
            assert out.err.endswith("\n") and all(x.startswith("btfsm validate: error: ") for x in problems), out.err[-500:]
            assert len(lines) == 1 or lines[-1].startswith(f"btfsm validate: {len(problems)} errors"), out.err[-500:]

    run()
    print(f"\nbtfsm validate: {counter.n} inputs, exit codes {codes}")
    assert counter.n >= 120 and codes.get(2, 0) > 10


@pytest.mark.parametrize("name, text", SOURCES, ids=[s[0] for s in SOURCES])
def test_sources_are_valid(name, text):
    assert isinstance(loads_model(text, "yaml", name), Model)
