"""Scene files (sim/scene.py), the primitive library and its binding (sim/library.py),
runs and conformance in scenes (sim/scene_trial.py, ``btfsm sim|conform --scene``).

The part accounting invariant is checked over random scenes driven by random commands
(hypothesis); bad scene files and bindings are one-line errors (exit 2) before any trial.
"""
from __future__ import annotations

import copy
import json
import os
import subprocess
import sys

import pytest
from hypothesis import HealthCheck, given, settings
from memo_strategies import st

from btfsm.errors import ModelError
from btfsm.files import load_model
from btfsm.sim.conformance import conform
from btfsm.sim.library import bind_model
from btfsm.sim.scene import LOST, World, load_scene, scene_from_data
from btfsm.sim.scene_trial import run_scene

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TWO_AREA = os.path.join(ROOT, "models", "scenes", "two_area.yaml")
MACHINE = os.path.join(ROOT, "models", "scenes", "machine_tending.yaml")
MACHINE_MODEL = os.path.join(ROOT, "models", "examples", "machine_tending.yaml")


def _cli(*args, cwd=ROOT):
    return subprocess.run([sys.executable, "-m", "btfsm", *args], capture_output=True, text=True, cwd=cwd, timeout=300)


def _two_area_data():
    from btfsm.files import load_data

    return load_data(TWO_AREA)  # btfsm's YAML reading: `on:` stays a string


# --------------------------------------------------------------------------- shipped scenes
def test_two_area_runs_and_is_deterministic():
    model, scene = load_model("two-area"), load_scene(TWO_AREA)
    a, b = run_scene(model, scene, 3, check_invariant=True), run_scene(model, scene, 3, check_invariant=True)
    assert a.completed and a.mismatch is None and a.counts == {"out": 3} and a.lost == 0
    assert a.digest == b.digest and a.ticks == b.ticks  # same seed, same world
    c = run_scene(model, scene, 4)
    assert c.completed and c.digest != a.digest  # another seed, other arrivals


def test_conform_two_area_and_machine_tending():
    out = conform(load_model("two-area"), 3, 0, None, scene=TWO_AREA)
    assert out.conforms and len(out.results) == 3 and out.checked_states > 0
    out = conform(load_model(MACHINE_MODEL), 3, 1, None)  # its default scene
    assert out.conforms and all(r.completed for r in out.results)


def test_cli_conform_and_sim_exit_0():
    r = _cli("conform", "two-area", "--scenarios", "2")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "2 of 2 scenarios conform" in r.stdout
    r = _cli("sim", MACHINE_MODEL, "--scene", MACHINE, "--seed", "5")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "completed" in r.stdout and "lost 0" in r.stdout


def test_a_wrong_check_is_a_mismatch_with_its_tick():
    data = _two_area_data()
    data["checks"][1]["slack"] = [0, 0]  # placed counts only after the retreat: a real lag
    res = run_scene(load_model("two-area"), scene_from_data(data, "s.yaml"), 0)
    assert res.mismatch is not None and res.mismatch.kind == "abstraction"
    assert "placed is 0 but count(out) is 1" in res.mismatch.what and res.mismatch.tick > 0


def test_machine_door_blocks_the_tool_and_parts_dropped_in_the_machine_go_to_the_floor():
    scene = load_scene(MACHINE)
    w = World(scene, 0)
    assert w.move_to("arm", scene.frames["fixture"]) is False  # the door is shut
    w.set_door("machine_door", True)
    w.step(200)
    assert w.query("door", "machine_door")
    w.step(3000)  # 32 s: parts have reached the end stop, under the tool's home
    assert w.attach("arm")
    w.move_to("arm", (0.66, 0.62))  # inside the machine, 6 cm from the fixture
    w.step(400)
    w.release("arm")
    w.check_invariant()
    assert w.count("machine") == 0 and w.members.get(LOST) is None
    assert [str(p.place) for p in w.parts].count("FLOOR") == 1


