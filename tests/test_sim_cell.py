"""Tests of the 2D kitting cell (sim/cell.py) and its renderer (sim/render.py)."""
from __future__ import annotations

import math

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from btfsm.sim.cell import BELT, FLOOR, GRIPPER, LOST, RAIL_TRAVEL_LIMIT, Cell, CellConfig, Place
from btfsm.sim.render import Recorder, render_png

TICK = 24  # controller period in steps (10 Hz at dt = 1/240)


def run_until(cell: Cell, cond, timeout: float, check=True) -> float:
    """Step until ``cond()``; check the invariant every step; return the elapsed time."""
    t0 = cell.time
    while not cond():
        cell.step()
        if check:
            cell.check_invariant()
        assert cell.time - t0 <= timeout, f"timed out after {timeout} s"
    return cell.time - t0


def move(cell: Cell, pose, timeout: float = 10.0) -> float:
    cell.arm.move_to(*pose)
    return run_until(cell, lambda: cell.arm.arrived, timeout)


def pick_from_bin(cell: Cell, k: int) -> int:
    pid = cell.next_bin_part(k)
    move(cell, cell.pose_above(pid))
    above = cell.arm.pose
    cell.gripper.enable()
    cell.arm.move_to(*cell.pose_at(pid))
    run_until(cell, lambda: cell.gripper.attached_part == pid, 5.0)
    move(cell, above)
    return pid


def place_on_slot(cell: Cell, slot: int) -> None:
    move(cell, cell.pose_above(Place.tray(slot)))
    move(cell, cell.pose_at(Place.tray(slot)))
    cell.gripper.disable()
    move(cell, cell.pose_above(Place.tray(slot)))


def pick_from_belt(cell: Cell, pid: int) -> None:
    cell.arm.track(pid, cell.pose_above(pid)[2])
    run_until(cell, lambda: cell.arm.arrived, 10.0)
    cell.gripper.enable()
    cell.arm.track(pid, cell.pose_at(pid)[2])
    run_until(cell, lambda: cell.gripper.attached_part == pid, 5.0)
    x, y, z = cell.arm.pose
    move(cell, (x, y, z + cell.config.clearance))


# ---------------------------------------------------------------------------- belt
def test_belt_carries_part_at_belt_speed():
    cell = Cell(seed=3)
    pid = cell.spawn_conveyor_part()
    cell.step(240)  # settle
    x0, y0, _ = cell.position(pid)
    cell.step(480)
    x1, y1, _ = cell.position(pid)
    speed = math.hypot(x1 - x0, y1 - y0) / 2.0
    assert speed == pytest.approx(0.2, abs=1e-4)
    assert y1 < y0 and cell.place_of(pid) == BELT


def test_unpicked_part_is_lost_at_the_wall_after_the_pick_window():
    cfg = CellConfig()
    cell = Cell(cfg, seed=5, arrivals=[0.5])
    run_until(cell, lambda: cell.detections, 30.0)
    pid, t_detect = cell.detections[0]
    assert t_detect == pytest.approx(0.5 + cell.detect_delay_s, abs=0.02)
    y_prev = cell.position(pid)[1]
    while cell.place_of(pid) != LOST:
        assert cell.position(pid)[1] > cfg.belt_y_wall, "part passed the wall without being deleted"
        y_prev = cell.position(pid)[1]
        cell.step()
        cell.check_invariant()
        assert cell.time - t_detect < cfg.pick_window_s + 1.0
    t_lost = cell.time
    assert t_lost - t_detect == pytest.approx(cfg.pick_window_s, abs=0.2)
    assert cell.position(pid)[1] <= cfg.belt_y_wall < y_prev
    assert cell.lost_parts == [pid] and cell.parts_in(BELT) == []
    assert [d[0] for d in cell.detections] == [pid]  # detected once


def test_pick_window_is_inside_reach_and_rail_respects_ariac_limit():
    cfg = CellConfig()
    cell = Cell(cfg)
    assert cfg.belt_y_detect - cfg.belt_y_wall == pytest.approx(cfg.belt_speed * cfg.pick_window_s)
    assert cfg.rail_y_max - cfg.rail_y_min <= RAIL_TRAVEL_LIMIT + 1e-9
    for y in (cfg.belt_y_detect, cfg.belt_y_wall, -3.0):
        assert cell.reachable(cfg.belt_x, y)
    with pytest.raises(ValueError):
        Cell(CellConfig(rail_y_min=-3.0, rail_y_max=0.5))
    with pytest.raises(ValueError):
        Cell(CellConfig(belt_y_detect=3.5))  # window start out of reach


# ---------------------------------------------------------------------------- pick/place
def test_scripted_bin_pick_and_tray_place():
    cell = Cell(seed=1)
    pid = pick_from_bin(cell, 2)
    assert cell.place_of(pid) == GRIPPER and cell.bin_count(2) == 8
    place_on_slot(cell, 0)
    assert cell.place_of(pid) == Place.tray(0)
    assert cell.tray_count == 1 and cell.parts_in(Place.tray(0)) == [pid]
    sx, sy = cell.slot_position(0)
    x, y, _ = cell.position(pid)
    assert math.hypot(x - sx, y - sy) < cell.config.slot_tolerance
    cell.step(240)
    cell.check_invariant()
    assert cell.position(pid)[:2] == pytest.approx((x, y), abs=1e-6)  # rests in place


