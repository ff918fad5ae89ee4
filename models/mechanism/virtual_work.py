"""Inverse dynamics by d'Alembert's principle on the point masses, in 50-digit arithmetic.

``tau_a = sum_p m_p (d r_p / d q_a) . (r_p'' + g up)``: the generalised force of coordinate ``a``
is the virtual work of the point masses' inertia and weight. Link k's coordinates move rod
vector ``w_k = sign_k l_k u_k`` only, and every mass on link k's subtree with it (masses on
link k itself at their fraction ``n_beta``), so with the subtree sum

    F_k = sum_beta m_kbeta n_kbeta (r_kbeta'' + g up) + sum_{p below link k} m_p (r_p'' + g up)

one gets ``tau_a = (d w_k / d q_a) . F_k``: a backward pass over the tree, O(n) per sample.

This shares no code with the Lagrange derivation, the paper's matrices or Pinocchio, and it
needs no symbolic work, so it gives a 50-digit reference for any n (Lagrange's sympy
derivation is out of reach beyond a few links). Inputs are float64 and are converted to mpf
exactly; the result is rounded to float64 once, at the end.
"""

from __future__ import annotations

import mpmath
import numpy as np

from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import as_states


def _unit(dim, phi, psi):
    """u and its first and second partials (phi, psi, phiphi, phipsi, psipsi) as mpf lists."""
    cf, sf = mpmath.cos(phi), mpmath.sin(phi)
    if dim == 2:
        u = [cf, sf]
        return u, [-sf, cf], None, [-cf, -sf], None, None
    cp, sp = mpmath.cos(psi), mpmath.sin(psi)
    u = [cp * cf, cp * sf, sp]
    u_f = [-cp * sf, cp * cf, mpmath.mpf(0)]
    u_p = [-sp * cf, -sp * sf, cp]
    u_ff = [-cp * cf, -cp * sf, mpmath.mpf(0)]
    u_fp = [sp * sf, -sp * cf, mpmath.mpf(0)]
    u_pp = [-x for x in u]
    return u, u_f, u_p, u_ff, u_fp, u_pp


def _sample(mech: Mechanism, q, qd, qdd) -> list:
    n, dim = mech.nlinks, mech.dim
    mp = mpmath.mpf
    q, qd, qdd = [[mp(float(x)) for x in v] for v in (q, qd, qdd)]
    blocks = lambda v: (v[:n], v[n : 2 * n] if dim == 3 else [mp(0)] * n, v[-n:])
    (phi, psi, l), (dphi, dpsi, dl), (ddphi, ddpsi, ddl) = blocks(q), blocks(qd), blocks(qdd)
    up = [mp(0)] * (dim - 1) + [mp(mech.g)]
    add = lambda a, b: [x + y for x, y in zip(a, b)]
    scale = lambda c, a: [c * x for x in a]
    partials, wdd = [], []
    for k in range(n):
        u, u_f, u_p, u_ff, u_fp, u_pp = _unit(dim, phi[k], psi[k])
        s = mp(mech.sign[k])
        # d w_k / d q for (phi_k, psi_k, l_k)
        partials.append((scale(s * l[k], u_f), scale(s * l[k], u_p) if dim == 3 else None, scale(s, u)))
        # u'' = u_phi phi'' + u_phiphi phi'^2 (+ psi terms in 3D)
        udot = scale(dphi[k], u_f)
        uddot = add(scale(ddphi[k], u_f), scale(dphi[k] ** 2, u_ff))
        if dim == 3:
            udot = add(udot, scale(dpsi[k], u_p))
            uddot = add(
                uddot, add(scale(ddpsi[k], u_p), add(scale(2 * dphi[k] * dpsi[k], u_fp), scale(dpsi[k] ** 2, u_pp)))
            )
        # w'' = s (l'' u + 2 l' u' + l u'')
        wdd.append(scale(s, add(scale(ddl[k], u), add(scale(2 * dl[k], udot), scale(l[k], uddot)))))
    # Forward pass: accelerations of every rod's start point
    start: list[list | None] = [None] * n  # filled in tree order: a parent before its children
    end: list[list | None] = [None] * n
    for k in range(n):
        p = mech.parent[k]
        start[k] = end[p] if p >= 0 else [mp(0)] * dim
        end[k] = add(start[k], wdd[k])
    # Backward pass: F_k = own masses weighted by their fractions + everything below, whole
    below = [[mp(0)] * dim for _ in range(n)]  # sum over strict descendants of m_p (r_p'' + g up)
    F: list[list | None] = [None] * n
    for k in reversed(range(n)):
        own_weighted, own_whole = [mp(0)] * dim, [mp(0)] * dim
        for b in range(3):
            m, nb = mp(mech.masses[k][b]), mp(float(mech.fractions[k, b]))
            a = add(add(start[k], scale(nb, wdd[k])), up)
            own_weighted = add(own_weighted, scale(m * nb, a))
            own_whole = add(own_whole, scale(m, a))
        F[k] = add(own_weighted, below[k])
        p = mech.parent[k]
        if p >= 0:
            below[p] = add(below[p], add(own_whole, below[k]))
    dot = lambda a, b: mpmath.fsum(x * y for x, y in zip(a, b))
    tau_phi = [dot(partials[k][0], F[k]) for k in range(n)]
    tau_psi = [dot(partials[k][1], F[k]) for k in range(n)] if dim == 3 else []
    tau_l = [dot(partials[k][2], F[k]) for k in range(n)]
    return tau_phi + tau_psi + tau_l


def inverse_dynamics_mp(mech: Mechanism, q, qd, qdd, dps: int = 50) -> list[list]:
    """Generalised forces as mpf values (``dps`` significant digits), one list per sample."""
    q, qd, qdd = as_states(mech, q, qd, qdd)
    with mpmath.workdps(dps):
        return [_sample(mech, q[s], qd[s], qdd[s]) for s in range(q.shape[0])]


def inverse_dynamics(mech: Mechanism, q, qd, qdd, dps: int = 50) -> np.ndarray:
    """The ``dps``-digit result rounded once to float64, ``(S, dof)``."""
    return np.array([[float(x) for x in row] for row in inverse_dynamics_mp(mech, q, qd, qdd, dps)])
