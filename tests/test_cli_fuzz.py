"""CLI fuzz battery: every command x flag x bad value, plus hypothesis-generated argv lists.

Everything runs in-process through ``btfsm.cli.main`` (fast), and every input must end in
an expected exit code with at most one line of error and never a traceback or exit 70.
The number of inputs is in the test ids (``BAD_CASES``) and checked by
``test_battery_size``; hypothesis adds ``HYPOTHESIS_EXAMPLES`` argv lists per command group
(``test_generated_argv``) and up to ``FLAG_EXAMPLES`` real runs per command with generated
flag values (``test_generated_flag_values``); each prints its count and exit codes (``-s``).
In all about 1,600 inputs in about a minute.
"""
from __future__ import annotations

import atexit
import collections
import json
import math
import os
import shutil
import tempfile

import pytest
from hypothesis import HealthCheck, event, given, settings
from memo_strategies import st

from btfsm.cli import COMMANDS, MAX_FRAMES, MAX_SCENARIOS, MAX_SIM_TIME, MAX_STATES_LIMIT, MAX_TICKS, MAX_WORKERS, main

TWO = "two-area"  # a small built-in model
XML = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "models", "examples", "pick_place_btcpp.xml")
ARIAC = "ariac-preemptive"  # the one the kitting cell runs

# Paths: a scratch folder with a file, a folder and a FIFO (ids do not depend on its name).
SCRATCH = tempfile.mkdtemp(prefix="btfsm-cli-fuzz-")
atexit.register(shutil.rmtree, SCRATCH, True)
A_FILE = os.path.join(SCRATCH, "a-file.txt")
A_FIFO = os.path.join(SCRATCH, "a-fifo.yaml")
HUGE_DIGITS = "9" * 5000


def _setup_scratch():
    os.makedirs(os.path.join(SCRATCH, "a-dir.png"), exist_ok=True)
    if not os.path.exists(A_FILE):
        with open(A_FILE, "w") as fh:
            fh.write("not a model\n")
    if not os.path.exists(A_FIFO):
        os.mkfifo(A_FIFO)


_setup_scratch()
A_DIR = os.path.join(SCRATCH, "a-dir.png")

NOT_NUMBERS = ["", " ", "abc", "--", "1,5", "0x10", "1_000x", "\u00e9", "\udc80", "\0"]
NOT_INTS = NOT_NUMBERS + ["1.5", "nan", "inf", "-inf", "1e3", HUGE_DIGITS + ".0", "2**8"]
NOT_FINITE = NOT_NUMBERS + ["nan", "NaN", "-nan", "inf", "-inf", "Infinity", "1e400", "-1e400", HUGE_DIGITS]
BAD_OUTPUT_FILES = ["", "\0", A_DIR, A_DIR + "/", SCRATCH, "/dev/full", "/dev/null", "/proc/x", "/proc/x/y",
                    A_FIFO, os.path.join(A_FILE, "sub.png"), "/sys/x.png"]
BAD_OUTPUT_DIRS = ["", "\0", "/dev/full", "/dev/null", A_FILE, os.path.join(A_FILE, "sub"), "/proc/x", "/proc/x/y",
                   A_FIFO, "/sys/x"]
BAD_INPUTS = ["", "\0", "/dev/full", "/dev/zero", A_FIFO, A_DIR, "/nonexistent/m.yaml", "no-such-model",
              "/proc/x.yaml", A_FILE]


def _ints(lo, hi):
    """Bad values for an integer flag with range lo..hi."""
    out = list(NOT_INTS)
    if lo is not None:
        out += [str(lo - 1), str(lo - 10 ** 30), "-" + HUGE_DIGITS]
    if hi is not None:
        out += [str(hi + 1), str(hi + 10 ** 30), HUGE_DIGITS]
    return out


def _floats(lo, hi, lo_open=False):
    out = list(NOT_FINITE)
    if lo is not None:
        out += [repr(lo) if lo_open else repr(lo - 1e-6), repr(lo - 1), "-1e300"]
    if hi is not None:
        out += [repr(hi * 1.001 + 1), "1e300"]
    return out


CHOICE_BAD = ["", "xml", "DOT", "dot ", "\0", "--json"]

