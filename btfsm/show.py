"""Pictures of a model: the behavior tree and each FSM as Graphviz dot, svg or png.

``tree_to_dot(model)`` draws the tree (and every FSM state's subtree, in a box of its
own); ``fsm_to_dot(model, fsm)`` draws one FSM. Both return dot text, which needs no
Graphviz; ``render`` turns it into svg or png with the ``dot`` program.

Tree notation: ``->`` sequence, ``?`` fallback, ``=>`` parallel; a ``*`` marks the memory
variants (``->*``, ``?*``), the reactive ones have none. Decorators are hexagons,
conditions ellipses with their expression, actions boxes with their primitive, skill
requests bold boxes with ``fsm.goal(params)``. FSM notation: states are rounded boxes with
their primitive, an arrow from a dot marks the initial state, terminal states have a
double border; edges are labelled goals / trigger [guard] / effects, direct edges are
dashed, ``*`` means every goal of the FSM; markers are small double circles (S or F,
the reply) hanging off their state.

>>> from btfsm import *
>>> m = Model("m", tree=ReactiveSequence("root", [Condition("c", "true"), Action("a", outcomes=[success()])]))
>>> "->" in tree_to_dot(m) and '"c' in tree_to_dot(m)
True
"""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path
from typing import Any, cast

from .bt import Action, Composite, Condition, Decorator, Effects, Guard, Parallel, Repeat, Retry, SkillRequest
from .errors import UsageError
from .escape import dot_string
from .expr import Expr, to_text
from .fsm import FSM

__all__ = ["tree_to_dot", "fsm_to_dot", "pictures", "render", "GraphvizError", "args_show", "cli_show"]

RENDER_TIMEOUT = 60  # seconds for one dot run

_TRIGGER_COLOR = {"success": "black", "failure": "firebrick", "running": "royalblue", "direct": "gray30"}


class GraphvizError(UsageError):
    """Graphviz is missing or failed (exit code 2 on the command line)."""


def _attrs(**kw) -> str:
    return "[" + ", ".join(f"{k}={dot_string(v)}" for k, v in kw.items() if v is not None) + "]"


def _effects_text(effects) -> list:
    return [f"{name} := {to_text(e)}" for name, e in effects]


def _args_text(args) -> str:
    return ", ".join(f"{k}={_constant(v)}" for k, v in args)


def _constant(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (tuple, list)):
        return "[" + ", ".join(_constant(x) for x in v) + "]"
    return "null" if v is None else str(v)


# ============================================================================ tree


def _node_look(n) -> dict:
    """dot attributes (shape, label, style) of one tree node."""
    if isinstance(n, Composite) and n.glyph:  # the classes' symbols (btfsm.bt): -> ? ...
        return {"shape": "box", "label": f"{n.glyph}\n{n.name}", "style": "filled", "fillcolor": "gray92"}
    if isinstance(n, Parallel):
        s = "all" if n.success_threshold is None else n.success_threshold
        s = f"S={','.join(n.selected)}" if n.selected else f"S>={s}"
        sync = " sync" if n.synchronise else ""
        return {"shape": "box", "label": f"=>\n{n.name}\n{s} F>={n.failure_threshold}{sync}", "style": "filled", "fillcolor": "gray92"}
    if isinstance(n, Composite):  # SequenceWithMemory, ParallelAll, IfThenElse, WhileDoElse
        extra = f"\nfailures>={n.max_failures}" if hasattr(n, "max_failures") else ""
        return {"shape": "box", "label": f"{type(n).__name__}\n{n.name}{extra}", "style": "filled", "fillcolor": "gray92"}
    if isinstance(n, Decorator):
        if isinstance(n, Retry):
            head = f"Retry x{n.attempts}"
        elif isinstance(n, Repeat):
            head = f"Repeat x{n.times}"
        elif isinstance(n, Guard):
            head = f"Guard [{to_text(cast(Expr, n.condition))}]"
        elif isinstance(n, Effects):
            lines = [f"{f[3:]}: {t}" for f in ("on_start", "on_success", "on_failure", "on_halt")
                     for t in _effects_text(getattr(n, f))]
            head = "\n".join(["Effects"] + lines)
        else:
            head = n.glyph or type(n).__name__
        return {"shape": "hexagon", "label": f"{head}\n{n.name}", "style": "filled", "fillcolor": "lavender"}
    if isinstance(n, Condition):
        return {"shape": "ellipse", "label": f"{n.name}\n{to_text(cast(Expr, n.expr))}", "style": "filled", "fillcolor": "lightyellow"}
    if isinstance(n, Action):
        call = f"{n.primitive}({_args_text(n.args)})"
        outs = f"\n[{', '.join(o.name for o in n.outcomes)}]" if n.outcomes is not None else ""
        return {"shape": "box", "label": f"{n.name}\n{call}{outs}", "style": "rounded,filled", "fillcolor": "lightblue"}
    if isinstance(n, SkillRequest):
        params = ", ".join(f"{k}={to_text(e)}" for k, e in cast("tuple[tuple[str, Expr], ...]", n.params))
        lines = [n.name, f"{n.fsm}.{n.goal}({params})"]
        if n.pre is not None:
            lines.append(f"pre: {to_text(cast(Expr, n.pre))}")
        if n.post is not None:
            lines.append(f"post: {to_text(cast(Expr, n.post))}")
        return {"shape": "box", "label": "\n".join(lines), "style": "bold,filled", "fillcolor": "palegreen"}
    return {"shape": "box", "label": f"{type(n).__name__}\n{n.name}"}


