"""A memo keyed on user input holds at most a fixed number of entries (issue 34; the guide: "no module
globals that mutate" and a long-running process that prepares many mechanisms must not grow without
bound).

:class:`BoundedCache` is a dict that forgets its least recently stored or read entry beyond
``maxsize``: the module-level memos of derivations and compiled functions keyed on a mechanism
(lagrange/derivation.py, lagrange/numeric.py, bench/perf/peers.py) are instances of it. Memos of
constants (a kernel, a class's type hints) stay ``functools.cache``.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import TypeVar

K = TypeVar("K")
V = TypeVar("V")


class BoundedCache(OrderedDict[K, V]):
    """An ordered dict of at most ``maxsize`` entries; storing or reading (``[key]``) an entry makes it
    the most recent, and storing beyond ``maxsize`` drops the least recent."""

    def __init__(self, maxsize: int) -> None:
        if isinstance(maxsize, bool) or not isinstance(maxsize, int) or maxsize < 1:
            raise ValueError(f"BoundedCache: field 'maxsize': expected an integer >= 1, got {maxsize!r}")
        super().__init__()
        self.maxsize = maxsize

    def __getitem__(self, key: K) -> V:
        value = super().__getitem__(key)
        self.move_to_end(key)
        return value

    def __setitem__(self, key: K, value: V) -> None:
        super().__setitem__(key, value)
        self.move_to_end(key)
        while len(self) > self.maxsize:
            self.popitem(last=False)
