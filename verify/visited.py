"""The visited set of the traced engine (``btfsm.verify.traced``): the codes of the states
found so far, in discovery order, and a set of them: a table of state ids over the code
space (``Ids``, up to ``btfsm.verify.traced.DENSE_IDS`` codes: targets are ids at once), a
bitmap over the code space (``Bitmap``) or, past ``btfsm.verify.traced.DENSE_LIMIT`` codes,
an open-addressing hash table (``Hashed``). During the search the bitmap and the table only
answer "seen or not"; ``number`` turns the transitions' target codes into state ids once, at
the end."""
from __future__ import annotations

import sys
from typing import Any, Callable

import numpy as np

from .codec import code_dtype

__all__ = ["Visited", "Ids", "Bitmap", "Hashed", "STEP", "FIBONACCI"]

STEP = 1 << 20  # codes numbered, hashed or ranked at a time (bounds the temporaries)


class Visited:
    """The states found so far: their codes in discovery order (``codes[i]`` is state i's
    code, in the smallest type that holds the code space) and a set of codes. During the
    search the set only answers "seen or not" (``seen``); transitions keep their targets'
    codes, and ``number`` turns those into state ids once, at the end."""

    direct = False  # True: ``ids`` answers during the search (``Ids``)

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
    """Set bits of each unsigned int (numpy >= 2: ``bitwise_count``; else a byte table)."""
    count = getattr(np, "bitwise_count", None)
    if count is not None:
        return count(words)
    return _BYTE_BITS[words.view(np.uint8)].reshape(-1, words.itemsize).sum(axis=1, dtype=np.uint8)


_BYTE_BITS = np.array([bin(i).count("1") for i in range(256)], np.uint8)
_BIT = np.left_shift(np.uint64(1), np.arange(64, dtype=np.uint64))  # bit b of a word
_BELOW32 = np.left_shift(np.uint64(1), np.arange(32, dtype=np.uint64)) - np.uint64(1)  # the bits below bit b


class Bitmap(Visited):
    """Visited codes as one bit per code of the code space (``total / 8`` bytes, pages
    touched only where states are). Ids at the end: a code's rank among the visited codes
    (a prefix count per 32-bit word, packed beside the word, plus a popcount) indexes a
    rank-to-id table."""

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

    def ids(self, codes):
        if self.ranked is None:
            # 32 codes a word, each word packed with the number of visited codes before it
            # (high 32 bits) beside its bits (low 32 bits): a code's rank is one lookup and
            # a popcount
            words = self.bits.view(np.uint32) if sys.byteorder == "little" else np.stack(
                [self.bits & np.uint64(0xFFFFFFFF), self.bits >> np.uint64(32)], axis=1).ravel().astype(np.uint32)
            packed = np.empty(len(words), np.uint64)
            before = np.uint64(0)
            for a in range(0, len(words), STEP):
                w = words[a:a + STEP]
                count = _popcount(w)
                p = packed[a:a + STEP]
                np.cumsum(count, dtype=np.uint64, out=p)
                p += before
                before = p[-1]
                p -= count
                p <<= np.uint64(32)
                p |= w
            dt = np.int32 if self.n < 1 << 31 else np.int64
            by_rank = np.empty(self.n, dt)
            self.ranked = (packed, by_rank)
            for a in range(0, self.n, STEP):
                b = min(a + STEP, self.n)
                by_rank[self._rank(self.codes[a:b])] = np.arange(a, b, dtype=dt)
        return self.ranked[1][self._rank(codes)]

    def _rank(self, codes):
        p = self.ranked[0][codes >> 5]
        r = p >> np.uint64(32)
        r += _popcount(p & _BELOW32[codes & 31])
        return r


class Ids(Visited):
    """Visited codes as a table of state ids over the whole code space (id + 1 per code,
    0: not seen; 4 bytes per code, pages touched only where states are), for code spaces
    up to ``DENSE_IDS``: a target's id is known once its batch is done, so transitions
    keep ids from the start and nothing is numbered at the end (``direct``)."""

    direct = True

    def __init__(self, total, c0):
        super().__init__(total, c0)
        self.table = np.zeros(total, np.int32)
        self.table[c0] = 1

    def seen(self, codes):
        return self.table[codes] != 0

    def index(self, codes):
        self.table[codes] = np.arange(self.n - len(codes) + 1, self.n + 1, dtype=np.int32)

    def ids(self, codes):
        out = self.table[codes]
        out -= 1
        return out


#: Fibonacci hashing's multiplier, 2**64 / golden ratio (``Hashed``, and ``distributed.owner``)
FIBONACCI = np.uint64(0x9E3779B97F4A7C15)


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
        h = codes.astype(np.uint64) * FIBONACCI
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
