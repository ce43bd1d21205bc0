"""Progress bars for long commands (tqdm), shown only when stderr is a terminal.

``progress_bar(total, desc=...)`` is a ``tqdm`` bar on stderr that is silent unless the
stream is a terminal: piped output, CI logs and tests see nothing. Where the total is
known (trials of an experiment, frames of a GIF) it shows an ETA; where it is not (states
of an exploration) it shows the count and the rate.

``ExplorationProgress`` is the ``progress(what, states, transitions, seconds)`` callback
that ``btfsm.verify.report.check`` (and ``btfsm.verify.skills.derive``, with
``transitions=None``) call during an exploration: one bar per explored system, shown
after ``delay`` seconds so that quick checks print nothing.

>>> import io
>>> p = ExplorationProgress(file=io.StringIO(), delay=0)
>>> p("model", 1000, 2500, 0.5); p.close()
>>> p.file.getvalue()  # not a terminal: nothing
''
"""
from __future__ import annotations

import os
import sys

from tqdm import tqdm

__all__ = ["is_terminal", "progress_bar", "ExplorationProgress"]


def is_terminal(stream) -> bool:
    """True when ``stream`` is an open terminal."""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):  # no isatty, or closed
        return False


def progress_bar(total: "int | None" = None, *, desc: "str | None" = None, unit: str = "it", file=None,
                 delay: float = 0.0, disable: bool = False, leave: bool = False, **options) -> tqdm:
    """A tqdm bar on ``file`` (default: stderr), disabled when ``disable`` is true or the
    stream is not a terminal. ``delay``: seconds before it first appears; ``leave``: keep
    the last state on screen; other ``options`` go to tqdm (e.g. ``mininterval``)."""
    file = sys.stderr if file is None else file
    # a terminal of unknown size (a bare pseudo-terminal) would make tqdm print nothing
    width = {"dynamic_ncols": True} if _columns(file) > 0 else {"ncols": 80, "nrows": 24}
    return tqdm(total=total, desc=desc, unit=unit, file=file, delay=delay, leave=leave,
                disable=disable or not is_terminal(file), **{**width, **options})


def _columns(stream) -> int:
    """The terminal's width, 0 when unknown (a pseudo-terminal without a size)."""
    try:
        return os.get_terminal_size(stream.fileno()).columns
    except (AttributeError, OSError, ValueError):  # io.UnsupportedOperation is an OSError
        return 0


class ExplorationProgress:
    """``progress(what, states, transitions, seconds)``: a bar per explored system
    (``what``, e.g. ``model`` or ``fsm arm``) with states, states/s, transitions and
    transitions/s (``seconds``: since that exploration started)."""

    def __init__(self, file=None, delay: float = 1.0, **options):
        self.file = sys.stderr if file is None else file
        self.delay = delay
        self.options = options  # for tqdm
        self._what = None
        self._bar = None

    def __call__(self, what, states, transitions=None, seconds=None):
        if self._bar is None or what != self._what:
            self.close()
            self._what = what
            self._bar = progress_bar(desc=str(what), unit=" states", file=self.file, delay=self.delay, **self.options)
        bar = self._bar
        if transitions is not None and not bar.disable:
            rate = f" ({transitions / seconds:,.0f}/s)" if seconds else ""  # wide branching: transitions outrun states
            bar.set_postfix_str(f"{transitions:,} transitions{rate}", refresh=False)
        if states > bar.n:
            bar.update(states - bar.n)

    def close(self) -> None:
        """End the current bar (it is erased: the report follows)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None
        self._what = None

    done = close  # the name verify.cli's hand-written progress line used

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
