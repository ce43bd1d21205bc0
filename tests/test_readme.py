"""The README's and docs' examples are what the code does.

* The README's Python example model builds, checks clean and runs.
* Every transcript (an untagged fenced block starting with ``$ btfsm ...`` or
  ``$ python ...``) in README.md and docs/*.md is run and compared with what it shows,
  by the rules of scripts/update_doc_outputs.py (which also regenerates them:
  ``python scripts/update_doc_outputs.py``). Transcripts marked ``<!-- transcript: slow -->``
  run only with ``BTFSM_SLOW_DOCS=1`` (CI sets it), those marked ``<!-- transcript: long -->``
  only with ``BTFSM_LONG=1``.
* Every untagged fenced block is a transcript (a block showing anything else is tagged),
  every block marked ``<!-- file: PATH -->`` is that repository file, and every block
  marked ``<!-- excerpt: PATH -->`` is a run of consecutive lines of it.
"""
import importlib.util
import os
import re
import sys

import pytest

from btfsm.oracles import RandomOracle
from btfsm.runtime import Runtime

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
_spec = importlib.util.spec_from_file_location("update_doc_outputs",
                                               os.path.join(ROOT, "scripts", "update_doc_outputs.py"))
dox = importlib.util.module_from_spec(_spec)
sys.modules.setdefault("update_doc_outputs", dox)
_spec.loader.exec_module(dox)

TRANSCRIPTS = dox.transcripts()
FAST = [b for b in TRANSCRIPTS if not b.slow]
SLOW = [b for b in TRANSCRIPTS if b.slow and not b.long]
LONG = [b for b in TRANSCRIPTS if b.long]


def _example():
    text = open(os.path.join(ROOT, "README.md"), encoding="utf-8").read()
    ns: dict = {}
    exec(re.search(r"```python\n(.*?)```", text, re.S).group(1), ns)  # our own README
    return ns["model"]


def test_readme_example_checks_clean():
    from btfsm.verify import check

    report = check(_example())
    assert report.exit_code == 0, report.format_text()


def test_readme_example_runs():
    rt = Runtime(_example(), fallback=RandomOracle(3))
    for k in range(50):
        rt.tick(["arrive"] if k == 2 else [])
    assert rt.vars["part"] is True


# ------------------------------------------------------------------------ transcripts
def _check(block) -> None:
    problems = dox.check_transcript(block)
    assert not problems, "\n".join(problems) + "\n(regenerate: python scripts/update_doc_outputs.py)"


@pytest.mark.parametrize("block", FAST, ids=[b.id for b in FAST])
def test_transcript(block):
    _check(block)


@pytest.mark.slow
@pytest.mark.skipif(os.environ.get("BTFSM_SLOW_DOCS") != "1", reason="set BTFSM_SLOW_DOCS=1 to run slow transcripts")
@pytest.mark.parametrize("block", SLOW, ids=[b.id for b in SLOW])
def test_slow_transcript(block):
    _check(block)


@pytest.mark.slow
@pytest.mark.skipif(os.environ.get("BTFSM_LONG") != "1", reason="set BTFSM_LONG=1 to run long transcripts")
@pytest.mark.parametrize("block", LONG, ids=[b.id for b in LONG])
def test_long_transcript(block):
    _check(block)


def test_every_output_block_is_a_tested_transcript():
    """Lists every fenced block: an untagged one must be a transcript, and every transcript
    is one of the parametrised cases above (fast, slow or long)."""
    tested = {b.id for b in FAST} | {b.id for b in SLOW} | {b.id for b in LONG}
    blocks = [b for p in dox.doc_files() for b in dox.find_blocks(p)]
    untagged = [f"{b.id}: {b.lines[0] if b.lines else ''!r}" for b in blocks
                if b.info in ("", "console") and not b.is_transcript]
    assert not untagged, ("untagged blocks that are not transcripts (start them with '$ COMMAND' "
                          "or tag them: ```text, ```sh, ...):\n" + "\n".join(untagged))
    assert {b.id for b in blocks if b.is_transcript} == tested
    assert len(tested) >= 10           # README 5, model-files.md 1, first-model.md 6 today


def test_every_transcript_command_can_be_run_here():
    for block in TRANSCRIPTS:
        for cmd in dox.parse_commands(block):
            assert cmd.line.split()[0] in ("btfsm", "python", "python3"), (block.id, cmd.line)


def test_file_blocks_are_the_files():
    blocks = [b for p in dox.doc_files() for b in dox.find_blocks(p) if "file" in b.markers]
    assert blocks, "no <!-- file: PATH --> blocks found"
    for b in blocks:
        text = open(os.path.join(ROOT, b.markers["file"]), encoding="utf-8").read().rstrip("\n")
        assert "\n".join(b.lines) == text, f"{b.id} differs from {b.markers['file']} (python scripts/update_doc_outputs.py)"


