"""Draw a scene's world (top view) to PNG and animated GIF (matplotlib Agg, Pillow).

Areas are grey rectangles (with their slots), belts blue bands with an arrow, sinks red,
doors brown (hatched while not fully open), sensors green outlines, fault regions orange,
robots a reach outline, the base or rail, and the tool point, walls dark lines; parts are
discs rimmed by place (held: red, on a belt: blue, in an area: green, on the floor: black)
and filled with their part type's ``colour`` (else the place's colour)."""
from __future__ import annotations

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.patches import Circle, FancyArrow, Polygon, Rectangle

__all__ = ["draw_world", "render_scene", "write_gif", "picture_png", "new_figure"]

_COLOUR = {"GRIPPER": "tab:red", "BELT": "tab:blue", "AREA": "tab:green", "FLOOR": "black"}


def _rect(ax, r, **kw):
    ax.add_patch(Rectangle((r[0], r[1]), r[2] - r[0], r[3] - r[1], **kw))


def draw_world(ax, scene, snap: dict, title: "str | None" = None) -> None:
    """Draw one snapshot (``World.snapshot()``) of ``scene`` on ``ax``."""
    import math

    xs, ys = [], []
    for name, a in scene.areas.items():
        _rect(ax, a["region"], facecolor="0.9", edgecolor="0.4")
        ax.text(a["region"][0], a["region"][3], name, fontsize=7, va="bottom")
        for sx, sy in a["slots"]:
            ax.add_patch(Circle((sx, sy), a["slot_tolerance"], fill=False, edgecolor="0.6", lw=0.5))
        xs += [a["region"][0], a["region"][2]]; ys += [a["region"][1], a["region"][3]]
    for name, b in scene.belts.items():
        (x0, y0), (x1, y1), w = b["from"], b["to"], b["width"]
        ux, uy = (x1 - x0) / b["length"], (y1 - y0) / b["length"]
        nx, ny = -uy * w / 2, ux * w / 2
        ax.add_patch(Polygon([(x0 + nx, y0 + ny), (x1 + nx, y1 + ny), (x1 - nx, y1 - ny), (x0 - nx, y0 - ny)],
                             facecolor="lightsteelblue", edgecolor="steelblue"))
        ax.add_patch(FancyArrow(x0, y0, (x1 - x0) * 0.2, (y1 - y0) * 0.2, width=w * 0.1, color="steelblue"))
        ax.text(x0, y0 + w, f"{name} ({b['end']})", fontsize=7)
        xs += [x0, x1]; ys += [y0, y1]
    for name, r in scene.sinks.items():
        _rect(ax, r, facecolor="mistyrose", edgecolor="red")
        ax.text(r[0], r[1], f"sink {name}", fontsize=7, va="top", color="red")
    for name, d in scene.doors.items():
        shut = snap["doors"].get(name, 0.0) < 1.0
        _rect(ax, d["region"], fill=False, edgecolor="saddlebrown", lw=2 if shut else 0.8, hatch="//" if shut else None)
        ax.text(d["region"][0], d["region"][1], f"door {name}: {snap['doors'].get(name, 0.0):.0%} open",
                fontsize=7, va="top", color="saddlebrown")
    for name, s in scene.sensors.items():
        _rect(ax, s["region"], fill=False, edgecolor="green", ls="--")
    for name, f in scene.faults.items():
        _rect(ax, f["region"], facecolor="moccasin", edgecolor="orange", alpha=0.6)
    for name, r in scene.robots.items():
        a, b = r["rail"]
        ax.plot([a[0], b[0]], [a[1], b[1]], color="0.3", lw=3)
        ang = math.atan2(b[1] - a[1], b[0] - a[0])
        pts = [(a[0] + r["reach"] * math.cos(ang + math.pi / 2 + t * math.pi / 24),
                a[1] + r["reach"] * math.sin(ang + math.pi / 2 + t * math.pi / 24)) for t in range(25)]
        pts += [(b[0] + r["reach"] * math.cos(ang - math.pi / 2 + t * math.pi / 24),
                 b[1] + r["reach"] * math.sin(ang - math.pi / 2 + t * math.pi / 24)) for t in range(25)]
        ax.add_patch(Polygon(pts, fill=False, edgecolor="0.7", ls=":"))
        xs += [p[0] for p in pts]; ys += [p[1] for p in pts]
    for w in scene.walls.values():
        pts = w["points"] + ([w["points"][0]] if w["closed"] else [])
        ax.plot([p[0] for p in pts], [p[1] for p in pts], color="0.15", lw=max(1.0, w["thickness"] * 200))
    for pid, ptype, rad, x, y, place in snap["parts"]:
        kind = place.split("(")[0]
        if kind != "LOST":  # filled with the part type's colour (if it has one), rimmed by where it is
            colour = _COLOUR.get(kind, "black")
            ax.add_patch(Circle((x, y), rad, facecolor=scene.part_colours.get(ptype) or colour, edgecolor=colour,
                                lw=1.2))
    for name, (x, y, held) in snap["robots"].items():
        cx, cy = scene.carriage(name, (x, y))  # the arm starts at its carriage
        ax.plot([cx, x], [cy, y], color="0.2", lw=1.5)
        ax.add_patch(Circle((x, y), scene.robots[name]["radius"], fill=False, edgecolor="red", lw=1.5))
    lost = sum(1 for p in snap["parts"] if p[5] == "LOST")
    ax.set_title(f"{title or scene.name}\nt = {snap['time']:.1f} s, lost {lost}", fontsize=9)
    if xs:
        ax.set_xlim(min(xs) - 0.1, max(xs) + 0.1)
        ax.set_ylim(min(ys) - 0.1, max(ys) + 0.1)
    ax.set_aspect("equal")
    ax.tick_params(labelsize=7)


