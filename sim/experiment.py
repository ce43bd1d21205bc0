"""The paper's ARIAC experiment: trials, parallel execution, statistics, files, figure.

Protocol (Wuthier et al., ICRA 2021): put 18 parts on the AGV tray (9 from bin 2, 9 from
bin 3) while conveyor parts are detected every dTa = 30 + 0.2 k seconds, k = 1..40, one
trial per k and per variant (preemptive, memory baseline); a conveyor part must be taken
off the belt within the pick window dt* = 16 s or it is lost.

Every trial is seeded from (variant, k) only, so results do not depend on the number of
worker processes or their order (``test_results_independent_of_workers``).

Resuming: with ``save_dir`` each finished trial is saved at once (atomically) as
``save_dir/trials/VARIANT-kNN.json`` holding its spec and result; ``load_finished`` reads
back those whose spec matches, so an interrupted experiment re-run with the same folder
runs only the missing trials and gives the same results as an uninterrupted run.
"""
from __future__ import annotations

import csv
import json
import os
import statistics
import sys
from dataclasses import asdict
from typing import Iterable, Sequence

from .protocol import VARIANTS, TrialResult, TrialSpec, arrival_period

__all__ = ["TrialSpec", "TrialResult", "PAPER", "VARIANTS", "trial_specs", "run_experiment",
           "summarize", "format_table", "write_results", "plot_reaction_times", "arrival_period",
           "trial_file", "save_trial", "load_finished", "TRIAL_FILE_FORMAT"]

#: Version of the per-trial files in ``OUT/trials/``; files of another version are ignored.
#: 2 since the ARIAC cell became a scene file (2026-11-25): trials of the pymunk cell are run again.
TRIAL_FILE_FORMAT = 2

# The paper's figures over its 80 trials, as the project brief quotes them.
PAPER = {
    "skills": 3134, "preemptions": 150,
    "conveyor_picks": {"preemptive": 234, "baseline": 205},
    "lost": {"preemptive": 0, "baseline": 17},
    "max_reaction_fraction": 0.75,
}


def trial_specs(ks: Sequence[int] = tuple(range(1, 41)), variants: Sequence[str] = VARIANTS, **kw) -> list:
    return [TrialSpec(v, k, **kw) for v in variants for k in ks]


def _run_one(spec: TrialSpec) -> TrialResult:
    from .trial import run_trial

    return run_trial(spec)


def trial_file(folder: str, spec: TrialSpec) -> str:
    """Where a finished trial of ``spec`` is saved under ``folder``."""
    return os.path.join(folder, "trials", f"{spec.variant}-k{spec.k:02d}.json")


def save_trial(folder: str, spec: TrialSpec, result: TrialResult) -> str:
    """Save a finished trial (atomically); return its path."""
    from btfsm.outputs import atomic_write_text

    path = trial_file(folder, spec)
    atomic_write_text(path, json.dumps({"format": TRIAL_FILE_FORMAT, "spec": asdict(spec),
                                        "result": asdict(result)}, indent=1) + "\n")
    return path


def load_finished(specs: Sequence[TrialSpec], folder: str) -> dict:
    """``{index in specs: TrialResult}`` for the trials saved in ``folder`` whose spec matches
    exactly; unreadable, foreign or outdated files are ignored (those trials run again)."""
    found = {}
    for i, spec in enumerate(specs):
        try:
            with open(trial_file(folder, spec), encoding="utf-8") as fh:
                data = json.load(fh)
            if (isinstance(data, dict) and data.get("format") == TRIAL_FILE_FORMAT
                    and data.get("spec") == asdict(spec) and isinstance(data.get("result"), dict)):
                result = TrialResult(**data["result"])
                if (result.variant, result.k) == (spec.variant, spec.k):
                    found[i] = result
        except (OSError, ValueError, TypeError):
            continue
    return found


def run_experiment(specs: Sequence[TrialSpec], workers: int = 1, progress: bool = True,
                   save_dir: "str | None" = None, finished: "dict | None" = None) -> list:
    """Run trials (in ``workers`` processes); results come back in ``specs`` order.

    ``finished`` (``{index: TrialResult}``, from ``load_finished``) are taken as they are;
    with ``save_dir`` each newly finished trial is saved there as soon as it completes.
    ``progress``: a bar with an ETA on stderr (``btfsm.progress``; on a terminal only)."""
    from btfsm.progress import progress_bar

    specs = list(specs)
    results: list = [None] * len(specs)
    for i, res in (finished or {}).items():
        results[i] = res
    todo = [(i, spec) for i, spec in enumerate(specs) if results[i] is None]
    with progress_bar(len(specs), desc="trials", unit=" trial", disable=not progress, leave=True) as bar:
        bar.update(len(specs) - len(todo))

        def finish(i, res):
            results[i] = res
            if save_dir is not None:
                save_trial(save_dir, specs[i], res)
            bar.update(1)

        if workers <= 1 or len(todo) <= 1:
            for i, spec in todo:
                finish(i, _run_one(spec))
        else:
            import multiprocessing as mp

            ctx = mp.get_context("fork" if sys.platform.startswith("linux") else "spawn")
            with ctx.Pool(min(workers, len(todo)), initializer=_worker_init) as pool:
                for i, res in pool.imap_unordered(_indexed, todo):
                    finish(i, res)
    return results


