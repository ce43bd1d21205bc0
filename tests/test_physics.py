"""The scene world's contact physics (pymunk): a held part slips when the tool accelerates
harder than the gripper's force allows, parts pushed into one another on a belt collide,
a part pushed off its support falls where it lies, and the part accounting (every part in
exactly one place, the physics agreeing with it) holds under hypothesis-generated commands
in crowded scenes with walls and weak grippers."""
from __future__ import annotations

import copy
import math

from hypothesis import HealthCheck, given, settings
from memo_strategies import st

from btfsm.errors import ModelError
from btfsm.sim.scene import FLOOR, Place, World, scene_from_data
from test_scene import drive, random_scenes


def _arm_scene(max_force: float, mass: float = 2.0, acceleration: float = 8.0) -> dict:
    return {"dt": 0.005, "part_types": {"heavy": {"radius": 0.03, "mass": mass}},
            "areas": {"src": {"region": [0.3, -0.1, 0.5, 0.1], "parts": {"heavy": 1}},
                      "dst": {"region": [-0.5, -0.1, -0.3, 0.1]}},
            "robots": {"arm": {"base": [0, 0], "reach": 1.0, "home": [0.4, 0.0], "speed": 2.0,
                               "acceleration": acceleration,
                               "gripper": {"type": "vacuum", "radius": 0.03, "max_force": max_force}}}}


def _carry(world: World) -> None:
    assert world.attach("arm")
    world.move_to("arm", (-0.4, 0.0))
    for _ in range(400):
        world.step()
        world.check_invariant()


def test_a_held_part_slips_when_the_tool_accelerates_harder_than_the_grip_allows():
    # 2 kg at 8 m/s^2 needs 16 N; the cup holds with 5 N: the part slides out and lands
    w = World(scene_from_data(_arm_scene(max_force=5.0)))
    _carry(w)
    slips = [i for i in w.incidents if i[1] == "slip"]
    assert len(slips) == 1 and slips[0][2] == 0, w.incidents
    assert "5 N" in slips[0][3] and "2 kg" in slips[0][3] and "m/s^2" in slips[0][3]
    assert w.robots["arm"].holding is None
    p = w.parts[0]
    assert p.place != Place("AREA", "dst")  # it never arrived
    # it slid 3 cm within 0.1 s of the start (lag 0.5 * (8 - 5 / 2) * t^2): it lands back on the source area
    assert 0.3 < p.x < 0.4 and p.place == Place("AREA", "src") and w.query("holding", "arm") is False


def test_a_held_part_slips_in_a_sharp_turn_a_preempted_move_makes():
    """A move re-targeted while under way (a preemption) starts the new move from rest: the
    tool turns at once, and the 2 kg part, moving at 1 m/s, cannot be turned by 12 N."""
    outcomes = []
    for max_force in (12.0, 400.0):
        w = World(scene_from_data(_arm_scene(max_force=max_force, acceleration=4.0)))
        assert w.attach("arm")
        w.move_to("arm", (-0.4, 0.0), 0.5)
        for _ in range(80):
            w.step()
        assert w.robots["arm"].holding == 0  # at half speed: 2 m/s^2, 4 N < 12 N: carried so far
        w.move_to("arm", (0.0, 0.4), 0.5)  # the turn
        for _ in range(200):
            w.step()
            w.check_invariant()
        outcomes.append([i[1] for i in w.incidents])
    assert outcomes == [["slip"], []]


def test_the_same_move_with_a_strong_enough_grip_or_a_gentle_acceleration_carries_the_part():
    for data in (_arm_scene(max_force=20.0), _arm_scene(max_force=5.0, acceleration=2.0)):
        w = World(scene_from_data(data))
        _carry(w)
        assert not w.incidents and w.robots["arm"].holding == 0
        w.release("arm")
        assert w.parts[0].place == Place("AREA", "dst")


