"""Ctrl-C and SIGTERM that are never lost.

Python turns SIGINT into a ``KeyboardInterrupt`` raised wherever the main thread happens to
be. When that is inside a destructor or a weakref callback (matplotlib has some), Python
prints "Exception ignored" and goes on: the interrupt is lost and the command runs to its
end. ``handling()`` records every signal it turns into an exception; long loops call
``check()`` (it raises the recorded interrupt again if it was swallowed), and
``btfsm.cli.main`` asks ``received()`` when a command returns normally.

>>> reset(); received() is None
True
"""
from __future__ import annotations

import signal
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
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
