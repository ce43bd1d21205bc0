"""The cell in the HTML report (``btfsm.html``): a recorder for the cell loops.

``CellView(model, title)`` is an ``on_tick(rt, world)`` callback for the loops that run a
model in a cell (``run_scene``, ``run_scenario``, ``replay_in_cell``, ``replay_in_scene``;
their runtime records its steps). Each tick becomes a neutral view record
(``btfsm.html.RunRecorder``: node statuses, FSM states, fired edges, variables). The
world is snapshotted (``World.snapshot()``) at the first tick, at every tick where an FSM
changes state, at least every ``every`` ticks, and at the end, at most ``max_pictures``
in all; ``run()`` draws those snapshots with the scene engine's renderer
(``scene_render.picture_png``, about 0.1 s and 20-40 kB each), so a run that is recorded
but not shown costs no drawing. The page shows, at every tick, the last picture taken at
or before it, with its tick.
"""
from __future__ import annotations

from typing import Any

from btfsm.html import RunRecorder

__all__ = ["CellView"]


class CellView:
    def __init__(self, model, title: str, max_pictures: int = 40, every: int = 50):
        self.every = every
        self.rec = RunRecorder(model, "cell", title, max_pictures)
        self.world: Any = None
        self.prev = None
        self.snaps: list = []  # (index of the tick, snapshot)

    def __call__(self, rt, world) -> None:
        step = rt.last
        self.world = world
        if self.prev is None:
            self.rec.start(rt.program.initial)
            self.prev = rt.program.initial
        self.rec.tick(self.prev, step, round(world.time, 3))
        ticks = self.rec.ticks
        last = self.snaps[-1][0] if self.snaps else None
        if (last is None or ticks[-1]["fsm"] != ticks[-2]["fsm"] or len(ticks) - 1 - last >= self.every) \
                and len(self.snaps) < self.rec.max_pictures - 1:  # one left for the end
            self.snaps.append((len(ticks) - 1, world.snapshot()))
        self.prev = step.state

    def run(self, summary: str = "", mismatch=None) -> dict:
        """The recorded run with its pictures drawn; ``mismatch`` (a ``Mismatch``) is marked
        on the timeline at the last tick recorded (the failing tick did not happen, or was
        not recorded)."""
        from .scene_render import new_figure, picture_png

        ticks = self.rec.ticks
        if not ticks:
            return self.rec.run(summary=summary or "no tick was recorded")
        if self.world is not None and (not self.snaps or self.snaps[-1][0] != len(ticks) - 1):
            self.snaps.append((len(ticks) - 1, self.world.snapshot()))
        fig = new_figure()
        for i, snap in self.snaps:
            t = ticks[i]
            states = ", ".join(f"{f}: {s}" for f, (s, _g) in t["fsm"].items())
            self.rec.picture(picture_png(self.world.scene, snap, f"tick {t['tick']}; {states}", fig), tick=i)
        if mismatch is not None:
            self.rec.marks.append([len(ticks) - 1, f"the first mismatch comes next: {mismatch}"])
        return self.rec.run(summary=summary)


class ConformViews:
    """``views`` for ``conform`` under ``btfsm conform --html``: every scenario is recorded
    (view records and snapshots, no drawing) until the first one that does not conform;
    the page shows that one (else the first scenario), with the first mismatch marked."""

    def __init__(self, model, max_pictures: int = 40):
        self.model, self.max_pictures = model, max_pictures
        self.current: "CellView | None" = None
        self.first: "tuple | None" = None  # (index, CellView, result)
        self.failed: "tuple | None" = None

    def __call__(self, index: int):
        if self.failed is not None:
            return None
        self.current = CellView(self.model, f"scenario {index}", self.max_pictures)
        return self.current

    def result(self, index: int, scenario, res) -> None:
        """Call from ``conform``'s ``on_result``."""
        view, self.current = self.current, None
        if view is None:
            return
        if res.mismatch is not None and self.failed is None:
            self.failed = (index, view, res)
        elif self.first is None:
            self.first = (index, view, res)

    def page(self, rows: list) -> dict:
        """``btfsm.html.page`` keywords: one verdict per scenario (``rows``: the command's
        JSON rows), the chosen scenario as the run."""
        index, view, res = self.failed or self.first or (None, None, None)
        runs: list = []
        if view is not None:
            what = "the first that does not conform" if res.mismatch is not None else "every scenario conforms; the first"
            runs.append(view.run(summary=f"scenario {index}: {what}; {res.ticks} tick(s)", mismatch=res.mismatch))
        verdicts = []
        for row in rows:
            ok = row["conforms"]
            verdicts.append({"name": f"scenario {row['scenario']} (seed {row['seed']})",
                             "verdict": "conforms" if ok else "MISMATCH", "cls": "holds" if ok else "violated",
                             "summary": f"{row['ticks']} ticks" + ("" if ok else f"; first mismatch at {row['mismatch']}"),
                             "run": 0 if runs and row["scenario"] == index else None})
        failed = sum(1 for r in rows if not r["conforms"])
        return {"title": f"btfsm conform {self.model.name}", "verdicts": verdicts, "runs": runs,
                "notes": [f"{len(rows) - failed} of {len(rows)} scenarios conform"]}