def _worker_init():
    """Workers leave Ctrl-C and SIGTERM to the parent, which stops the pool (no worker tracebacks)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _indexed(item):
    i, spec = item
    return i, _run_one(spec)


def summarize(results: Iterable[TrialResult]) -> dict:
    """Per variant: totals and reaction-time statistics."""
    out = {}
    for variant in VARIANTS:
        rs = [r for r in results if r.variant == variant]
        if not rs:
            continue
        times = sorted(t for r in rs for t in r.reaction_times)
        window = 16.0
        out[variant] = {
            "trials": len(rs),
            "completed": sum(r.completed for r in rs),
            "skills": sum(r.skills for r in rs),
            "preemptions": sum(r.preemptions for r in rs),
            "conveyor_arrivals": sum(r.conveyor_arrivals for r in rs),
            "conveyor_picks": sum(r.conveyor_picks for r in rs),
            "lost": sum(r.lost for r in rs),
            "reaction_min": times[0] if times else None,
            "reaction_median": statistics.median(times) if times else None,
            "reaction_max": times[-1] if times else None,
            "reaction_max_fraction": (times[-1] / window) if times else None,
            "sim_time": sum(r.sim_time for r in rs),
            "conformance_errors": sum(bool(r.conformance_error) for r in rs),
        }
    return out


def format_table(summary: dict, paper: dict = PAPER) -> str:
    """A text table of our figures beside the paper's."""
    rows = [("trials (completed)", lambda s, v: f"{s['trials']} ({s['completed']})", lambda v: "40"),
            ("skills executed", lambda s, v: str(s["skills"]), lambda v: f"{paper['skills']} (both)"),
            ("preemptions", lambda s, v: str(s["preemptions"]), lambda v: f"{paper['preemptions']} (both)"),
            ("conveyor parts detected", lambda s, v: str(s["conveyor_arrivals"]), lambda v: "-"),
            ("conveyor picks", lambda s, v: str(s["conveyor_picks"]), lambda v: str(paper["conveyor_picks"][v])),
            ("parts lost", lambda s, v: str(s["lost"]), lambda v: str(paper["lost"][v])),
            ("reaction min / median / max [s]", lambda s, v: _rt(s), lambda v: "-"),
            ("max reaction / dt* (16 s)", lambda s, v: _pct(s["reaction_max_fraction"]),
             lambda v: f"{paper['max_reaction_fraction']:.0%}" if v == "preemptive" else "-")]
    n_paper = paper.get("trials", 40)
    head = f"{'':34s}" + "".join(f"{v + ' (ours)':>20s}{v + ' (paper)':>20s}" for v in summary)
    counts = f"{'totals over':34s}" + "".join(f"{_trials(summary[v]['trials']):>20s}{_trials(n_paper):>20s}"
                                               for v in summary)
    lines = [head, counts, "-" * len(head)]
    for label, ours, theirs in rows:
        lines.append(f"{label:34s}" + "".join(f"{ours(summary[v], v):>20s}{theirs(v):>20s}" for v in summary))
    ns = sorted({summary[v]["trials"] for v in summary})
    if ns != [n_paper]:
        totals = " or ".join(_trials(n) for n in ns)
        lines.append(f"note: ours are totals over {totals} per variant, the paper's over {n_paper}: "
                     "compare counts per trial, not the totals")
    return "\n".join(lines)


def _trials(n: int) -> str:
    return f"{n} trial" + ("" if n == 1 else "s")


def _rt(s) -> str:
    if s["reaction_min"] is None:
        return "-"
    return f"{s['reaction_min']:.1f}/{s['reaction_median']:.1f}/{s['reaction_max']:.1f}"


def _pct(x) -> str:
    return "-" if x is None else f"{x:.0%}"


def write_results(results: Sequence[TrialResult], out_dir: str) -> tuple:
    """Write trials.csv and trials.json (every trial) into ``out_dir`` atomically; return the paths."""
    from btfsm.outputs import atomic_writer, ensure_output_dir

    ensure_output_dir(out_dir)
    csv_path, json_path = os.path.join(out_dir, "trials.csv"), os.path.join(out_dir, "trials.json")
    fields = [f for f in TrialResult.__dataclass_fields__ if f != "reaction_times"] + ["reaction_times"]
    with atomic_writer(csv_path, newline="") as fh:
        w = csv.writer(fh)
        w.writerow(fields)
        for r in results:
            d = asdict(r)
            d["reaction_times"] = " ".join(f"{t:.3f}" for t in r.reaction_times)
            w.writerow([d[f] for f in fields])
    with atomic_writer(json_path) as fh:
        json.dump([asdict(r) for r in results], fh, indent=1)
    return csv_path, json_path


def plot_reaction_times(results: Sequence[TrialResult], path: str, window: float = 16.0) -> str:
    """Histogram of reaction times (detection to removal from the belt) per variant."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7, 4), dpi=120)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    bins = [i * 0.5 for i in range(int(window * 2) + 3)]
    for variant, colour in zip(VARIANTS, ("tab:blue", "tab:orange")):
        times = [t for r in results if r.variant == variant for t in r.reaction_times]
        lost = sum(r.lost for r in results if r.variant == variant)
        if times or lost:
            ax.hist(times, bins=bins, alpha=0.6, color=colour, label=f"{variant} ({len(times)} picked, {lost} lost)")
    ax.axvline(window, color="red", linestyle="--", label=f"pick window dt* = {window:g} s")
    ax.set_xlabel("reaction time: detection to removal from the belt [s]")
    ax.set_ylabel("conveyor parts")
    from matplotlib.ticker import MaxNLocator

    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_title("Reaction times, preemptive vs memory baseline")
    ax.legend(fontsize=8)
    fig.tight_layout()
    from btfsm.outputs import atomic_path

    with atomic_path(path) as tmp:
        fig.savefig(tmp)
    return path
