"""Output files: complete or absent (temporary name, then rename), never a folder, a device
or the input model; ``show -o``'s file-or-folder rule."""
from __future__ import annotations

import errno
import json
import os
import shutil

import pytest

import btfsm.outputs as outputs
from btfsm.cli import main
from btfsm.errors import UsageError
from btfsm.validators import check_output_dir, check_output_file

TWO_FILE = os.path.join(os.path.dirname(__file__), "..", "models", "examples", "two_area.yaml")


def _run(argv, capsys):
    try:
        code = main([str(a) for a in argv])
    except SystemExit as exc:
        code = exc.code
    got = capsys.readouterr()
    return code, got.out, got.err


def _tmp_files(folder):
    return [p for p in folder.rglob(".*.tmp*")]


# ---------------------------------------------------------------- btfsm.outputs

def test_atomic_write_replaces_and_keeps_mode(tmp_path):
    target = tmp_path / "sub" / "out.txt"
    outputs.atomic_write_text(target, "one\n")
    outputs.atomic_write_text(target, "two\n")
    assert target.read_text() == "two\n" and sorted(os.listdir(target.parent)) == ["out.txt"]
    mask = os.umask(0o022)
    os.umask(mask)
    assert os.stat(target).st_mode & 0o777 == 0o666 & ~mask


def test_a_symlink_target_is_written_through_the_link(tmp_path):
    real, link = tmp_path / "real.txt", tmp_path / "link.txt"
    real.write_text("old\n")
    link.symlink_to(real)
    outputs.atomic_write_text(link, "new\n")
    assert link.is_symlink() and real.read_text() == "new\n" and sorted(os.listdir(tmp_path)) == ["link.txt", "real.txt"]


@pytest.mark.parametrize("exc", [OSError(errno.ENOSPC, "No space left on device"), KeyboardInterrupt(),
                                 RuntimeError("bug"), UsageError("stop")])
def test_failed_write_leaves_old_content_and_no_temporary(exc, tmp_path):
    target = tmp_path / "out.json"
    target.write_text("old\n")
    with pytest.raises((UsageError, KeyboardInterrupt, RuntimeError)) as info:
        with outputs.atomic_writer(target) as fh:
            fh.write("half")
            raise exc
    if isinstance(exc, OSError):
        assert info.type is UsageError and "No space left on device" in str(info.value)
    assert target.read_text() == "old\n" and os.listdir(tmp_path) == ["out.json"]


def test_failed_write_of_a_new_file_leaves_nothing(tmp_path):
    with pytest.raises(UsageError):
        with outputs.atomic_path(tmp_path / "new.png") as tmp:
            assert tmp.endswith(".png") and os.path.dirname(tmp) == str(tmp_path)
            raise OSError(errno.ENOSPC, "No space left on device")
    assert os.listdir(tmp_path) == []


def test_full_disk_at_flush(tmp_path, monkeypatch):
    def full(path):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(outputs, "_fsync", full)
    with pytest.raises(UsageError, match="cannot write .*No space left on device"):
        outputs.atomic_write_bytes(tmp_path / "x.bin", b"data")
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize("target", ["/dev/full", "/dev/null", "/proc/x", "/proc/x/y.txt"])
def test_unwritable_targets(target):
    with pytest.raises(UsageError, match="cannot write"):
        outputs.atomic_write_text(target, "x")


def test_output_file_rules(tmp_path):
    (tmp_path / "dir.svg").mkdir()
    (tmp_path / "file.txt").write_text("x")
    os.mkfifo(tmp_path / "fifo")
    ok = [tmp_path / "new.svg", tmp_path / "file.txt", tmp_path / "missing" / "deeper" / "x.png"]
    bad = {tmp_path / "dir.svg": "is a folder", f"{tmp_path}/dir.svg/": "is a folder", tmp_path / "fifo": "not a regular",
           tmp_path / "file.txt" / "x.png": "is not a folder", "/dev/full": "not a regular", "": "expected a file",
           "/proc/x.png": "cannot create files"}
    for path in ok:
        assert check_output_file(str(path)) == "", path
    for path, why in bad.items():
        assert why in check_output_file(str(path)), path
    assert "ending in .gif" in check_output_file(str(tmp_path / "a.png"), (".gif",))


def test_output_dir_rules(tmp_path):
    (tmp_path / "file.txt").write_text("x")
    assert check_output_dir(str(tmp_path / "new" / "deeper")) == ""
    assert check_output_dir(str(tmp_path)) == ""
    for path, why in {tmp_path / "file.txt": "not a folder", tmp_path / "file.txt" / "d": "not a folder",
                      "/dev/full": "not a folder", "/proc/x": "cannot create files"}.items():
        assert why in check_output_dir(str(path)), path


# ---------------------------------------------------------------- the commands

@pytest.fixture
def model_file(tmp_path):
    path = tmp_path / "model.yaml"
    shutil.copy(TWO_FILE, path)
    return path


