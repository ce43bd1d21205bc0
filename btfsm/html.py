"""One self-contained HTML page to *see* a check, a counterexample or a recorded run.

``btfsm check MODEL --html r.html``, ``btfsm replay FILE MODEL --html r.html`` and
``btfsm conform MODEL --html r.html`` write one HTML file with everything inlined (the
viewer's script and style, the drawings as SVG, pictures as ``data:`` URIs; a
Content-Security-Policy forbids every network request): the verdicts, and per run (a
counterexample, a trace, a cell run) a timeline whose slider and arrow keys step through
the ticks, the tree with each node coloured by its status in the selected tick, each FSM
with the token's state and the fired edges highlighted, the variables and events of the
tick, and, for cell runs, the cell's picture.

**The viewer's input is neutral.** A page is built from *runs*; a run is a list of
per-tick records that say what was seen, not how it was obtained::

    {"tick": 3, "time": 0.3 or null, "status": "RUNNING" or null (root),
     "nodes": {node: "RUNNING" | "SUCCESS" | "FAILURE" | "halted"},   # absent: IDLE
     "halted": [node, ...], "fsm": {fsm: [state, goal or null]}, "fired": [[fsm, edge id]],
     "changes": {variable or slot: value}, "env": [event, ...], "lines": [text, ...],
     "picture": index into the run's pictures (optional)}

``nodes`` holds the status each node returned in that tick (the last one, when it was
ticked twice) or ``halted``; a node not in it was not ticked (IDLE). Counterexamples and
traces fill it exactly, by re-running their steps through the one step function
(``Program.step`` with ``record=True``; ``view_tick``); any other recorder of per-tick node
statuses (a BehaviorTree.CPP ``.btlog``) can fill it from its own transitions, and the
page needs nothing else. Layouts come from Graphviz (``dot -Tsvg`` of ``btfsm.show``'s
drawings); without ``dot`` the commands stop with exit 2 and say so (``require_dot``).
"""
from __future__ import annotations

import base64
import dataclasses
import html
import json
import xml.etree.ElementTree as ET
from importlib import resources

from .formats import jsonable
from .show import GraphvizError, fsm_to_dot, render, tree_to_dot

__all__ = ["FORMAT", "view_tick", "counterexample_run", "trace_run", "RunRecorder", "page", "write_page",
           "read_page", "require_dot", "check_page", "replay_page", "log_page", "COLLAPSE_AT"]

FORMAT = "btfsm-view/1"
_NAMES = ("RUNNING", "SUCCESS", "FAILURE")
#: An FSM with more states than this is drawn collapsed first: the states some run of the
#: page visits (and the initial one), the edges between them, one box for the rest; the
#: whole FSM stays one click away.
COLLAPSE_AT = 24
#: A full drawing of an FSM is left out (the collapsed one only) past this many states.
FULL_LIMIT = 400
_SVG = "http://www.w3.org/2000/svg"


def require_dot(flag: str = "--html") -> None:
    """Raise ``GraphvizError`` (exit 2) with the reason when Graphviz's ``dot`` is missing."""
    import shutil

    if shutil.which("dot") is None:
        raise GraphvizError(f"{flag} needs Graphviz's 'dot' program to lay out the tree and the FSMs, and it is not on "
                            "PATH; install graphviz (Debian: apt-get install graphviz)")


# ============================================================================ per-tick records


def _fsm_of(program, state) -> dict:
    return {f.name: [ids[state[tok]], f.goals[state[g] - 1] if state[g] else None]
            for f, ids, tok, g, _ in program.fsm_info}


def _values(program, state) -> dict:
    """Readable values of every slot (``Program.decode``; node memory and timers have a
    ``:`` in their names, and the page lists them apart)."""
    return {program.slots[i].name: jsonable(program.decode_slot(i, state[i])) for i in range(len(state))}


