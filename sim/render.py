"""Draw the kitting cell (top view) to PNG and animated GIF with matplotlib's Agg canvas.

No pyplot and no global backend switch: every figure is a ``matplotlib.figure.Figure``
on its own ``FigureCanvasAgg``. GIFs are assembled with Pillow (a matplotlib dependency).

>>> rec = Recorder()
>>> # every N steps: rec.add(cell.snapshot(), fsm_state="PICK")
>>> # rec.write_gif("run.gif", fps=10)
"""
from __future__ import annotations

import math
import os
from typing import Iterable

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Polygon, Rectangle

from btfsm.outputs import atomic_path

__all__ = ["PLACE_COLOURS", "draw_snapshot", "render_png", "render_gif", "Recorder"]

PLACE_COLOURS = {
    "BIN": "tab:blue", "GRIPPER": "tab:orange", "TRAY": "tab:green",
    "BELT": "tab:purple", "FLOOR": "tab:red",
}
_UPPER_ARM, _FOREARM = 0.612, 0.5723 + 0.2  # UR10 links, wrist + cup folded into the forearm
_XLIM, _YLIM = (-1.0, 2.0), (-4.0, 4.7)


def _as_snapshot(source) -> dict:
    return source if isinstance(source, dict) else source.snapshot()


def _new_figure() -> Figure:
    fig = Figure(figsize=(4.2, 9.0), dpi=90)
    FigureCanvasAgg(fig)
    return fig


def _draw_static(ax, lay: dict) -> None:
    belt = lay["belt"]
    x0 = belt["x"] - belt["width"] / 2
    ax.add_patch(Rectangle((x0, belt["y_wall"]), belt["width"], belt["y_spawn"] + 0.3 - belt["y_wall"],
                           fc="0.85", ec="0.5"))
    ax.plot([x0, x0 + belt["width"]], [belt["y_detect"]] * 2, "--", c="tab:cyan", lw=1.5)
    ax.plot([x0, x0 + belt["width"]], [belt["y_wall"]] * 2, "-", c="tab:red", lw=3)
    ax.text(x0 + belt["width"] + 0.03, belt["y_detect"], "beam", fontsize=7, va="center")
    ax.text(x0 + belt["width"] + 0.03, belt["y_wall"], "wall", fontsize=7, va="center")
    for k, bx, by, size in lay["bins"]:
        ax.add_patch(Rectangle((bx - size / 2, by - size / 2), size, size, fc="none", ec="k"))
        ax.text(bx - size / 2, by + size / 2 + 0.03, f"bin {k}", fontsize=7)
    _draw_tray(ax, lay["tray"])
    rail = lay["rail"]
    ax.plot([rail["x"]] * 2, [rail["y_min"], rail["y_max"]], c="0.3", lw=4, solid_capstyle="butt")
    for x0_, y0_, x1_, y1_ in lay["drop_regions"]:
        ax.add_patch(Rectangle((x0_, y0_), x1_ - x0_, y1_ - y0_, fc="tab:red", alpha=0.12, ec="tab:red"))


def _draw_tray(ax, tray: dict) -> None:
    (cx, cy), (w, h), (cols, rows) = tray["centre"], tray["size"], tray["grid"]
    ax.add_patch(Rectangle((cx - w / 2, cy - h / 2), w, h, fc="wheat", ec="k"))
    px, py = w / cols, h / rows
    for slot, (sx, sy) in enumerate(tray["slots"]):
        ax.add_patch(Rectangle((sx - px / 2 + 0.01, sy - py / 2 + 0.01), px - 0.02, py - 0.02,
                               fc="none", ec="0.55", lw=0.6))
        ax.text(sx, sy - py / 2 + 0.015, str(slot), fontsize=5, ha="center", color="0.4")


def _part_patch(shape: tuple, x: float, y: float, angle: float, colour: str):
    if shape[0] == "circle":
        return Circle((x, y), shape[1][0], fc=colour, ec="k", lw=0.5)
    w, h = shape[1]
    c, s = math.cos(angle), math.sin(angle)
    pts = [(x + c * dx - s * dy, y + s * dx + c * dy)
           for dx, dy in ((-w / 2, -h / 2), (w / 2, -h / 2), (w / 2, h / 2), (-w / 2, h / 2))]
    return Polygon(pts, closed=True, fc=colour, ec="k", lw=0.5)


def _elbow(base: tuple, tip: tuple) -> tuple:
    """Two-link IK (for looks only): elbow position, reach clamped to the links."""
    dx, dy = tip[0] - base[0], tip[1] - base[1]
    d = min(max(math.hypot(dx, dy), 1e-6), _UPPER_ARM + _FOREARM - 1e-6)
    cos_a = (_UPPER_ARM ** 2 + d * d - _FOREARM ** 2) / (2 * _UPPER_ARM * d)
    a = math.acos(max(-1.0, min(1.0, cos_a)))
    heading = math.atan2(dy, dx) + a  # elbow on the left of the shoulder-to-tip line
    return (base[0] + _UPPER_ARM * math.cos(heading), base[1] + _UPPER_ARM * math.sin(heading))