def test_scripted_pick_from_moving_belt():
    cell = Cell(seed=2, arrivals=[0.0])
    run_until(cell, lambda: cell.detections, 30.0)
    pid = cell.detections[0][0]
    move(cell, cell.conveyor_approach(cell.position(pid)[1] - 1.0))
    pick_from_belt(cell, pid)
    assert cell.place_of(pid) == GRIPPER
    place_on_slot(cell, 1)
    assert cell.place_of(pid) == Place.tray(1) and cell.lost_parts == []


def test_release_places():
    cell = Cell(seed=1)
    sx, sy = cell.slot_position(4)
    assert cell.landing_place(sx + 0.01, sy) == Place.tray(4)
    assert cell.landing_place(sx + 0.05, sy + 0.05) == FLOOR  # on the tray, off any slot
    assert cell.landing_place(-0.3, -1.15) == Place.bin(2)
    assert cell.landing_place(1.21, 0.0) == BELT
    assert cell.landing_place(1.21, -2.5) == FLOOR  # past the wall
    assert cell.landing_place(0.7, 1.0) == FLOOR


def test_drop_region_drops_the_part_on_the_floor():
    cfg = CellConfig(drop_regions=((-0.2, -2.6, 0.8, -2.2),))
    cell = Cell(cfg, seed=1)
    pid = pick_from_bin(cell, 3)
    cell.arm.move_to(*cell.pose_above(Place.tray(0)))
    run_until(cell, lambda: cell.gripper.attached_part is None, 10.0)
    assert cell.place_of(pid) == FLOOR and cell.gripper.drops == 1
    run_until(cell, lambda: cell.arm.arrived, 10.0)
    cell.arm.move_to(*cell.pose_at(pid))
    run_until(cell, lambda: cell.arm.arrived, 10.0)
    assert cell.gripper.attached_part is None  # no re-grasp until re-enabled


def test_move_times_are_ur10_like():
    cell = Cell(seed=1)
    arm = cell.arm
    for k in (2, 3):
        t = arm.duration(cell.pose_above(cell.next_bin_part(k)), cell.pose_above(Place.tray(0)))
        assert 2.0 <= t <= 3.0, f"bin {k} -> tray {t:.2f} s"
    x, y, z = cell.pose_above(0)
    assert 0.5 <= arm.duration((x, y, z), (x, y, z - cell.config.clearance)) <= 1.0
    assert move(cell, (x, y, z)) == pytest.approx(arm.duration(cell.config.home, (x, y, z)), abs=0.01)
    with pytest.raises(ValueError):
        arm.move_to(3.0, 0.0, 1.0)


# ---------------------------------------------------------------------------- determinism
def scripted_digests(seed: int) -> list:
    cell = Cell(seed=seed, arrivals=[0.0, 3.0])
    digests = []
    orig_step = cell.step

    def step(n=1):
        orig_step(n)
        if cell.steps % TICK == 0:
            digests.append(cell.digest())

    cell.step = step
    pick_from_bin(cell, 2)
    place_on_slot(cell, 0)
    run_until(cell, lambda: len(cell.detections) == 2, 30.0, check=False)
    pick_from_belt(cell, cell.detections[0][0])
    place_on_slot(cell, 1)
    return digests


def test_same_seed_same_commands_give_identical_digests():
    a, b = scripted_digests(7), scripted_digests(7)
    assert len(a) > 100 and a == b


def test_other_seed_changes_belt_parts():
    a, b = scripted_digests(7), scripted_digests(8)
    assert a != b


# ---------------------------------------------------------------------------- property
commands = st.lists(
    st.tuples(st.integers(0, 70), st.sampled_from(["on", "off", "bin2", "bin3", "tray", "belt", "down"])),
    max_size=12)


@settings(max_examples=10, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])
@given(arrivals=st.lists(st.floats(0.0, 3.0), max_size=4), cmds=commands, seed=st.integers(0, 3))
def test_random_commands_never_break_the_invariant(arrivals, cmds, seed):
    cfg = CellConfig(belt_y_spawn=1.5)  # parts reach the pick window within the short run
    cell = Cell(cfg, seed=seed, arrivals=arrivals)
    by_tick = {}
    for tick, name in cmds:
        by_tick.setdefault(tick, []).append(name)
    for tick in range(80):  # 8 s
        for name in by_tick.get(tick, ()):
            apply_command(cell, name)
        for _ in range(TICK):
            cell.step()
            cell.check_invariant()


def apply_command(cell: Cell, name: str) -> None:
    if name == "on":
        cell.gripper.enable()
    elif name == "off":
        cell.gripper.disable()
    elif name in ("bin2", "bin3"):
        pid = cell.next_bin_part(int(name[-1]))
        if pid is not None:
            cell.arm.move_to(*cell.pose_at(pid))
    elif name == "tray":
        cell.arm.move_to(*cell.pose_at(Place.tray(cell.steps % 18)))
    elif name == "belt" and cell.belt_parts():
        cell.arm.track(cell.belt_parts()[-1][0], cell.config.z_belt)
    elif name == "down":
        x, y, _ = cell.arm.pose
        cell.arm.move_to(x, y, cell.config.z_bin)


# ---------------------------------------------------------------------------- rendering
def test_render_png_and_gif(tmp_path):
    cell = Cell(seed=1, arrivals=[0.0])
    rec = Recorder(every_steps=120)
    for _ in range(3 * 120):
        cell.step()
        rec.capture(cell, fsm_state="IDLE")
    png = tmp_path / "cell.png"
    render_png(cell, png, title="cell", fsm_state="IDLE")
    assert png.stat().st_size > 1000
    gif = tmp_path / "cell.gif"
    assert rec.write_gif(gif, fps=5) == 3
    assert gif.read_bytes()[:6] in (b"GIF87a", b"GIF89a")