def view_tick(program, tick: int, step, before, time=None, keep=None) -> dict:
    """The neutral record of one tick from a recorded ``Step`` (``Program.step(...,
    record=True)``) taken from state ``before``. ``keep``: the slots that exist (an FSM's
    open system keeps some); default all."""
    nodes, halted, fired, env, lines = {}, [], [], [], []
    for ev in step.events or ():
        kind = ev[0]
        if kind == "status":
            nodes[ev[1]] = _NAMES[ev[2]]
        elif kind == "halt":
            nodes[ev[1]] = "halted"
            halted.append(ev[1])
            lines.append(f"halt {ev[1]}")
        elif kind == "fire":
            fired.append([ev[1], ev[2]])
            lines.append(f"fired {ev[1]}: {ev[2]}")
        elif kind == "outcome":
            lines.append(f"{ev[1]} -> {ev[2]}")
        elif kind == "env":
            env.append(ev[1])
            lines.append(f"event {ev[1]}")
        elif kind != "write":
            lines.append(" ".join(str(x) for x in ev))
    for v in step.violations or ():
        lines.append("violation: " + " ".join(str(x) for x in v))
    after = step.state
    idx = range(len(after)) if keep is None else keep
    changes = {program.slots[i].name: jsonable(program.decode_slot(i, after[i])) for i in idx if before[i] != after[i]}
    return {"tick": tick, "time": time, "status": _NAMES[step.status], "nodes": nodes, "halted": halted,
            "fsm": _fsm_of(program, after), "fired": fired, "changes": changes, "env": env, "lines": lines}


def _initial_tick(program, state, time=None) -> dict:
    return {"tick": 0, "time": time, "status": None, "nodes": {}, "halted": [], "fsm": _fsm_of(program, state),
            "fired": [], "changes": {}, "env": [], "lines": ["initial state"]}


def _run(kind: str, title: str, initial: dict, ticks: list, **extra) -> dict:
    run = {"kind": kind, "title": title, "initial": initial, "ticks": ticks, "loop": None, "marks": [],
           "summary": "", "violation": "", "pictures": []}
    run.update(extra)
    return run


def counterexample_run(model, ce, title: "str | None" = None) -> dict:
    """A run of a counterexample (a ``Counterexample`` or its JSON) of ``model``.

    Model-level steps are re-run through ``Program.step`` from the recorded choice
    scripts (FSM level: the FSM's open system), so every node status is the step
    function's; each re-run state is compared with the counterexample's, and a step that
    differs (a counterexample of another version of the model) ends the re-run: from
    there the page shows only what the file records (FSM states, fired edges, halts)."""
    from btfsm.trace import encode_state

    d = ce if isinstance(ce, dict) else ce.to_json()
    prog = model.program
    title = title or f"{d['property']}: {d['summary']}"
    run = _run("counterexample", title, dict(d["initial"]), [], property=d["property"], level=d["level"],
               fsm_name=d.get("fsm"), summary=d["summary"], violation=(d.get("violation") or {}).get("text", ""),
               loop=d.get("loop"))
    if d["level"] == "fsm":
        run["note"] = (f"FSM {d.get('fsm')} as an open system: one step is one request to it, and the tree does "
                       "not run (only FSM states' subtrees can)")
    if d["level"] == "static":
        run["note"] = "no path: two guards that can be true together (both elements highlighted)"
        v = d.get("violation") or {}
        fsm = {f.name: [f.initial, None] for f in model.fsms}
        fired = []
        if v.get("fsm") in fsm and v.get("state"):
            fsm[v["fsm"]] = [v["state"], None]
            fired = [[v["fsm"], v[k]] for k in ("a", "b") if isinstance(v.get(k), str)]
        run["ticks"] = [{"tick": 0, "time": None, "status": None, "nodes": {}, "halted": [], "fsm": fsm,
                         "fired": fired, "changes": {}, "env": [], "lines": ["the two overlapping elements"]}]
        return run
    try:
        runner, keep = _runner(model, d)
        state = encode_state(prog, d["initial"])
    except (KeyError, ValueError) as exc:  # a file of another model: show what it records
        state, run["note"] = None, f"not re-run on {model.name}: {exc}"
    ticks = [_initial_tick(prog, state) if state is not None else _recorded_tick(0, {}, None)]
    for st in d["steps"]:
        rec = None
        if state is not None and not st.get("error"):
            rec, state = _rerun(prog, runner, keep, st, state)
            if rec is None:
                run["note"] = (f"step {st['tick']} does not re-run to the state the file records: from there the page "
                               "shows only what the file records")
        if rec is None:
            rec = _recorded_tick(st["tick"], st.get("fsm") or ticks[-1]["fsm"], st)
        if st.get("error"):
            rec["lines"].append(f"error: {st['error']}")
            run["marks"].append([st["tick"], "the domain error"])
        ticks.append(rec)
    run["ticks"] = ticks
    v = d.get("violation") or {}
    if isinstance(v.get("trigger_step"), int) and 0 <= v["trigger_step"] < len(ticks):
        run["marks"].append([v["trigger_step"], f"the trigger ({v.get('trigger')})"])
    return run


