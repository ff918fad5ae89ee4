"""The stride's coordinates (bench/studies/stride/coordinates.py): the free map, the mirror, and moving
the hips along the floor (:func:`shift_root`), which must change nothing of the motion but where it is.

Error model: a shift by ``dx`` recomputes the root's polar coordinates, so positions and rates carry a
few roundings of the root's length (~2 m): 1e-13 holds them; inverse dynamics is compared to conftest's
error model (:func:`conftest.term_scale`, K ulps) like any two implementations.
"""

from __future__ import annotations

import numpy as np
from conftest import K, assert_close, term_scale

from exo_bench import prepare
from exo_bench.bench.studies.stride.coordinates import free_map, mirror_matrix, shift_root
from exo_bench.models.mechanism.kinematics import point_mass_positions, point_mass_velocities
from exo_bench.models.gait.motion import smooth_random_motion
from exo_bench.models.simulation.contact import balanced_standing
from exo_bench.models.mechanism.presets import human

M = human(2)
N, ROOT = M.nlinks, M.names.index("root")


def _motion():
    mo = smooth_random_motion(M, np.linspace(0, 1, 7), seed=3)
    q = mo.q.copy()
    q[:, N + ROOT] = np.abs(q[:, N + ROOT]) + 1.0  # the hips away from O
    return q, mo.qd, mo.qdd


def test_shift_root_moves_every_point_by_dx_at_the_same_velocity():
    q, qd, qdd = _motion()
    q2, qd2, _ = shift_root(q, qd, qdd, ROOT, N, 0.7)
    P, P2 = point_mass_positions(M, q), point_mass_positions(M, q2)
    np.testing.assert_allclose(P2[:, 1:] - P[:, 1:], np.broadcast_to([0.7, 0.0], P[:, 1:].shape), atol=1e-13)
    V, V2 = point_mass_velocities(M, q, qd), point_mass_velocities(M, q2, qd2)
    np.testing.assert_allclose(V2[:, 1:], V[:, 1:], atol=1e-13 * np.abs(V).max())


def test_shift_root_keeps_the_dynamics_the_same_and_the_force_at_the_hips():
    q, qd, qdd = _motion()
    q2, qd2, qdd2 = shift_root(q, qd, qdd, ROOT, N, -0.4)
    ne = prepare(M, "newton-euler", kernel="numpy")
    tau, tau2 = ne.inverse_dynamics(q, qd, qdd), ne.inverse_dynamics(q2, qd2, qdd2)
    rows = [i for i in range(M.dof) if i not in (ROOT, N + ROOT)]
    scale = np.maximum(term_scale(M, q, qd, qdd), term_scale(M, q2, qd2, qdd2))
    assert_close(tau2[:, rows], tau[:, rows], scale[:, rows], 4 * K, "every row but the root's")

    def hip_force(q_, t_):  # the root's rows are J^T F: (u . F, l u_perp . F)
        phi, l = q_[:, ROOT], q_[:, N + ROOT]
        u, w = np.stack([np.cos(phi), np.sin(phi)], 1), np.stack([-np.sin(phi), np.cos(phi)], 1)
        return t_[:, N + ROOT, None] * u + (t_[:, ROOT] / l)[:, None] * w

    np.testing.assert_allclose(hip_force(q2, tau2), hip_force(q, tau), atol=1e-10 * np.abs(tau).max())


def test_the_free_map_turns_the_heel_with_the_foot_and_the_mirror_is_an_involution():
    fm = free_map(M, balanced_standing(M))
    assert fm.nz == 13
    z = np.random.default_rng(0).normal(size=(3, fm.nz))
    q = fm.full(z)
    for side in ("right", "left"):
        heel, foot = M.names.index(f"{side}_heel"), M.names.index(f"{side}_foot")
        np.testing.assert_allclose(q[:, heel] - q[:, foot], fm.c[heel], atol=1e-15)
    P = mirror_matrix(fm)
    np.testing.assert_array_equal(P @ P, np.eye(fm.nz))
    assert (P @ np.arange(fm.nz))[fm.index("right_leg angle")] == fm.index("left_leg angle")
