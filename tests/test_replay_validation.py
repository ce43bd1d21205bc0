"""Tampered traces and counterexamples given to ``btfsm replay`` (the tamper battery).

A real trace (``btfsm run two-area --ticks 20 --trace t.jsonl``) and a real counterexample
(``btfsm check defect-trap --counterexample-dir ce``) are mutated by fixed tables
(records replaced by lists, ints, null, NaN...; every field deleted and retyped; the
counterexample truncated at every byte offset) and by hypothesis (any JSON value, lone
surrogates included, put anywhere). Every mutant runs in-process through
``btfsm.cli.main(["replay", ...])``: it must end in exit 0 (reproduces), 1 (a valid file
the model does not reproduce) or 2 (not a valid file: one line on stderr naming the file
and the line or JSON path), never a traceback. Where the mutation surely breaks the format
the exit must be 2. The number of mutants of each family is asserted; in all there are
well over 600 (see ``test_battery_size``).

To keep the battery fast the model loader and the argument parser are cached for this
module (they are tested elsewhere; the file reading and replay are not cached).
"""
from __future__ import annotations

import contextlib
import copy
import functools
import io
import json

import pytest
from hypothesis import HealthCheck, given, settings
from memo_strategies import st

import btfsm.cli as cli
import btfsm.files.loading as files  # where load_cli_model looks load_model up (the cache below)
from btfsm.formats import FormatError, validate
from btfsm.trace import plain_record, read_trace
from btfsm.verify.counterexample import load_counterexample

TICKS = 20
TRACE_LINES = TICKS + 1
# JSON values of every type, for retyping a field
PALETTE = [None, True, False, 0, -1, 1.5, 10 ** 30, "x", "\ud800", [], {}, [["a"]], [1, 2], {"a": 1}]
# whole lines that are no trace record
BAD_LINES = ["[]", "[1, 2]", "5", "null", '"x"', "true", "1.5", "{}", "NaN", "Infinity", "-Infinity", "[1e999]",
             "{", '{"tick": NaN}', '"\\ud800"', '{"tick": 1e999}', "1" * 5000, "[" * 5000, "\x00"]
RECORD_FIELDS = ["tick", "time", "status", "env", "outcomes", "changes", "fired", "fsm", "writes", "violations"]
HEADER_FIELDS = ["format", "model", "tick_rate", "initial"]
MUTATED_LINES = [0, 1, 10, TRACE_LINES - 1]


@pytest.fixture(scope="module", autouse=True)
def _cached_setup():
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(files, "load_model", functools.lru_cache(maxsize=None)(files.load_model))
        mp.setattr(cli, "build_parser", functools.lru_cache(maxsize=None)(cli.build_parser))
        yield


def _main(argv) -> int:
    try:
        return cli.main(argv)
    except SystemExit as exc:
        return exc.code


@pytest.fixture(scope="module")
def real(tmp_path_factory):
    d = tmp_path_factory.mktemp("replay")
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert _main(["run", "two-area", "--ticks", str(TICKS), "--trace", str(d / "t.jsonl")]) == 0
        assert _main(["check", "defect-trap", "--counterexample-dir", str(d / "ce")]) == 1
    (ce,) = (d / "ce").glob("*.json")
    return Files({"dir": d, "trace": (d / "t.jsonl").read_text("utf-8"), "ce": ce.read_bytes()})


class Files(dict):
    def __repr__(self):  # keep hypothesis' reports short
        return "<the real trace and counterexample>"


