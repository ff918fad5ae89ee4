"""One source per kernel family for 2D and 3D (issue 35): the batched SIMD kernels of ``matrix-factored``
(matrix_method/numba_kernels/simd.py) and ``newton-euler`` (models/newton_euler/simd.py) build each
dimension's compiled functions from one Python function (``dim`` a constant of its closure), and both
families run step 2 (trig, libm for the angles beyond the fast range) through the one pass of
models/machine/simd_blocks.py. The numbers are held elsewhere: tests/test_compiled_simd.py and
tests/test_newton_euler_simd.py (agreement, bit-identity across block sizes and threads).

Each compiled closure carries its dimension in its qualified name (numba names its symbol after it:
two closures of one source that shared a name could swap machine code through the on-disk cache,
models/machine/numba_runtime.py ``jit_for``).
"""

from __future__ import annotations

import pytest

from exo_bench.matrix_method.numba_kernels import simd as factored_simd
from exo_bench.models.machine import simd_blocks
from exo_bench.models.newton_euler import simd as ne_simd


def _cells(dispatcher) -> dict:
    fn = dispatcher.py_func
    return dict(zip(fn.__code__.co_freevars, (c.cell_contents for c in fn.__closure__ or ())))


@pytest.mark.parametrize(
    "planar, spatial",
    [
        (factored_simd.KERNELS[2], factored_simd.KERNELS[3]),
        (factored_simd._compute_2d, factored_simd._compute_3d),
        (ne_simd._forward_2d, ne_simd._forward_3d),
        (ne_simd._NARROW._forward_2d, ne_simd._NARROW._forward_3d),
    ],
    ids=["factored-driver", "factored-steps", "newton-euler-forward", "newton-euler-forward-narrow"],
)
def test_2d_and_3d_are_one_source_with_the_dimension_a_constant(planar, spatial):
    assert planar is not spatial
    assert planar.py_func.__code__ is spatial.py_func.__code__  # one function body, compiled twice
    assert _cells(planar)["dim"] == 2 and _cells(spatial)["dim"] == 3
    assert planar.py_func.__qualname__ != spatial.py_func.__qualname__
    assert "_2d" in planar.py_func.__qualname__ and "_3d" in spatial.py_func.__qualname__


@pytest.mark.parametrize("step", [factored_simd._compute_3d, ne_simd._forward_3d, ne_simd._NARROW._forward_2d])
def test_both_families_run_the_one_angle_pass(step):
    cells = _cells(step)
    assert cells["link_pass"] is simd_blocks.link_pass
    assert cells["libm_pass"] is simd_blocks.libm_pass


def test_the_newton_euler_block_sizes_are_named_apart():
    wide, narrow = ne_simd._forward_3d.py_func.__qualname__, ne_simd._NARROW._forward_3d.py_func.__qualname__
    assert (
        wide != narrow and wide.endswith(f"_{ne_simd.LANES}lanes") and narrow.endswith(f"_{ne_simd.NARROW_LANES}lanes")
    )
