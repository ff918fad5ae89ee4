"""Smooth ground contact (models/simulation/contact.py): where it pushes, how friction acts, its derivatives, and
that its dissipation takes energy out of a bounce.

Error models: the Jacobians are closed forms of the same few operations as the force, so they agree
with complex-step derivatives (exact to rounding: no subtraction) to ~1e-14 of the largest entry;
1e-11 leaves a margin and catches any wrong term (a dropped factor changes an entry by O(1)). The
drop is integrated by an adaptive Runge-Kutta method at rtol 1e-10, so speeds at the same height
agree to ~1e-8 where no energy is lost; energy losses asserted are 2 % or more.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from exo_bench.models.simulation.contact import (
    MAX_INPUT,
    ContactParameters,
    contact_force,
    contact_force_jacobians,
    ground_forces,
)

C = ContactParameters()
G = 9.81


def _near_floor(rng, n, dim):
    p = rng.normal(0, 0.3, (n, dim))
    p[:, -1] = rng.uniform(-0.02, 0.005, n)
    return p, rng.normal(0, 0.5, (n, dim))


@pytest.mark.parametrize("dim", [2, 3])
def test_no_force_well_above_the_floor(dim):
    p = np.zeros((50, dim))
    p[:, -1] = np.linspace(30 * C.penetration_smoothing, 1e3, 50)
    f = contact_force(p, np.ones((50, dim)))
    # softplus: d_s <= s_d exp(-30), so f_n <= K (s_d exp(-30))^1.5 = 2.6e-15 N
    assert np.all(np.abs(f) <= C.hertz * (C.penetration_smoothing * np.exp(-30)) ** 1.5 * (1 + 2 * 1.5 * C.dissipation))


def test_normal_force_grows_with_penetration_and_is_hertz_beyond_the_smoothing():
    z = np.linspace(0.01, -0.03, 400)
    p = np.stack([np.zeros_like(z), z], -1)
    fn = contact_force(p, np.zeros_like(p))[:, 1]
    assert np.all(fn > 0) and np.all(np.diff(fn) > 0)
    deep = z <= -15 * C.penetration_smoothing  # softplus(d) - d < s_d exp(-15): 3e-7 relative at 1.5 cm
    np.testing.assert_allclose(fn[deep], C.hertz * (-z[deep]) ** 1.5, rtol=1e-5)


def test_dissipation_adds_force_when_pressing_and_never_pulls():
    p = np.array([[0.0, -0.005]] * 3)
    v = np.array([[0.0, -1.0], [0.0, 0.0], [0.0, 10.0]])  # pressing in, still, pulling out fast
    fn = contact_force(p, v)[:, 1]
    assert fn[0] > fn[1] > fn[2] >= 0
    # softplus(1 + 3/2 c dd) = (1 + 3/2 c dd) + O(s_c exp(-1 / s_c)), 1e-10 at s_c = 0.05
    np.testing.assert_allclose(fn[0] / fn[1], 1 + 1.5 * C.dissipation, rtol=1e-9)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("viscous", [0.0, 0.5])
def test_friction_opposes_sliding_and_is_bounded_by_mu_n(dim, viscous):
    c = ContactParameters(static_friction=1.0, dynamic_friction=0.7, viscous_friction=viscous)
    rng = np.random.default_rng(3)
    p, v = _near_floor(rng, 2000, dim)
    v[:200, :-1] *= 1e-3  # slow slips, near the Stribeck peak and below
    f = contact_force(p, v, c)
    ft, fn, vt = f[:, :-1], f[:, -1], v[:, :-1]
    speed = np.linalg.norm(vt, axis=1)
    assert np.all(np.einsum("si,si->s", ft, vt) < 0)
    cos = -np.einsum("si,si->s", ft, vt) / (np.linalg.norm(ft, axis=1) * speed)
    np.testing.assert_allclose(cos, 1, atol=1e-12)  # along -v_t
    bound = (c.static_friction + viscous * speed) * fn
    assert np.all(np.linalg.norm(ft, axis=1) <= bound * (1 + 1e-12))
    fast = contact_force(
        np.array([[0.0] * (dim - 1) + [-0.01]]), np.array([[50 * c.transition_velocity] + [0.0] * (dim - 1)]), c
    )
    mu = np.linalg.norm(fast[0, :-1]) / fast[0, -1] - viscous * 50 * c.transition_velocity
    tail = c.dynamic_friction * np.tanh(50) + (c.static_friction - c.dynamic_friction) * 100 / 2501  # x = 50
    np.testing.assert_allclose(mu, tail, rtol=1e-9)  # slip smoothing: 1e-4 m/s in 10 m/s, 5e-11


@pytest.mark.parametrize("dim", [2, 3])
def test_jacobians_equal_complex_step(dim):
    rng = np.random.default_rng(dim)
    p, v = _near_floor(rng, 64, dim)
    v[:8, :-1] = 0.0  # no slip: the smoothed direction
    p[8:16, -1] = 0.0  # on the floor
    f, jp, jv = contact_force_jacobians(p, v)
    np.testing.assert_array_equal(f, contact_force(p, v))
    h = 1e-30
    for j in range(dim):
        e = np.zeros(dim)
        e[j] = h
        cs_p = contact_force(p + 1j * e, v).imag / h
        cs_v = contact_force(p, v + 1j * e).imag / h
        scale = np.abs(jp).max() + np.abs(jv).max()
        np.testing.assert_allclose(jp[..., j], cs_p, rtol=0, atol=1e-11 * scale)
        np.testing.assert_allclose(jv[..., j], cs_v, rtol=0, atol=1e-11 * scale)


def _apex_energy(c: ContactParameters, mass=14.0, v_in=1.0) -> float:
    """A point mass 3 cm up (30 smoothing widths: the force there is below 1e-14 N) moves down at
    ``v_in``; returns its energy at the top of the bounce over its energy at the start (both ``g z + v^2 /
    2``: the contact's elastic energy at the apex, more than 15 widths up, is below 1e-12 of it)."""
    z0 = 30 * c.penetration_smoothing

    def rhs(t, y):
        f = contact_force(np.array([[0.0, y[0]]]), np.array([[0.0, y[1]]]), c)[0, 1]
        return [y[1], f / mass - G]

    def apex(t, y):
        return y[1] if t > 0 else -1.0

    apex.terminal, apex.direction = True, -1
    sol = solve_ivp(rhs, (0, 0.5), [z0, -v_in], method="DOP853", rtol=1e-10, atol=1e-12, events=apex)
    assert sol.status == 1 and sol.y_events[0][0][0] > 15 * c.penetration_smoothing, "no bounce"
    return G * sol.y_events[0][0][0] / (G * z0 + v_in**2 / 2)


def test_dissipation_makes_a_dropped_point_lose_energy_and_without_it_none():
    np.testing.assert_allclose(_apex_energy(ContactParameters(dissipation=0.0)), 1.0, rtol=1e-6)
    kept = [_apex_energy(ContactParameters(dissipation=c)) for c in (0.05, 0.5)]
    assert 0.98 > kept[0] > kept[1] > 0


def test_extreme_but_finite_inputs_give_finite_forces_and_derivatives():
    big = MAX_INPUT
    p = np.array([[0, big], [0, -big], [big, 0.0], [0, 0.0], [0, -1e-3], [0, 1e3]])
    v = np.array([[big, big], [-big, -big], [0, 0.0], [0, 0.0], [0, big], [-big, 0.0]])
    for out in contact_force_jacobians(p, v):
        assert np.all(np.isfinite(out))


@pytest.mark.parametrize(
    ("p", "match"),
    [
        (
            np.array([[0.0, np.nan]]),
            r"contact: field 'position': expected finite values within \+-1e\+50, got nan at \(0, 1\)",
        ),
        (np.array([[2e50, 0.0]]), r"field 'position': expected finite values.*got 2e\+50 at \(0, 0\)"),
        (np.zeros((3, 4)), r"field 'position': expected an array \(\.\.\., dim\) with dim 2 or 3, got shape \(3, 4\)"),
    ],
)
def test_bad_states_are_named(p, match):
    with pytest.raises(ValueError, match=match):
        contact_force(p, np.zeros((1, 2)))


@pytest.mark.parametrize(
    ("kw", "match"),
    [
        ({"stiffness": 0.0}, r"contact: field 'stiffness': expected a number in \[1e-9, 1e12\], got 0.0"),
        ({"radius": float("inf")}, r"field 'radius': expected a number in"),
        ({"dissipation": -1.0}, r"field 'dissipation': expected 0 or a number in"),
        ({"dynamic_friction": 0.9}, r"field 'dynamic_friction': expected <= static_friction = 0.8, got 0.9"),
        ({"transition_velocity": "0.2"}, r"field 'transition_velocity'"),
    ],
)
def test_bad_parameters_are_named(kw, match):
    with pytest.raises(ValueError, match=match):
        ContactParameters(**kw)


def test_ground_forces_fill_the_f_ext_layout_at_the_masked_points_only():
    from exo_bench.models.mechanism.kinematics import point_mass_positions, point_mass_velocities
    from exo_bench.models.mechanism.presets import human, human_standing

    m = human(2)
    q = human_standing(m)
    q[0, m.nlinks] -= 0.02  # the root rod (vertical) 2 cm shorter: every point 2 cm lower, the soles in the floor
    qd = np.zeros_like(q)
    mask = np.zeros((m.nlinks, 3), bool)
    mask[[4, 5, 8, 9], 2] = True  # toes and heels
    f = ground_forces(point_mass_positions(m, q), point_mass_velocities(m, q, qd), mask, C)
    assert f.shape == (1, m.nlinks, 3, 2)
    np.testing.assert_array_equal(f[0, ~mask], 0.0)
    np.testing.assert_allclose(f[0, mask, 1], C.hertz * 0.02**1.5, rtol=1e-8)  # softplus: 1e-10 at 20 widths
    with pytest.raises(ValueError, match=r"field 'points': expected a mask of shape \(10, 3\), got \(3,\)"):
        ground_forces(point_mass_positions(m, q), point_mass_velocities(m, q, qd), mask[0], C)