class Battery:
    """Runs mutants through ``btfsm replay`` and collects every wrong ending."""

    def __init__(self, capsys, folder, suffix, model):
        self.capsys, self.model, self.count, self.bad = capsys, model, 0, []
        self.path = folder / f"mutant{suffix}"

    def run(self, label, data, want=None):
        """``data`` (text or bytes) as the file; ``want``: the exit code it must have, or
        None for any of 0, 1, 2."""
        self.count += 1
        self.path.write_bytes(data if isinstance(data, bytes) else data.encode("utf-8", "surrogatepass"))
        try:
            rc = _main(["replay", str(self.path), self.model])
        except BaseException as exc:  # a traceback: the one thing that must never happen
            self.capsys.readouterr()
            self.bad.append(f"{label}: raised {type(exc).__name__}: {exc}")
            return None
        out, err = self.capsys.readouterr()
        lines = err.strip().splitlines()
        if rc not in (0, 1, 2) or (want is not None and rc != want):
            self.bad.append(f"{label}: exit {rc} (want {want if want is not None else '0, 1 or 2'}): {err.strip()[:200]}")
        elif rc == 2 and (len(lines) != 1 or self.path.name not in lines[0] or out):
            self.bad.append(f"{label}: exit 2 without one line naming the file: {err!r}")
        elif rc in (0, 1) and (err or len(out.strip().splitlines()) != 1):
            self.bad.append(f"{label}: exit {rc} without one line of result: {out!r} {err!r}")
        return rc

    def check(self, at_least: int):
        assert not self.bad, f"{len(self.bad)} of {self.count} mutants went wrong:\n" + "\n".join(self.bad[:30])
        assert self.count >= at_least


def _lines(real):
    return real["trace"].splitlines()


def _text(lines):
    return "\n".join(lines) + "\n"


def _set(lines, i, obj):
    out = list(lines)
    out[i] = json.dumps(obj)
    return out


def _jtype(x):
    return "number" if type(x) in (int, float) else type(x)


# ---------------------------------------------------------------------- traces


def test_real_trace_and_counterexample_replay(real, capsys):
    b = Battery(capsys, real["dir"], ".jsonl", "two-area")
    assert b.run("trace as written", real["trace"], want=0) == 0
    c = Battery(capsys, real["dir"], ".json", "defect-trap")
    assert c.run("counterexample as written", real["ce"], want=0) == 0
    b.check(1)
    c.check(1)


