"""A prepared model's batches in chunks: the working set of one chunk, whatever the batch's length.

A batch is evaluated :attr:`ChunkedCalls.chunk_samples` samples at a time into a preallocated result,
so that a batch of any length needs the inputs, the result and a fixed working set (one chunk's
temporaries): 10^6 samples take no more scratch memory than one chunk (bench/test_memory.py measures
it). The default chunk keeps the working set near :data:`~exo_bench.models.machine.memory.CHUNK_BYTES` for the
largest per-sample temporaries of any method (``n x n`` matrices), or for a method's measured
:meth:`ChunkedCalls.sample_bytes`; ``exo_bench.prepare`` sets it from the method's calibrated cost model
(exo_bench/api/cost_model.py). A result of 4 MiB or more reuses the memory of one returned before, once
nothing refers to that one any more (:mod:`exo_bench.models.runtime.result_pool`).

:class:`~exo_bench.models.runtime.prepared.PreparedModel` derives from :class:`ChunkedCalls`; its public calls
run their per-method parts through :meth:`ChunkedCalls._chunked`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import ClassVar

import numpy as np

from exo_bench.models.machine.memory import chunks, default_chunk_samples
from exo_bench.models.runtime.result_pool import ResultPool


class ChunkedCalls:
    """The chunks of a prepared model of ``dof`` coordinates (module docstring)."""

    #: The registry name of the method (set by each method's class; named in the messages).
    method: ClassVar[str] = ""
    _chunk: int
    _results: ResultPool

    def _start_chunks(self, dof: int, nlinks: int, dim: int) -> None:
        """The default chunk for this mechanism and an empty pool of results (called once, by ``__init__``)."""
        self._chunk = default_chunk_samples(dof, self.sample_bytes(nlinks, dim))
        self._results = ResultPool()  # new batched results, recycled once dropped (models/runtime/result_pool.py)

    @classmethod
    def sample_bytes(cls, nlinks: int, dim: int) -> float | None:
        """Bytes of one sample's temporaries in a batch, measured (the cost model's figure, which
        sizes the chunks); None: the bound of :func:`default_chunk_samples`."""
        return None

    @property
    def chunk_samples(self) -> int:
        """Samples evaluated at a time: batches longer than this are split into chunks written
        into one preallocated result (the working set stays that of one chunk)."""
        return self._chunk

    @chunk_samples.setter
    def chunk_samples(self, value: int) -> None:
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"{self.method}: chunk_samples: expected an integer >= 1, got {value!r}")
        self._chunk = int(value)

    def _chunked(
        self, fn: Callable[..., np.ndarray], arrays: Sequence[np.ndarray], out_shape: tuple[int, ...]
    ) -> np.ndarray:
        """``fn(*chunks)`` over the rows of ``arrays`` in chunks of :attr:`chunk_samples`, into one
        result of shape ``(S, *out_shape)``; one call when the batch fits in a chunk."""
        S = arrays[0].shape[0]
        if S <= self._chunk:
            return fn(*arrays)
        out = self._results.empty((S, *out_shape))
        for c in chunks(S, self._chunk):
            out[c] = fn(*(a[c] for a in arrays))
        return out
