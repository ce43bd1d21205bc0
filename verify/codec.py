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


_DIGITS = 1 << 16  # values of one group of slots decoded by one table lookup


def _groups(prog, kept, mults) -> list:
    """Runs of consecutive kept columns whose domains multiply to at most ``_DIGITS``:
    ``(first column, end column, multiplier of the run's last slot, values)``."""
    out, end, prod = [], len(kept), 1
    for col in range(len(kept) - 1, -1, -1):
        size = max(prog.slots[kept[col]].size, 1)
        if prod * size > _DIGITS and end > col + 1:
            out.append((col + 1, end, mults[kept[end - 1]], prod))
            end, prod = col + 1, 1
        prod *= size
    out.append((0, end, mults[kept[end - 1]] if end else 1, prod))
    return out


def decode(prog, kept, codes, offset, mults) -> np.ndarray:
    """Rows of slot values of the codes (``codes + offset`` as stored): each run of
    slots (``_groups``) is one digit of the code, read by one division and turned into
    the run's columns by one lookup in the table of all its values."""
    c = np.frombuffer(codes, dtype=np.int64) - offset
    dt = dtype(prog, kept)
    out = np.empty((len(c), len(kept)), dtype=dt)
    if not kept:
        return out
    for a, b, m, prod in _groups(prog, kept, mults):
        if prod > _DIGITS or 4 * len(c) < prod:  # one slot alone past the table size, or few codes
            for col in range(a, b):
                info = prog.slots[kept[col]]
                out[:, col] = (c // mults[kept[col]]) % max(info.size, 1) + info.lo
            continue
        digit = np.arange(prod, dtype=np.int64)
        table = np.empty((prod, b - a), dtype=dt)
        for col in range(a, b):
            info = prog.slots[kept[col]]
            table[:, col - a] = (digit // (mults[kept[col]] // m)) % max(info.size, 1) + info.lo
        out[:, a:b] = table[(c // m) % prod if m != 1 else c % prod]
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