def _figure():
    fig = Figure(figsize=(6, 5), dpi=100)
    FigureCanvasAgg(fig)
    return fig


def render_scene(scene, snap: dict, path, title: "str | None" = None) -> str:
    fig = _figure()
    draw_world(fig.add_subplot(1, 1, 1), scene, snap, title)
    fig.tight_layout()
    fig.savefig(path, format="png")
    return str(path)


def picture_png(scene, snap: dict, title: "str | None" = None, fig=None) -> bytes:
    """One snapshot as small PNG bytes (64 colours), for pages that inline their pictures
    (``btfsm.html``); ``fig``: a figure to draw on again (from ``_figure()``)."""
    import io

    from PIL import Image

    fig = fig or _figure()
    ax = fig.axes[0] if fig.axes else fig.add_subplot(1, 1, 1)
    ax.clear()
    draw_world(ax, scene, snap, title)
    if not getattr(fig, "laid_out", False):  # one layout for every picture (as write_gif)
        fig.tight_layout()
        fig.laid_out = True
    fig.canvas.draw()
    rgb = Image.frombuffer("RGBA", fig.canvas.get_width_height(), fig.canvas.buffer_rgba()).convert("RGB")
    out = io.BytesIO()
    rgb.quantize(colors=64, method=Image.Quantize.FASTOCTREE).save(out, format="PNG")
    return out.getvalue()


def new_figure():
    """A figure for ``picture_png`` to draw on again and again."""
    return _figure()


def write_gif(scene, snaps, path, fps: float = 2.0, title: "str | None" = None, progress: bool = True) -> int:
    """Write world snapshots (any iterable, e.g. a generator) as an animated GIF; return
    the number of frames. A folder as ``path`` is refused before any drawing
    (IsADirectoryError); ``progress``: a bar on stderr while frames are drawn (on a
    terminal only; with an ETA when ``snaps`` has a length)."""
    import os

    from PIL import Image

    from btfsm.outputs import atomic_path
    from btfsm.progress import progress_bar

    if os.path.isdir(path):
        raise IsADirectoryError(21, "is a directory", str(path))
    fig = _figure()
    ax = fig.add_subplot(1, 1, 1)
    frames: list = []
    total = len(snaps) if hasattr(snaps, "__len__") else None
    with progress_bar(total, desc="GIF frames", unit=" frame", disable=not progress) as bar:
        for snap in snaps:
            ax.clear()
            draw_world(ax, scene, snap, title)
            if not frames:
                fig.tight_layout()  # same layout for every frame
            fig.canvas.draw()
            rgb = Image.frombuffer("RGBA", fig.canvas.get_width_height(), fig.canvas.buffer_rgba()).convert("RGB")
            frames.append(rgb.quantize(colors=64, method=Image.Quantize.FASTOCTREE))
            bar.update(1)
    if not frames:
        raise ValueError("no frames to write")
    with atomic_path(path) as tmp:
        frames[0].save(tmp, format="GIF", save_all=True, append_images=frames[1:], loop=0,
                       duration=max(1, round(1000.0 / fps)))
    return len(frames)