# command -> (valid argv before the flag, {flag: bad values})
TABLE = {
    "validate": ([TWO], {}),
    "show": ([TWO], {"--format": CHOICE_BAD,
                     "--output": ["", "\0", "/dev/full", "/proc/x.svg", A_FILE + "/x.dot", A_DIR, "p.svg", "p.png",
                                  os.path.join(SCRATCH, "x.svg"), os.path.join(SCRATCH, "x.png")],
                     "--what": ["", "\0", "nofsm", "TREE", "\udc80"]}),
    "run": ([TWO, "--ticks", "2"], {"--ticks": _ints(0, MAX_TICKS), "--seed": _ints(-(2 ** 63 - 1), 2 ** 63 - 1),
                                    "--p-env": _floats(0.0, 1.0) + ["2", "1.0001", "-0.0001"],
                                    "--trace": BAD_OUTPUT_FILES}),
    "replay": ([A_FILE + ".jsonl", TWO], {"--time": _floats(0.0, MAX_SIM_TIME, lo_open=True) + ["0", "-0.0"],
                                          "--render": BAD_OUTPUT_FILES + ["x.jpg", "x.gif", "x"],
                                          "--gif": BAD_OUTPUT_FILES + ["x.png", "x"], "--pace": CHOICE_BAD}),
    "check": ([TWO], {"--max-states": _ints(1, MAX_STATES_LIMIT) + ["0"], "--counterexample-dir": BAD_OUTPUT_DIRS,
                      "--engine": CHOICE_BAD, "--property": ["", "\0", "no-such-property", "deadlock-freedom "]}),
    "export": ([TWO, "--format", "smv"], {"--format": CHOICE_BAD, "--output": BAD_OUTPUT_FILES,
                                          "--fsm": ["", "\0", "nofsm", "ARM"]}),
    "skills": ([TWO], {"--max-states": _ints(1, MAX_STATES_LIMIT) + ["0"], "--format": CHOICE_BAD}),
    "experiment": ([], {"--k": _ints(1, 40) + ["99", "0"], "--trials": _ints(1, 40),
                        "--workers": _ints(1, MAX_WORKERS) + ["0"],
                        "--time": _floats(0.0, MAX_SIM_TIME, lo_open=True) + ["0"],
                        "--out": BAD_OUTPUT_DIRS, "--variant": CHOICE_BAD + ["both"]}),
    "sim": ([ARIAC, "--time", "0.5"], {"--k": _ints(1, 40), "--time": _floats(0.0, MAX_SIM_TIME, lo_open=True) + ["0"],
                                       "--fps": _floats(0.01, 100.0) + ["0", "-1", "1e-9", "0.001"],
                                       "--max-frames": _ints(1, MAX_FRAMES) + ["0"],
                                       "--render": BAD_OUTPUT_FILES + ["x.jpg", "x"],
                                       "--gif": BAD_OUTPUT_FILES + ["x.png", "x"],
                                       "--worst": _ints(1, 2), "--step": _ints(1, 1000), "--misses": _ints(0, 3),
                                       "--workers": _ints(1, MAX_WORKERS) + ["0"]}),
    "import": ([XML], {"--output": BAD_OUTPUT_FILES + ["x.txt", "x"], "--leaves": BAD_INPUTS,
                       "--semantics": CHOICE_BAD}),
    "conform": ([ARIAC, "--scenarios", "1", "--time", "0.5"], {
        "--scenarios": _ints(1, MAX_SCENARIOS) + ["-1", "0"], "--seed": _ints(-(2 ** 63 - 1), 2 ** 63 - 1),
        "--time": _floats(0.0, MAX_SIM_TIME, lo_open=True) + ["0", "nan"],
        "--max-states": _ints(1, MAX_STATES_LIMIT) + ["0"]}),
}

