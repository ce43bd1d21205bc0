"""The ARIAC kitting cell as a scene file (models/scenes/ariac.yaml) in the one scene
engine (sim/scene.py): its layout, belt, z axis, belt-part tracking, grasp test, part
accounting and determinism, scripted the way the kitting binding drives it."""
from __future__ import annotations

import math

import pytest
from hypothesis import HealthCheck, given, settings
from memo_strategies import st

from btfsm.errors import ModelError
from btfsm.sim.protocol import TrialSpec
from btfsm.sim.scene import FLOOR, LOST, Place, World, builtin_scene, load_scene
from btfsm.sim.trial import ariac_scene, build_trial

TICK = 24  # controller period in steps (10 Hz at dt = 1/240)
BELT, TRAY, HELD = Place("BELT", "conveyor"), Place("AREA", "tray"), Place("GRIPPER", "arm")


def world_for(detections=(), seed=1, faults=(), **kw) -> World:
    spec = TrialSpec("preemptive", 1, **kw)
    return World(ariac_scene(spec, list(detections), faults), seed)


def run_until(w: World, cond, timeout: float, check=True) -> float:
    t0 = w.time
    while not cond():
        w.step()
        if check:
            w.check_invariant()
        assert w.time - t0 <= timeout, f"timed out after {timeout} s"
    return w.time - t0


def move(w: World, pose, timeout: float = 10.0) -> float:
    w.move_to("arm", pose[:2], 1.0, z=pose[2])
    return run_until(w, lambda: w.robots["arm"].arrived, timeout)


def top(w, pid):
    p = w.parts[pid]
    return (p.x, p.y, w.top(pid))


def above(pose, clearance=0.2):
    return (pose[0], pose[1], pose[2] + clearance)


def slot(w, k):
    x, y = w.scene.areas["tray"]["slots"][k]
    held = w.robots["arm"].holding
    return (x, y, w.scene.areas["tray"]["height"] + (w.parts[held].height if held is not None else 0.0))


def pick_from_bin(w: World, area: str) -> int:
    pid = w.parts_in(Place("AREA", area))[0]
    move(w, above(top(w, pid)))
    w.grip("arm")
    w.move_to("arm", top(w, pid)[:2], 1.0, z=top(w, pid)[2])
    run_until(w, lambda: w.robots["arm"].holding == pid, 5.0)
    move(w, above(top(w, pid)))
    return pid


def place_on_slot(w: World, k: int) -> None:
    move(w, above(slot(w, k)))
    move(w, slot(w, k))
    w.release("arm")
    move(w, above(slot(w, k)))


def pick_from_belt(w: World, pid: int) -> None:
    w.track("arm", pid, above(top(w, pid))[2])
    run_until(w, lambda: w.robots["arm"].arrived, 10.0)
    w.grip("arm")
    w.track("arm", pid, top(w, pid)[2])
    run_until(w, lambda: w.robots["arm"].holding == pid, 5.0)
    r = w.robots["arm"]
    move(w, (r.x, r.y, r.z + 0.2))


def detections(w):
    return [(pid, t) for t, sensor, _ev, pid, _type in w.events if sensor == "beam"]


# ---------------------------------------------------------------------------- the file
def test_the_shipped_scene_is_the_ariac_cell():
    sc = load_scene(builtin_scene("ariac"))
    assert sc.robots["arm"]["rail"] == ((0.3, -2.5), (0.3, 0.26))  # ARIAC 2019: 2.76 m of travel
    assert len(sc.areas["tray"]["slots"]) == 18
    b = sc.belts["conveyor"]
    y_detect = sc.sensors["beam"]["region"][3]
    assert (y_detect - b["to"][1]) / b["speed"] == pytest.approx(16.0)  # the pick window dt*
    assert (b["from"][1] - y_detect) / b["speed"] == pytest.approx(17.0)  # rides unseen before detection
    assert sc.binding["python"] == "btfsm.sim.binding:KittingBinding"


# ---------------------------------------------------------------------------- belt
def test_belt_carries_part_at_belt_speed():
    w = world_for([17.5])
    run_until(w, lambda: w.parts_in(BELT), 5.0)
    pid = w.parts_in(BELT)[0]
    x0, y0 = w.parts[pid].x, w.parts[pid].y
    w.step(480)
    x1, y1 = w.parts[pid].x, w.parts[pid].y
    assert math.hypot(x1 - x0, y1 - y0) / 2.0 == pytest.approx(0.2, abs=1e-9) and y1 < y0