def test_trace_lines_replaced_by_non_records(real, capsys):
    """399 mutants: every line replaced by a list, an int, null, NaN, a truncated line..."""
    b = Battery(capsys, real["dir"], ".jsonl", "two-area")
    lines = _lines(real)
    for i, line in enumerate(lines):
        for k, bad in enumerate(BAD_LINES + [line[: len(line) // 2]]):
            b.run(f"line {i + 1} <- bad {k}", _text(lines[:i] + [bad] + lines[i + 1:]), want=2)
    b.check(TRACE_LINES * (len(BAD_LINES) + 1))


def test_trace_fields_deleted_retyped_and_added(real, capsys):
    """4 header fields and 10 fields of 3 records: deleted (34), retyped with 14 values
    of every JSON type (476), one unknown field added per line (4): 514 mutants."""
    b = Battery(capsys, real["dir"], ".jsonl", "two-area")
    lines = _lines(real)
    for i in MUTATED_LINES:
        obj = json.loads(lines[i])
        for field in (HEADER_FIELDS if i == 0 else RECORD_FIELDS):
            gone = {k: v for k, v in obj.items() if k != field}
            b.run(f"line {i + 1}: {field} deleted", _text(_set(lines, i, gone)), want=2)
            for value in PALETTE:
                new = dict(obj, **{field: value})
                must_fail = _jtype(value) != _jtype(obj[field]) and not (field == "time" and value == 0)
                b.run(f"line {i + 1}: {field} = {value!r}", _text(_set(lines, i, new)), want=2 if must_fail else None)
        b.run(f"line {i + 1}: extra field", _text(_set(lines, i, dict(obj, extra=1))), want=2)
    b.check(4 + 30 + (4 + 30) * len(PALETTE))


def test_trace_header_and_order_tampering(real, capsys):
    b = Battery(capsys, real["dir"], ".jsonl", "two-area")
    lines = _lines(real)
    header = json.loads(lines[0])
    rec = [json.loads(x) for x in lines[1:]]
    table = [
        ("other format", _set(lines, 0, dict(header, format="btfsm-trace/2")), 2),
        ("no header", lines[1:], 2),
        ("header twice", lines[:1] + lines, 2),
        ("other model", _set(lines, 0, dict(header, model="other")), 1),
        ("model with a lone surrogate", _set(lines, 0, dict(header, model="a\ud800")), 1),
        ("tick rate 0", _set(lines, 0, dict(header, tick_rate=0)), 2),
        ("tick rate -1", _set(lines, 0, dict(header, tick_rate=-1)), 2),
        ("another tick rate", _set(lines, 0, dict(header, tick_rate=5.0)), 1),
        ("unknown slot in initial", _set(lines, 0, dict(header, initial=dict(header["initial"], nope=1))), 1),
        ("initial out of domain", _set(lines, 0, dict(header, initial=dict(header["initial"], waiting=99))), 1),
        ("initial int for a bool", _set(lines, 0, dict(header, initial=dict(header["initial"], holding=1))), 1),
        ("initial bool for an int", _set(lines, 0, dict(header, initial=dict(header["initial"], waiting=True))), 1),
        ("initial flag out of range", _set(lines, 0, dict(header, initial=dict(header["initial"], **{"work:running": 7}))), 1),
        ("initial enum value unknown", _set(lines, 0, dict(header, initial=dict(header["initial"], **{"arm.state": "nowhere"}))), 1),
        ("initial empty", _set(lines, 0, dict(header, initial={})), 0),
        ("two records swapped", lines[:2] + [lines[3], lines[2]] + lines[4:], 2),
        ("a record dropped", lines[:5] + lines[6:], 2),
        ("a record doubled", lines[:5] + [lines[5]] + lines[5:], 2),
        ("last record dropped", lines[:-1], 0),
        ("header only", lines[:1], 0),
        ("empty file", [], 2),
        ("blank lines", [lines[0], "", "   "] + lines[1:], 0),
        ("first tick 1", _set(lines, 1, dict(rec[0], tick=1)), 2),
        ("a huge tick", _set(lines, 3, dict(rec[2], tick=10 ** 40)), 2),
        ("negative time", _set(lines, 3, dict(rec[2], time=-0.1)), 2),
        ("other time", _set(lines, 3, dict(rec[2], time=123.0)), 1),
        ("other status", _set(lines, 3, dict(rec[2], status="FAILURE" if rec[2]["status"] != "FAILURE" else "SUCCESS")), 1),
        ("unknown event", _set(lines, 3, dict(rec[2], env=["no-such-event"])), 1),
        ("undeclared outcome", _set(lines, 1, dict(rec[0], outcomes=[[rec[0]["outcomes"][0][0], "bogus"]])), 1),
        ("outcome at another site", _set(lines, 1, dict(rec[0], outcomes=[["nowhere", "x"]])), 1),
        ("outcomes missing", _set(lines, 1, dict(rec[0], outcomes=[])), 1),
        ("an outcome too many", _set(lines, 1, dict(rec[0], outcomes=rec[0]["outcomes"] * 2)), 1),
        ("changes status unknown", _set(lines, 1, dict(rec[0], changes={"x": "DONE"})), 2),
        ("fsm goal a number", _set(lines, 1, dict(rec[0], fsm={"arm": ["at_in", 3]})), 2),
        ("fsm three items", _set(lines, 1, dict(rec[0], fsm={"arm": ["at_in", None, 1]})), 2),
        ("writes a list", _set(lines, 1, dict(rec[0], writes={"waiting": [1]})), 2),
        ("violation of one item", _set(lines, 1, dict(rec[0], violations=[["x"]])), 2),
        ("lone surrogate in an event", _set(lines, 1, dict(rec[0], env=["\udc80"])), 1),
        ("lone surrogate in a site", _set(lines, 1, dict(rec[0], outcomes=[["\udc80", "x"]])), 1),
    ]
    for label, ls, want in table:
        b.run(label, _text(ls), want=want)
    text = _text(lines)
    b.run("CRLF line ends", text.replace("\n", "\r\n"), want=0)
    b.run("a byte that is not UTF-8", text.encode()[:100] + b"\xff" + text.encode()[100:], want=2)
    b.run("a byte order mark", "\ufeff" + text, want=2)
    b.run("no final newline", text.rstrip("\n"), want=0)
    b.run("a NUL byte", text[:50] + "\x00" + text[50:], want=2)
    b.check(len(table) + 5)


def test_trace_errors_name_line_and_field(real, capsys):
    lines = _lines(real)
    rec = json.loads(lines[3])
    b = Battery(capsys, real["dir"], ".jsonl", "two-area")
    b.run("env an int", _text(_set(lines, 3, dict(rec, env=5))), want=2)
    b.check(1)
    b.run("again, to read the message", _text(_set(lines, 3, dict(rec, env=5))), want=None)
    try:
        read_trace(_set(lines, 3, dict(rec, env=5)))
    except FormatError as exc:
        assert str(exc) == "<trace>: line 4: env: expected the environment events that happened (a list of names), got an integer (5)"
    else:
        pytest.fail("no FormatError")
    with pytest.raises(FormatError, match=r"^<trace>: line 6: missing field 'tick'$"):
        read_trace(_set(lines, 5, {k: v for k, v in rec.items() if k != "tick"}))
    with pytest.raises(FormatError, match=r"^<trace>: line 2: time: NaN is not allowed"):
        read_trace(lines[:1] + [lines[1].replace('"time": 0.0', '"time": NaN')] + lines[2:])
    with pytest.raises(FormatError, match=r"^<trace>: line 3: expected a tick record .*, got an array of 0 item\(s\)$"):
        read_trace(lines[:2] + ["[]"] + lines[3:])


# ---------------------------------------------------------------------- counterexamples


def test_counterexample_truncated_at_every_byte(real, capsys):
    """Every prefix of the file (about 2,200 mutants): exit 2, except the whole document."""
    data = real["ce"]
    b = Battery(capsys, real["dir"], ".json", "defect-trap")
    whole = data.rstrip()
    for n in range(len(data)):
        b.run(f"first {n} bytes", data[:n], want=0 if data[:n].rstrip() == whole else 2)
    b.check(1000)


def test_counterexample_fields_deleted_and_retyped(real, capsys):
    """Every top-level field, every field of every step and of the violation: deleted and
    retyped with 14 values of every JSON type."""
    ce = json.loads(real["ce"])
    b = Battery(capsys, real["dir"], ".json", "defect-trap")
    places = [((), k) for k in ce] + [(("violation",), k) for k in ce["violation"]]
    places += [(("steps", i), k) for i, step in enumerate(ce["steps"]) for k in step]
    required_step = {"tick", "script", "choices", "env", "outcomes", "status", "state"}
    for where, key in places:
        parent = ce
        for p in where:
            parent = parent[p]
        required = (not where) or (where[0] == "steps" and key in required_step) or key == "kind"
        d = copy.deepcopy(ce)
        target = d
        for p in where:
            target = target[p]
        del target[key]
        b.run(f"{where}.{key} deleted", json.dumps(d, indent=1), want=2 if required else None)
        for value in PALETTE:
            target[key] = value
            strict = (not where or where[0] == "steps") and parent[key] is not None
            must_fail = strict and _jtype(value) != _jtype(parent[key])
            b.run(f"{where}.{key} = {value!r}", json.dumps(d, indent=1), want=2 if must_fail else None)
    b.check(len(places) * (1 + len(PALETTE)))


def test_counterexample_whole_document_and_cross_checks(real, capsys):
    ce = json.loads(real["ce"])
    b = Battery(capsys, real["dir"], ".json", "defect-trap")
    steps = ce["steps"]
    table = [
        ("a list", [], 2), ("an int", 5, 2), ("null", None, 2), ("a string", "x", 2), ("an empty object", {}, 2),
        ("other format", dict(ce, format="btfsm-counterexample/2"), 2),
        ("other model", dict(ce, model="other"), 1),
        ("other level", dict(ce, level="galaxy"), 2),
        ("fsm level without fsm", dict(ce, level="fsm"), 2),
        ("static level, path violation", dict(ce, level="static"), 2),
        ("steps renumbered", dict(ce, steps=[dict(s, tick=s["tick"] + 1) for s in steps]), 2),
        ("steps swapped", dict(ce, steps=steps[::-1]), 2),
        ("loop past the end", dict(ce, loop=len(steps) + 1), 2),
        ("loop negative", dict(ce, loop=-1), 2),
        ("non-progress without loop", dict(ce, violation={"kind": "non-progress", "goal": "g"}), 2),
        ("goal violation without goal", dict(ce, violation={"kind": "goal"}), 2),
        ("invariant without name", dict(ce, violation={"kind": "invariant"}), 2),
        ("unknown invariant", dict(ce, violation={"kind": "invariant", "name": "nope"}), 1),
        ("unknown violation kind", dict(ce, violation={"kind": "bogus"}), 1),
        ("unknown node of a contract", dict(ce, violation={"kind": "contract", "node": "nope"}), 1),
        ("no steps", dict(ce, steps=[]), 1),
        ("a step recording an error", dict(ce, steps=steps[:1] + [dict(steps[1], error="boom")]), 1),
        ("outcome with 3 items", dict(ce, steps=[dict(steps[0], choices=[["outcome", "a", "b"]])] + steps[1:]), 2),
        ("choice of 2 items", dict(ce, steps=[dict(steps[0], choices=[["choice", "a"]])] + steps[1:]), 2),
        ("unknown choice kind", dict(ce, steps=[dict(steps[0], choices=[["wish", "a"]])] + steps[1:]), 2),
        ("other outcome", dict(ce, steps=[dict(steps[0], outcomes=[["arm/home", "nope"]])] + steps[1:]), 1),
        ("other status", dict(ce, steps=[dict(steps[0], status="FAILURE")] + steps[1:]), 1),
        ("state value changed", dict(ce, steps=[dict(steps[0], state=dict(steps[0]["state"], stop=True))] + steps[1:]), 1),
        ("report with it", {"model": "defect-trap", "properties": [{"name": "x", "counterexample": ce}]}, 0),
        ("report with none", {"model": "defect-trap", "properties": [{"name": "x", "counterexample": None}]}, 2),
        ("report with two", {"properties": [{"counterexample": ce}, {"counterexample": ce}]}, 2),
        ("report of the wrong shape", {"properties": 5}, 2),
        ("report with a bad one", {"properties": [{"counterexample": dict(ce, steps=5)}]}, 2),
        ("extra field", dict(ce, more=1), 2),
    ]
    for label, doc, want in table:
        b.run(label, json.dumps(doc), want=want)
    text = real["ce"].decode()
    raw = [("NaN for loop", text.replace('"loop": null', '"loop": NaN'), 2),
           ("Infinity for a tick", text.replace('"tick": 1', '"tick": Infinity', 1), 2),
           ("a huge float", text.replace('"tick": 1', '"tick": 1e999', 1), 2),
           ("a huge int", text.replace('"tick": 1', '"tick": 1' + "0" * 5000, 1), 2),
           ("deep nesting", "[" * 100000, 2),
           ("not UTF-8", text.encode()[:30] + b"\xc3\x28" + text.encode()[30:], 2),
           ("empty file", "", 2),
           ("two documents", text + text, 2)]
    for label, data, want in raw:
        b.run(label, data, want=want)
    b.check(len(table) + len(raw))


def test_counterexample_errors_name_the_json_path(real):
    ce = json.loads(real["ce"])
    bad = copy.deepcopy(ce)
    bad["steps"][1]["outcomes"] = [["a"]]
    with pytest.raises(FormatError, match=r"^<counterexample>: steps\[1\]\.outcomes\[0\]: expected a pair of names"):
        load_counterexample(bad)
    with pytest.raises(FormatError, match=r"^x\.json: line \d+ column \d+: the JSON ends too early"):
        load_counterexample(real["ce"].decode()[:200], name="x.json")


# ---------------------------------------------------------------------- hypothesis

JSON = st.recursive(
    st.none() | st.booleans() | st.integers(-(10 ** 20), 10 ** 20) | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(st.characters(codec=None, exclude_categories=()), max_size=8),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=5), inner, max_size=3),
    max_leaves=6)


def _paths(obj, prefix=()):
    """Every JSON path inside ``obj`` (containers and leaves)."""
    yield prefix
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _paths(v, prefix + (i,))


def _mutate(doc, path, value, delete):
    d = copy.deepcopy(doc)
    if not path:
        return value
    parent = d
    for p in path[:-1]:
        parent = parent[p]
    if delete:
        del parent[path[-1]]
    else:
        parent[path[-1]] = value
    return d


HYPO = settings(max_examples=150, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


@HYPO
@given(data=st.data())
def test_trace_random_mutants(real, capsys, data):
    """150 mutants: one JSON value anywhere in one line replaced (or deleted)."""
    lines = _lines(real)
    i = data.draw(st.integers(0, len(lines) - 1))
    obj = json.loads(lines[i])
    path = data.draw(st.sampled_from(list(_paths(obj))))
    value = data.draw(JSON)
    new = _mutate(obj, path, value, delete=bool(path) and data.draw(st.booleans()))
    if i > 0 and plain_record(new):  # the fast check never accepts what the schema refuses
        validate(new, "trace", "t", "", "record")
    b = Battery(capsys, real["dir"], ".jsonl", "two-area")
    b.run(f"line {i + 1} {path}", _text(_set(lines, i, new)))
    b.check(1)


@HYPO
@given(data=st.data())
def test_counterexample_random_mutants(real, capsys, data):
    """150 mutants: one JSON value anywhere in the counterexample replaced (or deleted)."""
    ce = json.loads(real["ce"])
    path = data.draw(st.sampled_from(list(_paths(ce))))
    value = data.draw(JSON)
    new = _mutate(ce, path, value, delete=bool(path) and data.draw(st.booleans()))
    b = Battery(capsys, real["dir"], ".json", "defect-trap")
    b.run(f"{path}", json.dumps(new, indent=1))
    b.check(1)


@settings(max_examples=300, deadline=None, derandomize=True)
@given(rec=st.fixed_dictionaries({k: JSON for k in RECORD_FIELDS}) | JSON)
def test_fast_record_check_accepts_only_what_the_schema_accepts(rec):
    """``plain_record`` lets records skip jsonschema: it must never accept more."""
    if plain_record(rec):
        validate(rec, "trace", "t", "", "record")


def test_fast_record_check_accepts_real_records(real):
    lines = _lines(real)
    assert all(plain_record(json.loads(x)) for x in lines[1:])


# ---------------------------------------------------------------------- the formats cover what is written

from btfsm.models.examples.defects import EXPECTED  # noqa: E402


@pytest.mark.parametrize("name", sorted(k for k, v in EXPECTED.items() if v))
def test_every_counterexample_of_the_defect_catalogue_follows_the_schema(name):
    """Model, FSM and static levels, lassos, domain errors: each counterexample as written
    passes the schema (checked with plain jsonschema too) and replays."""
    import jsonschema

    from btfsm.files import load_model
    from btfsm.formats import load_schema
    from btfsm.verify import check, replay_counterexample

    model = load_model(name)
    report = check(model, sorted(EXPECTED[name]))
    ces = [r.counterexample for r in report.results if r.counterexample is not None]
    assert ces
    for ce in ces:
        doc = json.loads(json.dumps(ce.to_json(), default=lambda x: x.item() if hasattr(x, "item") else str(x)))
        jsonschema.validate(doc, load_schema("counterexample"))
        assert load_counterexample(doc).to_json() == doc
        ok, text = replay_counterexample(doc, model)
        assert ok, text


@pytest.mark.parametrize("name", ["two-area", "defect-contract", "ariac-preemptive"])
def test_traces_as_written_follow_the_schema(name, tmp_path):
    import jsonschema

    from btfsm.formats import load_schema

    path = tmp_path / "t.jsonl"
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        assert _main(["run", name, "--ticks", "60", "--trace", str(path)]) in (0, 1)
    schema = load_schema("trace")
    lines = path.read_text().splitlines()
    jsonschema.validate(json.loads(lines[0]), {"$defs": schema["$defs"], "$ref": "#/$defs/header"})
    for line in lines[1:]:
        rec = json.loads(line)
        jsonschema.validate(rec, {"$defs": schema["$defs"], "$ref": "#/$defs/record"})
        assert plain_record(rec)


# ---------------------------------------------------------------------- btfsm run meets a violation


@pytest.mark.parametrize("name,what", [("defect-domain", "domain error"), ("defect-dead-state", "blocked"),
                                       ("defect-contract", "contract violation")])
def test_run_stops_at_a_violation_with_one_line_and_exit_1(name, what, tmp_path, capsys):
    trace = tmp_path / "t.jsonl"
    assert _main(["run", name, "--ticks", "200", "--trace", str(trace)]) == 1
    out, err = capsys.readouterr()
    assert err.count("\n") == 1 and err.startswith("btfsm run: stopped at tick ") and what in err
    assert "Traceback" not in out + err
    header, records = read_trace(str(trace))  # the ticks up to the violation, complete
    assert records and f"{len(records)} ticks" in out
    if what == "contract violation":
        assert records[-1]["violations"]  # the violating tick is in the trace
    assert [p.name for p in tmp_path.iterdir()] == ["t.jsonl"]  # no temporary file left
    assert _main(["replay", str(trace), name]) == 0
    assert "reproduces exactly" in capsys.readouterr().out


def test_run_without_violation_exits_0(capsys):
    assert _main(["run", "two-area", "--ticks", "30"]) == 0
    out, err = capsys.readouterr()
    assert err == "" and "30 ticks" in out


def test_run_trace_is_replaced_only_when_complete(tmp_path, capsys, monkeypatch):
    """A run that fails half-way (here: an unexpected error) leaves an existing trace as it
    was and no temporary file; a successful run replaces it."""
    from btfsm.runtime import Runtime

    trace = tmp_path / "t.jsonl"
    trace.write_text("old\n")
    calls = []

    def broken(self, events=()):
        calls.append(1)
        if len(calls) > 3:
            raise RuntimeError("implementation crashed")
        return real_tick(self, events)

    real_tick = Runtime.tick
    monkeypatch.setattr(Runtime, "tick", broken)
    assert cli.main(["run", "two-area", "--ticks", "10", "--trace", str(trace)]) == 70  # an internal error
    assert "internal error" in capsys.readouterr().err
    assert trace.read_text() == "old\n" and [p.name for p in tmp_path.iterdir()] == ["t.jsonl"]
    monkeypatch.setattr(Runtime, "tick", real_tick)
    assert _main(["run", "two-area", "--ticks", "10", "--trace", str(trace)]) == 0
    assert len(read_trace(str(trace))[1]) == 10
    capsys.readouterr()


@pytest.mark.parametrize("target", ["model", "folder"])
def test_run_refuses_trace_targets(target, tmp_path, capsys):
    model = tmp_path / "m.yaml"
    from btfsm.files import dump_model, load_model

    dump_model(load_model("two-area"), str(model))
    before = model.read_bytes()
    path = {"model": model, "folder": tmp_path}[target]
    assert _main(["run", str(model), "--ticks", "3", "--trace", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(path) in err
    assert model.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.yaml"]


def test_run_trace_into_a_missing_folder_creates_it(tmp_path, capsys):
    """The rule of every output file (btfsm.outputs): missing parent folders are created."""
    path = tmp_path / "no" / "t.jsonl"
    assert _main(["run", "two-area", "--ticks", "3", "--trace", str(path)]) == 0
    assert len(read_trace(str(path))[1]) == 3 and sorted(p.name for p in path.parent.iterdir()) == ["t.jsonl"]
    capsys.readouterr()


def test_run_trace_to_a_full_device(capsys):
    import os

    if not os.path.exists("/dev/full"):
        pytest.skip("no /dev/full")
    assert _main(["run", "two-area", "--ticks", "3", "--trace", "/dev/full"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "/dev/full" in err