# Positional and structural misuse: (argv,) each must exit 2.
STRUCTURAL = ([[]] + [[c] for c in COMMANDS if c not in ("experiment", "sweep")] + [["no-such-command"], ["--no-such-flag"],
              ["validate", TWO, "--no-such-flag"], ["export", TWO], ["replay", TWO], ["check", TWO, "extra"],
              ["sim", TWO, "--k"], ["run", TWO, "--ticks"], ["experiment", "positional"],
              ["experiment", "--k", "1", "--trials"], ["validate", TWO, "--strict=yes"],
              ["sweep", "positional"], ["sweep", "--belt-speed"], ["sweep", "--belt-speed", "-0.1"],
              ["sweep", "--period", "0"], ["sweep", "--pick-window", "nan"], ["sweep", "--workers", "0"],
              ["bound", TWO], ["bound", TWO, "--trigger", "x"], ["sim", ARIAC, "--step", "3"],
              ["sim", ARIAC, "--at-phase"], ["sim", ARIAC, "--workers", "2"], ["sim", ARIAC, "--misses", "1"], ["sim", TWO, "--worst", "1"], ["sim", ARIAC, "--worst", "1", "--gif", "w.gif"],
              ["sim", ARIAC, "--worst", "2", "--scene", "models/scenes/two_area.yaml"]]
              + [[c, bad] for c in COMMANDS if c not in ("experiment", "sweep", "replay") for bad in BAD_INPUTS]
              + [["replay", bad, TWO] for bad in BAD_INPUTS if bad != A_FILE]
              + [["replay", A_FILE + ".jsonl", bad] for bad in BAD_INPUTS])


def _cases():
    out = []
    for command, (base, flags) in TABLE.items():
        for flag, values in flags.items():
            for i, value in enumerate(values):
                out.append(pytest.param([command, *base, flag, value], id=f"{command}{flag}-{i}"))
    for i, argv in enumerate(STRUCTURAL):
        out.append(pytest.param(argv, id=f"structural-{i}"))
    return out


BAD_CASES = _cases()
HYPOTHESIS_EXAMPLES = 120


def run_cli(argv, capsys):
    """(exit code, stdout, stderr) of ``btfsm ARGV`` run in-process."""
    try:
        code = main(list(argv))
    except SystemExit as exc:  # --help / --version
        code = exc.code
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def assert_clean(code, out, err, allowed, argv=()):
    """The exit code is allowed, never 70, no traceback; an exit-2 error is one line on stderr
    (or, under --json, one JSON object on stdout)."""
    assert code in allowed, (code, err, out)
    assert code != 70, err
    assert "Traceback" not in out + err, err
    if code == 2:
        if "--json" in argv[: argv.index("--") if "--" in argv else len(argv)]:
            assert json.loads(out)["error"]["exit_code"] == 2, out
        else:
            lines = [line for line in err.splitlines() if line.strip()]
            assert len(lines) == 1 and lines[0].startswith("btfsm"), err


def test_battery_size():
    """The table battery alone holds this many inputs (hypothesis adds more)."""
    json_cases = len([b for b in BAD_CASES[::7] if "--" not in b.values[0]])
    generated = 4 * HYPOTHESIS_EXAMPLES + 8 * FLAG_EXAMPLES
    print(f"CLI battery: {len(BAD_CASES)} table inputs, {json_cases} under --json, up to {generated} generated")
    assert len(BAD_CASES) >= 700 and len(BAD_CASES) + json_cases + generated >= 1500


