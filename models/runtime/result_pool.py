"""Result arrays recycled once their caller has dropped them: a prepared model's free list.

A batched call without ``out=`` returns a new array. glibc serves a request above its mmap threshold
(dynamic, at most 32 MiB) with a fresh mapping, which it unmaps again on ``free``, so every such call
pays the OS for zeroing the result's pages on first touch, in the kernel's threads. Measured on
``newton-euler``, 3D chain of 1000 links, 1398 samples (the full sweep's row: a 33.5 MB result), two
threads: 19.2-24.0 ms per call with a new result (530 page faults each, ``getrusage``) against
12.6-14.1 ms with ``out=``, the rest of the call unchanged. Whether glibc maps afresh or reuses its
heap depends on what the process allocated before, so the same call measured 12.5 ms in another
script: the cost was noise in the sweep as well as a cost.

:class:`ResultPool` keeps the last :data:`KEEP` results of at least :data:`MIN_BYTES` that it handed
out, and hands one out again when nothing outside the pool refers to it any more (its reference count
is the pool's own, :func:`_refs`): the caller's result is never written after it was returned, and
a view, a ``memoryview`` or a ``ctypes`` pointer object of it keeps it from reuse like the array itself.
Two alternate in a loop ``tau = model.inverse_dynamics(...)``, which still holds the previous result
while the next call runs. The cost is memory: up to :data:`KEEP` results stay allocated after the
caller dropped them, until the model is released. Reference counts cannot tell this in a
free-threaded build (deferred counts), so there every call allocates (:data:`RECYCLES`).
"""

from __future__ import annotations

import sys
import threading

import numpy as np

#: Results kept per pool. Two: a loop holds the previous result during the next call.
KEEP = 2
#: Smaller results come from ``np.empty``: glibc's heap recycles those itself (its threshold starts at
#: 128 KiB and rises to the size of any mapped block freed, up to 32 MiB).
MIN_BYTES = 1 << 22


def _refs(pool: list, i: int) -> int:
    """The reference count of ``pool[i]`` as seen from here (the list's, plus this call's own)."""
    return sys.getrefcount(pool[i])


def _own_refs() -> int:
    """:func:`_refs` of an array that only its list refers to: measured, not assumed, since the
    interpreter's own references differ between versions."""
    return _refs([np.empty(1)], 0)


def _own_bound_refs() -> int:
    """The reference count :meth:`ResultPool.empties` reads of an array that only its list refers to,
    bound to a loop variable as there (measured, as :func:`_own_refs`)."""
    for a in [np.empty(1)]:
        return sys.getrefcount(a)
    raise AssertionError


#: False where reference counts are deferred (free-threaded builds): then nothing is recycled.
RECYCLES = bool(getattr(sys, "_is_gil_enabled", lambda: True)())
_OWN = _own_refs()
_OWN_BOUND = _own_bound_refs()


class ResultPool:
    """Float64 results of one prepared model: :meth:`empty` is ``np.empty`` that reuses a dropped
    result of the same shape (module docstring)."""

    def __init__(self, keep: int = KEEP, min_bytes: int = MIN_BYTES):
        self._keep = keep
        self._min_bytes = min_bytes
        self._arrays: list[np.ndarray] = []
        self._lock = threading.Lock()

    def empty(self, shape: tuple[int, ...]) -> np.ndarray:
        """An uninitialised C-ordered float64 array of ``shape`` that no one else refers to."""
        size = 8
        for d in shape:  # not np.prod (3-15 us a call), nor a generator (a frame per step)
            size *= int(d)
        if not RECYCLES or size < self._min_bytes:
            return np.empty(shape)
        shape = tuple(int(d) for d in shape)
        with self._lock:
            arrays = self._arrays
            for i in range(len(arrays)):
                if arrays[i].shape == shape and _refs(arrays, i) == _OWN:
                    return arrays[i]
            new = np.empty(shape)
            self._arrays = [new, *arrays][: self._keep]
            return new

    def empties(self, shape: tuple[int, ...], count: int) -> list[np.ndarray]:
        """``count`` arrays of :meth:`empty` at once, distinct, in one Python call (no generator: the
        derivative calls count the Python functions they run)."""
        out: list[np.ndarray] = []
        size = 8
        for d in shape:  # as empty: not np.prod, nor a generator
            size *= int(d)
        if not RECYCLES or size < self._min_bytes:
            for _ in range(count):
                out.append(np.empty(shape))
            return out
        shape = tuple(map(int, shape))
        with self._lock:
            for a in self._arrays:  # a result handed out in this call is referred to by out: never again
                if len(out) < count and a.shape == shape and sys.getrefcount(a) == _OWN_BOUND:
                    out.append(a)
            new = []
            while len(out) < count:
                new.append(np.empty(shape))
                out.append(new[-1])
            self._arrays = [*new, *self._arrays][: self._keep]
        return out

    def release(self) -> None:
        """Drop the kept results (their memory is freed once their callers drop them too)."""
        with self._lock:
            self._arrays = []

    def __len__(self) -> int:
        return len(self._arrays)
