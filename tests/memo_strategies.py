"""``hypothesis.strategies`` as ``st``, with the strategies the test generators build at
every draw memoised (``from memo_strategies import st``).

The generators (core_strategies.py, strategies.py) write ``draw(st.integers(0, 4))``,
``draw(st.sampled_from(names))`` deep inside their recursion, so each example builds
hundreds of new strategy objects, and hypothesis validates (and analyses) each new
strategy object the first time it draws from it: that, not building the models, was most
of their cost. A memoised strategy is the same strategy (equal arguments of equal types),
so the same choices give the same examples.
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


def _memo_key(x):
    """A hashable key that tells apart equal values of different types (1, 1.0, True)."""
    if type(x) in (tuple, list):
        return (type(x), tuple(_memo_key(y) for y in x))
    return (type(x), x)


st = _Memo()