def _runner(model, d):
    """(step runner, kept slots) for the counterexample's level."""
    prog = model.program
    if d["level"] == "model":
        return (lambda s, o: prog.step(s, o, True)), None
    from btfsm.verify.explore import open_fsm

    op = open_fsm(model, d["fsm"])
    return (lambda s, o: op.run(s, o, True)), tuple(op.kept)


def _rerun(prog, runner, keep, st, state):
    """(record, next state) of one counterexample step re-run from ``state``, or (None, None)."""
    from btfsm.errors import DomainError
    from btfsm.verify.search import EnumOracle

    try:
        step = runner(tuple(state), EnumOracle(tuple(st["script"])))
    except (DomainError, ValueError, IndexError):
        return None, None
    if step is None or step.state is None:
        return None, None
    want = st.get("state") or {}
    have = {prog.slots[i].name: jsonable(prog.decode_slot(i, step.state[i])) for i in range(len(step.state))}
    if any(have.get(k) != v for k, v in want.items()):
        return None, None
    rec = view_tick(prog, st["tick"], step, state, keep=keep)
    if st.get("request"):
        req = st["request"]
        rec["lines"].insert(0, "request " + req.get("goal", "?") + "".join(
            f" {k}={v}" for k, v in {**req.get("params", {}), **req.get("inputs", {})}.items()))
    return rec, step.state


def _recorded_tick(tick, fsm, st) -> dict:
    """A tick from what a counterexample step records, without re-running it."""
    st = st or {}
    nodes = {n: "halted" for n in st.get("halted", ())}
    lines = [f"{a} -> {b}" for a, b in st.get("outcomes", ())]
    return {"tick": tick, "time": None, "status": st.get("status"), "nodes": nodes, "halted": list(st.get("halted", ())),
            "fsm": {k: list(v) for k, v in fsm.items()} if isinstance(fsm, dict) and tick else {},
            "fired": [list(x) for x in st.get("fired", ())], "changes": dict(st.get("changes", {})),
            "env": list(st.get("env", ())), "lines": lines}


