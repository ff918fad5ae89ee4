"""Chart-free simulation: the equations of motion in the rod vectors, ``M_r r'' = f - g_r``.

In the rod vectors ``r_i = s_i l_i u_i`` (docs/paper.md section 6) the mass matrix ``M_r = mu (x) I``
is constant and factored once (:mod:`exo_bench.models.newton_euler.passes`), there are no velocity-product
terms and gravity is the constant ``g_r = g nu (x) up``. The state ``(r, r')`` has no chart: a
vertical rod or a rod through any direction is an ordinary state, so an integration never meets
the singularity of the absolute angles at ``cos psi = 0``.

**The loads** are rod-wise vectors ``f_i`` conjugate to ``r_i``: the generalised forces of the rod
vectors (``tau_i = J_i^T f_i`` wherever the chart is regular). From a motion they are the backward
pass of inverse dynamics, ``f = M_r r'' + g_r`` (:func:`rod_loads`, O(n)). Physically (and
independently, from the point masses, :func:`rod_loads_from_joint_loads`): with the net joint
moments ``M_k`` of :func:`exo_bench.models.mechanism.kinematics.net_joint_loads` and the rod's axial force
``F_l,k = tau_l,k``,

    f_k = s_k u_k F_l,k + ((M_k - sum_{children c} M_c) x r_k) / l_k^2,

because ``r_k x f_k = M_k - sum_c M_c`` (the moment the rod itself carries: the joint moment at its
start minus those its children take at its end) and ``u_k . f_k = s_k F_l,k``. Only ``l_k > 0`` is
needed: the vertical rods of walking are regular here.

**Paper coordinates** are read back from ``(r, r')`` by :func:`paper_coordinates` where the chart
is defined (``l > 0``, and in 3D not vertical); elsewhere the mask says so (no NaN is returned
silently).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import overload

import numpy as np
from numpy.typing import ArrayLike

from exo_bench.models.mechanism.kinematics import _rod_vectors, place_down_the_tree
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import as_states
from exo_bench.models.newton_euler import passes
from exo_bench.models.newton_euler.passes import Tree, prepare_tree, solve_coupling
from exo_bench.models.runtime.conditioning import singular_mass_reason
from exo_bench.models.mechanism.singularity import COS_VERTICAL


@overload
def rod_vectors(mech: Mechanism, q: ArrayLike, qd: None = None) -> tuple[np.ndarray, None]: ...
@overload
def rod_vectors(mech: Mechanism, q: ArrayLike, qd: ArrayLike) -> tuple[np.ndarray, np.ndarray]: ...
def rod_vectors(mech: Mechanism, q: ArrayLike, qd: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """``r (S, n, dim)`` and ``r'`` (None without ``qd``) of states in paper coordinates."""
    return _rod_vectors(mech, np.atleast_2d(q), None if qd is None else np.atleast_2d(qd))


def rod_loads(mech: Mechanism, q, qd, qdd, tree: Tree | None = None) -> np.ndarray:
    """``f = M_r r'' + g_r``, ``(S, n, dim)``: the loads conjugate to ``r`` that produce the motion
    ``(q, qd, qdd)`` (the two passes of inverse dynamics, defined at vertical rods too)."""
    q, qd, qdd = as_states(mech, q, qd, qdd)
    tree = prepare_tree(mech) if tree is None else tree
    kappa = passes.rod_accelerations(tree, mech.dim, q, qd, qdd)
    return np.moveaxis(passes.rod_forces(tree, mech.dim, mech.g, kappa), 2, 0)


def rod_loads_from_joint_loads(mech: Mechanism, q, joint_moments: np.ndarray, axial: np.ndarray) -> np.ndarray:
    """``f (S, n, dim)`` from net joint moments ``M`` (``(S, n, 3)`` in 3D, ``(S, n)`` in 2D, as
    :func:`exo_bench.models.mechanism.kinematics.net_joint_loads` gives them) and the rods' axial forces ``(S, n)``
    (module docstring). Needs ``l > 0``."""
    q = np.atleast_2d(np.asarray(q, dtype=float))
    r, _ = rod_vectors(mech, q)
    n = mech.nlinks
    l2 = (r**2).sum(axis=-1)
    carried = np.array(joint_moments, dtype=float, copy=True)
    for c in range(n):
        p = mech.parent[c]
        if p >= 0:
            carried[:, p] -= joint_moments[:, c]
    u = mech.sign_array[None, :, None] * r / np.sqrt(l2)[..., None]
    along = mech.sign_array[None, :, None] * u * axial[..., None]
    if mech.dim == 2:  # (M e_z) x r = M (-r_y, r_x)
        perp = carried[..., None] * np.stack([-r[..., 1], r[..., 0]], axis=-1)
    else:
        perp = np.cross(carried, r)
    return along + perp / l2[..., None]


