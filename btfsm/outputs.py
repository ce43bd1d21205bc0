"""Output files that are complete or absent: write to a temporary name beside the target,
then rename.

Every file the CLI writes goes through ``atomic_path`` (directly or via ``atomic_writer``,
``atomic_write_text``, ``atomic_write_bytes``): the data goes to a hidden temporary file in
the target's folder, is flushed to disk, and replaces the target in one ``os.replace``. On
any error or interrupt (a full disk, Ctrl-C) the temporary file is removed and the target
keeps its old content (or stays absent). Errors become ``UsageError("cannot write ...")``,
which the CLI prints as one line with exit 2.

>>> import os, tempfile
>>> folder = tempfile.mkdtemp()
>>> target = os.path.join(folder, "out.txt")
>>> atomic_write_text(target, "hello\\n")
>>> open(target).read()
'hello\\n'
>>> os.listdir(folder)
['out.txt']
>>> import shutil; shutil.rmtree(folder)
"""
from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager

from .errors import UsageError
from .validators import check_output_dir, check_output_file

__all__ = ["atomic_path", "atomic_writer", "atomic_write_text", "atomic_write_bytes", "ensure_output_dir"]


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _reason(path: str, why: str) -> str:
    """``why`` without the leading path it names (the message names the path once)."""
    return why[len(path):].lstrip(": ") if why.startswith(path) else why


def _describe(exc: OSError) -> str:
    return exc.strerror or str(exc)


@contextmanager
def atomic_path(path, *, suffixes: "tuple | None" = None):
    """Yield a temporary path in ``path``'s folder (same suffix, so libraries that pick a
    format by suffix still do); on success rename it to ``path``, on failure remove it."""
    path = os.fspath(path)
    if os.path.islink(path):  # write the file the link points to; the link stays a link
        path = os.path.realpath(path)
    why = check_output_file(path, suffixes)
    if why:
        raise UsageError(f"cannot write {path}: {_reason(path, why)}")
    folder = os.path.dirname(os.path.abspath(path))
    base = os.path.basename(path)
    stem, ext = os.path.splitext(base)
    try:
        os.makedirs(folder, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{stem}.", suffix=f".tmp{ext}", dir=folder)
        os.close(fd)
    except OSError as exc:
        raise UsageError(f"cannot write {path}: {_describe(exc)}") from None
    try:
        yield tmp
        try:
            mode = os.stat(path).st_mode & 0o777 if os.path.isfile(path) else 0o666 & ~_umask()
            os.chmod(tmp, mode)
            _fsync(tmp)
            os.replace(tmp, path)
        except OSError as exc:
            raise UsageError(f"cannot write {path}: {_describe(exc)}") from None
    except OSError as exc:  # raised by the code writing the temporary file
        _remove(tmp)
        raise UsageError(f"cannot write {path}: {_describe(exc)}") from None
    except BaseException:
        _remove(tmp)
        raise


def _fsync(path: str) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _remove(path: str) -> None:
    try:
        os.unlink(path)
    except OSError:
        pass


@contextmanager
def atomic_writer(path, mode: str = "w", *, encoding: "str | None" = "utf-8", newline: "str | None" = None,
                  suffixes: "tuple | None" = None):
    """Yield a file object for streaming writes; ``path`` appears only once it is complete."""
    binary = "b" in mode
    with atomic_path(path, suffixes=suffixes) as tmp:
        with open(tmp, mode, encoding=None if binary else encoding, newline=None if binary else newline) as fh:
            yield fh


def atomic_write_text(path, text: str, *, encoding: str = "utf-8") -> None:
    """Write ``text`` to ``path`` atomically."""
    with atomic_writer(path, "w", encoding=encoding) as fh:
        fh.write(text)


def atomic_write_bytes(path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_writer(path, "wb") as fh:
        fh.write(data)


def ensure_output_dir(path) -> str:
    """Create the output folder ``path`` (and its parents) or raise a one-line ``UsageError``."""
    path = os.fspath(path)
    why = check_output_dir(path)
    if why:
        raise UsageError(f"cannot write into {path}: {_reason(path, why)}")
    try:
        os.makedirs(path, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"cannot create folder {path}: {_describe(exc)}") from None
    return path
