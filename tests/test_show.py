"""Pictures: dot text for the tree and FSMs, rendering, and ``btfsm show``."""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings

from btfsm import FSM, Action, Condition, Edge, Marker, Model, ReactiveSequence, State, success
from btfsm.files import load_model
from btfsm.show import fsm_to_dot, pictures, render, tree_to_dot

from strategies import random_models

ROOT = Path(__file__).resolve().parent.parent
TWO = ROOT / "models/examples/two_area.yaml"
TEMPLATED = ROOT / "models/examples/templated.yaml"
HAS_DOT = shutil.which("dot") is not None
needs_dot = pytest.mark.skipif(not HAS_DOT, reason="Graphviz 'dot' is not installed")


def _cli(*args, env=None):
    return subprocess.run([sys.executable, "-m", "btfsm.cli", *map(str, args)], capture_output=True, cwd=ROOT,
                          env=env, timeout=120)


def _check_dot(text: str):
    """The text parses as dot: with Graphviz when present, else balanced structure."""
    assert text.startswith("digraph ") and text.rstrip().endswith("}")
    bare = re.sub(r'"(?:[^"\\\n]|\\.)*"', "Q", text)  # quoted strings out: well-formed quoting
    assert '"' not in bare and bare.count("{") == bare.count("}")
    for line in bare.strip().splitlines()[1:-1]:
        assert re.fullmatch(r"\s*(Q \[.*\];|Q -> Q \[.*\];|(graph|node|edge) \[.*\];|subgraph Q \{|\})", line), line
    if HAS_DOT:
        out = subprocess.run(["dot", "-Tsvg"], input=text.encode(), capture_output=True, timeout=60)
        assert out.returncode == 0, out.stderr.decode()
        assert b"<svg" in out.stdout
        return out.stdout.decode()
    return None


def _unquote(s: str) -> str:
    return s.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")


# ---------------------------------------------------------------- dot text


@pytest.mark.parametrize("path", [TWO, TEMPLATED], ids=lambda p: p.name)
def test_fsm_dot_has_every_state_edge_and_marker(path):
    m = load_model(path)
    for f in m.fsms:
        text = fsm_to_dot(m, f.name)
        svg = _check_dot(text)
        for st in f.states:
            assert f'id="state:{_unquote(st.id)}"' in text
        for e in f.edges:
            assert f'id="edge:{_unquote(e.id)}"' in text
        for mk in f.markers:
            assert f'id="marker:{_unquote(mk.id)}"' in text
        if svg is not None:  # Graphviz kept every element id
            assert len(re.findall(r'id="edge:', svg)) == len(f.edges)
            assert len(re.findall(r'id="state:', svg)) == len(f.states)


def test_fsm_dot_conventions():
    m = load_model(TWO)
    text = fsm_to_dot(m, "arm")
    start = [line for line in text.splitlines() if line.strip().startswith('"start" ->')]
    assert start == ['  "start" -> "s:over_bins" [tooltip="initial state"];']
    direct = [line for line in text.splitlines() if 'id="edge:over_belt->over_bins"' in line][0]
    assert 'style="dashed"' in direct and "pick_bins\\ndirect" in direct
    guarded = [line for line in text.splitlines() if 'id="edge:over_tray->release"' in line][0]
    assert "place\\nsuccess [holding]" in guarded and "dashed" not in guarded
    effects = [line for line in text.splitlines() if 'id="edge:release->over_tray"' in line][0]
    assert "placed := min(placed + 1, 3)" in effects and "source := 'none'" in effects
    assert text.count("shape=\"doublecircle\"") == len(m.fsm("arm").markers)
    assert 'label="F"' in text and 'label="S"' in text
    assert "over_bins\\nmove(to=bins)" in text and "grasp(shaking=true)" in text


def test_goal_lists_abbreviated_when_all_goals():
    f = FSM("f", [State("a"), State("b"), State("t")], "a", ["g1", "g2"],
            [Edge("a", "b"), Edge("b", "a", ["g1"]), Edge("b", "t", ["g2", "g1"])], [Marker("b", ["g1"])], terminal=["t"])
    m = Model("m", fsms=[f])
    text = fsm_to_dot(m, f)
    assert 'label="*\\nsuccess"' in text  # Edge default goals: every goal
    assert 'label="*\\nsuccess"' in [ln for ln in text.splitlines() if "edge:b->t" in ln][0]  # same set, other order
    assert 'label="g1\\nsuccess"' in text
    assert 'peripheries="2"' in [ln for ln in text.splitlines() if 'id="state:t"' in ln][0]
    _check_dot(text)


def test_tree_dot_shapes_and_symbols():
    m = load_model(TWO)
    text = tree_to_dot(m)
    _check_dot(text)
    for n in m.nodes():
        assert f'"n:{n.name}"' in text
    line = {n.name: next(ln for ln in text.splitlines() if ln.strip().startswith(f'"n:{n.name}" [')) for n in m.nodes()}
    assert 'label="=>\\ncell\\nS>=1 F>=1"' in line["cell"]
    assert 'label="?\\nwork"' in line["work"] and 'label="->\\ndeliver"' in line["deliver"]
    assert 'shape="ellipse"' in line["tray_full"] and "placed == 3" in line["tray_full"]
    assert 'shape="hexagon"' in line["place_twice"] and "Retry x2" in line["place_twice"]
    assert "Guard [bin_parts > 0]" in line["bin_not_empty"]
    assert "success: bin_parts := bin_parts - 1" in line["count_bin_pick"]
    assert "monitor_belt\\nwatch()" in line["monitor_belt"]
    assert "arm.pick_bins(part='gear')\\npost: holding" in line["pick_from_bins"]