def test_parts_pushed_into_one_another_on_a_belt_collide_and_queue():
    data = {"dt": 0.01, "part_types": {"p": {"radius": 0.03}},
            "belts": {"b": {"from": [0, 0], "to": [1, 0], "width": 0.1, "speed": 0.3, "end": "stop",
                            "part_type": "p", "arrivals": {"schedule": [0.0, 0.3, 0.6]}}},
            "robots": {"r": {"base": [0, 1], "reach": 0.2, "home": [0, 0.9]}}}
    w = World(scene_from_data(data))
    for _ in range(800):
        w.step()
        w.check_invariant()
    hits = [i for i in w.incidents if i[1] == "collision"]
    assert len(hits) >= 2 and all("on BELT(b)" in i[3] for i in hits)
    xs = sorted(p.x for p in w.parts)
    assert len(xs) == 3 and abs(xs[-1] - 0.97) < 0.005  # the first rests against the end stop
    assert all(b - a >= 0.06 - 0.002 for a, b in zip(xs, xs[1:]))  # the others behind it, touching
    assert all(p.place == Place("BELT", "b") for p in w.parts)


def test_a_fence_across_a_belt_pushes_parts_off_its_side():
    data = {"dt": 0.01,
            "belts": {"b": {"from": [0, 0], "to": [1, 0], "width": 0.1, "speed": 0.3, "end": "lost",
                            "arrivals": {"schedule": [0.0]}}},
            "walls": {"fence": {"points": [[0.4, 0.08], [0.6, -0.08]], "on": "b"}},
            "robots": {"r": {"base": [0, 1], "reach": 0.2, "home": [0, 0.9]}}}
    w = World(scene_from_data(data))
    for _ in range(600):
        w.step()
        w.check_invariant()
    assert w.parts[0].place == FLOOR and [i[1] for i in w.incidents] == ["fell_off"]
    assert 0.4 < w.parts[0].x < 0.7


def test_parts_pushed_out_of_their_slots_leave_the_tray_count():
    data = {"dt": 0.01, "areas": {"tray": {"region": [-0.1, -0.1, 0.1, 0.1], "slots": [[0, 0], [0.04, 0]],
                                           "slot_tolerance": 0.005, "parts": 2}},
            "robots": {"r": {"base": [0, 1], "reach": 0.2, "home": [0, 0.9]}}}
    w = World(scene_from_data(data))
    assert w.count("tray") == 2  # two 3 cm discs 4 cm apart: they overlap and push each other away
    for _ in range(100):
        w.step()
        w.check_invariant()
    assert [i[1] for i in w.incidents] == ["pushed_out_of_slot", "pushed_out_of_slot"]
    assert "by part" in w.incidents[0][3] and w.count("tray") == 0
    assert [p.place for p in w.parts] == [FLOOR, FLOOR]


def test_a_part_released_away_from_a_free_slot_is_off_target():
    data = _arm_scene(max_force=50.0)
    data["areas"]["dst"]["slots"] = [[-0.45, 0.0]]
    w = World(scene_from_data(data))
    _carry(w)
    w.release("arm")
    assert w.parts[0].place == FLOOR
    assert [i[1] for i in w.incidents] == ["off_target"] and "no free slot" in w.incidents[0][3]


# --------------------------------------------------------------------------- accounting under physics
_coord = st.floats(-0.6, 0.6, allow_nan=False).map(lambda v: round(v, 3))


@st.composite
def crowded_scenes(draw):
    """Crowded areas and belts, a wall, a weak or strong gripper, random commands."""
    def region():
        x, y = draw(_coord), draw(_coord)
        return [x, y, x + draw(st.floats(0.1, 0.4)), y + draw(st.floats(0.1, 0.4))]

    data = {"dt": 0.01, "seed": draw(st.integers(0, 9)), "time_limit": 60,
            "part_types": {"big": {"radius": 0.05, "mass": draw(st.sampled_from([0.2, 2.0]))}},
            "robots": {"r": {"base": [0, 0], "reach": 1.2, "home": [0, 0.1],
                             "acceleration": draw(st.sampled_from([1.0, 10.0])),
                             "gripper": {"type": "vacuum", "radius": 0.06,
                                         "max_force": draw(st.sampled_from([0.5, 50.0]))}}}}
    data["areas"] = {f"a{i}": {"region": region(), "parts": {"big": draw(st.integers(0, 6))}}
                     for i in range(draw(st.integers(1, 2)))}
    if draw(st.booleans()):
        data["areas"]["a0"]["slots"] = [[(data["areas"]["a0"]["region"][0] + data["areas"]["a0"]["region"][2]) / 2,
                                         (data["areas"]["a0"]["region"][1] + data["areas"]["a0"]["region"][3]) / 2]]
        data["areas"]["a0"]["parts"] = {"big": 0}
    data["belts"] = {"b": {"from": [-0.8, draw(_coord)], "to": [0.8, draw(_coord)], "speed": 0.4, "width": 0.15,
                           "part_type": "big", "end": draw(st.sampled_from(["lost", "stop"])),
                           "arrivals": {"period": draw(st.sampled_from([0.2, 1.0])), "count": 8}}}
    if draw(st.booleans()):
        data["walls"] = {"w": {"points": [[draw(_coord), draw(_coord)], [draw(_coord), draw(_coord)]]}}
    if draw(st.booleans()):
        data["sinks"] = {"s": region()}
    commands = draw(st.lists(st.tuples(st.sampled_from(["move", "grip", "release", "wait"]),
                                       _coord, _coord, st.integers(1, 60)), max_size=12))
    return data, commands


