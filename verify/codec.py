"""The state codec shared by the exploration engines: a state is one int code, a mixed
radix over the kept slots' domains (``code = sum(state[k] * mults[k]) - offset``), and
batches of codes decode into rows of small ints.

>>> from btfsm import Model, Int, Bool
>>> prog = Model("m", variables=[Int("n", 1, 3), Bool("b")]).program
>>> mults, offset, total = codec(prog, (0, 1))
>>> mults, offset, total
((2, 1), 2, 6)
>>> from array import array
>>> decode(prog, (0, 1), array("q", [3 * 2 + 1]), offset, mults).tolist()
[[3, 1]]
"""
from __future__ import annotations

import numpy as np

__all__ = ["codec", "decode", "decode_codes", "code_dtype", "rows", "dtype"]


def codec(prog, kept):
    """(multipliers over all slots, offset, total): code = sum(s * mult) - offset."""
    mults = [0] * len(prog.slots)
    total, offset = 1, 0
    for k in reversed(kept):
        info = prog.slots[k]
        mults[k] = total
        offset += info.lo * total
        total *= max(info.size, 1)
    return tuple(mults), offset, total


def dtype(prog, kept):
    lo = min((prog.slots[k].lo for k in kept), default=0)
    hi = max((prog.slots[k].lo + prog.slots[k].size - 1 for k in kept), default=0)
    for dt in (np.int8, np.int16, np.int32):
        info = np.iinfo(dt)
        if info.min <= lo and hi <= info.max:
            return dt
    return np.int64


def decode(prog, kept, codes, offset, mults) -> np.ndarray:
    c = np.frombuffer(codes, dtype=np.int64) - offset
    out = np.empty((len(c), len(kept)), dtype=dtype(prog, kept))
    for col, k in enumerate(kept):
        info = prog.slots[k]
        out[:, col] = (c // mults[k]) % max(info.size, 1) + info.lo
    return out


def decode_codes(prog, kept, codes: np.ndarray, mults) -> np.ndarray:
    """Rows of slot values (one column per ``kept`` slot) of an array of codes as ``codec``
    makes them (the offset already subtracted), one column at a time."""
    out = np.empty((len(codes), len(kept)), dtype=dtype(prog, kept))
    wide = codes.astype(np.int64, copy=False)
    for col, k in enumerate(kept):
        info = prog.slots[k]
        out[:, col] = (wide // mults[k]) % max(info.size, 1) + info.lo
    return out


def code_dtype(total: int):
    """The smallest numpy type that holds every code below ``total``: uint32 or int64."""
    return np.uint32 if total <= 1 << 32 else np.int64


def rows(prog, kept, tuples) -> np.ndarray:
    return np.array(tuples, dtype=dtype(prog, kept)).reshape(len(tuples), len(kept))
