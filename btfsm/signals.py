"""Ctrl-C and SIGTERM that are never lost.

Python turns SIGINT into a ``KeyboardInterrupt`` raised wherever the main thread happens to
be. When that is inside a destructor or a weakref callback (matplotlib has some), Python
prints "Exception ignored" with a traceback and goes on: the interrupt is lost and the
command runs to its end. ``handling()`` records every signal it turns into an exception
and keeps Python quiet about the ones swallowed so (``sys.unraisablehook``: the command's
one line says it); long loops call ``check()`` (it raises the recorded interrupt again if it
was swallowed), and ``btfsm.cli.main`` asks ``received()`` when a command returns normally.

>>> reset(); received() is None
True
"""
from __future__ import annotations

import signal
import sys
import threading
from contextlib import contextmanager

from .errors import Terminated

__all__ = ["handling", "check", "received", "reset"]

_state = {"received": None, "raised": False}


def received() -> "int | None":
    """The signal number recorded since ``handling()`` began (or ``reset``), if any."""
    return _state["received"]


def reset() -> None:
    _state["received"] = None


def check() -> None:
    """Raise the recorded interrupt again (it was swallowed where it was first raised)."""
    sig = _state["received"]
    if sig is not None:
        raise Terminated() if sig == signal.SIGTERM else KeyboardInterrupt()


def _handler(signum, frame):
    _state["received"] = signum
    raise Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def _quiet_about_ours(previous):
    """An unraisable-exception hook: our recorded interrupt, swallowed in a destructor or a
    weakref callback, is dropped (``check`` raises it again); anything else goes on to
    ``previous``."""
    def hook(unraisable):
        if isinstance(unraisable.exc_value, KeyboardInterrupt) and _state["received"] is not None:
            return
        previous(unraisable)
    return hook


@contextmanager
def handling():
    """SIGINT raises KeyboardInterrupt and SIGTERM ``Terminated`` while the block runs,
    and both are recorded (main thread only; elsewhere nothing changes)."""
    reset()
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {}
    try:
        for sig in (signal.SIGINT, signal.SIGTERM):
            if signal.getsignal(sig) is signal.SIG_IGN:  # e.g. a background job of a shell
                continue
            previous[sig] = signal.signal(sig, _handler)
    except (ValueError, OSError):
        pass
    hook = sys.unraisablehook
    sys.unraisablehook = _quiet_about_ours(hook)
    try:
        yield
    finally:
        sys.unraisablehook = hook
        for sig, old in previous.items():
            signal.signal(sig, old)