# --------------------------------------------------------------------------- errors
@pytest.mark.parametrize("edit, where, problem", [
    (lambda d: d.update(colour="red"), "", "unknown field 'colour'"),
    (lambda d: d["robots"]["arm"].update(reach="far"), "robots.arm.reach", "expected"),
    (lambda d: d["areas"]["out"].update(region={"at": "nowhere", "size": [1, 1]}), "areas.out.region.at",
     "unknown frame 'nowhere'"),
    (lambda d: d["bind"]["move"].update(primitive="teleport"), "bind.move.primitive",
     "unknown library primitive 'teleport'"),
    (lambda d: d["bind"]["grasp"]["args"].update(wait=False), "bind.grasp",
     "can answer failure (missed) but model primitive 'grasp'"),
    (lambda d: d["bind"].update(fly={"primitive": "succeed"}), "bind.fly", "the model has no primitive 'fly'"),
    (lambda d: d["sensors"]["at_end"].update(on_enter="appear"), "sensors.at_end.on_enter",
     "no environment event 'appear'"),
    (lambda d: d["checks"].append({"var": "nothing", "world": "count(out)"}), "checks[2].var",
     "no variable 'nothing'"),
    (lambda d: d["checks"].append({"var": "placed", "world": "count(nowhere)"}), "checks[2].world",
     "no area named 'nowhere'"),
    (lambda d: d["frames"].update(out_place=[5.0, 0.3]), "bind.move.args.frame",
     "frame 'out_place' at (5, 0.3) is out of the reach of robot 'arm'"),
    (lambda d: d["bind"]["move"]["args"].update(frame="{where}"), "bind.move.args.frame",
     "'{where}' is not an argument"),
    (lambda d: d["belts"]["feed"]["arrivals"].update(period=3), "belts.feed.arrivals",
     "give one of schedule, period or random"),
    (lambda d: d["bind"].pop("grasp"), "bind", "model primitive 'grasp'"),
])
def test_bad_scenes_and_bindings_are_one_line_errors(tmp_path, edit, where, problem):
    data = _two_area_data()
    edit(data)
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data), encoding="utf-8")
    with pytest.raises(ModelError) as exc:
        scene = load_scene(str(path))
        bind_model(scene, load_model("two-area"), World(scene))
    assert exc.value.file == str(path) and exc.value.element == where and problem in exc.value.problem, str(exc.value)
    r = _cli("conform", "two-area", "--scene", str(path), "--scenarios", "1")
    assert r.returncode == 2 and r.stdout == "", r.stdout + r.stderr
    line = r.stderr.strip()
    assert "\n" not in line and line.startswith(f"btfsm conform: error: {path}: {where + ': ' if where else ''}"), line
    assert problem in line


def test_unreadable_and_malformed_scene_files_exit_2(tmp_path):
    bad = tmp_path / "s.yaml"
    bad.write_text("robots: [1, 2\n", encoding="utf-8")
    for args in (["--scene", str(bad)], ["--scene", str(tmp_path / "missing.yaml")]):
        r = _cli("sim", "two-area", *args)
        assert r.returncode == 2 and "Traceback" not in r.stderr and r.stderr.count("\n") == 1, r.stderr


