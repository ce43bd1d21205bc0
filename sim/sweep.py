"""Parameter sweeps of the ARIAC experiment on Dask: ``btfsm sweep``.

A sweep is the experiment (``btfsm.sim.trial.run_trial``) over a grid of trial parameters
(``TrialSpec``: belt speed, arrival period, the arm's speed scale, the pick window dt*, the
trial index k, which also seeds the trial, and the variant). Each trial depends on its
spec alone, so the table is the same whatever runs it:

* ``dask`` (default): an embedded ``distributed.LocalCluster`` (worker processes, one
  thread each, no dashboard), or the running cluster at ``scheduler`` (``tcp://HOST:PORT``);
* ``processes``: a local process pool (also the fallback when dask is not installed);
* ``inline``: this process (tests, one worker).

Every finished trial is saved at once under ``DIR/cache/`` (named by a hash of its spec, the
spec stored beside the result and compared in full when read back), so an interrupted sweep
continues where it stopped. The table (``sweep.csv``, ``sweep.parquet``: one row per trial,
the parameters then the results) and the figure (lost parts against belt speed, per
variant) are written atomically at the end.

>>> [ (s.variant, s.belt_speed) for s in grid(["preemptive"], [1], belt_speed=[0.2, 0.3])]
[('preemptive', 0.2), ('preemptive', 0.3)]
"""
from __future__ import annotations

import csv
import hashlib
import itertools
import json
import os
from dataclasses import asdict, fields

from .protocol import VARIANTS, TrialResult, TrialSpec

__all__ = ["grid", "run_sweep", "cached", "write_table", "plot_lost", "check_geometry", "PARAMS", "ENGINES",
           "CACHE_FORMAT", "WINDOW_M"]

PARAMS = ("belt_speed", "period", "speed_scale", "pick_window")
WINDOW_M = 0.2 * 16.0  # metres of belt a part rides within the arm's reach after detection (default cell)
ENGINES = ("dask", "processes", "inline")
CACHE_FORMAT = "btfsm-sweep-trial/2"  # /2: the ARIAC cell is a scene file (trials of the pymunk cell run again)


def grid(variants=VARIANTS, ks=(1,), *, belt_speed=(0.2,), period=(None,), speed_scale=(0.5,), pick_window=(None,),
         time_limit: float = 1500.0) -> list:
    """The trial specs of a grid, in a fixed order (parameters, then variant, then k). A pick
    window None is the time the belt takes to carry a part through the arm's reach:
    ``WINDOW_M / belt_speed`` (16 s at 0.2 m/s; a faster belt gives a shorter window)."""
    out = []
    for bs, per, sc, pw in itertools.product(belt_speed, period, speed_scale, pick_window):
        pw = WINDOW_M / bs if pw is None else pw
        for v in variants:
            for k in ks:
                out.append(TrialSpec(v, k, pick_window=pw, time_limit=time_limit, belt_speed=bs, speed_scale=sc,
                                     period=per))
    return out


def check_geometry(specs) -> None:
    """ValueError naming the first spec whose cell cannot be laid out (a pick window that
    ends out of the arm's reach)."""
    from btfsm.errors import ModelError

    from .trial import build_trial

    seen = set()
    for s in specs:
        key = (s.belt_speed, s.pick_window, s.physics_rate)
        if key in seen:
            continue
        seen.add(key)
        try:
            build_trial(s)
        except ModelError as exc:
            raise ValueError(f"belt speed {s.belt_speed:g} m/s with pick window {s.pick_window:g} s: "
                             f"{exc.problem}") from None


def run_spec(spec: TrialSpec) -> TrialResult:
    """One trial (what a worker runs)."""
    from .trial import run_trial

    return run_trial(spec)


def _key(spec: TrialSpec) -> str:
    return hashlib.sha256(json.dumps(asdict(spec), sort_keys=True).encode()).hexdigest()[:20]


def _cache_path(folder: str, spec: TrialSpec) -> str:
    return os.path.join(folder, "cache", f"{spec.variant}-k{spec.k:02d}-{_key(spec)}.json")


def _save(folder: str, spec: TrialSpec, result: TrialResult) -> None:
    from btfsm.outputs import atomic_write_text

    atomic_write_text(_cache_path(folder, spec), json.dumps({"format": CACHE_FORMAT, "spec": asdict(spec),
                                                              "result": asdict(result)}, indent=1) + "\n")


def cached(specs, folder: str) -> dict:
    """``{index: TrialResult}`` of the trials of ``specs`` saved under ``folder`` whose spec
    matches exactly; unreadable or foreign files are ignored (those trials run again)."""
    found = {}
    for i, spec in enumerate(specs):
        try:
            with open(_cache_path(folder, spec), encoding="utf-8") as fh:
                data = json.load(fh)
            if data.get("format") == CACHE_FORMAT and data.get("spec") == asdict(spec):
                found[i] = TrialResult(**data["result"])
        except (OSError, ValueError, TypeError, AttributeError):
            continue
    return found


def run_sweep(specs, *, engine: str = "dask", workers: int = 2, scheduler: "str | None" = None,
              folder: "str | None" = None, progress: bool = True) -> list:
    """Results of ``specs`` in order. Trials cached under ``folder`` are reused; each new one
    is saved there as soon as it finishes."""
    from btfsm.progress import progress_bar

    specs = list(specs)
    results: list = [None] * len(specs)
    if folder is not None:
        for i, r in cached(specs, folder).items():
            results[i] = r
    todo = [i for i, r in enumerate(results) if r is None]
    with progress_bar(len(specs), desc="trials", unit=" trial", disable=not progress, leave=True) as bar:
        bar.update(len(specs) - len(todo))

        def finish(i, res):
            results[i] = res
            if folder is not None:
                _save(folder, specs[i], res)
            bar.update(1)

        if not todo:
            pass
        elif engine == "inline" or (engine == "processes" and workers <= 1):
            from btfsm.signals import check as check_signals

            for i in todo:
                check_signals()
                finish(i, run_spec(specs[i]))
        elif engine == "dask" and dask_installed():
            _run_dask(specs, todo, workers, scheduler, finish)
        elif engine in ("dask", "processes"):
            _run_pool(specs, todo, workers, finish)
        else:
            raise ValueError(f"engine must be one of {', '.join(ENGINES)}, not {engine!r}")
    return results


