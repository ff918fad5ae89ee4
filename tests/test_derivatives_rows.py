"""The output rows of the analytic derivatives written 4 columns at a time (models/newton_euler/derivatives_compiled.py,
numba intrinsics) against the loops they replace (:func:`rows_python`, which also runs under
``NUMBA_DISABLE_JIT``): the same bits, for 2D and 3D, row lengths below 4, multiples of 4 and not (the last 4
columns overlapping), and nothing written outside the link's ``dim`` rows."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from exo_bench.models.newton_euler import derivatives_compiled as dr


@njit
def _compiled_3d(o, i, m, Y, n, e, z):
    dr.rows_3d(o, i, m, Y, n, e, z[0], z[1], z[2], z[3], z[4], z[5], z[6], z[7], z[8])


@njit
def _compiled_2d(o, i, m, Y, n, e, z):
    dr.rows_2d(o, i, m, Y, n, e, z[0], z[1], z[2], z[3])


@pytest.mark.parametrize("dim, n", [(3, 1), (2, 1), (2, 2), (3, 4), (3, 5), (2, 7), (3, 11)])
def test_rows_are_the_loops_bits_and_touch_only_their_rows(dim, n):
    rng = np.random.default_rng(10 * dim + n)
    dof = dim * n
    Y = rng.normal(size=(9, 3 * n)) * 10.0 ** rng.integers(-8, 8, size=(9, 3 * n))
    m = rng.normal(size=dof)
    z = rng.normal(size=dim * dim)
    for i in range(n):
        for e in range(0, 3 * dim, dim):
            ours = np.full((dof, dof), np.nan)
            ref = np.full((dof, dof), np.nan)
            (_compiled_3d if dim == 3 else _compiled_2d)(ours, i, m, Y, n, e, z)
            dr.rows_python(ref, i, m, Y, n, e, *z)
            np.testing.assert_array_equal(ours, ref)  # NaN where neither wrote: only rows c n + i are written
            assert np.isnan(ours).sum() == dof * dof - dim * dof