def test_custom_python_primitive(tmp_path, monkeypatch):
    (tmp_path / "my_prims.py").write_text(
        "class Nudge:\n"
        "    def __init__(self, world, robot, args):\n"
        "        self.world, self.robot, self.n = world, robot, 0\n"
        "    def tick(self):\n"
        "        self.world.release(self.robot)\n"
        "        return 'success'\n"
        "def release(world, robot, args):\n"
        "    return Nudge(world, robot, args)\n"
        "release.outcomes = ('success',)\n", encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    data = _two_area_data()
    data["bind"]["gripper"][0] = {"when": {"on": False}, "python": "my_prims:release"}
    res = run_scene(load_model("two-area"), scene_from_data(data), 0)
    assert res.completed and res.mismatch is None
    data["bind"]["gripper"][0] = {"when": {"on": False}, "python": "my_prims:nothing"}
    with pytest.raises(ModelError, match="cannot import 'my_prims:nothing'"):
        bind_model(scene_from_data(data), load_model("two-area"), None)


# --------------------------------------------------------------------------- accounting invariant
_coord = st.floats(-1.0, 1.0, allow_nan=False).map(lambda v: round(v, 3))


@st.composite
def random_scenes(draw):
    """A random scene: one robot, 0-2 areas, 0-2 belts, 0-1 sink/door/fault/sensor."""
    def region():
        x, y = draw(_coord), draw(_coord)
        return [x, y, x + draw(st.floats(0.1, 0.6)), y + draw(st.floats(0.1, 0.6))]

    data = {"dt": draw(st.sampled_from([0.005, 0.01, 0.02])), "seed": draw(st.integers(0, 99)), "time_limit": 60,
            "robots": {"r": {"base" if draw(st.booleans()) else "rail":
                             [0, 0] if draw(st.booleans()) else [[-0.5, 0], [0.5, 0]],
                             "reach": 1.2, "home": [0, 0.1],
                             "gripper": {"type": draw(st.sampled_from(["vacuum", "fingers"])), "radius": 0.06}}}}
    r = data["robots"]["r"]
    if "base" in r and isinstance(r["base"][0], list):
        r["rail"] = r.pop("base")
    if "rail" in r and not isinstance(r["rail"][0], list):
        r["base"] = r.pop("rail")
    data["areas"] = {f"a{i}": {"region": region(), "parts": draw(st.integers(0, 4)), "capacity": 6}
                     for i in range(draw(st.integers(0, 2)))}
    data["belts"] = {}
    for i in range(draw(st.integers(0, 2))):
        kind = draw(st.sampled_from(["schedule", "period", "random"]))
        arr = {"schedule": {"schedule": [0.5, 1.0, 4.0]}, "period": {"period": 2.0, "count": 6},
               "random": {"random": {"mean_interval": 2.0, "min_interval": 0.2}}}[kind]
        data["belts"][f"b{i}"] = {"from": [draw(_coord), draw(_coord)], "to": [draw(_coord) + 1.5, draw(_coord)],
                                  "speed": draw(st.floats(0.05, 0.5)), "width": 0.2,
                                  "end": draw(st.sampled_from(["lost", "stop"])), "arrivals": arr}
    if draw(st.booleans()):
        data["sinks"] = {"s": region()}
    if draw(st.booleans()):
        data["doors"] = {"d": {"region": region(), "open_time": 0.5}}
    if draw(st.booleans()):
        data["faults"] = {"f": {"region": region(), "probability": draw(st.floats(0, 1))}}
    if draw(st.booleans()):
        data["sensors"] = {"z": {"region": region()}}
    commands = draw(st.lists(st.tuples(st.sampled_from(["move", "grip", "release", "door", "wait"]),
                                       _coord, _coord, st.integers(1, 80)), max_size=25))
    return data, commands


def drive(w, scene, commands) -> None:
    """Run drawn ``(command, x, y, steps)`` on world ``w`` of ``scene``, checking the part
    accounting after every step (robot ``r``, door ``d``)."""
    for cmd, x, y, n in commands:
        if cmd == "move" and scene.reachable("r", (x, y)):
            w.move_to("r", (x, y), 1.0)
        elif cmd == "grip":
            w.grip("r")
        elif cmd == "release":
            w.release("r")
        elif cmd == "door" and scene.doors:
            w.set_door("d", x > 0)
        for _ in range(n):
            w.step()
            w.check_invariant()


@settings(derandomize=True, max_examples=200, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(random_scenes())
def test_every_part_is_in_exactly_one_place(case):
    data, commands = case
    try:
        scene = scene_from_data(copy.deepcopy(data))
    except ModelError:
        return  # e.g. home out of reach of a drawn rail, a bad belt: refused up front, fine
    runs = []
    for _ in range(2):
        w = World(scene)
        w.check_invariant()
        drive(w, scene, commands)
        runs.append((w.digest(), [str(p.place) for p in w.parts], list(w.events)))
        assert sum(len(v) for v in w.members.values()) == len(w.parts)
    assert runs[0] == runs[1]  # same seed and commands: the same world


def test_assert_conforms_in_a_scene():
    from btfsm.testing import assert_conforms

    out = assert_conforms("two-area", scenarios=2, time_limit=300.0)  # its default scene
    assert out.conforms
    data = _two_area_data()
    data["checks"][1]["slack"] = [0, 0]
    with pytest.raises(AssertionError, match=r"scenario 0 \(seed \d+, in its scene\) does not conform: "
                                             r"first mismatch at tick \d+"):
        assert_conforms("two-area", scenarios=2, scene=scene_from_data(data), time_limit=300.0)


def test_two_area_file_scene_choices_and_belt_losses():
    model = load_model(os.path.join(ROOT, "models", "examples", "two_area.yaml"))
    out = conform(model, 4, 0, None)  # default scene models/scenes/two_area_file.yaml
    assert out.conforms and all(r.completed for r in out.results)
    scene = load_scene(os.path.join(ROOT, "models", "scenes", "two_area_file.yaml"))
    losses = [run_scene(model, scene, seed).lost for seed in range(6)]
    assert any(losses) and not all(losses)  # parts that leave untaken are lost, and the model allows it
    from btfsm.files import load_data

    data = load_data(os.path.join(ROOT, "models", "scenes", "two_area_file.yaml"))
    data["sensors"]["extra"] = {"region": [0.0, 0.0, 0.1, 0.1], "on_enter": "part_stays"}
    with pytest.raises(ModelError, match=r"sensors: environment choice 'belt' needs exactly one option that no "
                                         r"sensor raises"):
        bind_model(scene_from_data(data), model, None)


def test_a_fault_region_is_caught_as_a_mismatch():
    data = _two_area_data()
    data["faults"] = {"slip": {"region": [-0.05, 0.5, 0.05, 0.7], "probability": 1.0}}  # on the way in -> out
    res = run_scene(load_model("two-area"), scene_from_data(data), 0, check_invariant=True)
    assert res.mismatch is not None and res.mismatch.kind == "abstraction", res
    assert "holding is True but holding(arm) is False" in res.mismatch.what


def test_scene_json_rows_and_file_errors(tmp_path):
    r = _cli("conform", "two-area", "--scenarios", "1", "--json")
    assert r.returncode == 0, r.stderr
    row = json.loads(r.stdout)["scenarios"][0]
    assert row["scene"] == "two-area" and row["conforms"] and row["completed"]
    for text, problem in (("", "the file is empty (expected a mapping with the scene)"),
                          ("[1, 2]", "expected a mapping with the scene, got a list of 2 item(s)")):
        p = tmp_path / "s.yaml"
        p.write_text(text, encoding="utf-8")
        r = _cli("sim", "two-area", "--scene", str(p))
        assert r.returncode == 2 and r.stderr.strip() == f"btfsm sim: error: {p}: {problem}"
    r = _cli("conform", "two-area", "--drops", "--scenarios", "6")  # faults on the robot's paths are caught
    assert r.returncode == 1, r.stdout + r.stderr
    assert "drop region (" in r.stdout and "abstraction mismatch: holding is True but holding(arm) is False" in r.stdout


def test_replay_a_counterexample_in_a_scene(tmp_path):
    src = open(os.path.join(ROOT, "models", "examples", "two_area.yaml"), encoding="utf-8").read()
    model_file = tmp_path / "lossy.yaml"  # same model, one more invariant: nothing is ever lost
    model_file.write_text(src.replace("  release_only_when_holding:", "  nothing_lost: lost == 0\n"
                                      "  release_only_when_holding:"), encoding="utf-8")
    r = _cli("check", str(model_file), "--property", "invariants", "--counterexample-dir", str(tmp_path / "ce"), "-q")
    assert r.returncode == 1, r.stdout + r.stderr
    (ce,) = (tmp_path / "ce").iterdir()
    r = _cli("replay", str(ce), str(model_file), "--cell", "--render", str(tmp_path / "end.png"))
    assert r.returncode == 0, r.stdout + r.stderr
    assert "scene replay of a counterexample on two-area-file in scene two-area-file: 2 environment event(s)" in r.stdout
    assert "'part_arrives' (part 3 put where a sensor will see it; FSMs at arm=over_bins" in r.stdout
    assert "'part_leaves' (left to the world" in r.stdout
    assert "part 3 taken by the gripper" in r.stdout  # in this cell the arm is fast enough: nothing is lost
    assert (tmp_path / "end.png").stat().st_size > 1000


def test_library_primitives_one_by_one():
    from btfsm.sim.library import LIBRARY

    scene = scene_from_data({
        "dt": 0.01, "frames": {"a": [0.5, 0.0], "inside": [0.0, 0.5]},
        "areas": {"bin": {"region": {"at": "a", "size": [0.2, 0.2]}, "parts": 1},
                  "box": {"region": {"at": "inside", "size": [0.2, 0.2]}}},
        "doors": {"lid": {"region": {"at": "inside", "size": [0.3, 0.3]}, "open_time": 0.5}},
        "sensors": {"eye": {"region": "bin"}},
        "robots": {"r": {"base": [0, 0], "reach": 1.0, "home": [-0.5, 0], "speed": 1.0, "acceleration": 2.0,
                         "gripper": {"type": "fingers", "radius": 0.05, "close_time": 0.3}}}})
    w = World(scene)

    def run(name, **args):
        act = LIBRARY[name].start(w, "r", args)
        answers = [act.tick()]
        while answers[-1] in ("moving", "closing", "waiting", "opening") and len(answers) < 1000:
            w.step(10)  # one 10 Hz tick
            answers.append(act.tick())
        return answers

    assert run("detect", region="eye") == ["seen"] and run("detect", region="box") == ["nothing"]
    assert run("wait", seconds=0.35)[-1] == "done" and len(run("wait", seconds=0.35)) == 5  # 4 ticks of 0.1 s
    a = run("move_to", frame=(0.5, 0.0), speed=1.0)
    assert a[-1] == "arrived" and 11 <= len(a) <= 16  # 1 m rest to rest at 1 m/s, 2 m/s^2: 1.5 s
    g = run("grip", wait=False)
    assert g[0] == "closing" and g[-1] == "gripped" and len(g) in (4, 5)  # fingers close in 0.3 s
    assert run("move_to", frame=(0.0, 0.5), speed=1.0) == ["blocked"]  # behind the closed lid
    assert run("open_door", door="lid")[-1] == "open"
    assert run("move_to", frame=(0.0, 0.5), speed=1.0)[-1] == "arrived"
    act = LIBRARY["close_door"].start(w, "r", {"door": "lid"})
    for _ in range(10):
        assert act.tick() == "closing"  # never on the tool
        w.step(10)
    assert run("release") == ["released"] and w.count("box") == 1
    assert run("move_to", frame=(-0.5, 0.0), speed=1.0)[-1] == "arrived"
    w.step(10)
    assert act.tick() == "closing"
    w.step(60)
    assert act.tick() == "closed"
    w.check_invariant()
    assert run("grip", wait=False)[-1] == "missed" and w.robots["r"].closing is None


def test_two_robots_each_bound_by_name():
    data = _two_area_data()
    data["robots"]["helper"] = {"base": [2.0, 0.0], "reach": 0.5, "home": [2.0, 0.2]}
    data["bind"]["move"]["robot"] = "arm"
    scene = scene_from_data(data)
    res = run_scene(load_model("two-area"), scene, 0, check_invariant=True)
    assert res.completed and res.mismatch is None  # the first robot is the default for unnamed bindings
    data["bind"]["grasp"]["robot"] = "helper"  # the helper's cup is far from the input: it waits for ever
    res = run_scene(load_model("two-area"), scene_from_data(data), 0, 60.0)
    assert not res.completed and res.counts == {"out": 0} and res.mismatch is None
    data["bind"]["grasp"]["robot"] = "nobody"
    with pytest.raises(ModelError, match=r"bind.grasp.robot: no robot named 'nobody' \(robots: arm, helper\)"):
        bind_model(scene_from_data(data), load_model("two-area"), None)


# --------------------------------------------------------------------------- fuzz: never a traceback
_json_values = st.recursive(
    st.none() | st.booleans() | st.integers(-3, 3) | st.floats(-5, 5, allow_nan=False) |
    st.sampled_from(["", "a", "in_approach", "{area}", "{nope}", "count(out)", "holding(arm)", "x(", "move_to",
                     "grip", "stop", "lost", "vacuum", "arrive", "pkg.mod:fn", "os:getcwd"]),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.sampled_from(["at", "size", "region", "x", "on"]),
                                                               inner, max_size=3),
    max_leaves=8)


def _paths(obj, prefix=()):
    yield prefix
    if isinstance(obj, dict):
        for k, v in obj.items():
            yield from _paths(v, prefix + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj):
            yield from _paths(v, prefix + (i,))


@settings(derandomize=True, max_examples=150, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(st.data())
def test_mutated_scenes_give_model_errors_never_tracebacks(data):
    base = _two_area_data()
    target = copy.deepcopy(base)
    for _ in range(data.draw(st.integers(1, 3))):
        paths = [p for p in _paths(target) if p]
        path = data.draw(st.sampled_from(paths))
        parent = target
        for k in path[:-1]:
            parent = parent[k]
        action = data.draw(st.sampled_from(["replace", "delete", "add", "tweak", "tweak"]))
        leaf = parent[path[-1]]
        if action == "tweak" and isinstance(leaf, (int, float)) and not isinstance(leaf, bool):
            parent[path[-1]] = data.draw(st.sampled_from([0, -1, 0.001, 1e-9, 0.5, 2, 1e6]))  # past the schema
        elif action == "tweak" and isinstance(leaf, str):
            parent[path[-1]] = data.draw(st.sampled_from(["in_approach", "out_place", "out", "feed", "arm", "{area}",
                                                          "{pose}_{area}", "count(feed)", "sensor(at_end)",
                                                          "door(x)", "placed", "holding", "wait", "detect",
                                                          "release", "move_to_part", "arrive", "stop", "lost"]))
        elif action == "delete" and isinstance(parent, dict):
            del parent[path[-1]]
        elif action == "add" and isinstance(parent, dict):
            parent[data.draw(st.sampled_from(["extra", "x", "on", "when"]))] = data.draw(_json_values)
        else:
            parent[path[-1]] = data.draw(_json_values)
    model = load_model("two-area")
    try:
        scene = scene_from_data(target, "fuzz.yaml")
        run_scene(model, scene, 0, 5.0, check_invariant=True)
    except ModelError as exc:
        assert exc.file == "fuzz.yaml" and "\n" not in str(exc)


def test_same_seed_same_world_across_processes():
    code = ("from btfsm.files import load_model; from btfsm.sim.scene import load_scene; "
            "from btfsm.sim.scene_trial import run_scene; import sys; "
            f"r = run_scene(load_model({MACHINE_MODEL!r}), load_scene({MACHINE!r}), 7, check_invariant=True); "
            "print(r.digest, r.ticks, r.time)")
    outs = {subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                           env={**os.environ, "PYTHONHASHSEED": h}).stdout for h in ("0", "12345")}
    assert len(outs) == 1 and len(next(iter(outs)).split()[0]) == 64, outs
