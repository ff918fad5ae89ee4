"""The step's coordinates: which rows are the sagittal angles, and the leg swap ``x_start = S x_end``.

Shared by the problem (:mod:`exo_bench.bench.studies.step.problem`) and its transcription with exact
derivatives (:mod:`exo_bench.bench.studies.step.transcription`), which import it, not each other.
"""

from __future__ import annotations

import numpy as np

from exo_bench.models.mechanism.mechanism import Mechanism


def angle_rows(mech: Mechanism) -> np.ndarray:
    """Indices of the sagittal angles of links 1..n: ``phi`` in 2D, ``psi`` in 3D."""
    n = mech.nlinks
    return np.arange(n) if mech.dim == 2 else np.arange(n, 2 * n)


def swap_matrix(mech: Mechanism) -> np.ndarray:
    """``S`` with ``x_start = S x_end``: links (1, 2, 3, 4, 5) take the coordinates of (4, 3, 2, 1, 5);
    3D azimuths change sign (the other leg is the mirror image)."""
    n = mech.nlinks
    perm = [3, 2, 1, 0, 4]
    blocks = 2 if mech.dim == 2 else 3
    S = np.zeros((mech.dof, mech.dof))
    for b in range(blocks):
        sgn = -1.0 if (mech.dim == 3 and b == 0) else 1.0
        for i, j in enumerate(perm):
            S[b * n + i, b * n + j] = sgn
    return S
