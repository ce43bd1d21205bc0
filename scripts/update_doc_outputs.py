#!/usr/bin/env python3
"""Check or regenerate the command outputs printed in README.md and docs/*.md.

Usage (from anywhere; the documents are found next to this script):

    python scripts/update_doc_outputs.py            # rewrite every transcript with today's output
    python scripts/update_doc_outputs.py --check    # only compare; exit 1 on a difference
    python scripts/update_doc_outputs.py --fast     # skip transcripts marked slow
    python scripts/update_doc_outputs.py README.md  # only these documents

tests/test_doc_outputs.py runs the same code (``check_transcript``) on every transcript.

**Transcripts.** A fenced block with no info string (or ``console``) whose first line
starts with ``$ `` is a transcript: each ``$ COMMAND`` line is followed by what the command
prints (stdout and stderr, interleaved as written). Every untagged block must be a
transcript; a block that shows something else is tagged (```` ```text ````, ``yaml``...).

* ``$ btfsm ARGS`` runs in-process through ``btfsm.cli.main``; ``$ python ARGS`` runs
  ``sys.executable ARGS`` in a subprocess. Other commands are refused.
* Every transcript runs in a fresh temporary directory that holds a symbolic link to each
  top-level entry of the repository (except ``out``), so paths are written as from the
  repository root (``docs/examples/first_model.yaml``) and files written by the commands
  (``ce/``, ``out/``) land in the temporary directory. Commands of one block share it.
* The expected exit code is 0; a command line may say otherwise with a shell comment
  ``# exit N`` (any text may follow).
* A line that is exactly ``...`` stands for any number of omitted lines (none included).

**Normalisation** (applied to both the printed and the documented text before comparing):

1. a line holding a carriage return (a progress display redrawn in place) is dropped;
2. trailing white space is removed from every line, and trailing empty lines at the end;
3. measured durations: ``(0.19 s)`` becomes ``(<t> s)`` and `` in 0.09 s`` becomes
   `` in <t> s``; a speed ``1,524x real time`` becomes ``<n>x real time``;
4. the temporary directory's path becomes ``<tmp>``.

**Markers**: an HTML comment on the line just before a fence: ``<!-- transcript: slow -->``
marks a transcript whose commands take too long for the default test run (its test runs
only with ``BTFSM_SLOW_DOCS=1``, as in CI); ``<!-- transcript: long -->`` one too long for
CI as well (its test runs only with ``BTFSM_LONG=1``); ``<!-- file: PATH -->`` says that the block's text is
the repository file PATH (a test compares them; the update copies the file into the block);
``<!-- excerpt: PATH -->`` says that the block's lines appear, consecutively, in that file
(a test checks it; the update leaves such blocks alone).

**Updating** keeps the shape of each documented output: a command whose output still
matches is left as it is, and in a changed output every line that equals a documented line
after normalisation keeps its documented text (so timings do not churn). Otherwise the
new output replaces the old, except where ``...`` elides lines: each run of documented lines between elisions
(a segment) is placed in the new output at the line equal to its first line (or, failing
that, starting with the same text up to its first ``:``); a segment that ended with an empty
line before ``...`` is refilled with as many whole paragraphs (blank-line separated) as it
had, any other segment with as many lines as it had; the last segment, when no ``...``
follows it, runs to the end of the output. A segment that cannot be placed is reported and
left out (the script names it and exits 1: review that block and the text around it). A
changed exit code rewrites the command's ``# exit N`` comment (and says so).
"""
from __future__ import annotations

import argparse
import contextlib
import difflib
import glob
import io
import os
import re
import shlex
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field

__all__ = ["ROOT", "Block", "Command", "doc_files", "find_blocks", "transcripts", "parse_commands",
           "normalise", "matches", "run_command", "run_transcript", "check_transcript", "updated_output",
           "with_exit_code", "update_file", "main"]

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ELISION = "..."
_FENCE = re.compile(r"^(```+)(.*)$")
_MARKER = re.compile(r"^<!--\s*(transcript|file|excerpt)\s*:\s*(.*?)\s*-->\s*$")
_EXIT = re.compile(r"#\s*exit\s+(\d+)")
_RULES = [(re.compile(r"\(\d+(?:\.\d+)? s\)"), "(<t> s)"),
          (re.compile(r" in \d+(?:\.\d+)? s\b"), " in <t> s"),
          (re.compile(r"\b\d[\d,]*x real time"), "<n>x real time")]