def _tree_lines(root, indent: str) -> list:
    out, stack = [], [root]
    while stack:
        n = stack.pop()
        out.append(f"{indent}{dot_string('n:' + n.name)} {_attrs(id=n.name, tooltip=type(n).__name__, **_node_look(n))};")
        kids = [c for c in n.children_of() if c is not None]
        for k, c in enumerate(kids):
            label = str(k + 1) if len(kids) > 1 else None
            out.append(f"{indent}{dot_string('n:' + n.name)} -> {dot_string('n:' + c.name)} {_attrs(taillabel=label)};")
        stack.extend(reversed(kids))
    return out


def tree_to_dot(model) -> str:
    """The tree as dot: the main tree, then each FSM state's subtree in its own box."""
    lines = [f"digraph {dot_string(model.name + ' tree')} {{",
             f"  graph {_attrs(label=f'{model.name}: tree', labelloc='t', fontname='Helvetica', ordering='out')};",
             f"  node {_attrs(fontname='Helvetica', fontsize='10')};",
             f"  edge {_attrs(arrowsize='0.6', fontsize='8', fontname='Helvetica')};"]
    roots = model.roots()
    if not roots:
        lines.append(f"  {dot_string('empty')} {_attrs(shape='note', label='(this model has no tree)')};")
    for k, (path, root) in enumerate(roots):
        if path == "tree":
            lines += _tree_lines(root, "  ")
        else:
            lines.append(f"  subgraph {dot_string(f'cluster_{k}')} {{")
            lines.append(f"    graph {_attrs(label=path, style='dashed', fontsize='9')};")
            lines += _tree_lines(root, "    ")
            lines.append("  }")
    lines.append("}")
    return "\n".join(lines) + "\n"


# ============================================================================ FSMs


def _goals_text(goals, fsm: FSM) -> str:
    if len(fsm.goals) > 1 and set(goals) == set(fsm.goals):
        return "*"
    return ", ".join(goals)


def _state_label(st) -> str:
    if st.subtree is not None:
        return f"{st.id}\n[subtree {st.subtree.name}]"
    prim = st.primitive or (st.id if st.outcomes is not None else "")
    if not prim:
        return st.id
    return f"{st.id}\n{prim}({_args_text(st.args)})"


def _trigger(el) -> str:
    return "direct" if el.direct else el.on.name.lower()


def _head(trigger: str, guard) -> str:
    return trigger + (f" [{to_text(guard)}]" if guard is not None else "")


def fsm_to_dot(model, fsm) -> str:
    """One FSM (an FSM object or its name) as dot."""
    f = model.fsm(fsm) if isinstance(fsm, str) else fsm
    extras = []
    if f.params:
        extras.append("params: " + ", ".join(f"{p.name} ({p.describe_domain()})" for p in f.params))
    if f.retarget != "immediate":
        extras.append(f"retarget: {f.retarget} via '{f.withdraw_goal}'")
    title = "\n".join([f"{model.name}: FSM {f.name}", "goals: " + ", ".join(f.goals)] + extras)
    lines = [f"digraph {dot_string('fsm ' + f.name)} {{",
             f"  graph {_attrs(label=title, labelloc='t', rankdir='LR', fontname='Helvetica')};",
             f"  node {_attrs(fontname='Helvetica', fontsize='10')};",
             f"  edge {_attrs(fontname='Helvetica', fontsize='8', arrowsize='0.7')};",
             f"  {dot_string('start')} {_attrs(shape='point', width='0.12', label='')};",
             f"  {dot_string('start')} -> {dot_string('s:' + f.initial)} {_attrs(tooltip='initial state')};"]
    for st in f.states:
        look: Any = {"shape": "box", "style": "rounded", "label": _state_label(st)}
        if st.id in f.terminal:
            look["peripheries"] = "2"
        if st.id == f.initial:
            look["style"] = "rounded,bold"
        lines.append(f"  {dot_string('s:' + st.id)} {_attrs(id=f'state:{st.id}', tooltip=st.id, **look)};")
    for e in f.edges:
        trig = _trigger(e)
        label = "\n".join([_goals_text(e.goals, f), _head(trig, e.guard)] + _effects_text(e.effects))
        colour = _TRIGGER_COLOR[trig]
        look = _attrs(id=f"edge:{e.id}", tooltip=e.id, label=label, style="dashed" if e.direct else None,
                      color=colour, fontcolor=colour)
        lines.append(f"  {dot_string('s:' + e.source)} -> {dot_string('s:' + e.target)} {look};")
    for k, m in enumerate(f.markers):
        ok = m.outcome.name == "SUCCESS"
        node, colour = f"m:{k}", "darkgreen" if ok else "firebrick"
        look = _attrs(id=f"marker:{m.id}", tooltip=m.id, shape="doublecircle", label="S" if ok else "F", width="0.25",
                      fixedsize="true", fontsize="8", style="filled", fillcolor="palegreen" if ok else "mistyrose")
        lines.append(f"  {dot_string(node)} {look};")
        label = f"{_goals_text(m.goals, f)}\n{_head(_trigger(m), m.guard)}"
        look = _attrs(label=label, style="dashed" if m.direct else "dotted", arrowhead="dot", color=colour, fontcolor=colour)
        lines.append(f"  {dot_string('s:' + m.state)} -> {dot_string(node)} {look};")
    lines.append("}")
    return "\n".join(lines) + "\n"


