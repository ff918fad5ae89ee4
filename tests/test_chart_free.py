"""Chart-free simulation in the rod vectors (models/newton_euler/chart_free.py): the paper's gait with
the trunk exactly vertical runs inverse -> forward and back, which the absolute angles cannot do."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import EPS, K

from exo_bench import prepare
from exo_bench.models.mechanism.kinematics import net_joint_loads, point_mass_accelerations
from exo_bench.models.gait.motion import gait, planar_gait, random_states
from exo_bench.models.newton_euler import chart_free as cf
from exo_bench.models.mechanism.presets import exo5, random_tree
from exo_bench.models.mechanism.singularity import SingularConfigurationError


def test_the_gait_with_the_trunk_exactly_vertical_round_trips_to_a_micrometre():
    """Inverse dynamics along eq. (26) gives the rod loads; DOP853 at rtol 1e-10, atol 1e-12 (the
    stated tolerance) integrates M_r r'' = f - g_r over one period from the gait's initial state;
    every point mass is recovered to 1e-6 m (measured: about 1e-12 m)."""
    rt = cf.gait_round_trip()
    assert rt.status == "ok"
    assert rt.trunk_psi == math.pi / 2 and rt.vertical_rods >= 1
    assert (rt.rtol, rt.atol) == (cf.ROUND_TRIP_RTOL, cf.ROUND_TRIP_ATOL)
    assert rt.max_position_error < 1e-6
    assert rt.max_coordinate_error < 1e-6


def test_the_chart_cannot_start_the_same_gait():
    """The absolute angles' forward dynamics refuses the gait's first state (the trunk is vertical),
    naming the trunk, on every chart-based method."""
    m = exo5(3)
    g0 = gait(m, np.array([0.0]))
    tau = prepare(m, "newton-euler").inverse_dynamics(g0.q, g0.qd, g0.qdd)
    for method in ("newton-euler", "pinocchio", "matrix-factored"):
        with pytest.raises(SingularConfigurationError, match=r"link 5 \(trunk\): vertical rod"):
            prepare(m, method).forward_dynamics(g0.q, g0.qd, tau)


@pytest.mark.parametrize("dim", [2, 3])
def test_rod_loads_are_the_joint_moments_carried_by_each_rod_and_its_axial_force(dim):
    """``f_k = s_k u_k F_l,k + ((M_k - sum_c M_c) x r_k) / l_k^2`` with the net joint moments of
    models/mechanism/kinematics.py (point masses, an independent sum): the passes' ``M_r r'' + g_r`` agree at
    the gait's vertical trunk. Error model: each side sums at most every point mass's
    ``m (|a| + g)`` with lever arms up to the sum ``L`` of the rod lengths, divided by ``l_k`` on the
    moment side: ``K eps W (1 + 2 L / l_k)``, ``W = sum m (|a| + g)``."""
    m = exo5(dim)
    mo = gait(m, np.linspace(0.0, 0.98, 9)) if dim == 3 else planar_gait(m, np.linspace(0.0, 0.98, 9))
    f = cf.rod_loads(m, mo.q, mo.qd, mo.qdd)
    M, _ = net_joint_loads(m, mo.q, mo.qd, mo.qdd)
    axial = prepare(m, "pinocchio").inverse_dynamics(mo.q, mo.qd, mo.qdd)[:, -m.nlinks :]
    g = cf.rod_loads_from_joint_loads(m, mo.q, M, axial)
    a = np.linalg.norm(point_mass_accelerations(m, mo.q, mo.qd, mo.qdd), axis=-1)
    W = (m.mass_array[None] * (a + m.g)).sum(axis=(1, 2))[:, None, None]
    l = mo.q[:, -m.nlinks :][..., None]
    bound = K * EPS * W * (1 + 2 * l.sum(axis=1, keepdims=True) / l)
    assert (np.abs(f - g) <= bound).all(), float((np.abs(f - g) / bound).max())


@pytest.mark.parametrize("dim", [2, 3])
def test_paper_coordinates_read_back_the_states(dim):
    m = random_tree(6, dim, 3)
    q, qd, _ = random_states(m, 20, 4)
    r, v = cf.rod_vectors(m, q, qd)
    q2, qd2, ok = cf.paper_coordinates(m, r, v, near=q)
    assert ok.all()
    assert np.abs(q2 - q).max() < 1e-12 * max(1.0, np.abs(q).max())
    assert np.abs(qd2 - qd).max() < 1e-11 * max(1.0, np.abs(qd).max())


def test_paper_coordinates_mark_a_vertical_rod_instead_of_guessing_its_azimuth():
    m = exo5(3)
    g0 = gait(m, np.array([0.0]))
    r, v = cf.rod_vectors(m, g0.q, g0.qd)
    q, qd, ok = cf.paper_coordinates(m, r, v)
    assert not ok[0, 4] and ok[0, :4].all()
    assert math.isnan(q[0, 4]) and math.isnan(q[0, 9]) and q[0, 14] == pytest.approx(g0.q[0, 14])


def test_a_singular_M_r_is_refused_with_the_link():
    m = exo5(3)
    masses = list(m.masses)
    masses[4] = (masses[4][0], 0.0, 0.0)
    bad = m.replace(masses=tuple(masses))
    with pytest.raises(ValueError, match=r"link 5 \(trunk\)"):
        cf.simulate_rods(bad, np.zeros((5, 3)), np.zeros((5, 3)), (0.0, 0.1), lambda t, r, v: np.zeros((5, 3)))