def test_unpicked_part_is_lost_after_the_pick_window():
    w = world_for([17.5])
    run_until(w, lambda: detections(w), 30.0)
    pid, t_detect = detections(w)[0]
    assert t_detect == pytest.approx(17.5, abs=0.01)
    run_until(w, lambda: w.parts[pid].place == LOST, 17.0)
    t_lost = next(t for t, p, _a, b in w.log if p == pid and b == LOST)
    assert t_lost - t_detect == pytest.approx(16.0, abs=0.01)
    assert w.lost == 1 and w.parts_in(BELT) == [] and detections(w) == [(pid, t_detect)]  # seen once


def test_a_pick_window_out_of_reach_is_refused_before_the_trial():
    with pytest.raises(ModelError, match="out of the arm's reach"):
        build_trial(TrialSpec("preemptive", 1, pick_window=30.0))  # the belt would end at y = -5.1
    from btfsm.sim.sweep import check_geometry

    with pytest.raises(ValueError, match="pick window 30 s"):
        check_geometry([TrialSpec("preemptive", 1, pick_window=30.0)])
    check_geometry([TrialSpec("preemptive", 1)])


# ---------------------------------------------------------------------------- pick/place
def test_scripted_bin_pick_and_tray_place():
    w = world_for()
    pid = pick_from_bin(w, "bin2")
    assert w.parts[pid].place == HELD and w.count("bin2") == 8
    place_on_slot(w, 0)
    assert w.parts[pid].place == TRAY and w.count("tray") == 1
    assert (w.parts[pid].x, w.parts[pid].y) == pytest.approx(w.scene.areas["tray"]["slots"][0])
    w.step(240)
    w.check_invariant()


def test_the_cup_takes_a_part_only_within_its_grasp_tolerance_of_the_top():
    w = world_for()
    pid = w.parts_in(Place("AREA", "bin2"))[0]
    move(w, above(top(w, pid), 0.05))
    w.grip("arm")
    w.step(24)
    assert w.robots["arm"].holding is None  # 5 cm above the part: nothing
    move(w, above(top(w, pid), 0.009))
    w.step()
    assert w.robots["arm"].holding == pid


def test_an_aimed_cup_takes_only_its_part_and_only_centred_on_it():
    """The kitting binding aims the cup at the part it picks (``World.aim``): a cup that
    passes low over another part does not take it, and takes its own part only once the
    tool is centred on it within the grasp tolerance (not at the edge of its radius)."""
    w = world_for()
    a, b = w.parts_in(Place("AREA", "bin2"))[:2]  # 20 cm apart, their tops at one height
    move(w, above(top(w, a), 0.005))
    w.aim("arm", b)
    w.grip("arm")
    w.step(24)
    r = w.robots["arm"]
    assert r.holding is None  # right above part a, aimed at b
    w.move_to("arm", top(w, b)[:2], 1.0, z=top(w, b)[2])  # level, within the grasp tolerance all the way
    run_until(w, lambda: r.holding is not None, 5.0)
    assert r.holding == b and math.hypot(*r.anchor) <= r.spec["grasp_tolerance"] < r.spec["radius"]
    w.release("arm")  # the aim ends with the release
    move(w, above(top(w, a), 0.005))
    w.grip("arm")
    w.step()
    assert r.holding == a


def test_scripted_pick_from_moving_belt():
    w = world_for([17.5])
    run_until(w, lambda: detections(w), 30.0)
    pid = detections(w)[0][0]
    move(w, (1.2, -0.5, 1.2))
    pick_from_belt(w, pid)
    assert w.parts[pid].place == HELD
    place_on_slot(w, 1)
    assert w.parts[pid].place == TRAY and w.lost == 0


def test_landing_places():
    w = world_for()
    sx, sy = w.scene.areas["tray"]["slots"][4]
    assert w.landing(sx + 0.01, sy)[:3] == (TRAY, sx, sy)
    assert w.landing(sx + 0.05, sy + 0.05)[0] == FLOOR  # on the tray, off any slot
    assert w.landing(-0.3, -1.15)[0] == Place("AREA", "bin2")
    assert w.landing(1.21, 0.0)[0] == BELT
    assert w.landing(1.21, -2.5)[0] == FLOOR  # past the belt's end
    assert w.landing(0.7, 1.0)[0] == FLOOR


def test_a_fault_region_drops_the_part_and_the_cup_does_not_take_it_again():
    w = world_for(faults=((-0.2, -2.6, 0.8, -2.2),))
    pid = pick_from_bin(w, "bin3")
    w.move_to("arm", slot(w, 0)[:2], 1.0, z=above(slot(w, 0))[2])
    run_until(w, lambda: w.robots["arm"].holding is None, 10.0)
    assert w.parts[pid].place == FLOOR
    run_until(w, lambda: w.robots["arm"].arrived, 10.0)
    move(w, top(w, pid))
    w.step(24)
    assert w.robots["arm"].holding is None  # no grasp until the gripper is switched again


