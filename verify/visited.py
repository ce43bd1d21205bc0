"""The visited set of the traced engine (``btfsm.verify.traced``): the codes of the states
found so far, in discovery order, and a set of them: a bitmap over the code space
(``Bitmap``) or, past ``btfsm.verify.traced.DENSE_LIMIT`` codes, an open-addressing hash
table (``Hashed``). During the search the set only answers "seen or not"; ``number`` turns
the transitions' target codes into state ids once, at the end."""
from __future__ import annotations

from typing import Any, Callable

import numpy as np

from .codec import code_dtype

__all__ = ["Visited", "Bitmap", "Hashed", "STEP"]

STEP = 1 << 20  # codes numbered, hashed or ranked at a time (bounds the temporaries)


class Visited:
    """The states found so far: their codes in discovery order (``codes[i]`` is state i's
    code, in the smallest type that holds the code space) and a set of codes. During the
    search the set only answers "seen or not" (``seen``); transitions keep their targets'
    codes, and ``number`` turns those into state ids once, at the end."""

    def __init__(self, total, c0):
        self.codes = np.zeros(1024, code_dtype(total))
        self.codes[0] = c0
        self.n = 1

    # each subclass's set of codes
    ids: Callable[[np.ndarray], np.ndarray]
    index: Callable[[np.ndarray], Any]

    def batch(self, head: int, k: int) -> np.ndarray:
        return self.codes[head:head + k].astype(np.int64)

    def add(self, codes):
        """Number the new (distinct, unseen) ``codes`` ``n, n+1, ...``."""
        m = len(codes)
        if self.n + m > len(self.codes):
            grown = np.zeros(max(2 * len(self.codes), self.n + m), self.codes.dtype)
            grown[:self.n] = self.codes[:self.n]
            self.codes = grown
        self.codes[self.n:self.n + m] = codes
        self.n += m
        self.index(codes)

    def number(self, targets: np.ndarray) -> np.ndarray:
        """The state ids of the codes ``targets`` (all seen), converted in place when the
        types allow (uint32 codes to int32 ids), in slices."""
        dt = np.int32 if self.n < 1 << 31 else np.int64
        out = targets.view(dt) if targets.dtype.itemsize == np.dtype(dt).itemsize else np.empty(len(targets), dt)
        for a in range(0, len(targets), STEP):
            out[a:a + STEP] = self.ids(targets[a:a + STEP])
        return out


def _popcount(words: np.ndarray) -> np.ndarray:
    """Set bits of each uint64 (numpy >= 2: ``bitwise_count``; else a byte table)."""
    count = getattr(np, "bitwise_count", None)
    if count is not None:
        return count(words)
    return _BYTE_BITS[words.view(np.uint8)].reshape(-1, 8).sum(axis=1, dtype=np.uint8)


_BYTE_BITS = np.array([bin(i).count("1") for i in range(256)], np.uint8)
_BIT = np.left_shift(np.uint64(1), np.arange(64, dtype=np.uint64))  # bit b of a word
_BELOW = _BIT - np.uint64(1)  # the bits below bit b