_SKIP_LINKS = {"out", ".git", ".venv"}


@dataclass
class Block:
    """One fenced block of a document: ``lines`` is its content; ``start`` the index of the
    opening fence in the document's lines; ``markers`` the comments just before it."""
    path: str
    start: int
    info: str
    lines: list
    markers: dict = field(default_factory=dict)

    @property
    def id(self) -> str:
        return f"{os.path.relpath(self.path, ROOT)}:{self.start + 1}"

    @property
    def is_transcript(self) -> bool:
        return self.info in ("", "console") and bool(self.lines) and self.lines[0].startswith("$ ")

    @property
    def slow(self) -> bool:
        """Marked slow or long: not in the default test run (nor in ``--fast`` updates)."""
        return self.markers.get("transcript") in ("slow", "long")

    @property
    def long(self) -> bool:
        """Marked long: run by the tests only with ``BTFSM_LONG=1`` (CI runs the slow ones)."""
        return self.markers.get("transcript") == "long"


@dataclass
class Command:
    line: str            # the command as written, without the leading "$ "
    expected: list       # the documented output lines
    exit_code: int = 0


def doc_files(root: str = ROOT) -> list:
    """README.md and docs/*.md."""
    return [os.path.join(root, "README.md")] + sorted(glob.glob(os.path.join(root, "docs", "*.md")))


def find_blocks(path: str) -> list:
    """Every fenced block of a Markdown file."""
    lines = open(path, encoding="utf-8").read().split("\n")
    out, i = [], 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        fence, info = m.group(1), m.group(2).strip()
        j = i + 1
        while j < len(lines) and lines[j].rstrip() != fence:
            j += 1
        markers, k = {}, i - 1
        while k >= 0 and _MARKER.match(lines[k]):
            mk = _MARKER.match(lines[k])
            markers[mk.group(1)] = mk.group(2)
            k -= 1
        out.append(Block(path, i, info, lines[i + 1:j], markers))
        i = j + 1
    return out


def transcripts(root: str = ROOT) -> list:
    return [b for p in doc_files(root) for b in find_blocks(p) if b.is_transcript]


def parse_commands(block: Block) -> list:
    cmds: list = []
    for line in block.lines:
        if line.startswith("$ "):
            m = _EXIT.search(line)
            cmds.append(Command(line[2:], [], int(m.group(1)) if m else 0))
        else:
            cmds[-1].expected.append(line)
    return cmds


def normalise(text_or_lines, tmp: str | None = None) -> list:
    """The comparison form of an output (see the module docstring)."""
    lines = text_or_lines.split("\n") if isinstance(text_or_lines, str) else list(text_or_lines)
    out = []
    for line in lines:
        if "\r" in line:
            continue
        if tmp:
            line = line.replace(os.path.realpath(tmp), "<tmp>").replace(tmp, "<tmp>")
        for rx, repl in _RULES:
            line = rx.sub(repl, line)
        out.append(line.rstrip())
    while out and not out[-1]:
        out.pop()
    return out


def _pattern(expected: list) -> re.Pattern:
    parts = [r"(?:[^\n]*\n)*?" if line.strip() == ELISION else re.escape(line) + r"\n" for line in expected]
    return re.compile("".join(parts), re.S)


def matches(expected: list, actual: list) -> bool:
    """Whether the normalised documented lines (with ``...`` elisions) match the output."""
    text = "".join(line + "\n" for line in actual)
    return _pattern(expected).fullmatch(text) is not None