def trace_run(model, header: dict, records: list, title: str) -> dict:
    """A run of a trace (``btfsm.trace.read_trace``'s header and records) of ``model``.

    Each tick is re-run through ``Program.step`` answered from the record
    (``ReplayOracle``: the events by name, the outcomes in order), as ``btfsm replay``
    does; the first tick whose re-run differs from the record is marked on the timeline (the
    first nonconforming step), and from there the page shows the trace's own records
    (``nodes``: the status changes the trace records)."""
    from btfsm.clock import Clock
    from btfsm.errors import DomainError
    from btfsm.trace import ReplayOracle, encode_state
    from btfsm.trace import tick_record as trace_record

    prog = model.program
    run = _run("trace", title, dict(header.get("initial", {})), [])
    try:
        state = encode_state(prog, header.get("initial", {}))
        ticks = [_initial_tick(prog, state, time=0.0)]
    except ValueError as exc:
        state = None
        run["marks"].append([0, f"the trace's initial state does not fit {model.name}: {exc}"])
        ticks = [_recorded_tick(0, {}, None)]
    last: dict
    clock, last = Clock(model.tick_rate), {}
    for rec in records:
        mine = None
        if state is not None:
            oracle = ReplayOracle(prog, rec)
            try:
                step = prog.step(tuple(state), oracle, True)
            except DomainError as exc:
                why: "str | None"
                step, why = None, f"the model fails here: {exc}"
            else:
                why = oracle.error or (None if step.state is not None else "the model cannot take this tick")
            if why is None and trace_record(prog, clock, step, last) != rec:
                why = "the re-run record differs from the trace"
            if why is None:
                mine = view_tick(prog, rec["tick"] + 1, step, state, time=rec["time"])
                state = step.state
                clock.tick += 1
            else:
                state = None
                run["marks"].append([rec["tick"] + 1, f"the first step that differs: trace tick {rec['tick']}: {why}"])
                run["note"] = "from the first step that differs on, the page shows the trace's own records"
        if mine is None:
            mine = {"tick": rec["tick"] + 1, "time": rec["time"], "status": rec["status"], "nodes": dict(rec["changes"]),
                    "halted": [n for n, s in rec["changes"].items() if s == "halted"], "fsm": rec["fsm"],
                    "fired": rec["fired"], "changes": dict(rec["writes"]), "env": rec["env"],
                    "lines": [f"{a} -> {b}" for a, b in rec["outcomes"]]}
        ticks.append(mine)
    run["ticks"] = ticks
    run["summary"] = f"{len(records)} tick(s) of {header.get('model')}"
    return run


class RunRecorder:
    """Collects the ticks of a live run (a ``Runtime`` with ``record=True``): call
    ``start(state)`` once, then ``tick(state_before, step, time)`` after each tick;
    ``picture(png_bytes)`` attaches a picture to the last tick. ``run()`` is the result."""

    def __init__(self, model, kind: str, title: str, max_pictures: int = 60):
        self.program, self.kind, self.title = model.program, kind, title
        self.ticks: list = []
        self.pictures: list = []
        self.max_pictures = max_pictures
        self.initial: dict = {}
        self.marks: list = []  # [tick, text]: e.g. the first nonconforming step
        self.note = ""

    def start(self, state, time=0.0) -> None:
        self.initial = _values(self.program, state)
        self.ticks = [_initial_tick(self.program, state, time=time)]

    def tick(self, before, step, time=None) -> None:
        self.ticks.append(view_tick(self.program, len(self.ticks), step, before, time=time))

    def picture(self, png: bytes, tick: int = -1) -> bool:
        """Attach ``png`` to the tick at index ``tick`` (default the last); False (nothing
        kept) once ``max_pictures`` are held."""
        if len(self.pictures) >= self.max_pictures:
            return False
        self.pictures.append("data:image/png;base64," + base64.b64encode(png).decode("ascii"))
        self.ticks[tick]["picture"] = len(self.pictures) - 1
        return True

    def run(self, **extra) -> dict:
        return _run(self.kind, self.title, self.initial, self.ticks, marks=self.marks, pictures=self.pictures,
                    note=self.note, **extra)


# ============================================================================ drawings


def _svg(dot_text: str, prefix: str) -> str:
    """``dot -Tsvg`` of ``dot_text``, its ids removed (several drawings share one page) and
    each node and edge named by a ``data-k`` attribute: ``prefix`` + its dot name."""
    raw = render(dot_text, "svg").decode("utf-8")
    ET.register_namespace("", _SVG)
    ET.register_namespace("xlink", "http://www.w3.org/1999/xlink")
    root = ET.fromstring(raw)
    for g in root.iter(f"{{{_SVG}}}g"):
        cls = g.get("class")
        gid = g.attrib.pop("id", None)
        if cls == "node" and gid and gid.startswith("marker:"):  # a marker fires like an edge
            g.set("data-k", "e:" + gid[len("marker:"):])
        elif cls == "node":
            title = g.find(f"{{{_SVG}}}title")
            g.set("data-k", prefix + (title.text or "" if title is not None else ""))
        elif cls == "edge" and gid and gid.startswith("edge:"):
            g.set("data-k", "e:" + gid[len("edge:"):])
    for a in root.iter(f"{{{_SVG}}}a"):  # tooltips: keep the title, drop the link wrapper's target
        a.attrib.pop("{http://www.w3.org/1999/xlink}href", None)
    w, h = root.attrib.pop("width", None), root.attrib.pop("height", None)
    root.set("data-size", f"{w} {h}")
    return ET.tostring(root, encoding="unicode")


