"""``btfsm sweep`` (issue 12.4): the experiment over a grid of cell parameters on Dask.

The table must not depend on what runs the trials (this process, a process pool, an
embedded Dask cluster of 1 or 2 workers); an interrupted sweep continues from its cache;
bad grids are one-line errors (exit 2). Trials are shortened (60 simulated seconds).
"""
from __future__ import annotations

import csv
import os

import pytest

from btfsm.cli import main
from btfsm.sim.sweep import WINDOW_M, cached, grid, run_sweep, write_table

SPECS = grid(("preemptive", "baseline"), [1], belt_speed=(0.2, 0.25), time_limit=60.0)


def _table(tmp_path, name, results):
    folder = tmp_path / name
    csv_path, pq_path = write_table(SPECS, results, str(folder))
    return open(csv_path, encoding="utf-8").read(), pq_path


def test_grid_couples_the_window_to_the_belt_speed():
    assert [s.pick_window for s in SPECS] == [16.0, 16.0, WINDOW_M / 0.25, WINDOW_M / 0.25]
    assert len(grid(("preemptive",), [1, 2], belt_speed=(0.2,), speed_scale=(0.4, 0.5), pick_window=(16.0,))) == 4


def test_the_table_is_the_same_whatever_runs_it(tmp_path):
    pytest.importorskip("distributed")
    inline = run_sweep(SPECS, engine="inline", progress=False)
    ref, pq_path = _table(tmp_path, "inline", inline)
    for name, kw in [("pool", dict(engine="processes", workers=2)), ("dask1", dict(engine="dask", workers=1)),
                     ("dask2", dict(engine="dask", workers=2))]:
        res = run_sweep(SPECS, progress=False, **kw)
        assert _table(tmp_path, name, res)[0] == ref, name
    pq = pytest.importorskip("pyarrow.parquet")
    t = pq.read_table(pq_path)
    assert t.num_rows == 4 and t.column("belt_speed").to_pylist() == [0.2, 0.2, 0.25, 0.25]
    assert t.column("lost").to_pylist() == [r.lost for r in inline]


def test_an_interrupted_sweep_continues_from_its_cache(tmp_path, monkeypatch):
    folder = str(tmp_path / "out")
    first = run_sweep(SPECS[:2], engine="inline", folder=folder, progress=False)
    assert set(cached(SPECS, folder)) == {0, 1}
    ran = []
    import btfsm.sim.sweep as sweep

    real = sweep.run_spec
    monkeypatch.setattr(sweep, "run_spec", lambda spec: ran.append(spec) or real(spec))
    again = run_sweep(SPECS, engine="inline", folder=folder, progress=False)
    assert ran == SPECS[2:]  # only the trials not cached ran
    assert again[:2] == first
    # a cache file of another spec (tampered) is not taken
    path = next(p for p in os.listdir(os.path.join(folder, "cache")) if p.startswith("preemptive"))
    full = os.path.join(folder, "cache", path)
    text = open(full, encoding="utf-8").read().replace('"belt_speed": 0.2', '"belt_speed": 0.21')
    open(full, "w", encoding="utf-8").write(text)
    assert 0 not in cached(SPECS, folder)


def test_cli_writes_table_parquet_and_figure(tmp_path, capsys):
    out = tmp_path / "sw"
    assert main(["sweep", "--belt-speed", "0.2", "--variant", "preemptive", "--time", "60", "--engine", "inline",
                 "--out", str(out), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "preemptive" in printed and "table:" in printed
    rows = list(csv.DictReader(open(out / "sweep.csv", encoding="utf-8")))
    assert len(rows) == 1 and rows[0]["belt_speed"] == "0.2" and rows[0]["pick_window"] == "16.0"
    assert (out / "lost_vs_belt_speed.png").stat().st_size > 1000


@pytest.mark.parametrize("argv,msg", [
    (["sweep", "--belt-speed", "0.3", "--pick-window", "16"], "out of the arm's reach"),
    (["sweep", "--belt-speed", "0"], "--belt-speed"),
    (["sweep", "--engine", "ray"], "--engine"),
    (["sweep", "--speed-scale", "2"], "--speed-scale"),
])
def test_bad_grids_exit_2(tmp_path, capsys, argv, msg):
    assert main(argv + ["--out", str(tmp_path / "o"), "--engine" if "--engine" not in argv else "--quiet",
                        *(["inline"] if "--engine" not in argv else [])]) == 2
    err = capsys.readouterr().err
    assert msg in err and "Traceback" not in err