def dask_installed() -> bool:
    """Dask's distributed scheduler can be imported (else the dask engine runs a process pool)."""
    import importlib.util

    return importlib.util.find_spec("distributed") is not None


def _run_dask(specs, todo, workers, scheduler, finish):
    import logging

    from distributed import Client, LocalCluster, as_completed

    if scheduler:
        client, cluster = Client(scheduler), None
    else:
        # no dashboard, no memory monitor (memory_limit=0): neither is used here, and on a
        # small machine their polling takes CPU from the trials
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                               memory_limit=0, silence_logs=logging.ERROR)
        client = Client(cluster)
    try:
        futures = client.map(run_spec, [specs[i] for i in todo], pure=False)
        index = {f.key: i for f, i in zip(futures, todo)}
        for fut in as_completed(futures):
            finish(index[fut.key], fut.result())
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _pool_init():
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _one(item):
    i, spec = item
    return i, run_spec(spec)


def _run_pool(specs, todo, workers, finish):
    import multiprocessing as mp
    import sys

    ctx = mp.get_context("fork" if sys.platform.startswith("linux") else "spawn")
    with ctx.Pool(min(workers, len(todo)), initializer=_pool_init) as pool:
        for i, res in pool.imap_unordered(_one, [(i, specs[i]) for i in todo]):
            finish(i, res)


def _columns():
    spec_cols = [f.name for f in fields(TrialSpec)]
    result_cols = [f.name for f in fields(TrialResult) if f.name not in ("variant", "k")]
    return spec_cols, result_cols


def _rows(specs, results) -> list:
    spec_cols, result_cols = _columns()
    rows = []
    for s, r in zip(specs, results):
        d = {c: getattr(s, c) for c in spec_cols}
        for c in result_cols:
            v = getattr(r, c)
            d[c] = " ".join(f"{t:.3f}" for t in v) if c == "reaction_times" else v
        rows.append(d)
    return rows


def write_table(specs, results, folder: str) -> tuple:
    """``sweep.csv`` and ``sweep.parquet`` in ``folder`` (atomically); their paths."""
    from btfsm.outputs import atomic_writer, ensure_output_dir

    ensure_output_dir(folder)
    rows = _rows(specs, results)
    cols = list(rows[0]) if rows else [c for group in _columns() for c in group]
    csv_path = os.path.join(folder, "sweep.csv")
    with atomic_writer(csv_path, newline="") as fh:
        w = csv.writer(fh)
        w.writerow(cols)
        for d in rows:
            w.writerow(["" if d[c] is None else d[c] for c in cols])
    pq_path = os.path.join(folder, "sweep.parquet")
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return csv_path, None
    table = pa.Table.from_pylist(rows) if rows else pa.table({c: [] for c in cols})
    tmp = pq_path + ".tmp"
    pq.write_table(table, tmp)
    os.replace(tmp, pq_path)
    return csv_path, pq_path


def plot_lost(specs, results, path: str, limits: "dict | None" = None) -> str:
    """Lost parts per trial against belt speed, one line per variant (mean, with each trial's
    count as a dot). ``limits``: ``{variant: speed_limit.Limit}``, each proved limit belt
    speed drawn as a dashed vertical line in its variant's colour."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from btfsm.outputs import atomic_writer

    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    below = []
    for variant in dict.fromkeys(s.variant for s in specs):
        pts = sorted((s.belt_speed, r.lost) for s, r in zip(specs, results) if s.variant == variant)
        speeds = sorted({p[0] for p in pts})
        means = [sum(l for v, l in pts if v == x) / sum(1 for v, _ in pts if v == x) for x in speeds]
        line, = ax.plot(speeds, means, marker="o", label=f"{variant} (mean per trial)")
        ax.scatter([p[0] for p in pts], [p[1] for p in pts], s=10, color=line.get_color(), alpha=0.4)
        lim = (limits or {}).get(variant)
        if lim is not None and lim.speed is not None:
            ax.axvline(lim.speed, color=line.get_color(), linestyle="--", linewidth=1,
                       label=f"{variant}: proved limit {'>= ' if lim.above else ''}{lim.speed:g} m/s")
        elif lim is not None:
            below.append(variant)
    if limits:  # the paper's claim, for comparison: the belt could run about 33 % faster than 0.2 m/s
        ax.axvline(0.2 * 4 / 3, color="grey", linestyle=":", linewidth=1, label="paper: about 33 % faster than 0.2 m/s")
    ax.set_xlabel("belt speed [m/s]")
    ax.set_ylabel("parts lost per trial")
    title = "ARIAC cell: lost belt parts against belt speed"
    if limits:
        title += "\ndashed: the fastest belt for which 'reach' is proved (every part reached within dt*)"
        if below:
            title += f"; none proved for {', '.join(below)}"
    ax.set_title(title, fontsize=8)
    ax.legend(fontsize=7)
    fig.tight_layout()
    with atomic_writer(path, "wb") as fh:
        fig.savefig(fh, format="png", dpi=100)
    plt.close(fig)
    return path