def test_move_times_are_ur10_like():
    for area in ("bin2", "bin3"):
        w = world_for()
        pid = w.parts_in(Place("AREA", area))[0]
        move(w, above(top(w, pid)))
        t = move(w, above(slot(w, 0)))
        assert 2.0 <= t <= 3.0, f"{area} -> tray {t:.2f} s"
    w = world_for()
    move(w, (0.3, -1.0, 1.0))
    assert 0.5 <= move(w, (0.3, -1.0, 0.8)) <= 1.0  # 20 cm down


def test_tracking_stays_within_reach_while_the_part_leaves_it():
    w = world_for([17.5])
    run_until(w, lambda: detections(w), 30.0)
    pid = detections(w)[0][0]
    w.track("arm", pid, 1.0)
    run_until(w, lambda: w.parts[pid].place == LOST, 20.0)  # check_invariant: the tool stays within reach
    w.step()
    assert not w.robots["arm"].moving and w.robots["arm"].tracking is None  # tracking ends when the part is lost


# ---------------------------------------------------------------------------- determinism
def scripted_digests(seed: int) -> list:
    w = world_for([17.5, 21.0], seed=seed)
    digests = []
    orig = w.step

    def step(n=1):
        for _ in range(n):
            orig()
            if w.steps % TICK == 0:
                digests.append(w.digest())

    w.step = step
    pick_from_bin(w, "bin2")
    place_on_slot(w, 0)
    run_until(w, lambda: len(detections(w)) == 2, 30.0, check=False)
    pick_from_belt(w, detections(w)[0][0])
    place_on_slot(w, 1)
    return digests


def test_same_seed_same_commands_give_identical_digests():
    a, b = scripted_digests(7), scripted_digests(7)
    assert len(a) > 100 and a == b


def test_same_trial_twice_gives_the_same_result():
    from btfsm.sim.trial import run_trial

    spec = TrialSpec("baseline", 3, time_limit=200.0)
    assert run_trial(spec) == run_trial(spec)


commands = st.lists(
    st.tuples(st.integers(0, 70), st.sampled_from(["on", "off", "bin2", "bin3", "tray", "belt", "down"])),
    max_size=12)


@settings(max_examples=10, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])
@given(arrivals=st.lists(st.floats(17.0, 20.0), max_size=4), cmds=commands, seed=st.integers(0, 3))
def test_random_commands_never_break_the_part_accounting(arrivals, cmds, seed):
    w = world_for(sorted(arrivals), seed=seed)
    w.step(round(15.0 / w.dt))  # the parts reach the belt's reachable stretch
    by_tick = {}
    for tick, name in cmds:
        by_tick.setdefault(tick, []).append(name)
    for tick in range(80):  # 8 s
        for name in by_tick.get(tick, ()):
            apply_command(w, name)
        for _ in range(TICK):
            w.step()
            w.check_invariant()


def apply_command(w: World, name: str) -> None:
    r = w.robots["arm"]
    if name == "on":
        w.grip("arm")
    elif name == "off":
        w.release("arm")
    elif name in ("bin2", "bin3"):
        ids = w.parts_in(Place("AREA", name))
        if ids:
            w.move_to("arm", top(w, ids[0])[:2], 1.0, z=top(w, ids[0])[2])
    elif name == "tray":
        w.move_to("arm", slot(w, w.steps % 18)[:2], 1.0, z=slot(w, w.steps % 18)[2])
    elif name == "belt" and w.parts_in(BELT):
        w.track("arm", w.parts_in(BELT)[-1], 0.92)
    elif name == "down":
        w.move_to("arm", (r.x, r.y), 1.0, z=0.72)


# ---------------------------------------------------------------------------- pictures
def test_render_png_and_gif(tmp_path):
    pytest.importorskip("matplotlib")
    from btfsm.sim.scene_render import render_scene, write_gif

    w = world_for([17.5])
    snaps = []
    for _ in range(3):
        w.step(120)
        snaps.append(w.snapshot())
    png = tmp_path / "cell.png"
    render_scene(w.scene, w.snapshot(), png, title="cell")
    assert png.stat().st_size > 1000
    gif = tmp_path / "cell.gif"
    assert write_gif(w.scene, snaps, gif, fps=5) == 3
    assert gif.read_bytes()[:6] in (b"GIF87a", b"GIF89a")