def run_command(line: str, cwd: str) -> tuple:
    """Run one documented command in ``cwd``; return (exit code, combined output)."""
    argv = shlex.split(line, comments=True)
    if not argv:
        raise ValueError("empty command")
    if argv[0] == "btfsm":
        from btfsm.cli import main as cli_main

        # one stream for stdout and stderr (their order kept), not a terminal, with a
        # .buffer and .reconfigure like the real ones
        raw = io.BytesIO()
        buf = io.TextIOWrapper(raw, encoding="utf-8", errors="backslashreplace", write_through=True)
        old = os.getcwd()
        os.chdir(cwd)
        try:
            with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(buf):
                try:
                    code = cli_main(argv[1:])
                except SystemExit as exc:
                    code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
                buf.flush()
        finally:
            os.chdir(old)
        return int(code or 0), raw.getvalue().decode("utf-8", errors="backslashreplace")
    if argv[0] in ("python", "python3"):
        proc = subprocess.run([sys.executable, *argv[1:]], cwd=cwd, stdout=subprocess.PIPE,
                              stderr=subprocess.STDOUT, text=True, timeout=600)
        return proc.returncode, proc.stdout
    raise ValueError(f"unsupported command in a transcript: {line!r} (only btfsm and python)")


def _workdir() -> str:
    tmp = tempfile.mkdtemp(prefix="btfsm-doc-")
    for name in os.listdir(ROOT):
        if name not in _SKIP_LINKS and not name.startswith("."):
            os.symlink(os.path.join(ROOT, name), os.path.join(tmp, name))
    return tmp


def run_transcript(block: Block) -> list:
    """Run every command of a transcript; return [(Command, exit code, output, tmp)]."""
    import shutil

    tmp = _workdir()
    try:
        return [(cmd, *run_command(cmd.line, tmp), tmp) for cmd in parse_commands(block)]
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def check_transcript(block: Block) -> list:
    """The problems of one transcript (empty: it matches what the commands print)."""
    problems = []
    for cmd, code, out, tmp in run_transcript(block):
        actual = normalise(out, tmp)
        expected = normalise(cmd.expected)
        if code != cmd.exit_code:
            problems.append(f"{block.id}: $ {cmd.line}: exit code {code}, documented {cmd.exit_code}")
        if not matches(expected, actual):
            diff = "\n".join(difflib.unified_diff(expected, actual, "documented", "printed", lineterm=""))
            problems.append(f"{block.id}: $ {cmd.line}: output differs:\n{diff}")
    return problems


# ----------------------------------------------------------------------------- updating
def _segments(expected: list) -> tuple:
    """(segments, leading elision, trailing elision) of documented lines."""
    segs, cur = [], []
    lead = bool(expected) and expected[0].strip() == ELISION
    for line in expected:
        if line.strip() == ELISION:
            if cur:
                segs.append(cur)
            cur = []
        else:
            cur.append(line)
    trail = bool(expected) and expected[-1].strip() == ELISION
    if cur:
        segs.append(cur)
    return segs, lead, trail


def _key(line: str) -> str:
    return line.split(":", 1)[0].rstrip() if ":" in line else line.rstrip()


def _find(anchor: str, lines: list, start: int) -> int | None:
    norm = normalise([anchor])
    want = norm[0] if norm else ""
    got = [normalise([x]) for x in lines]
    for i in range(start, len(lines)):
        if got[i] and got[i][0] == want:
            return i
    for i in range(start, len(lines)):
        if lines[i].strip() and _key(lines[i]) == _key(anchor):
            return i
    return None


def _extent(seg: list, lines: list, at: int, last_open: bool) -> int:
    """End index (exclusive) in ``lines`` of a segment placed at ``at``."""
    if last_open:
        return len(lines)
    if seg and not seg[-1].strip():
        paragraphs = sum(1 for x in seg if not x.strip())
        i, seen = at, 0
        while i < len(lines) and seen < paragraphs:
            if not lines[i].strip():
                seen += 1
            i += 1
        return i
    return min(len(lines), at + len(seg))


def updated_output(expected: list, printed: str, tmp: str | None = None, dropped: list | None = None) -> list:
    """New documented lines for a command. A segment that cannot be placed is left out
    (its first line is appended to ``dropped``)."""
    lines = [line.rstrip() for line in printed.split("\n") if "\r" not in line]
    if tmp:
        lines = [line.replace(os.path.realpath(tmp), "<tmp>").replace(tmp, "<tmp>") for line in lines]
    while lines and not lines[-1]:
        lines.pop()
    if matches(normalise(expected), normalise(lines)):
        return expected
    segs, lead, trail = _segments(expected)
    if not segs and (lead or trail):
        return expected                         # everything elided
    if not segs:
        return _keep_equal_lines(expected, lines)
    out: list = [ELISION] if lead else []
    pos = 0
    for n, seg in enumerate(segs):
        at = pos if (n == 0 and not lead) else _find(seg[0], lines, pos)
        if at is None:
            if dropped is not None:
                dropped.append(seg[0])
            if not out or out[-1] != ELISION:
                out.append(ELISION)
            continue
        end = _extent(seg, lines, at, last_open=(n == len(segs) - 1 and not trail))
        out.extend(lines[at:end])
        if (n < len(segs) - 1 or trail) and (not out or out[-1] != ELISION):
            out.append(ELISION)
        pos = end
    return _keep_equal_lines(expected, out)