def paper_coordinates(
    mech: Mechanism, r: np.ndarray, v: np.ndarray, near: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``q, qd (S, dof)`` from rod vectors ``r`` and rates ``v`` ``(S, n, dim)``, and a mask ``(S, n)``
    of the rods where the chart is defined (``l > 0``; 3D: ``|cos psi| > COS_VERTICAL``). The angles
    of a rod outside the chart are NaN and its mask entry False.

    ``u = s r / l``; ``phi = atan2(u_y, u_x)``, ``psi = atan2(u_z, |u_xy|)`` (3D); rates by ``J^-1 v``
    (:func:`exo_bench.models.mechanism.rod_elements.rates_3d`). The chart has two branches in 3D, ``(phi, psi)`` and
    ``(phi + pi, pi - psi)`` (the same ``u``), and ``phi`` is defined modulo ``2 pi``: without ``near``
    ``psi`` is in ``[-pi/2, pi/2]`` and ``phi`` in ``(-pi, pi]``; with ``near`` (``(S, dof)``, e.g. the
    previous step or a reference motion) each rod takes the branch and the turn closest to it."""
    s = mech.sign_array[None, :, None]
    u = s * r
    l = np.sqrt((u**2).sum(axis=-1))
    ok = l > 0
    with np.errstate(invalid="ignore", divide="ignore"):
        u = u / l[..., None]
        phi = np.arctan2(u[..., 1], u[..., 0])
        n = mech.nlinks
        if mech.dim == 3:
            horizontal = np.hypot(u[..., 0], u[..., 1])
            psi = np.arctan2(u[..., 2], horizontal)
            ok &= horizontal > COS_VERTICAL
            if near is not None:
                wrap = lambda a: np.angle(np.exp(1j * a))
                other_phi, other_psi = phi + np.pi, np.pi - psi
                flip = np.abs(wrap(other_phi - near[:, :n])) + np.abs(other_psi - near[:, n : 2 * n]) < np.abs(
                    wrap(phi - near[:, :n])
                ) + np.abs(psi - near[:, n : 2 * n])
                phi, psi = np.where(flip, other_phi, phi), np.where(flip, other_psi, psi)
            q = np.concatenate([phi, psi, l], axis=1)
        else:
            q = np.concatenate([phi, l], axis=1)
        if near is not None:  # the turn of phi nearest the reference
            q[:, :n] = near[:, :n] + np.angle(np.exp(1j * (q[:, :n] - near[:, :n])))
        tree = prepare_tree(mech)
        qd = passes.coordinate_rates(tree, mech.dim, q, np.moveaxis(v, 0, 2))
    bad = np.tile(~ok, mech.dim)
    bad[:, -n:] = False  # the length is defined everywhere
    q[:, :-n][bad[:, :-n]] = np.nan
    qd[bad] = np.nan
    return q, qd, ok


def end_points(mech: Mechanism, r: np.ndarray) -> np.ndarray:
    """Every point mass of the rods ``r (S, n, dim)``: ``(S, n, 3, dim)`` (start, middle, end)."""
    return place_down_the_tree(mech, r)


@dataclass
class RodSimulation:
    """The outcome of :func:`simulate_rods`: accepted steps of ``y = [r, r']`` (flattened per rod)."""

    t: np.ndarray  # (N,)
    r: np.ndarray  # (N, n, dim)
    v: np.ndarray  # (N, n, dim)
    rtol: float
    atol: float
    nfev: int
    status: str
    solution: object | None = None

    @property
    def ok(self) -> bool:
        return self.status == "ok"


def simulate_rods(
    mech: Mechanism,
    r0: np.ndarray,
    v0: np.ndarray,
    t_span: tuple[float, float],
    loads,
    rtol: float = 1e-10,
    atol: float = 1e-12,
    dense: bool = True,
) -> RodSimulation:
    """Integrate ``M_r r'' = loads(t, r, v) - g_r`` from ``(r0, v0)`` (``(n, dim)`` each) with scipy's
    DOP853 at ``rtol``/``atol``. ``loads(t, r, v)`` returns ``(n, dim)``. A singular ``M_r`` (a link
    whose end point moves no mass) is refused with a ValueError naming the link."""
    from scipy.integrate import solve_ivp

    tree = prepare_tree(mech)
    if tree.singular >= 0:
        raise ValueError(f"chart-free simulation: M_r is singular: {singular_mass_reason(mech, int(tree.singular))}")
    n, d = mech.nlinks, mech.dim
    gr = np.zeros((n, d))
    gr[:, -1] = mech.g * tree.nu

    def rhs(t, y):
        r, v = y[: n * d].reshape(n, d), y[n * d :].reshape(n, d)
        a = solve_coupling(tree, np.asarray(loads(t, r, v), dtype=float) - gr)
        return np.concatenate([v.ravel(), a.ravel()])

    y0 = np.concatenate([np.asarray(r0, float).ravel(), np.asarray(v0, float).ravel()])
    sol = solve_ivp(rhs, t_span, y0, method="DOP853", rtol=rtol, atol=atol, dense_output=dense)
    Y = sol.y.T
    return RodSimulation(
        sol.t,
        Y[:, : n * d].reshape(-1, n, d),
        Y[:, n * d :].reshape(-1, n, d),
        rtol,
        atol,
        int(sol.nfev),
        "ok" if sol.status == 0 else f"failed: {sol.message}",
        sol.sol,
    )


#: The round trip's integrator tolerances: DOP853 (8th order) at these keeps the global error of a
#: period-long integration of the gait's smooth loads far below the 1e-6 m target.
ROUND_TRIP_RTOL = 1e-10
ROUND_TRIP_ATOL = 1e-12


@dataclass
class RoundTrip:
    """The paper's gait through inverse dynamics and the chart-free forward simulation."""

    period: float
    trunk_psi: float  # psi_5 along the gait: exactly pi/2
    max_position_error: float  # m, over every point mass and every accepted step
    max_coordinate_error: float  # m: l cos psi |dphi|, l |dpsi|, |dl| where the chart is defined
    vertical_rods: int  # rods outside the chart at the start (the trunk)
    steps: int
    nfev: int
    rtol: float
    atol: float
    status: str


def gait_round_trip(
    mech: Mechanism | None = None, rtol: float = ROUND_TRIP_RTOL, atol: float = ROUND_TRIP_ATOL
) -> RoundTrip:
    """Eq. (26) with the trunk exactly vertical (``psi_5 = pi/2``): the loads ``f(t) = M_r r'' + g_r``
    along the gait (inverse dynamics), then the chart-free simulation from the gait's initial
    ``(r, r')`` over one period; the point masses' positions against the gait's."""
    from exo_bench.models.gait.motion import GaitParams, gait
    from exo_bench.models.mechanism.presets import exo5

    mech = exo5(3) if mech is None else mech
    tree = prepare_tree(mech)
    T = GaitParams().T

    def loads(t, r, v):
        m = gait(mech, np.array([t]))
        return rod_loads(mech, m.q, m.qd, m.qdd, tree)[0]

    m0 = gait(mech, np.array([0.0]))
    r0, v0 = rod_vectors(mech, m0.q, m0.qd)
    sim = simulate_rods(mech, r0[0], v0[0], (0.0, T), loads, rtol, atol)
    ref = gait(mech, sim.t)
    want = end_points(mech, rod_vectors(mech, ref.q)[0])
    got = end_points(mech, sim.r)
    pos = float(np.abs(got - want).max())
    q, _, ok = paper_coordinates(mech, sim.r, sim.v, near=ref.q)
    n = mech.nlinks
    cols = np.concatenate([np.tile(ok, mech.dim - 1), np.ones_like(ok)], axis=1)
    # an angle's error as the displacement it makes at the rod's end (l cos psi dphi, l dpsi): near a
    # vertical crossing the azimuth itself is ill-conditioned (the chart's fault), the rod is not
    l, cpsi = ref.q[:, -n:], np.abs(np.cos(ref.q[:, n : 2 * n]))
    lever = np.concatenate([l * cpsi, l, np.ones_like(l)], axis=1)
    coord = float((np.abs(q - ref.q) * lever)[cols].max())
    return RoundTrip(
        T, float(ref.q[0, 2 * n - 1]), pos, coord, int((~ok[0]).sum()), len(sim.t) - 1, sim.nfev, rtol, atol, sim.status
    )


__all__ = [
    "RodSimulation",
    "RoundTrip",
    "end_points",
    "gait_round_trip",
    "paper_coordinates",
    "rod_loads",
    "rod_loads_from_joint_loads",
    "rod_vectors",
    "simulate_rods",
]