def test_memory_variants_are_marked():
    from btfsm import MemoryFallback, MemorySequence, ReactiveFallback
    leaf = lambda n: Condition(n, "true")  # noqa: E731
    m = Model("m", tree=ReactiveFallback("rf", [MemorySequence("ms", [leaf("a")]), MemoryFallback("mf", [leaf("b")]),
                                                ReactiveSequence("rs", [leaf("c")])]))
    text = tree_to_dot(m)
    assert 'label="->*\\nms"' in text and 'label="?*\\nmf"' in text
    assert 'label="->\\nrs"' in text and 'label="?\\nrf"' in text


def test_subtrees_are_drawn_in_boxes_and_empty_tree():
    f = FSM("f", [State("s", subtree=Action("act", outcomes=[success()]))], "s", ["g"], markers=[Marker("s")])
    m = Model("m", fsms=[f])
    text = tree_to_dot(m)
    assert "cluster_0" in text and 'label="fsms.f.states.s.subtree"' in text and '"n:act"' in text
    _check_dot(text)
    assert "[subtree act]" in fsm_to_dot(m, "f")
    empty = tree_to_dot(Model("e"))
    assert "(this model has no tree)" in empty
    _check_dot(empty)


def test_pictures_selection():
    m = load_model(TWO)
    assert [s for s, _ in pictures(m, "all")] == ["tree", "fsm_arm"]
    assert [s for s, _ in pictures(m, "arm")] == ["fsm_arm"]
    from btfsm.cli import UsageError
    with pytest.raises(UsageError, match="'nope' is not 'tree', 'all' or an FSM of two-area-file \\(arm\\)"):
        pictures(m, "nope")


@needs_dot
@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(random_models())
def test_random_models_give_valid_dot(model):
    for _, text in pictures(model, "all"):
        _check_dot(text)


def test_odd_names_are_escaped():
    ids = ['quote"d', "back\\slash", "end\\", "{brace}", "a->b", "*/ x /*"]  # labels are printable: no newline
    f = FSM("f", [State(i) for i in ids], ids[0], ["g"], [Edge(ids[k], ids[k + 1]) for k in range(len(ids) - 1)])
    m = Model("m", fsms=[f], tree=Condition('c"x', "true"))
    _check_dot(fsm_to_dot(m, "f"))
    _check_dot(tree_to_dot(m))


# ---------------------------------------------------------------- rendering and the command


@needs_dot
def test_render_svg_and_png():
    text = fsm_to_dot(load_model(TWO), "arm")
    assert render(text, "svg").lstrip().startswith(b"<?xml") or b"<svg" in render(text, "svg")
    assert render(text, "png").startswith(b"\x89PNG")


def test_cli_show_dot_to_stdout():
    out = _cli("show", TWO, "--what", "arm")
    assert out.returncode == 0, out.stderr
    assert out.stdout.decode() == fsm_to_dot(load_model(TWO), "arm")
    both = _cli("show", TWO).stdout.decode()
    assert both.count("digraph ") == 2


@needs_dot
def test_cli_show_all_svg_png_into_folder(tmp_path):
    for fmt, magic in (("svg", b"<svg"), ("png", b"\x89PNG")):
        folder = tmp_path / f"pics_{fmt}" / "nested"
        out = _cli("show", TEMPLATED, "--format", fmt, "--output", folder)
        assert out.returncode == 0, out.stderr
        paths = out.stdout.decode().split()
        assert [Path(p).name for p in paths] == [f"tree.{fmt}", f"fsm_arm.{fmt}"]
        for p in paths:
            assert magic in Path(p).read_bytes()[:400]


@needs_dot
def test_cli_show_single_file_and_svg_stdout(tmp_path):
    out = _cli("show", TWO, "--format", "svg", "--what", "tree", "-o", tmp_path / "t.svg")
    assert out.returncode == 0 and (tmp_path / "t.svg").read_bytes().find(b"<svg") >= 0
    out = _cli("show", TWO, "--format", "svg", "--what", "tree")
    assert out.returncode == 0 and b"<svg" in out.stdout


def test_cli_show_usage_errors(tmp_path):
    for args, needle in ((("--what", "nope"), b"'nope' is not 'tree', 'all' or an FSM"),
                         (("--format", "png"), b"needs --output")):
        out = _cli("show", TWO, *args)
        if not HAS_DOT and b"png" in b" ".join(a.encode() for a in args):
            needle = b"Graphviz is not installed"
        assert out.returncode == 2 and needle in out.stderr, out.stderr
        assert b"Traceback" not in out.stderr and out.stderr.count(b"\n") == 1


def test_cli_show_without_graphviz(tmp_path):
    env = dict(os.environ, PATH=str(tmp_path))  # no 'dot' anywhere on PATH
    for fmt in ("svg", "png"):
        out = _cli("show", TWO, "--format", fmt, "-o", tmp_path / "x", env=env)
        assert out.returncode == 2
        err = out.stderr.decode()
        assert "Graphviz is not installed" in err and "--format dot" in err
        assert "Traceback" not in err and err.count("\n") == 1
    ok = _cli("show", TWO, "--format", "dot", env=env)
    assert ok.returncode == 0 and ok.stdout.startswith(b"digraph")


def test_cli_show_bad_model_exits_2(tmp_path):
    p = tmp_path / "bad.yaml"
    p.write_text("name: x\ntree: {Condition: c}\n")
    out = _cli("show", p)
    assert out.returncode == 2 and b"tree: missing field 'expr'" in out.stderr and b"Traceback" not in out.stderr