def with_exit_code(line: str, code: int) -> str:
    """A command line whose ``# exit N`` comment says ``code`` (none for 0)."""
    m = _EXIT.search(line)
    if m:
        if code == 0:
            return line[:line.index("#", m.start())].rstrip()
        return line[:m.start(1)] + str(code) + line[m.end(1):]
    return line if code == 0 else f"{line}   # exit {code}"


def _keep_equal_lines(old: list, new: list) -> list:
    """``new``, where a line equal to a documented one after normalisation (a timing, say)
    keeps its documented text."""
    a = [(normalise([x]) or [""])[0] for x in old]
    b = [(normalise([x]) or [""])[0] for x in new]
    out = list(new)
    for tag, i1, i2, j1, j2 in difflib.SequenceMatcher(None, a, b, autojunk=False).get_opcodes():
        if tag == "equal":
            out[j1:j2] = old[i1:i2]
    return out


def update_file(path: str, fast: bool = False, log=print) -> tuple:
    """Rewrite the transcripts and file blocks of one document; return (changed, failed)."""
    text = open(path, encoding="utf-8").read()
    lines = text.split("\n")
    changed = failed = 0
    for block in reversed(find_blocks(path)):     # from the end: indices stay valid
        new = None
        if "file" in block.markers:
            new = open(os.path.join(ROOT, block.markers["file"]), encoding="utf-8").read().rstrip("\n").split("\n")
        elif block.is_transcript and not (fast and block.slow):
            new = []
            for cmd, code, out, tmp in run_transcript(block):
                line = cmd.line
                if code != cmd.exit_code:
                    line = with_exit_code(line, code)
                    log(f"{block.id}: $ {cmd.line}: exit code {code}, documented {cmd.exit_code}: "
                        "comment updated (check the text around the block)")
                dropped: list = []
                got = updated_output(cmd.expected, out, tmp, dropped)
                for first in dropped:
                    failed += 1
                    log(f"{block.id}: $ {cmd.line}: no longer printed, left out: {first!r} "
                        "(review the block and the text around it)")
                new.append("$ " + line)
                new.extend(got)
        if new is not None and new != block.lines:
            lines[block.start + 1:block.start + 1 + len(block.lines)] = new
            changed += 1
            log(f"{block.id}: updated")
    if changed:
        with open(path + ".tmp", "w", encoding="utf-8") as fh:
            fh.write("\n".join(lines))
        os.replace(path + ".tmp", path)
    return changed, failed


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("docs", nargs="*", help="documents (default: README.md and docs/*.md)")
    ap.add_argument("--check", action="store_true", help="compare only; exit 1 on a difference")
    ap.add_argument("--fast", action="store_true", help="skip transcripts marked slow")
    args = ap.parse_args(argv)
    paths = [os.path.abspath(p) for p in args.docs] or doc_files()
    bad = 0
    for path in paths:
        if args.check:
            for block in find_blocks(path):
                if block.is_transcript and not (args.fast and block.slow):
                    for problem in check_transcript(block):
                        print(problem)
                        bad += 1
                for kind in ("file", "excerpt"):
                    if kind in block.markers:
                        text = open(os.path.join(ROOT, block.markers[kind]), encoding="utf-8").read()
                        shown = "\n".join(block.lines)
                        ok = (shown == text.rstrip("\n")) if kind == "file" else ("\n" + shown + "\n") in ("\n" + text)
                        if not ok:
                            print(f"{block.id}: not the text of {block.markers[kind]}")
                            bad += 1
        else:
            bad += update_file(path, fast=args.fast)[1]
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
