"""Reusable ``argparse`` ``type=`` validators for the command line.

Each validator turns the flag's text into a value or raises ``argparse.ArgumentTypeError``
with a short reason; the CLI prints it as one line naming the flag and exits 2.

>>> int_range(1, 40)("7")
7
>>> finite_float(0, None, lo_open=True)("0.5")
0.5
>>> probability("1")
1.0
>>> import argparse
>>> try:
...     finite_float(0, None, lo_open=True)("nan")
... except argparse.ArgumentTypeError as exc:
...     print(exc)
'nan' is not a finite number
"""
from __future__ import annotations

import argparse
import math
import os

__all__ = ["int_range", "positive_int", "nonnegative_int", "seed_int", "finite_float", "probability",
           "output_file", "output_dir", "input_text", "input_file", "check_output_file", "check_output_dir"]

#: Seeds are stored in traces and used with Python's ``random``: any integer of at most 64 bits.
SEED_LIMIT = 2 ** 63


def _fail(text: str):
    raise argparse.ArgumentTypeError(text)


def _show(text: str) -> str:
    shown = repr(text)
    return shown if len(shown) <= 60 else shown[:57] + "..."


def int_range(lo: "int | None" = None, hi: "int | None" = None):
    """An integer in ``lo..hi`` (either end may be None: unbounded on that side)."""

    def parse(text: str) -> int:
        try:
            value = int(str(text).strip(), 10)
        except ValueError:
            _fail(f"{_show(text)} is not a whole number")
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            _fail(f"{value} is out of range ({_range_text(lo, hi)})")
        return value

    parse.__name__ = "integer"
    return parse


def _range_text(lo, hi, lo_open=False, hi_open=False) -> str:
    if lo is not None and hi is not None:
        return f"expected {lo} {'<' if lo_open else '<='} value {'<' if hi_open else '<='} {hi}"
    if lo is not None:
        return f"expected {'>' if lo_open else '>='} {lo}"
    if hi is not None:
        return f"expected {'<' if hi_open else '<='} {hi}"
    return "any"


positive_int = int_range(1, None)
nonnegative_int = int_range(0, None)
seed_int = int_range(-(SEED_LIMIT - 1), SEED_LIMIT - 1)


def finite_float(lo: "float | None" = None, hi: "float | None" = None, *, lo_open: bool = False,
                 hi_open: bool = False):
    """A finite number in ``[lo, hi]`` (``lo_open``/``hi_open`` exclude that end)."""

    def parse(text: str) -> float:
        try:
            value = float(str(text).strip())
        except ValueError:
            _fail(f"{_show(text)} is not a number")
        if not math.isfinite(value):
            _fail(f"{_show(text)} is not a finite number")
        below = lo is not None and (value <= lo if lo_open else value < lo)
        above = hi is not None and (value >= hi if hi_open else value > hi)
        if below or above:
            _fail(f"{value:g} is out of range ({_range_text(lo, hi, lo_open, hi_open)})")
        return value

    parse.__name__ = "number"
    return parse


probability = finite_float(0.0, 1.0)
probability.__name__ = "probability"


def input_text(text: str) -> str:
    """A non-empty argument without NUL characters (a name, or a path)."""
    if not text or "\0" in text:
        _fail("expected a non-empty name without NUL characters")
    return text


def input_file(text: str) -> str:
    """An input: a name (e.g. a built-in model) or a path; an existing path must be a regular
    file or a folder (the loader explains a folder), never a device, FIFO or socket, which
    could block or never end."""
    input_text(text)
    if os.path.exists(text) and not (os.path.isfile(text) or os.path.isdir(text)):
        _fail(f"{text} is not a regular file")
    return text


def check_output_file(path: str, suffixes: "tuple | None" = None) -> str:
    """Why ``path`` cannot be an output file, or ``""`` when it can.

    An output file is a regular file or a new name; its folder is created when missing.
    Existing folders, devices, FIFOs and sockets are refused; so is a name without one of
    ``suffixes`` (when given)."""
    if not path or "\0" in path:
        return "expected a file name without NUL characters"
    if path.endswith(("/", os.sep)) or os.path.isdir(path):
        return f"{path} is a folder; expected a file name"
    if os.path.lexists(path) and not os.path.isfile(path):
        return f"{path} exists and is not a regular file"
    if suffixes and not path.lower().endswith(tuple(suffixes)):
        return f"{path}: expected a file name ending in {' or '.join(suffixes)}"
    folder = os.path.dirname(os.path.abspath(path))
    blocker = _existing_non_folder_ancestor(folder)
    if blocker:
        return f"{path}: {blocker} is not a folder"
    return _probe(folder, path)


def _probe(folder: str, path: str) -> str:
    """Whether a file can be created in ``folder`` (when it exists): an unnamed temporary
    file is created and dropped, so a read-only or virtual folder is refused before work."""
    while folder and not os.path.lexists(folder) and os.path.dirname(folder) != folder:
        folder = os.path.dirname(folder)
    if not os.path.isdir(folder):
        return ""
    import tempfile

    try:
        with tempfile.TemporaryFile(dir=folder):
            pass
    except OSError as exc:
        return f"{path}: cannot create files in {folder}: {exc.strerror or exc}"
    return ""


def check_output_dir(path: str) -> str:
    """Why ``path`` cannot be an output folder (created when missing), or ``""``."""
    if not path or "\0" in path:
        return "expected a folder name without NUL characters"
    if os.path.lexists(path) and not os.path.isdir(path):
        return f"{path} exists and is not a folder"
    blocker = _existing_non_folder_ancestor(os.path.abspath(path))
    if blocker:
        return f"{path}: {blocker} is not a folder"
    return _probe(os.path.abspath(path), path)


def _existing_non_folder_ancestor(folder: str) -> str:
    """The nearest existing ancestor of ``folder`` (itself included) when it is not a folder."""
    while folder and not os.path.lexists(folder):
        parent = os.path.dirname(folder)
        if parent == folder:
            return ""
        folder = parent
    return folder if folder and not os.path.isdir(folder) else ""


def output_file(*suffixes: str):
    """A path to write a file to (see ``check_output_file``); ``suffixes`` restrict its ending."""

    def parse(text: str) -> str:
        why = check_output_file(text, suffixes or None)
        if why:
            _fail(why)
        return text

    parse.__name__ = "output file"
    return parse


def output_dir(text: str) -> str:
    """A folder to write files into (see ``check_output_dir``)."""
    why = check_output_dir(text)
    if why:
        _fail(why)
    return text
