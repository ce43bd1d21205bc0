"""Progress bars (btfsm.progress, tqdm): nothing unless stderr is a terminal; a bar on one.

A terminal is faked with a StringIO whose ``isatty()`` is true (tqdm writes to the
``file=`` it is given)."""
from __future__ import annotations

import io
import sys

import pytest

from btfsm.progress import ExplorationProgress, is_terminal, progress_bar


class FakeTTY(io.StringIO):
    def isatty(self):
        return True


def test_is_terminal():
    assert is_terminal(FakeTTY()) and not is_terminal(io.StringIO())
    closed = io.StringIO()
    closed.close()  # isatty() raises ValueError
    assert not is_terminal(closed) and not is_terminal(object())


@pytest.mark.parametrize("stream,shown", [(io.StringIO, False), (FakeTTY, True)])
def test_bar_with_a_total_shows_an_eta_on_a_terminal_only(stream, shown):
    out = stream()
    with progress_bar(10, desc="trials", unit=" trial", file=out, leave=True, mininterval=0) as bar:
        for _ in range(10):
            bar.update(1)
    text = out.getvalue()
    if not shown:
        assert text == ""
    else:
        assert "trials" in text and "10/10" in text and "<" in text  # elapsed<remaining: the ETA


def test_disabled_bar_prints_nothing_even_on_a_terminal():
    out = FakeTTY()
    with progress_bar(5, file=out, disable=True) as bar:
        bar.update(5)
    assert out.getvalue() == ""


@pytest.mark.parametrize("stream,shown", [(io.StringIO, False), (FakeTTY, True)])
def test_exploration_progress_callback(stream, shown):
    out = stream()
    p = ExplorationProgress(file=out, delay=0, mininterval=0)
    p("model", 1000, 2500, 0.5)
    p("model", 5000, 9000, 1.0)
    p("fsm arm", 40, None, 0.1)
    p.close()
    text = out.getvalue()
    if not shown:
        assert text == ""
    else:
        assert "model" in text and "5000" in text and "9,000 transitions (9,000/s)" in text and "fsm arm" in text


def test_exploration_progress_waits_for_its_delay():
    out = FakeTTY()
    with ExplorationProgress(file=out, delay=60) as p:
        p("model", 10, 20, 0.01)
    assert out.getvalue() == ""


def test_check_reports_progress_through_the_callback():
    """verify.report.check calls progress(what, states, transitions, seconds)."""
    from btfsm.files import load_model
    from btfsm.verify.report import check

    out = FakeTTY()
    with ExplorationProgress(file=out, delay=0) as p:
        report = check(load_model("two-area"), ["workable-reachability"], progress=p)
    assert report.states > 0
    assert "model" in out.getvalue() and "states" in out.getvalue()


def test_check_cli_prints_no_progress_when_stderr_is_not_a_terminal(capsys):
    from btfsm.cli import main

    assert main(["check", "two-area", "--property", "workable-reachability"]) == 0
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("terminal", [False, True])
def test_check_cli_bar_that_is_due_shows_on_a_terminal_only(terminal, monkeypatch, capsys):
    """The command's bar with no delay: on a (fake) terminal it shows, on a pipe nothing
    (tests/test_verify_cli.py shows the real bar of a 4-second exploration on a pty)."""
    import btfsm.progress as progress
    from btfsm.cli import main

    class Due(progress.ExplorationProgress):
        def __init__(self, file=None, delay=0.0, **options):
            super().__init__(file, delay, mininterval=0, **options)

    monkeypatch.setattr(progress, "ExplorationProgress", Due)
    if terminal:
        monkeypatch.setattr(sys, "stderr", FakeTTY())
    assert main(["check", "two-area", "--property", "workable-reachability"]) == 0
    shown = sys.stderr.getvalue() if terminal else capsys.readouterr().err
    assert ("model" in shown and "states" in shown) if terminal else shown == ""


def test_experiment_progress_bar(monkeypatch):
    """run_experiment: a bar with an ETA on a terminal; none with progress=False (--quiet)."""
    from btfsm.sim import experiment

    monkeypatch.setattr(experiment, "_run_one", lambda spec: spec.k)
    specs = experiment.trial_specs(ks=[1, 2, 3], variants=["preemptive"])
    for progress, tty in ((True, FakeTTY()), (False, FakeTTY()), (True, io.StringIO())):
        monkeypatch.setattr(sys, "stderr", tty)
        assert experiment.run_experiment(specs, workers=1, progress=progress) == [1, 2, 3]
        shown = tty.getvalue()
        assert ("3/3" in shown and "trials" in shown) if progress and tty.isatty() else shown == ""


def test_gif_rendering_progress_bar(tmp_path, monkeypatch):
    pytest.importorskip("matplotlib")
    pytest.importorskip("PIL")
    from btfsm.sim.scene import World, builtin_scene, load_scene
    from btfsm.sim.scene_render import write_gif

    world = World(load_scene(builtin_scene("ariac")), 1)
    snaps = [world.snapshot()]
    world.step()
    snaps.append(world.snapshot())
    tty = FakeTTY()
    monkeypatch.setattr(sys, "stderr", tty)
    assert write_gif(world.scene, snaps, tmp_path / "a.gif", fps=5) == 2
    assert "GIF frames" in tty.getvalue() and "/2 " in tty.getvalue()  # the total is known
    quiet = io.StringIO()
    monkeypatch.setattr(sys, "stderr", quiet)
    assert write_gif(world.scene, iter(snaps), tmp_path / "b.gif", fps=5) == 2
    assert quiet.getvalue() == ""
    assert (tmp_path / "b.gif").read_bytes()[:6] in (b"GIF87a", b"GIF89a")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.gif", "b.gif"]  # no temporary file left


def test_gif_into_a_folder_is_refused_before_drawing(tmp_path):
    pytest.importorskip("matplotlib")
    from btfsm.sim.scene import builtin_scene, load_scene
    from btfsm.sim.scene_render import write_gif

    def never():
        raise AssertionError("drew frames for an output that cannot be written")
        yield

    with pytest.raises(IsADirectoryError):
        write_gif(load_scene(builtin_scene("ariac")), never(), tmp_path, fps=5)
