"""``hypothesis.strategies`` as ``st``, with the strategies the test generators build at
every draw memoised (``from memo_strategies import st``).

The generators (core_strategies.py, strategies.py, the tests' own) write
``draw(st.integers(0, 4))``, ``draw(st.sampled_from(names))`` deep inside their recursion,
so each example builds hundreds of new strategy objects, and hypothesis validates (and
analyses) each new strategy object the first time it draws from it: that, not building
the models, was most of their cost. A memoised strategy is the same strategy (equal
arguments of equal types), so the same choices give the same examples (objects other than
plain values are keyed by identity, so a draw gives the very objects it was given).
"""
from __future__ import annotations

from hypothesis import strategies as _st

__all__ = ["st"]


class _Memo:
    """``hypothesis.strategies``; the five below memoised (a bounded cache)."""

    LIMIT = 50_000

    def __init__(self):
        self._cache: dict = {}

    def __getattr__(self, name):
        return getattr(_st, name)

    def _get(self, fn, args, kwargs):
        try:
            key = (fn, _memo_key(args), _memo_key(tuple(sorted(kwargs.items()))))
            hit = self._cache.get(key)
        except TypeError:  # unhashable arguments: not memoised
            return getattr(_st, fn)(*args, **kwargs)
        if hit is None:
            if len(self._cache) >= self.LIMIT:
                self._cache.clear()
            hit = self._cache[key] = getattr(_st, fn)(*args, **kwargs)
        return hit

    def integers(self, *args, **kwargs):
        return self._get("integers", args, kwargs)

    def booleans(self):
        return self._get("booleans", (), {})

    def sampled_from(self, elements):
        return self._get("sampled_from", (tuple(elements),), {})

    def lists(self, *args, **kwargs):
        return self._get("lists", args, kwargs)

    def one_of(self, *args):
        return self._get("one_of", args, {})


_VALUES = (str, int, float, bool, bytes, type(None))


def _memo_key(x):
    """A hashable key: plain values by value and type (1, 1.0 and True differ), tuples
    element by element, any other object by identity (a test may compare what it drew
    with ``is``: an equal object from an earlier example would not do; the cache keeps the
    object alive, so its id is not reused). TypeError (not memoised) for lists: a test
    may change a list it drew."""
    if type(x) is tuple:
        return (tuple, tuple(_memo_key(y) for y in x))
    if isinstance(x, list):
        raise TypeError("a list is not memoised")
    if type(x) in _VALUES:
        return (type(x), x)
    return (type(x), id(x))


st = _Memo()
