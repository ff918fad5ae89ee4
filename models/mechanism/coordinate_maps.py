"""The constant linear maps between the study's coordinates and an engine's joint coordinates
(``q_joint = G q``, ``tau = G^T tau_joint``), applied so that chunking a batch changes no bit."""

from __future__ import annotations

import numpy as np


def rowwise_product(x: np.ndarray, m: np.ndarray) -> np.ndarray:
    """``x @ m`` for states ``(samples, k)``, with the same bits for a sample alone, in a chunk or in a
    whole batch: the map between the study's coordinates and an engine's joint coordinates (``G`` or
    ``G^T``). A BLAS product rounds a row differently by the batch's size (its kernels for one row and
    for many sum in other orders), and the engines' batches are chunked; numpy's einsum, without its
    BLAS path (``optimize=False``), sums every row in one order."""
    return np.einsum("sj,jk->sk", x, m, optimize=False)