def _visited(runs, fsm: str) -> set:
    out = set()
    for run in runs:
        for t in run["ticks"]:
            st = (t.get("fsm") or {}).get(fsm)
            if st:
                out.add(st[0])
    return out


def _collapsed_dot(model, f, visited: set) -> str:
    keep = [st for st in f.states if st.id in visited or st.id == f.initial]
    ids = {st.id for st in keep}
    small = dataclasses.replace(f, states=tuple(keep), edges=tuple(e for e in f.edges if e.source in ids and e.target in ids),
                                markers=tuple(m for m in f.markers if m.state in ids))
    text = fsm_to_dot(model, small).rstrip().rstrip("}")
    rest = len(f.states) - len(keep)
    text += (f'  "collapsed" [shape=note, style=dashed, label="{rest} state(s) no run here visits\\n'
             f'(collapsed; the button shows the whole FSM)"];\n}}\n')
    return text


def drawings(model, runs) -> dict:
    """The tree and each FSM as SVG (Graphviz): ``{"tree": svg or None, "fsms": [...]}``."""
    tree = _svg(tree_to_dot(model), "") if model.roots() else None
    fsms = []
    for f in model.fsms:
        visited = _visited(runs, f.name)
        entry = {"name": f.name, "states": len(f.states), "visited": len(visited | {f.initial}),
                 "full": None, "collapsed": None}
        if len(f.states) > COLLAPSE_AT and visited and len(visited | {f.initial}) < len(f.states):
            entry["collapsed"] = _svg(_collapsed_dot(model, f, visited), "")
        if len(f.states) <= FULL_LIMIT or entry["collapsed"] is None:
            entry["full"] = _svg(fsm_to_dot(model, f), "")
        fsms.append(entry)
    return {"tree": tree, "fsms": fsms}


# ============================================================================ the page


def _asset(name: str) -> str:
    return resources.files("btfsm").joinpath("viewer", name).read_text(encoding="utf-8")


def _script_json(obj) -> str:
    """JSON safe inside a <script> element (no ``</``, no ``<!--``)."""
    text = json.dumps(obj, separators=(",", ":"), ensure_ascii=False, default=str)
    return text.replace("<", "\\u003c").replace("\u2028", "\\u2028").replace("\u2029", "\\u2029")


_CSP = ("default-src 'none'; script-src 'unsafe-inline'; style-src 'unsafe-inline'; img-src data:; "
        "base-uri 'none'; form-action 'none'")