class Bitmap(Visited):
    """Visited codes as one bit per code of the code space (``total / 8`` bytes, pages
    touched only where states are). Ids at the end: a code's rank among the visited codes
    (a prefix count per 64-bit word plus a popcount) indexes a rank-to-id table."""

    def __init__(self, total, c0):
        super().__init__(total, c0)
        self.bits = np.zeros((total + 63) // 64, np.uint64)
        self.index(np.array([c0], np.int64))
        self.ranked = None

    def seen(self, codes):
        return (self.bits[codes >> 6] & _BIT[codes & 63]) != 0

    def index(self, codes):
        if not len(codes):
            return
        codes = np.sort(codes)
        word = codes >> 6
        starts = np.flatnonzero(np.concatenate(([True], word[1:] != word[:-1])))
        self.bits[word[starts]] |= np.bitwise_or.reduceat(_BIT[codes & 63], starts)

    def _rank(self, codes, prefix):
        word = codes >> 6
        return prefix[word] + _popcount(self.bits[word] & _BELOW[codes & 63])

    def ids(self, codes):
        if self.ranked is None:
            dt = np.int32 if self.n < 1 << 31 else np.int64
            counts = np.zeros(len(self.bits), dt)
            for a in range(0, len(self.bits), STEP):
                counts[a:a + STEP] = _popcount(self.bits[a:a + STEP])
            exclusive = np.zeros(len(self.bits), dt)  # visited codes in the words before
            np.cumsum(counts[:-1], out=exclusive[1:])
            del counts
            by_rank = np.empty(self.n, dt)
            for a in range(0, self.n, STEP):
                b = min(a + STEP, self.n)
                by_rank[self._rank(self.codes[a:b], exclusive)] = np.arange(a, b, dtype=dt)
            self.ranked = (exclusive, by_rank)
        exclusive, by_rank = self.ranked
        return by_rank[self._rank(codes, exclusive)]


_GOLDEN = np.uint64(0x9E3779B97F4A7C15)


class Hashed(Visited):
    """Visited codes as an open-addressing hash table of state ids (linear probing,
    multiplicative hashing, at most ``LOAD`` full, doubled when fuller); a slot holds an id
    and the code is read from ``codes``, so the table costs 4 bytes per slot (8 to 16
    bytes per state). For code spaces too large for a bitmap. Lookups and insertions are
    vectorised: each round settles every query whose probe hit its code or an empty slot,
    the others move one slot on."""

    LOAD = 0.5
    FIRST = 1 << 16  # slots of the first table

    def __init__(self, total, c0):
        super().__init__(total, c0)
        self.table = None
        self._resize(self.FIRST)

    def _resize(self, size):
        self.bits = size.bit_length() - 1
        self.mask = size - 1
        self.table = None  # the old table goes before the new one is made
        self.table = np.full(size, -1, np.int32 if size < 1 << 31 else np.int64)
        for a in range(0, self.n, STEP):  # in slices: few temporaries
            b = min(a + STEP, self.n)
            self._insert(self.codes[a:b].astype(np.int64), np.arange(a, b, dtype=np.int64))

    def _home(self, codes):
        h = codes.astype(np.uint64) * _GOLDEN
        return (h >> np.uint64(64 - self.bits)).astype(np.int64)

    def seen(self, codes):
        return self.ids(codes) >= 0

    def ids(self, codes):
        codes = codes.astype(np.int64)
        out = np.full(len(codes), -1, np.int64)
        idx = np.arange(len(codes), dtype=np.int64)
        h = self._home(codes)
        table, stored, mask = self.table, self.codes, self.mask
        while idx.size:
            got = table[h]
            live = got >= 0
            idx, h, got = idx[live], h[live], got[live]
            hit = stored[got] == codes[idx]
            out[idx[hit]] = got[hit]
            miss = ~hit
            idx, h = idx[miss], (h[miss] + 1) & mask
        return out

    def _insert(self, codes, ids):
        h = self._home(codes)
        idx = np.arange(len(codes), dtype=np.int64)
        table, mask = self.table, self.mask
        while idx.size:
            free = table[h] < 0
            fi, fh = idx[free], h[free]
            table[fh] = ids[fi]  # rivals for one slot: one of them gets it
            won = table[fh] == ids[fi]
            idx = np.concatenate([idx[~free], fi[~won]])
            h = (np.concatenate([h[~free], fh[~won]]) + 1) & mask

    def index(self, codes):
        if self.n > self.LOAD * len(self.table):
            size = len(self.table)
            while self.n > self.LOAD * size:
                size *= 2
            self._resize(size)  # re-inserts every stored code, the new ones included
        else:
            self._insert(codes.astype(np.int64), np.arange(self.n - len(codes), self.n, dtype=np.int64))
