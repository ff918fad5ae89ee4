"""The branch-free sin/cos of the SIMD kernel (models/machine/fast_trig.py) against numpy.

**Error model.** fast_trig states at most :data:`fast_trig.ULPS` (2) ulp from numpy's float64
``sin``/``cos`` (glibc's, correctly rounded in practice, so 1.5 ulp from exact) on
``|x| <= RANGE``; that is the bound asserted. An ulp is ``np.spacing`` of numpy's result (for a
result exactly 0 or subnormal: of the smallest normal, i.e. the absolute error is then checked at
2^-1022 granularity).

Where the bound must hold: uniformly over the range; at its edges (``+-RANGE`` and their
neighbours: the last doubles of the arithmetic path and the first of the libm fallback); at the
doubles nearest to every multiple of pi/2 in the range, where the reduction ``x - k pi/2``
cancels and an error in pi/2 would show as a large relative error; at the quadrant boundaries
(odd multiples of pi/4), where the reduced argument is largest. Beyond the range, and for
infinities and NaN, the fallback is libm itself: equal to numpy, NaN for NaN.
"""

from __future__ import annotations

import numpy as np
import pytest

from exo_bench.models.machine import fast_trig

BOUND = fast_trig.ULPS


def _ulps(got: np.ndarray, want: np.ndarray) -> np.ndarray:
    unit = np.maximum(np.spacing(np.abs(want)), np.finfo(float).tiny)
    return np.abs(got - want) / unit


def _check(x: np.ndarray, what: str, bound: float = BOUND) -> None:
    s, c = fast_trig.sincos_array(np.ascontiguousarray(x, dtype=float))
    es, ec = _ulps(s, np.sin(x)), _ulps(c, np.cos(x))
    worst = max(es.max(), ec.max())
    k = int(np.argmax(np.maximum(es, ec)))
    assert worst <= bound, f"{what}: {worst:.2f} ulp from numpy at x = {x[k]!r} (bound {bound})"


def test_uniformly_over_the_range():
    rng = np.random.default_rng(0)
    _check(rng.uniform(-fast_trig.RANGE, fast_trig.RANGE, 400_000), "uniform over +-RANGE")
    r = fast_trig.JOINT_RANGE
    _check(rng.uniform(-r, r, 400_000), "uniform over the joint range", fast_trig.JOINT_ULPS)
    _check(rng.uniform(-1e-3, 1e-3, 100_000), "small angles")


def test_at_the_doubles_nearest_every_multiple_of_half_pi():
    k = np.arange(-int(fast_trig.RANGE / (np.pi / 2)), int(fast_trig.RANGE / (np.pi / 2)) + 1)
    centre = k * (np.pi / 2)
    x = np.concatenate(
        [centre]
        + [np.nextafter(centre, d) for d in (np.inf, -np.inf)]
        + [np.nextafter(np.nextafter(centre, d), d) for d in (np.inf, -np.inf)]
    )
    _check(x[np.abs(x) <= fast_trig.RANGE], "next to k pi/2")


def test_at_the_quadrant_boundaries():
    k = np.arange(-int(fast_trig.RANGE / (np.pi / 2)), int(fast_trig.RANGE / (np.pi / 2)))
    mid = (k + 0.5) * (np.pi / 2)
    x = np.concatenate([mid, np.nextafter(mid, np.inf), np.nextafter(mid, -np.inf)])
    _check(x[np.abs(x) <= fast_trig.RANGE], "at (k + 1/2) pi/2")


def test_at_the_edges_of_the_range_and_beyond():
    r = fast_trig.RANGE
    edge = np.array(
        [
            r,
            -r,
            np.nextafter(r, 0),
            np.nextafter(-r, 0),
            np.nextafter(r, np.inf),
            np.nextafter(-r, -np.inf),
            2 * r,
            1e6,
            1e12,
            1e300,
            -1e300,
            0.0,
            -0.0,
            5e-324,
            1e-300,
        ]
    )
    _check(edge, "edges")
    beyond = np.array([np.nextafter(r, np.inf), 2 * r, 1e22, -1e300])
    s, c = fast_trig.sincos_array(beyond)
    assert np.array_equal(s, np.sin(beyond)) and np.array_equal(c, np.cos(beyond)), "beyond RANGE: libm itself"


def test_nan_and_infinity_give_nan_never_a_number():
    x = np.array([0.5, np.nan, np.inf, -np.inf, 0.25])
    s, c = fast_trig.sincos_array(x)
    assert np.isnan(s[1:4]).all() and np.isnan(c[1:4]).all()
    assert np.isfinite(s[[0, 4]]).all() and np.isfinite(c[[0, 4]]).all()


def test_exact_values_at_zero():
    """sin 0 = 0 and cos 0 = 1 exactly (of -0 too; the sign of sin(-0) is not kept: +0)."""
    s, c = fast_trig.sincos_array(np.array([0.0, -0.0]))
    assert s[0] == 0.0 and s[1] == 0.0 and c[0] == 1.0 and c[1] == 1.0


@pytest.mark.parametrize("n", [1, 7, 8, 31, 32, 33, 1000])
def test_every_length_of_array(n):
    """The vectorised loop and its remainder: lengths around every SIMD width."""
    x = np.linspace(-20.0, 20.0, n)
    x[n // 2] = 3e5 if n > 2 else x[n // 2]  # one angle on the libm path in the middle
    _check(x, f"length {n}")