# ============================================================================ rendering and the command


def pictures(model, what: str = "all") -> list:
    """``[(file stem, dot text)]`` for ``what``: ``tree``, an FSM name, or ``all``."""
    names = [f.name for f in model.fsms]
    if what == "tree":
        return [("tree", tree_to_dot(model))]
    if what == "all":
        out = [("tree", tree_to_dot(model))] if model.roots() or not names else []
        return out + [(f"fsm_{n}", fsm_to_dot(model, n)) for n in names]
    if what in names:
        return [(f"fsm_{what}", fsm_to_dot(model, what))]
    raise UsageError(f"--what: '{what}' is not 'tree', 'all' or an FSM of {model.name} ({', '.join(names) or 'it has none'})")


def render(dot_text: str, fmt: str, timeout: float = RENDER_TIMEOUT) -> bytes:
    """svg or png bytes from dot text, with Graphviz's ``dot`` (input on stdin)."""
    exe = shutil.which("dot")
    if exe is None:
        raise GraphvizError(f"Graphviz is not installed (no 'dot' program on PATH), so --format {fmt} is not available; "
                            "install graphviz, or use --format dot and render elsewhere")
    try:
        proc = subprocess.run([exe, f"-T{fmt}"], input=dot_text.encode("utf-8"), capture_output=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        raise GraphvizError(f"Graphviz 'dot' took longer than {timeout:g} s") from None
    except OSError as exc:
        raise GraphvizError(f"cannot run Graphviz 'dot': {exc}") from None
    if proc.returncode != 0:
        msg = " ".join(proc.stderr.decode("utf-8", "replace").split())[:300]
        raise GraphvizError(f"Graphviz 'dot' failed (exit {proc.returncode}): {msg}")
    return proc.stdout


def args_show(sp) -> None:
    """The flags of ``btfsm show`` (``btfsm.cli.COMMANDS``)."""
    from . import cliargs
    from .validators import input_text

    cliargs.model(sp)
    sp.add_argument("--format", choices=("dot", "svg", "png"), default="dot")
    sp.add_argument("--output", "-o", type=input_text,
                    help="a name ending in .dot, .svg or .png is a file (one picture, matching --format); "
                         "any other name is a folder, created if missing, with one file per picture "
                         "(default: stdout for dot)")
    sp.add_argument("--what", default="all", type=input_text, help="'tree', an FSM name, or 'all'")


def cli_show(args) -> int:
    """``btfsm show MODEL --format dot|svg|png [--output PATH] [--what tree|FSM|all]``.

    ``--output`` ending in ``.dot``, ``.svg`` or ``.png`` is one file (it must match
    ``--format`` and the pictures must be one); any other name is a folder, created if
    missing, with one ``NAME.FORMAT`` file per picture. Files are written atomically."""
    from .files import load_cli_model

    fmt, output = args.format, args.output
    if fmt != "dot" and shutil.which("dot") is None:
        render("", fmt)  # raises GraphvizError with the explanation
    model = load_cli_model(args)
    pics = pictures(model, args.what)
    if output is None:
        if fmt == "dot":
            sys.stdout.write("".join(text for _, text in pics))
            return 0
        if fmt == "svg" and len(pics) == 1:
            sys.stdout.write(render(pics[0][1], fmt).decode("utf-8"))
            return 0
        raise UsageError(f"--format {fmt} needs --output (a file, or a folder for several pictures)")
    from .outputs import atomic_write_bytes, ensure_output_dir

    # The rule: a name ending in .dot, .svg or .png is one file; any other name is a folder.
    suffix = Path(output).suffix.lower()
    if suffix in (".dot", ".svg", ".png"):
        if suffix != f".{fmt}":
            raise UsageError(f"--output {output}: a {suffix} file does not match --format {fmt}")
        if len(pics) > 1:
            raise UsageError(f"--output {output} names one file but --what {args.what} draws {len(pics)} pictures; "
                             f"name a folder, or pick one picture with --what")
        targets = [(Path(output), pics[0][1])]
    else:
        ensure_output_dir(output)
        targets = [(Path(output) / f"{stem}.{fmt}", text) for stem, text in pics]
    for path, text in targets:
        atomic_write_bytes(path, text.encode("utf-8") if fmt == "dot" else render(text, fmt))
        print(path)
    return 0