@settings(derandomize=True, max_examples=40, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(crowded_scenes())
def test_every_part_is_in_exactly_one_place_under_physics(case):
    data, commands = case
    try:
        scene = scene_from_data(copy.deepcopy(data))
    except ModelError:
        return
    runs = []
    for _ in range(2):
        w = World(scene)
        drive(w, scene, commands)
        runs.append((w.digest(), [str(p.place) for p in w.parts], list(w.events), list(w.incidents)))
    assert runs[0] == runs[1]


# --------------------------------------------------------------------------- a physical finding
SLIP = "models/scenes/two_area_slip.yaml"


def _conform(model_ref, scene_file, scenarios=1):
    from btfsm.files import load_model
    from btfsm.sim.conformance import conform
    from btfsm.sim.scene import load_scene

    from btfsm.sim.scene_trial import scene_for

    model = load_model(model_ref)
    scene = load_scene(scene_file or scene_for(model, model_ref))
    return conform(model, scenarios, 0, 120.0, scene=scene)


def test_a_slip_is_a_nonconformance_of_the_model_without_the_drop_and_not_of_the_one_with_it():
    out = _conform("two-area", SLIP)
    (res,) = out.results
    m = str(res.mismatch)
    assert "holding is True but holding(arm) is False" in m and "slip of part 0" in m and "4 N" in m
    out = _conform("models/examples/two_area.py:two_area_drops", None, scenarios=2)
    assert not out.failed


def test_a_check_over_an_enum_variable_is_refused_with_the_element(tmp_path):
    from btfsm.files import load_model
    from btfsm.sim.library import bind_model
    import pytest

    model = load_model("models/examples/machine_tending.yaml")
    enum = next((v for v in model.variables if v.kind == "enum"), None)
    assert enum is not None
    from btfsm.files import load_data

    data = load_data("models/scenes/machine_tending.yaml")
    data["checks"] = [{"var": enum.name, "world": "holding(arm)"}]
    scene = scene_from_data(data, "enum.scene.yaml")
    with pytest.raises(ModelError, match=rf"enum.scene.yaml: checks\[0\].var: '{enum.name}' is an enum"):
        bind_model(scene, model, World(scene))


def test_validate_recognises_a_scene_and_refuses_unstable_physics(tmp_path):
    import subprocess
    import sys

    def run(path):
        return subprocess.run([sys.executable, "-m", "btfsm", "validate", str(path)], capture_output=True, text=True)

    r = run("models/scenes/ariac.yaml")
    assert r.returncode == 0 and "ok (scene ariac: 3 areas, 1 belts" in r.stdout
    bad = tmp_path / "fast.scene.yaml"
    bad.write_text("dt: 0.01\nrobots: {r: {base: [0, 0], reach: 1, home: [0.5, 0]}}\n"
                   "belts: {b: {from: [0, 0], to: [1, 0], speed: 5}}\n")
    r = run(bad)
    assert r.returncode == 2 and "belts.b.speed: a part on the belt moves 0.05 m per step" in r.stderr
    bad.write_text("robots: {r: {base: [0, 0], reach: 1, home: [0.5, 0]}}\npart_types: {p: {radius: 0.03, friction: -1}}\n")
    r = run(bad)
    assert r.returncode == 2 and "part_types.p.friction: must be > 0" in r.stderr and "Traceback" not in r.stderr


# --------------------------------------------------------------------------- part types
def test_typed_sensors_checks_and_events_and_the_sorter_conforms():
    from btfsm.files import load_data, load_model
    from btfsm.sim.conformance import conform
    from btfsm.sim.scene import load_scene

    scene = load_scene("models/scenes/sorter.yaml")
    assert scene.world_query("count(red_bin, red)", "x") == ("count", ("red_bin", "red"))
    w = World(scene)
    for _ in range(1000):
        w.step()
    # red and blue arrive in turn and queue at the end stop; only the red sensor sees the red one
    assert [p.type for p in w.parts] == ["red", "blue", "red", "blue"]
    assert [e[1:3] + (e[4],) for e in w.events] == [("red_at_end", "red_arrives", "red")]
    assert w.query("sensor", ("red_at_end", "red")) == 1 and w.query("sensor", ("red_at_end", "blue")) == 0
    out = conform(load_model("models/examples/sorter.yaml"), 2, 0, 200.0, scene=scene)
    assert not out.failed and all(r.completed for r in out.results)
    data = load_data("models/scenes/sorter.yaml")
    data["checks"] = [{"var": "holding", "world": "holding(arm, red)"}]
    import pytest

    with pytest.raises(ModelError, match=r"checks\[0\].world: only count\(AREA, TYPE\) and sensor"):
        scene_from_data(data)


# --------------------------------------------------------------------------- batches of steps
_CHUNKS = (1, 3, 24, 2, 7, 5)  # the step calls of a command's ``n`` steps in every other command (batched)


def _stepwise(data, commands, batched: bool) -> list:
    """The world after each drawn command, stepped ``n`` at once (batches; every other
    command's ``n`` steps in calls of ``_CHUNKS`` steps, so that a horizon found by one
    call is kept by the next ones) or one at a time."""
    scene = scene_from_data(copy.deepcopy(data))
    w, seen = World(scene), []
    for i, (cmd, x, y, n) in enumerate(commands):
        if cmd == "move" and scene.reachable("r", (x, y)):
            w.move_to("r", (x, y), 1.0)
        elif cmd == "grip":
            w.grip("r")
        elif cmd == "pick":  # to the part nearest (x, y), the gripper ready
            near = sorted((math.hypot(p.x - x, p.y - y), p.id) for p in w.parts if p.place.kind not in ("GRIPPER", "LOST"))
            if near and scene.reachable("r", (w.parts[near[0][1]].x, w.parts[near[0][1]].y)):
                w.move_to("r", (w.parts[near[0][1]].x, w.parts[near[0][1]].y), 1.0)
                w.grip("r")
        elif cmd == "release":
            w.release("r")
        elif cmd == "door" and scene.doors:
            w.set_door("d", x > 0)
        if batched and i % 2:
            left, j = n, 0
            while left:
                c = min(left, _CHUNKS[j % len(_CHUNKS)])
                w.step(c)
                left, j = left - c, j + 1
        elif batched:
            w.step(n)
        else:
            for _ in range(n):
                w.step()
        w.check_invariant()
        seen.append((w.digest(), [str(p.place) for p in w.parts], list(w.events), list(w.incidents)))
    return seen


@st.composite
def sparse_scenes(draw):
    """Room to move: spaced parts in a bin and a tray with slots, a belt with a sensor (and
    maybe a sink, a fence, a closed door, a fault), a vacuum cup or fingers; long waits."""
    data = {"dt": draw(st.sampled_from([0.005, 0.01])), "seed": draw(st.integers(0, 9)), "time_limit": 60,
            "part_types": {"p": {"radius": 0.03, "mass": draw(st.sampled_from([0.5, 2.0]))}},
            "areas": {"bin": {"region": [-0.6, -0.6, -0.1, -0.1], "parts": {"p": draw(st.integers(0, 4))}},
                      "tray": {"region": [0.1, -0.6, 0.5, -0.2], "slots": [[0.2, -0.4], [0.4, -0.4]]}},
            "belts": {"b": {"from": [-0.8, 0.4], "to": [0.8, draw(st.sampled_from([0.3, 0.4]))],
                            "speed": draw(st.sampled_from([0.1, 0.4])), "width": 0.15, "part_type": "p",
                            "end": draw(st.sampled_from(["lost", "stop"])),
                            "arrivals": {"period": draw(st.sampled_from([0.7, 3.0])), "count": 5}}},
            "sensors": {"beam": {"region": [-0.1, 0.2, 0.0, 0.6], "on_enter": "seen", "on_exit": "gone"}},
            "robots": {"r": {"base": [0, 0], "reach": 1.0, "home": [0, 0.1],
                             "acceleration": draw(st.sampled_from([1.0, 30.0])),
                             "gripper": {"type": draw(st.sampled_from(["vacuum", "fingers"])), "radius": 0.04,
                                         "max_force": draw(st.sampled_from([2.0, 50.0]))}}}}
    if draw(st.booleans()):
        data["sinks"] = {"s": [0.5, 0.2, 0.9, 0.6]}
    if draw(st.booleans()):
        data["walls"] = {"fence": {"points": [[0.3, 0.5], [0.4, 0.35]], "on": "b"}}
    if draw(st.booleans()):
        data["doors"] = {"d": {"region": [-0.6, 0.6, -0.4, 0.8], "open_time": 0.3}}
    if draw(st.booleans()):
        data["faults"] = {"f": {"region": [-0.3, -0.1, -0.1, 0.1], "probability": 0.5}}
    commands = draw(st.lists(st.tuples(st.sampled_from(["move", "pick", "pick", "release", "door", "wait"]),
                                       _coord, _coord, st.integers(1, 150)), max_size=14))
    return data, commands


@settings(derandomize=True, max_examples=60, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(st.one_of(sparse_scenes(), crowded_scenes(), random_scenes()))
def test_a_batch_of_steps_is_the_same_as_the_steps_one_at_a_time(case):
    """``World.step(n)`` hands quiet runs of steps to Chipmunk in one batch: the world it
    leaves is the one ``n`` single steps leave, bit for bit (digest, places, events,
    incidents), with contacts, slips, belts, sensors, doors and grippers in play."""
    data, commands = case
    try:
        scene_from_data(copy.deepcopy(data))
    except ModelError:
        return
    assert _stepwise(data, commands, True) == _stepwise(data, commands, False)


def test_batches_end_where_a_belt_part_crosses_a_sensor_edge_or_reaches_a_waiting_cup():
    """Long batches over a belt whose parts cross a sensor's edges, come under an armed
    cup that waits on the belt, ride into a sink: every event at its step."""
    data = {"dt": 0.01,
            "belts": {"b": {"from": [-0.5, 0], "to": [0.5, 0], "speed": 0.2, "width": 0.1, "end": "lost",
                            "arrivals": {"schedule": [0.0, 1.5, 2.2]}}},
            "sensors": {"beam": {"region": [-0.2, -0.1, -0.15, 0.1], "on_enter": "seen", "on_exit": "gone"}},
            "sinks": {"s": [0.3, -0.2, 0.6, 0.2]},
            "robots": {"r": {"base": [0, 0.3], "reach": 0.5, "home": [0.1, 0.0],
                             "gripper": {"type": "vacuum", "radius": 0.02}}}}
    commands = [("grip", 0, 0, 350), ("release", 0, 0, 250), ("move", 0.1, 0.2, 400)]
    batched = _stepwise(data, commands, True)
    assert batched == _stepwise(data, commands, False)
    events, incidents = batched[-1][2], batched[-1][3]
    assert [e[2] for e in events] == ["seen", "gone"] * 3 and not incidents
    assert batched[0][1][0] == "GRIPPER(r)" and batched[-1][1] == ["LOST"] * 3


def test_an_ariac_trial_in_batches_is_the_same_as_one_step_at_a_time(monkeypatch):
    """The ARIAC trial (carrying, coasting, tracking a belt part, the belt sensor) gives
    the same digests tick by tick with and without batches."""
    from btfsm.sim.protocol import TrialSpec
    from btfsm.sim.trial import run_kitting

    def digests():
        seen = []
        run_kitting(TrialSpec("preemptive", 3, time_limit=90.0), on_tick=lambda rt, w: seen.append(w.digest()))
        return seen

    batched = digests()

    def one_at_a_time(self, n):
        self._wait = n
        return 0

    monkeypatch.setattr(World, "_quiet", one_at_a_time)
    assert digests() == batched and len(batched) == 900
