"""The CasADi functions the step optimisation calls.

* :func:`inverse_dynamics_function` - ``tau = ID(q, qd, qdd)`` of the mechanism as a ``casadi.Function``,
  the equations' CasADi export (one source of the physics: the closed forms of the numeric kernels).
  Everything else here is kinematics.
* :func:`kinematics_function` - the point masses' positions, velocities and accelerations by CasADi's
  forward differentiation of the positions ``p(q)`` of eq. (7) (no dynamics).
* :func:`net_loads_function` - the net joint moments and forces of :mod:`exo_bench.models.mechanism.joint_loads`
  (Newton-Euler on each subtree, the gait-analysis definition) from those point-mass accelerations, so
  that the objective weighs the same quantities the plausibility table reports. ``tests/test_step.py``
  checks them against :func:`exo_bench.models.mechanism.joint_loads.net_joint_loads`.

Layout of the outputs (column vectors, one sample per call; map over samples with ``Function.map``):
positions ``p`` are ``(n * 3 * dim,)`` in the order link, mass (start, middle, end), axis, like
:func:`exo_bench.models.mechanism.kinematics.point_mass_positions` flattened; moments ``M`` are ``(n * 3,)`` in 3D (world
axes) and ``(n,)`` in 2D; forces ``F`` are ``(n * dim,)``.
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from exo_bench.models.mechanism.mechanism import Mechanism


def inverse_dynamics_function(mech: Mechanism) -> ca.Function:
    """``tau = ID(q, qd, qdd)``: generalised forces of the paper's coordinates, as a ``casadi.Function``:
    the equations' CasADi export (:mod:`exo_bench.matrix_method.export.casadi_functions`, the factored closed forms of
    ``matrix-factored`` run on CasADi symbols)."""
    from exo_bench.matrix_method.export.casadi_functions import casadi_functions

    return casadi_functions(mech).inverse_dynamics


def _ident(mech: Mechanism) -> str:
    return "".join(c if c.isalnum() else "_" for c in mech.name)


def _unit(mech: Mechanism, q, i: int):
    n = mech.nlinks
    if mech.dim == 2:
        phi = q[i]
        return ca.vertcat(ca.cos(phi), ca.sin(phi))
    phi, psi = q[i], q[n + i]
    return ca.vertcat(ca.cos(psi) * ca.cos(phi), ca.cos(psi) * ca.sin(phi), ca.sin(psi))


def _positions(mech: Mechanism, q) -> list:
    """Point-mass positions (eq. 7): mass b of link i at ``end(parent) + frac_b * sign_i l_i u_i``."""
    n = mech.nlinks
    lengths = q[-n:]
    fr = mech.fractions
    ends: list = []
    out: list = []
    for i in range(n):
        w = mech.sign[i] * lengths[i] * _unit(mech, q, i)
        start = ends[mech.parent[i]] if mech.parent[i] >= 0 else ca.SX.zeros(mech.dim)
        ends.append(start + w)
        out += [start + float(fr[i, b]) * w for b in range(3)]
    return out


def _kinematics(mech: Mechanism, q, qd, qdd):
    p = _positions(mech, q)
    P = ca.vertcat(*p)
    v = ca.jtimes(P, q, qd)
    a = ca.jtimes(v, q, qd) + ca.jtimes(v, qd, qdd)
    d = mech.dim
    return p, [v[d * k : d * (k + 1)] for k in range(len(p))], [a[d * k : d * (k + 1)] for k in range(len(p))]


def _mass_forces(mech: Mechanism, a: list) -> list:
    """``m (a - g)`` of every point mass (gravity ``-g`` along the last axis)."""
    g = np.zeros(mech.dim)
    g[-1] = -mech.g
    m = mech.mass_array
    return [float(m[k // 3, k % 3]) * (a[k] - g) for k in range(len(a))]


def kinematics_function(mech: Mechanism) -> ca.Function:
    """``(p, v, a) = K(q, qd, qdd)``: every point mass's position, velocity and acceleration."""
    q, qd, qdd = (ca.SX.sym(s, mech.dof) for s in ("q", "qd", "qdd"))
    p, v, a = _kinematics(mech, q, qd, qdd)
    return ca.Function(
        f"{_ident(mech)}_kinematics",
        [q, qd, qdd],
        [ca.vertcat(*p), ca.vertcat(*v), ca.vertcat(*a)],
        ["q", "qd", "qdd"],
        ["p", "v", "a"],
    )


def _cross(a, b):
    return ca.vertcat(a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def net_loads_function(mech: Mechanism) -> ca.Function:
    """``(M, F) = L(q, qd, qdd)``: the net joint moment and force at the start of every link, exerted by
    the parent side on the link's subtree (:mod:`exo_bench.models.mechanism.joint_loads`)."""
    from exo_bench.models.mechanism.joint_loads import subtree

    q, qd, qdd = (ca.SX.sym(s, mech.dof) for s in ("q", "qd", "qdd"))
    p, _, a = _kinematics(mech, q, qd, qdd)
    f = _mass_forces(mech, a)
    Ms, Fs = [], []
    for k in range(mech.nlinks):
        r = p[3 * k]
        m = ca.SX.zeros(3 if mech.dim == 3 else 1)
        F = ca.SX.zeros(mech.dim)
        for i in subtree(mech, k):
            for b in range(3):
                arm, fj = p[3 * i + b] - r, f[3 * i + b]
                m += _cross(arm, fj) if mech.dim == 3 else arm[0] * fj[1] - arm[1] * fj[0]
                F += fj
        Ms.append(m)
        Fs.append(F)
    return ca.Function(
        f"{_ident(mech)}_net_loads", [q, qd, qdd], [ca.vertcat(*Ms), ca.vertcat(*Fs)], ["q", "qd", "qdd"], ["M", "F"]
    )


__all__ = ["inverse_dynamics_function", "kinematics_function", "net_loads_function"]