@pytest.mark.parametrize("argv", [["run", "{m}", "--ticks", "3", "--trace", "{m}"],
                                  ["run", "{m}", "--ticks", "3", "--trace", "{link}"],
                                  ["export", "{m}", "--format", "dot", "-o", "{m}"],
                                  ["check", "{m}", "--counterexample-dir", "{m}"],
                                  ["show", "{m}", "-o", "{m}"]])
def test_output_is_never_the_input_model(argv, model_file, capsys):
    before = model_file.read_bytes()
    link = model_file.parent / "link.jsonl"
    link.symlink_to(model_file)
    argv = [a.replace("{link}", str(link)) for a in argv]
    code, out, err = _run([a.replace("{m}", str(model_file)) for a in argv], capsys)
    assert code == 2 and len(err.splitlines()) == 1
    assert "refusing to overwrite" in err or "is not a folder" in err, err
    assert model_file.read_bytes() == before


def test_export_writes_atomically_what_it_prints(tmp_path, capsys):
    code, printed, _ = _run(["export", "pickplace3", "--format", "promela"], capsys)
    assert code == 0
    target = tmp_path / "m.pml"
    assert _run(["export", "pickplace3", "--format", "promela", "-o", target], capsys)[0] == 0
    assert target.read_text() == printed and _tmp_files(tmp_path) == []


def test_export_full_disk_leaves_nothing(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(outputs, "_fsync", lambda path: (_ for _ in ()).throw(OSError(errno.ENOSPC, "No space left")))
    code, _, err = _run(["export", "pickplace3", "--format", "smv", "-o", tmp_path / "m.smv"], capsys)
    assert code == 2 and "cannot write" in err and "No space left" in err and os.listdir(tmp_path) == []


def test_counterexamples_are_complete_json(tmp_path, capsys):
    folder = tmp_path / "ce"
    code, _, _ = _run(["check", "defect-trap", "--counterexample-dir", folder], capsys)
    files = sorted(os.listdir(folder))
    assert code == 1 and files and all(f.endswith(".json") for f in files)
    for f in files:
        json.loads((folder / f).read_text())


def test_counterexample_full_disk_leaves_no_truncated_json(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(outputs, "_fsync", lambda path: (_ for _ in ()).throw(OSError(errno.ENOSPC, "No space left")))
    code, _, err = _run(["check", "defect-trap", "--counterexample-dir", tmp_path / "ce"], capsys)
    assert code == 2 and "cannot write" in err and os.listdir(tmp_path / "ce") == []


# show -o: a name ending in .dot/.svg/.png is one file, any other name a folder
SHOW_RULES = [
    (["--what", "tree", "-o", "t.dot"], 0, ["t.dot"]),
    (["--what", "arm", "-o", "arm.DOT"], 0, ["arm.DOT"]),
    (["-o", "pics"], 0, ["pics/"]),
    (["-o", "pics/"], 0, ["pics/"]),
    (["-o", "all.dot"], 2, []),  # several pictures into one file
    (["--what", "tree", "-o", "t.svg"], 2, []),  # .svg does not match --format dot
    (["--what", "tree", "-o", "t.png"], 2, []),
    (["--what", "tree", "-o", "existing.dot"], 2, ["existing.dot/"]),  # a folder named like a file
    (["--what", "tree", "-o", "a-file"], 2, ["a-file"]),  # a folder name that is a file
    (["--what", "tree", "-o", "/dev/full"], 2, []),
    (["--what", "tree", "-o", "/proc/x.dot"], 2, []),
]


@pytest.mark.parametrize("extra,code,listing", SHOW_RULES, ids=[" ".join(r[0]) for r in SHOW_RULES])
def test_show_output_rule(extra, code, listing, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "existing.dot").mkdir()
    (tmp_path / "a-file").write_text("keep\n")
    got, out, err = _run(["show", "two-area", *extra], capsys)
    assert got == code, err
    if code == 2:
        assert len(err.splitlines()) == 1
    names = sorted(p.name + ("/" if p.is_dir() else "") for p in tmp_path.iterdir()
                   if p.name not in ("existing.dot", "a-file"))
    expect = sorted(n for n in listing if n not in ("existing.dot/", "a-file"))
    assert names == expect
    assert (tmp_path / "a-file").read_text() == "keep\n" and os.listdir(tmp_path / "existing.dot") == []
    if "pics/" in listing:
        assert sorted(os.listdir(tmp_path / "pics")) == ["fsm_arm.dot", "tree.dot"]


def test_sim_outputs(tmp_path, capsys):
    png, gif = tmp_path / "cell.png", tmp_path / "run.gif"
    code, out, err = _run(["sim", "ariac-preemptive", "--time", "1", "--render", png, "--gif", gif], capsys)
    assert code == 0 and png.read_bytes()[:4] == b"\x89PNG" and gif.read_bytes()[:3] == b"GIF"
    assert sorted(os.listdir(tmp_path)) == ["cell.png", "run.gif"]