@pytest.mark.parametrize("argv", BAD_CASES)
def test_bad_flag_value_exits_2(argv, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # relative outputs (p.svg, x.jpg) land in a scratch folder
    code, out, err = run_cli(argv, capsys)
    assert_clean(code, out, err, {2}, argv)


@pytest.mark.parametrize("argv", [b.values[0] for b in BAD_CASES[::7] if "--" not in b.values[0]])
def test_bad_flag_value_under_json_is_one_json_error(argv, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, out, err = run_cli([*argv, "--json"], capsys)
    assert code == 2 and "Traceback" not in out + err
    data = json.loads(out)
    assert set(data) == {"error"} and data["error"]["exit_code"] == 2 and data["error"]["kind"] in ("usage", "model")
    assert data["error"]["message"].startswith("btfsm")


# ---------------------------------------------------------------- hypothesis-generated argv lists

TOKENS = ["--json", "--debug", "--strict", "--quiet", "--drops", "--no-path", "--cell", "--fresh",
          "--k", "--time", "--fps", "--max-frames", "--max-states", "--ticks", "--seed", "--p-env",
          "--scenarios", "--workers", "--trials", "--variant", "--format", "--engine", "--property", "--what",
          "--fsm", "-o", "--output", "--trace", "--render", "--gif", "--out", "--counterexample-dir",
          "0", "1", "-1", "2", "40", "41", "0.5", "1e-9", "nan", "inf", "-inf", "1e400", HUGE_DIGITS, "", "abc",
          "dot", "svg", "json", "text", "smv", "promela", "baseline", "preemptive", "scalar", "traced",
          TWO, ARIAC, "tree", "arm", "all", "/dev/full", "/proc/x", A_DIR, A_FILE, A_FIFO, "\udc80", "\0"]
SLOW_VALID = {"sim", "experiment", "conform", "replay", "sweep"}
TIME_TOKENS = TOKENS + ["--trigger", "--response", "--within", "event:arrive", "event:nope", "q == 0", "arrive",
                        "--belt-speed", "--period", "--speed-scale", "--pick-window", "--scheduler", "dask", "inline",
                        "processes", "0.25", "0.3", "16"]


def _argv(command):
    token = st.one_of(st.sampled_from(TIME_TOKENS if command in ("bound", "sweep") else TOKENS), st.text(max_size=8))
    return st.lists(token, max_size=6).map(lambda rest: [command, *rest])


def _guard_slow(argv, tmp_path):
    """Keep valid runs of the simulator commands tiny and their files in tmp_path. ``replay``
    gets no existing trace file here: trace contents are fuzzed by the trace tests."""
    if argv[0] == "replay":
        argv = [a for a in argv if a != A_FILE]
    if argv[0] in SLOW_VALID:
        argv = argv + ["--time", "0.2"]  # the last --time wins
    if argv[0] == "experiment":
        argv = argv + ["--out", str(tmp_path / "exp"), "--k", "1", "--variant", "baseline", "--workers", "1",
                       "--quiet"]
    if argv[0] == "sweep":  # one tiny trial in this process (the engines are tested in test_sweep.py)
        argv = argv + ["--out", str(tmp_path / "sweep"), "--k", "1", "--variant", "baseline", "--engine", "inline",
                       "--belt-speed", "0.2", "--quiet"]
    if argv[0] == "conform":
        argv = argv + ["--scenarios", "1", "--no-path"]
    if argv[0] == "sim":
        argv = argv + ["--max-frames", "3"]
    return argv


_SETTINGS = settings(max_examples=HYPOTHESIS_EXAMPLES, deadline=None, derandomize=True,
                     suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])


@pytest.mark.parametrize("group", [("validate", "show", "skills", "import"), ("run", "check", "export"),
                                   ("sim", "conform", "replay"), ("experiment",), ("bound", "sweep")])
def test_generated_argv(group, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)

    @_SETTINGS
    @given(st.sampled_from(group).flatmap(_argv))
    def check(argv):
        argv = _guard_slow(argv, tmp_path)
        code, out, err = run_cli(argv, capsys)
        event(f"exit {code}")
        codes[code] += 1
        assert_clean(code, out, err, {0, 1, 2, 3}, argv)

    codes = collections.Counter()
    check()
    with capsys.disabled():
        print(f"\n{'/'.join(group)}: {sum(codes.values())} generated argv lists, exit codes {dict(sorted(codes.items()))}")
    # atomic outputs never leave their hidden temporary files behind
    assert [p for p in tmp_path.rglob(".*.tmp*")] == []


# ---------------------------------------------------------------- generated flag values on real runs

def _num(lo, hi, bad=("nan", "inf", "-inf", "1e400", "", "x", "-0", "1e-9")):
    """Numbers in lo..hi (as text; edges and out-of-range values included) or bad text."""
    ints = st.integers(math.ceil(lo), math.floor(hi)).map(str)
    floats = st.floats(lo, hi, allow_nan=False).map(repr)
    return st.one_of(ints, floats, st.sampled_from(bad))


def _paths(tmp_path, *names):
    return st.sampled_from([str(tmp_path / n) for n in names] + ["/dev/full", "/proc/x.png", A_DIR, A_FIFO, ""])


def _flag_specs(tmp_path):
    """command -> (models, {flag: strategy of its text value, or None for a switch})."""
    small_time = _num(-1, 2)
    return {
        "validate": ([TWO, "pickplace3", "defect-trap"], {"--strict": None, "--json": None}),
        "show": ([TWO, "pickplace3"], {"--what": st.sampled_from(["tree", "arm", "all", "nope", ""]),
                                       "-o": _paths(tmp_path, "p.dot", "pics", "p.svg", "p.png")}),
        "run": ([TWO, "defect-domain", "defect-dead-state", "defect-contract"],
                {"--ticks": _num(-2, 40), "--seed": _num(-(2 ** 64), 2 ** 64), "--p-env": _num(-0.5, 1.5),
                 "--trace": _paths(tmp_path, "t.jsonl")}),
        # defect-nondeterminism, not pickplace3: the same violated property with a counterexample,
        # in 20 states (a full check of pickplace3, 10,288 states, took 3 s of every example
        # without --max-states)
        "check": ([TWO, "defect-trap", "defect-nondeterminism"], {"--max-states": _num(-2, 3000), "--json": None,
                                                                  "--engine": st.sampled_from(["auto", "scalar", "traced", "x"]),
                                                                  "--counterexample-dir": _paths(tmp_path, "ce")}),
        # original, not pickplace3: an FSM of 565 states, not 10,288 (2.5 s a run without --max-states)
        "skills": ([TWO, "original"], {"--max-states": _num(-2, 3000), "--json": None}),
        "export": (["pickplace3", TWO], {"--format": st.sampled_from(["promela", "smv", "dot", "x"]),
                                         "--fsm": st.sampled_from(["arm", "nope"]), "-o": _paths(tmp_path, "m.out")}),
        "sim": ([ARIAC, TWO], {"--k": _num(-1, 41), "--time": small_time, "--fps": _num(-1, 101),
                               "--max-frames": _num(-1, 4), "--render": _paths(tmp_path, "c.png", "c.gif"),
                               "--gif": _paths(tmp_path, "r.gif", "r.png")}),
        "conform": ([ARIAC, TWO], {"--scenarios": _num(-1, 2), "--time": small_time, "--seed": _num(-5, 5),
                                   "--drops": None, "--json": None, "--max-states": _num(-1, 60)}),
    }


def _flag_argv(command, models, flags):
    chosen = st.lists(st.sampled_from(sorted(flags)), unique=True, max_size=len(flags))

    def build(model_and_names):
        model, names = model_and_names
        parts = [st.just([name]) if flags[name] is None else flags[name].map(lambda v, n=name: [n, v])
                 for name in names]
        return st.tuples(*parts).map(lambda ps: [command, model, *[w for p in ps for w in p]])

    return st.tuples(st.sampled_from(models), chosen).flatmap(build)


FLAG_EXAMPLES = 40


@pytest.mark.parametrize("command", ["validate", "show", "run", "check", "skills", "export", "sim", "conform"])
def test_generated_flag_values(command, capsys, tmp_path, monkeypatch):
    """Real runs with generated flag values: out-of-range ones exit 2, the others do their work."""
    monkeypatch.chdir(tmp_path)
    models, flags = _flag_specs(tmp_path)[command]

    @settings(max_examples=FLAG_EXAMPLES, deadline=None, derandomize=True,
              suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
    @given(_flag_argv(command, models, flags))
    def check(argv):
        # valid runs stay tiny: defaults that would simulate for minutes are replaced
        tiny = {"sim": {"--time": "0.5", "--max-frames": "3"},
                "conform": {"--time": "0.5", "--scenarios": "1", "--max-states": "40"}}.get(command, {})
        argv = argv + [w for flag, value in tiny.items() if flag not in argv for w in (flag, value)]
        code, out, err = run_cli(argv, capsys)
        event(f"exit {code}")
        codes[code] += 1
        assert_clean(code, out, err, {0, 1, 2, 3}, argv)

    codes = collections.Counter()
    check()
    with capsys.disabled():
        print(f"\n{command}: {sum(codes.values())} generated inputs, exit codes {dict(sorted(codes.items()))}")
    assert set(codes) - {2}, "every generated input was rejected: the battery never ran the command"
    assert [p for p in tmp_path.rglob(".*.tmp*")] == []
