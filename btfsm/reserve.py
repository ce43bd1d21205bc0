"""A memory reserve for reporting an exhaustion in one line.

Under an address-space limit (``ulimit -v``) a ``MemoryError`` can strike anywhere, and
the report itself (formatting a message, writing it, even a traceback) needs memory. The
command line holds ``RESERVE_BYTES`` from its start (``hold``); on a ``MemoryError`` it
lets go of the reserve and of what the failed computation held (``release``: the
exception chain's tracebacks keep its frames, and their arrays, alive) before it reports
the budget exit (3).

>>> hold(1 << 10); held()
True
>>> release(MemoryError()); held()
False
"""
from __future__ import annotations

import gc

__all__ = ["RESERVE_BYTES", "hold", "held", "release"]

RESERVE_BYTES = 32 << 20
_reserve: list = []


def hold(size: int = RESERVE_BYTES) -> None:
    """Set ``size`` bytes aside (once; a second call keeps the first reserve)."""
    if not _reserve:
        try:
            _reserve.append(bytearray(size))
        except MemoryError:  # too little memory to start with: nothing set aside
            pass


def held() -> bool:
    return bool(_reserve)


def release(exc: "BaseException | None" = None) -> None:
    """Free the reserve, drop the tracebacks of ``exc`` and the exceptions it chains
    (their frames hold the failed computation's data) and collect what is left."""
    _reserve.clear()
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        exc.__traceback__ = None
        exc = exc.__cause__ or exc.__context__
    gc.collect()
