"""Point-mass kinematics: velocities are the time derivatives of positions, energies are sums over masses."""

import numpy as np
import pytest

from exo_bench.models.mechanism.kinematics import (
    energy_rate,
    kinetic_energy,
    point_mass_positions,
    point_mass_velocities,
    potential_energy,
    total_energy,
)
from exo_bench.models.gait.motion import smooth_random_motion
from exo_bench.models.mechanism.presets import fig1, random_tree


@pytest.mark.parametrize("dim", [2, 3])
def test_velocities_are_time_derivatives_of_positions(dim):
    m = random_tree(5, dim, 11)
    t, h = np.linspace(0, 1, 9), 1e-5
    f = lambda t: smooth_random_motion(m, t, seed=2)
    fd = (point_mass_positions(m, f(t + h).q) - point_mass_positions(m, f(t - h).q)) / (2 * h)
    assert np.allclose(point_mass_velocities(m, f(t).q, f(t).qd), fd, atol=1e-8)


@pytest.mark.parametrize("dim", [2, 3])
def test_one_link_energies_are_eq1_and_eqs11_12(dim):
    m = fig1(dim)
    (m0, m1, m2), n = m.masses[0], m.n[0]
    zeta, eta = m1 * n**2 + m2, m1 * n + m2
    rng = np.random.default_rng(0)
    q, qd = rng.normal(size=(6, m.dof)), rng.normal(size=(6, m.dof))
    q[:, -1] = np.abs(q[:, -1]) + 0.1
    if dim == 2:
        (phi, l), (phid, ld) = q.T, qd.T
        T = 0.5 * zeta * (ld**2 + l**2 * phid**2)
        P = m.g * eta * l * np.sin(phi)
    else:
        (phi, psi, l), (phid, psid, ld) = q.T, qd.T
        T = 0.5 * zeta * (ld**2 + l**2 * (phid**2 * np.cos(psi) ** 2 + psid**2))
        P = m.g * eta * l * np.sin(psi)
    assert np.allclose(kinetic_energy(m, q, qd), T, rtol=1e-13)
    assert np.allclose(potential_energy(m, q), P, rtol=1e-13, atol=1e-13)


def test_energy_rate_is_exact_for_a_free_flight_of_known_energy():
    """A quadratic-in-time motion whose energy is a polynomial: the difference stencil is exact."""
    m = fig1(2)
    t = np.linspace(0, 1, 5)

    class Mo:  # phi = pi/2 fixed (vertical rod), l = 1 + t^2: T and Pi are polynomials in t
        def __init__(self, t):
            self.q = np.stack([np.full_like(t, np.pi / 2), 1 + t**2], -1)
            self.qd = np.stack([0 * t, 2 * t], -1)

    E = total_energy(m, Mo(t).q, Mo(t).qd)
    (m0, m1, m2), n = m.masses[0], m.n[0]
    zeta, eta = m1 * n**2 + m2, m1 * n + m2
    assert np.allclose(E, 0.5 * zeta * 4 * t**2 + m.g * eta * (1 + t**2))
    assert np.allclose(energy_rate(m, Mo, t), 4 * zeta * t + 2 * m.g * eta * t, rtol=1e-10)