def page(model, *, title: str, verdicts: list, runs: list, notes: "list | None" = None) -> str:
    """The HTML text. ``verdicts``: ``[{"name", "verdict", "summary", "run": index or None}]``;
    ``runs``: neutral runs (``counterexample_run``, ``trace_run``, ``RunRecorder.run``)."""
    data = {"format": FORMAT, "model": model.name, "title": title, "verdicts": verdicts, "runs": runs,
            "notes": list(notes or []), "tick_rate": model.tick_rate}
    draw = drawings(model, runs)
    fsm_html = []
    for k, f in enumerate(draw["fsms"]):
        views = "".join(f'<div class="view" data-view="{v}">{draw["fsms"][k][v]}</div>'
                        for v in ("collapsed", "full") if f[v] is not None)
        toggle = ('<button class="toggle" title="switch between the states the runs visit and the whole FSM">'
                  'whole FSM</button>' if f["collapsed"] and f["full"] else "")
        note = (f' <span class="dim">{f["states"]} states; {f["visited"]} visited</span>' if f["collapsed"] else
                f' <span class="dim">{f["states"]} states</span>')
        fsm_html.append(f'<section class="panel fsm" data-fsm="{html.escape(f["name"])}"><h3>FSM '
                        f'{html.escape(f["name"])}{note} <span class="cur"></span> {toggle}'
                        f'<button class="near" title="zoom in on the token\'s state">zoom to the state</button>'
                        f'<button class="fit">fit</button></h3><div class="graph">{views}</div></section>')
    legend = ('<span class="legend"><span class="l-IDLE">IDLE</span><span class="l-RUNNING">RUNNING</span>'
              '<span class="l-SUCCESS">SUCCESS</span><span class="l-FAILURE">FAILURE</span>'
              '<span class="l-halted">halted</span></span>')
    tree_html = (f'<section class="panel tree"><h3>tree {legend} <button class="fit">fit</button></h3>'
                 f'<div class="graph"><div class="view">{draw["tree"]}</div></div></section>' if draw["tree"] else
                 '<section class="panel tree"><h3>tree</h3><p class="dim">this model has no tree</p></section>')
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta http-equiv="Content-Security-Policy" content="{_CSP}">
<meta name="viewport" content="width=device-width, initial-scale=1">
<meta name="generator" content="btfsm">
<title>{html.escape(title)}</title>
<style>{_asset("viewer.css")}</style></head>
<body>
<header><h1>{html.escape(title)}</h1><p class="dim">model {html.escape(model.name)}; written by btfsm; one file, nothing
fetched. Keys: left/right arrow one tick, Home/End first/last tick, up/down arrow the previous/next run.</p></header>
<section id="verdicts"></section>
<section id="runbar"><label>run <select id="run"></select></label>
<div id="summary"></div>
<div class="controls"><button id="prev" title="previous tick (left arrow)">&#9664;</button>
<input id="slider" type="range" min="0" max="0" value="0" aria-label="tick">
<button id="next" title="next tick (right arrow)">&#9654;</button> <span id="tickinfo"></span></div>
<div id="strip"></div></section>
<main><div class="graphs">{tree_html}<div class="fsms">{"".join(fsm_html)}</div></div>
<section class="panel side"><h3>tick</h3><div id="events"></div><h3>variables</h3><div id="vars"></div>
<div id="picture"></div></section></main>
<script type="application/json" id="btfsm-data">{_script_json(data)}</script>
<script>{_asset("viewer.js")}</script>
</body></html>
"""


def write_page(path, model, **kw) -> str:
    """Write ``page(model, **kw)`` to ``path`` atomically; returns the path."""
    from .outputs import atomic_write_text

    atomic_write_text(path, page(model, **kw))
    return str(path)


def read_page(path) -> dict:
    """The data a page was written from (its ``btfsm-data`` script element): format,
    model, title, verdicts, runs, notes."""
    text = open(path, encoding="utf-8").read()
    start = text.index('<script type="application/json" id="btfsm-data">')
    start = text.index(">", start) + 1
    return json.loads(text[start:text.index("</script>", start)])


def check_page(model, report) -> dict:
    """``page`` keywords for a ``btfsm check`` report: the verdicts and one run per counterexample."""
    from btfsm.verify.report import lint_summary

    runs: list
    verdicts, runs = [], []
    for r in report.results:
        verdict = "holds" if r.holds else ("VIOLATED" if r.holds is False else "undecided")
        entry = {"name": r.name, "verdict": verdict, "summary": "", "run": None}
        if r.name == "lints":  # as the text report: warnings, not a verdict
            warns = r.info.get("warnings") or [{"element": n, "text": ""} for n in r.notes]
            entry.update(verdict=f"{len(r.notes)} warning(s)", cls="lints",
                         summary=lint_summary(warns) if r.notes else "")
        elif r.not_applicable is not None:
            entry.update(verdict="not applicable", cls="na", summary=r.not_applicable)
        elif r.holds is True and r.info.get("vacuous"):
            entry["summary"] = "vacuously: the model has no tree"
        if r.counterexample is not None:
            entry["summary"] = r.counterexample.summary
            entry["run"] = len(runs)
            runs.append(counterexample_run(model, r.counterexample))
        elif r.notes and r.holds is not True:
            entry["summary"] = str(r.notes[0])
        verdicts.append(entry)
        if r.name == "lints":  # a dead branch comes with the shortest run that shows why
            for w in r.info.get("warnings") or []:
                if isinstance(w, dict) and isinstance(w.get("run"), dict):
                    verdicts.append({"name": f"lint {w['element']}", "verdict": "warning", "cls": "lints",
                                     "summary": w.get("text", ""), "run": len(runs)})
                    runs.append(counterexample_run(model, w["run"], title=f"lint {w['element']}: {w.get('text', '')}"))
    explored = ", ".join(f"{s.get('kind')}{' ' + s['fsm'] if s.get('fsm') else ''}: {s['states']:,} states"
                         for s in report.systems)
    notes = [f"explored {explored}" if explored else "nothing explored"]
    if not report.complete:
        notes.append("INCOMPLETE: a budget was hit; the undecided properties say so")
    return {"title": f"btfsm check {model.name}", "verdicts": verdicts, "runs": runs, "notes": notes}


def replay_page(model, path, ok: bool, text: str, ce=None, cell: "dict | None" = None) -> dict:
    """``page`` keywords for ``btfsm replay FILE MODEL --html``: the counterexample (or
    the trace) as a run, and the cell run when ``--cell`` recorded one."""
    import os

    from .trace import read_trace

    name = os.path.basename(os.fspath(path))
    if ce is not None:
        runs = [counterexample_run(model, ce)]
        verdict = {"name": f"replay of {name}", "verdict": "confirmed" if ok else "not reproduced",
                   "cls": "violated" if ok else "undecided", "summary": text, "run": 0}
    else:
        header, records = read_trace(path)
        runs = [trace_run(model, header, records, f"trace {name}")]
        verdict = {"name": f"replay of {name}", "verdict": "reproduces" if ok else "differs",
                   "cls": "holds" if ok else "violated", "summary": text, "run": 0}
    verdicts = [verdict]
    if cell is not None:
        verdicts.append({"name": "in the cell", "verdict": "ran", "cls": "holds", "summary": cell.get("summary", ""),
                         "run": len(runs)})
        runs.append(cell)
    return {"title": f"btfsm replay {name} {model.name}", "verdicts": verdicts, "runs": runs}


def log_page(model, path, verdict, text: str) -> dict:
    """``page`` keywords for ``btfsm conform --log RUN MODEL --html``: the run of the model
    that explains the recording (``verdict.steps`` of ``btfsm.verify.runlog``: every tick
    re-run through ``Program.step`` while it was checked) as a run of the page; when the
    recording does not conform, the run up to the furthest point explained, with the first
    recorded transition no run explains marked on its last tick."""
    import os

    prog = model.program
    name = os.path.basename(os.fspath(path))
    state = verdict.steps[0][0] if verdict.steps else prog.initial
    ticks = [_initial_tick(prog, state)]
    for k, (before, step) in enumerate(verdict.steps, start=1):
        ticks.append(view_tick(prog, k, step, before))
    run = _run("log", f"recorded run {name}", prog.decode(state), ticks)
    if verdict.conforms:
        run["summary"] = f"the model's run that explains {name}: {len(verdict.steps)} tick(s)"
        entry = {"name": f"conform --log {name}", "verdict": "conforms", "cls": "holds", "summary": text, "run": 0}
    else:
        why = (verdict.first or {}).get("text", "incomplete: the search budget was hit")
        run["marks"].append([len(ticks) - 1, f"the first recorded transition no run explains: {why}"])
        run["summary"] = f"the model's run up to the furthest point of {name} explained: {len(verdict.steps)} tick(s)"
        entry = {"name": f"conform --log {name}", "verdict": "does not conform" if not verdict.incomplete
                 else "incomplete", "cls": "violated" if not verdict.incomplete else "undecided",
                 "summary": text, "run": 0}
    return {"title": f"btfsm conform --log {name} {model.name}", "verdicts": [entry], "runs": [run],
            "notes": [f"recorded by {'BehaviorTree.CPP (FileLogger2)' if verdict.engine == 'btcpp' else 'py_trees'}; "
                      f"checked under {verdict.semantics}"]}