def _draw_arm(ax, snap: dict) -> None:
    rail_x = snap["layout"]["rail"]["x"]
    base = (rail_x, snap["carriage_y"])
    tx, ty, _ = snap["tcp"]
    ex, ey = _elbow(base, (tx, ty))
    ax.add_patch(Rectangle((base[0] - 0.12, base[1] - 0.12), 0.24, 0.24, fc="0.35", ec="k", zorder=5))
    ax.plot([base[0], ex, tx], [base[1], ey, ty], "-o", c="tab:gray", lw=3, ms=4, zorder=6)
    on = snap["gripper_enabled"]  # suction on: solid black ring; off: thin dashed grey ring
    ax.add_patch(Circle((tx, ty), snap["layout"]["cup_radius"], fc="none", ec="k" if on else "0.4",
                        lw=2.0 if on else 1.0, ls="-" if on else "--", zorder=10))


def _info_text(snap: dict, fsm_state) -> str:
    lines = [f"t = {snap['time']:7.2f} s", f"tray {snap['tray_count']:2d}   lost {snap['lost_count']}",
             f"z = {snap['tcp'][2]:.3f} m"]
    if snap["attached"] is not None:
        lines.append(f"holding part {snap['attached']}")
    if fsm_state:
        lines.append(f"state: {fsm_state}")
    return "\n".join(lines)


def draw_snapshot(ax, snap: dict, title: str | None = None, fsm_state: str | None = None) -> None:
    """Draw one snapshot (from ``Cell.snapshot()``) on a matplotlib Axes."""
    lay = snap["layout"]
    _draw_static(ax, lay)
    held = []
    for pid, ptype, x, y, angle, place in snap["parts"]:
        kind = place.split("(")[0]
        if kind == "LOST":
            continue
        patch = _part_patch(lay["part_types"][ptype], x, y, angle, PLACE_COLOURS[kind])
        if kind == "GRIPPER":
            held.append(patch)
        else:
            ax.add_patch(patch)
    _draw_arm(ax, snap)
    for patch in held:
        patch.set_zorder(9)
        ax.add_patch(patch)
    for kind, colour in PLACE_COLOURS.items():
        ax.plot([], [], "o", c=colour, label=kind.lower())
    ax.legend(loc="lower right", fontsize=6, framealpha=0.8)
    ax.text(0.03, 0.98, _info_text(snap, fsm_state or snap.get("fsm_state")), transform=ax.transAxes,
            va="top", fontsize=8, family="monospace",
            bbox={"boxstyle": "round", "fc": "white", "alpha": 0.85})
    ax.set_xlim(*_XLIM)
    ax.set_ylim(*_YLIM)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    if title:
        ax.set_title(title, fontsize=9)


def render_png(cell, path, title: str | None = None, fsm_state: str | None = None) -> str:
    """Draw a Cell (or a snapshot dict) to a PNG file; return its path."""
    fig = _new_figure()
    ax = fig.add_subplot(1, 1, 1)
    draw_snapshot(ax, _as_snapshot(cell), title, fsm_state)
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png")
    return str(path)


def _pillow():
    try:
        from PIL import Image
    except ImportError as exc:  # pragma: no cover - Pillow ships with matplotlib
        raise RuntimeError("GIF writing needs Pillow (pip install pillow); "
                           "PNG rendering works without it") from exc
    return Image


def render_gif(snapshots: Iterable[dict], path, fps: float = 10.0, title: str | None = None,
               progress: bool = True) -> int:
    """Write snapshot dicts (any iterable, e.g. a generator) as an animated GIF; return frames.
    ``progress``: a bar on stderr while frames are drawn (on a terminal only; with an ETA
    when ``snapshots`` has a length)."""
    from btfsm.progress import progress_bar

    image = _pillow()
    _writable_target(path)  # before minutes of drawing
    fig = _new_figure()
    ax = fig.add_subplot(1, 1, 1)
    frames = []
    total = len(snapshots) if hasattr(snapshots, "__len__") else None
    with progress_bar(total, desc="GIF frames", unit=" frame", disable=not progress) as bar:
        for snap in snapshots:
            ax.clear()
            draw_snapshot(ax, snap, title)
            if not frames:
                fig.tight_layout()  # same layout for every frame
            canvas = fig.canvas
            canvas.draw()
            rgb = image.frombuffer("RGBA", canvas.get_width_height(), canvas.buffer_rgba()).convert("RGB")
            frames.append(rgb.quantize(colors=64, method=image.Quantize.FASTOCTREE))
            bar.update(1)
    if not frames:
        raise ValueError("render_gif got no snapshots")
    with atomic_path(path) as tmp:
        frames[0].save(tmp, format="GIF", save_all=True, append_images=frames[1:], loop=0,
                       duration=max(1, round(1000.0 / fps)))
    return len(frames)


def _writable_target(path) -> None:
    """Refuse a folder as the output file (an IsADirectoryError naming it)."""
    if os.path.isdir(path):
        raise IsADirectoryError(21, "is a directory", str(path))


class Recorder:
    """Collects snapshots (with an optional FSM state label) and writes them as a GIF."""

    def __init__(self, every_steps: int = 24, max_frames: int = 2000):
        self.every_steps = every_steps
        self.max_frames = max_frames
        self.frames: list = []

    def add(self, snapshot: dict, fsm_state: str | None = None) -> None:
        """Store a snapshot; frames past ``max_frames`` are dropped."""
        if len(self.frames) < self.max_frames:
            self.frames.append(dict(snapshot, fsm_state=fsm_state))

    def capture(self, cell, fsm_state: str | None = None) -> bool:
        """Snapshot ``cell`` if its step count is a multiple of ``every_steps``."""
        if cell.steps % self.every_steps:
            return False
        self.add(cell.snapshot(), fsm_state)
        return True

    def write_gif(self, path, fps: float = 10.0, title: str | None = None) -> int:
        return render_gif(self.frames, path, fps, title)
