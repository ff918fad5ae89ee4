"""The 8 x 8 SIMD transposes (models/machine/simd_blocks.py) and the block transposes built on them
(models/machine/simd_blocks.py: block_transposes), against numpy's indexing: pure data movement, so the
oracle is equality to the bit, with every column count of the last tile (1-8) and the masked
lanes neither read past the end of the states nor written into the result."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit

from exo_bench.models.machine.simd_blocks import ROWS, FROWS, O0, block_transposes
from exo_bench.models.machine.simd_blocks import TILE, tile_in, tile_out


@njit
def _in(src, base, stride, rem, dst, offs, c0, add):
    tile_in(src, base, stride, rem, dst, offs, c0, add)


@njit
def _out(src, offs, c0, add, dst, base, stride, rem):
    tile_out(src, offs, c0, add, dst, base, stride, rem)


@pytest.mark.parametrize("rem", range(1, TILE + 2))
def test_one_tile_in_and_out_moves_the_columns_it_is_given(rem):
    stride = max(rem, TILE) + 3
    rng = np.random.default_rng(rem)
    # the tile's last row ends where the array ends: the masked lanes would read past it
    src = rng.standard_normal((TILE - 1) * stride + rem)
    offs = np.array([5 + 11 * i for i in range(TILE)], dtype=np.int64)
    dst = np.full(5 + 11 * TILE + TILE, np.nan)
    _in(src, 0, stride, rem, dst, offs, 0, 2)
    rows = np.array([src[r * stride : r * stride + min(rem, TILE)] for r in range(TILE)])
    for i in range(min(rem, TILE)):
        assert np.array_equal(dst[offs[i] + 2 : offs[i] + 2 + TILE], rows[:, i])
    back = np.full(src.size, np.nan)
    _out(dst, offs, 0, 2, back, 0, stride, rem)
    for r in range(TILE):
        row = back[r * stride : r * stride + stride]
        assert np.array_equal(row[: min(rem, TILE)], rows[r])
        assert np.isnan(row[min(rem, TILE) :]).all()  # the masked lanes are not written


@pytest.mark.parametrize("n, blocks", [(1, 2), (1, 3), (5, 3), (3, 2), (8, 3), (6, 2)])
@pytest.mark.parametrize("lanes", [16, 32])
def test_block_transposes_put_every_state_in_its_row(n, blocks, lanes):
    scratch, rows_in, rows_out = block_transposes(lanes)
    dof, S = n * blocks, 2 * lanes + 3
    rng = np.random.default_rng(dof)
    q, qd, qdd = (rng.standard_normal(S * dof) for _ in range(3))
    for s0, m in ((0, lanes), (lanes, lanes), (2 * lanes, 3)):  # two whole blocks (tiles), a partial one (loops)
        W, F, T = scratch(n, blocks)
        rows_in(q, qd, qdd, s0, m, n, blocks, W, T)
        for a, x in enumerate((q, qd, qdd)):
            states = x.reshape(S, dof)[s0 : s0 + m]
            for k in range(blocks):
                for j in range(n):
                    row = (j * ROWS + 3 * a + k) * lanes
                    assert np.array_equal(W[row : row + m], states[:, k * n + j]), (s0, a, k, j)
        want = rng.standard_normal((m, dof))
        for k in range(blocks):
            for i in range(n):
                row = (i * FROWS + O0 + k) * lanes
                F[row : row + m] = want[:, k * n + i]
        o = np.full(S * dof, np.nan)
        rows_out(o, s0, m, n, blocks, F, T)
        o = o.reshape(S, dof)
        assert np.array_equal(o[s0 : s0 + m], want)
        assert np.isnan(np.delete(o, range(s0, s0 + m), axis=0)).all()