def test_excerpt_blocks_are_in_their_files():
    blocks = [b for p in dox.doc_files() for b in dox.find_blocks(p) if "excerpt" in b.markers]
    assert blocks, "no <!-- excerpt: PATH --> blocks found"
    for b in blocks:
        text = open(os.path.join(ROOT, b.markers["excerpt"]), encoding="utf-8").read()
        assert b.lines and "\n" + "\n".join(b.lines) + "\n" in "\n" + text, f"{b.id} is not in {b.markers['excerpt']}"


# ------------------------------------------------------------- the checker's own rules
@pytest.mark.parametrize("expected, actual, ok", [
    (["a", "b"], ["a", "b"], True),
    (["a", "b"], ["a", "b", "c"], False),                  # no silent tail
    (["a", "..."], ["a", "b", "c"], True),
    (["...", "c"], ["a", "b", "c"], True),
    (["a", "...", "c"], ["a", "c"], True),                # an elision may stand for nothing
    (["a", "...", "c"], ["a", "b", "x"], False),
    (["a", "...", "c", "...", "e"], ["a", "b", "c", "d", "e"], True),
    (["a", "...", "e", "...", "c"], ["a", "b", "c", "d", "e"], False),   # order counts
    (["a.b"], ["axb"], False),                             # literal text, not a pattern
    ([], [], True),
    ([], ["x"], False),
])
def test_matching_with_elisions(expected, actual, ok):
    assert dox.matches(expected, actual) is ok


@pytest.mark.parametrize("text, want", [
    ("model m: 3 states (0.19 s)", "model m: 3 states (<t> s)"),
    ("explored 5 states in 0.09 s", "explored 5 states in <t> s"),
    ("80 trials, 40,594 simulated s in 26.6 s wall (1,524x real time on 2 worker(s))",
     "80 trials, 40,594 simulated s in <t> s wall (<n>x real time on 2 worker(s))"),
    ("the arm stayed (36.0 s without a move)", "the arm stayed (36.0 s without a move)"),   # not a timing
    ("t =   15.8 s: belt part", "t =   15.8 s: belt part"),
    ("trailing   ", "trailing"),
])
def test_normalisation_rules(text, want):
    assert dox.normalise(text) == [want]


def test_normalisation_drops_progress_redraws_and_temporary_paths():
    assert dox.normalise("a\n[##..] 1/2\r[####] 2/2\nb\n\n") == ["a", "b"]
    assert dox.normalise("wrote /tmp/x1/ce.json", tmp="/tmp/x1") == ["wrote <tmp>/ce.json"]


@pytest.mark.parametrize("expected, printed, want", [
    (["a", "b"], "a\nb\n", ["a", "b"]),                              # unchanged
    (["x (0.10 s)"], "x (0.50 s)\n", ["x (0.10 s)"]),                 # only a timing: kept
    (["a", "b"], "a\nB\nc\n", ["a", "B", "c"]),                       # no elision: replaced
    (["s1", "", "..."], "s1\ns2\n\nw1\nw2\n", ["s1", "s2", "", "..."]),   # whole paragraph kept
    (["...", "k: x", "..."], "a\nk: y\nb\n", ["...", "k: y", "..."]),     # anchored by 'k:'
    (["...", "FSM support: 1"], "a\n\nFSM support: 2\nmore\n", ["...", "FSM support: 2", "more"]),
    (["...", "gone", "..."], "a\nb\n", ["..."]),                       # cannot be placed: left out
    (["s", "...", "gone", "...", "k: 1"], "s\nx\nk: 2\n", ["s", "...", "k: 2"]),
    (["..."], "anything\n", ["..."]),
    (["a", "x (0.10 s)", "b"], "a\nNEW\nx (9.99 s)\nb\n", ["a", "NEW", "x (0.10 s)", "b"]),   # timing kept
])
def test_update_keeps_the_shape(expected, printed, want):
    assert dox.updated_output(expected, printed) == want
    assert dox.matches(dox.normalise(want), dox.normalise(printed))


def test_update_names_what_it_left_out():
    dropped = []
    dox.updated_output(["a", "...", "gone", "..."], "a\nb\n", dropped=dropped)
    assert dropped == ["gone"]


@pytest.mark.parametrize("line, code, want", [
    ("btfsm check m", 0, "btfsm check m"),
    ("btfsm check m", 1, "btfsm check m   # exit 1"),
    ("btfsm check m   # exit 1: violated", 3, "btfsm check m   # exit 3: violated"),
    ("btfsm check m   # exit 1: violated", 0, "btfsm check m"),
])
def test_exit_code_comment(line, code, want):
    assert dox.with_exit_code(line, code) == want
