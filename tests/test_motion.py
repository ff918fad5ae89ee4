"""Prescribed motions: analytic derivatives agree with finite differences; eq. (26) is periodic."""

import numpy as np
import pytest

from exo_bench.models.gait.motion import GaitParams, gait, planar_gait, smooth_random_motion
from exo_bench.models.mechanism.presets import exo5, fig5, random_tree

T = np.linspace(0.0, 2.2, 37)


def _fd(motion_of_t, t, h=1e-4):
    """Fourth-order central differences of q and qd."""
    m = [motion_of_t(t + k * h) for k in (-2, -1, 1, 2)]
    d = lambda a, b, c, e: (a - 8 * b + 8 * c - e) / (12 * h)
    return d(*(x.q for x in m)), d(*(x.qd for x in m))


CASES = {
    "gait eq. 26 (3D)": lambda t: gait(exo5(3), t),
    "planar gait (2D, five links)": lambda t: planar_gait(exo5(2), t),
    "planar gait (2D, Fig. 5)": lambda t: planar_gait(fig5(2), t),
    "smooth random (3D tree)": lambda t: smooth_random_motion(random_tree(4, 3, 7), t, seed=3),
    "smooth random (2D tree)": lambda t: smooth_random_motion(random_tree(6, 2, 8), t, seed=4),
}


@pytest.mark.parametrize("case", sorted(CASES))
def test_analytic_derivatives_match_finite_differences(case):
    f = CASES[case]
    m = f(T)
    dq, dqd = _fd(f, T)
    assert np.abs(m.qd - dq).max() < 1e-8 * max(1.0, np.abs(m.qd).max())
    assert np.abs(m.qdd - dqd).max() < 1e-7 * max(1.0, np.abs(m.qdd).max())


def test_gait_is_periodic_with_period_T():
    p = GaitParams()
    a, b = gait(exo5(3), T), gait(exo5(3), T + p.T)
    for x, y in ((a.q, b.q), (a.qd, b.qd), (a.qdd, b.qdd)):
        assert np.allclose(x, y, atol=1e-9)


def test_gait_matches_eq26_at_quarter_period():
    """At t = T/4: cos(2 pi t/T) = 0 and sin = 1, so eq. (26) reads off directly."""
    p = GaitParams()
    q = gait(exo5(3), np.array([p.T / 4])).q[0]
    j, f, ls, l = p.j, p.f, p.l_star, p.l
    h = np.pi / 2
    assert np.allclose(q[:5], [j[0], 0, 0, j[3], 0], atol=1e-15)
    assert np.allclose(
        q[5:10],
        [
            h + j[0] * np.sin(f[0] - h),
            h + j[1] * np.cos(f[1] - h),
            h + j[2] * np.cos(f[2] - h),
            h + j[3] * np.sin(f[3] - h),
            h,
        ],
    )
    assert np.allclose(q[10:], [ls[0] * (1 + l), ls[1] * (1 + l), ls[2] * (1 + l), ls[3] * (1 - l), ls[4] * (1 + l)])


def test_gait_refuses_models_it_does_not_describe():
    with pytest.raises(ValueError, match="five-link"):
        gait(fig5(3), T)
    with pytest.raises(ValueError, match="2D model with at most 5 links"):
        planar_gait(random_tree(6, 2, 0), T)
