"""Lagrange II from the point masses' T and Pi, built from the geometry alone.

Positions are built link by link down the tree (:mod:`exo_bench.models.mechanism.mechanism`): link ``i`` starts at the
end of its parent and its masses sit at fractions ``0, n_i, 1`` of ``w_i = sign_i l_i u_i``. Then

* ``T = 1/2 sum_ib m_ib |v_ib|^2`` with ``v_ib = sum_a (d r_ib / d q_a) qd_a``,
* ``Pi = g sum_ib m_ib h_ib`` (``h`` the last Cartesian coordinate),
* Lagrange II, term by term: ``tau_a = sum_b (d2T/dqd_a dq_b) qd_b + sum_b (d2T/dqd_a dqd_b) qdd_b
  - dT/dq_a + dPi/dq_a``.

Two engines: :func:`energies_poly` and :func:`lagrange_poly` do every step in the ring of
:mod:`exo_bench.lagrange.ring`; :func:`derive_expr` is the textbook route (sympy expressions, ``sympy.diff``,
``sympy.expand``), identical equations about a hundred times slower. What the result depends on is
the :class:`Structure` (tree, signs, zero masses), never the numbers.
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp
from sympy.polys.rings import PolyElement

from exo_bench.lagrange.budget import Deadline
from exo_bench.lagrange.ring import TrigRing
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.mechanism.symbols import Symbols


@dataclass(frozen=True)
class Structure:
    """What the symbolic derivation depends on: the tree, the signs and the zero masses."""

    dim: int
    parent: tuple[int, ...]
    sign: tuple[int, ...]
    zero_masses: tuple[tuple[bool, bool, bool], ...]

    @property
    def nlinks(self) -> int:
        return len(self.parent)


def structure_of(mech: Mechanism) -> Structure:
    zero_masses = tuple((m0 == 0.0, m1 == 0.0, m2 == 0.0) for m0, m1, m2 in mech.masses)
    return Structure(mech.dim, mech.parent, mech.sign, zero_masses)


@dataclass
class Energies:
    T: PolyElement  # in the ring of exo_bench.lagrange.ring.TrigRing
    Pi: PolyElement


def energies_poly(st: Structure, rg: TrigRing, dl: Deadline) -> Energies:
    """T and Pi of the point masses, positions built down the tree from the geometry."""
    R, S, n, dim = rg.R, rg.S, st.nlinks, st.dim
    dof = dim * n
    g = rg.gen[S.g]
    ends: list[list] = []
    T, Pi = R.zero, R.zero
    for i in range(n):
        p = st.parent[i]
        start = ends[p] if p >= 0 else [R.zero] * dim  # end of the parent, or O
        w = [st.sign[i] * rg.q_l[i] * x for x in rg.unit(i)]  # w_i = s_i l_i u_i
        ends.append([a + b for a, b in zip(start, w)])
        for b, frac in enumerate((R.zero, rg.gen[S.n[i]], R.one)):
            dl.check()
            if st.zero_masses[i][b]:
                continue
            m = rg.gen[S.m[i][b]]
            r = [a + frac * c for a, c in zip(start, w)]  # r_ib = start + n_ib w_i
            v = [sum((rg.d_dq(x, a) * rg.qd[a] for a in range(dof)), R.zero) for x in r]
            T += m * sum((x * x for x in v), R.zero) / 2  # 1/2 m |v|^2
            Pi += m * g * r[-1]  # m g h
    return Energies(rg.reduce(T), Pi)


def lagrange_poly(rg: TrigRing, E: Energies, dof: int, dl: Deadline) -> list:
    """Lagrange II for every coordinate, in the ring."""
    eqs = []
    for a in range(dof):
        dl.check()
        p_a = E.T.diff(rg.qd[a])  # dT/dqd_a
        # First term: d/dt dT/dqd_a = sum_b d2T/dqd_a dq_b qd_b + sum_b d2T/dqd_a dqd_b qdd_b
        ddt = sum((rg.d_dq(p_a, b) * rg.qd[b] for b in range(dof)), rg.R.zero)
        ddt += sum((p_a.diff(rg.qd[b]) * rg.qdd[b] for b in range(dof)), rg.R.zero)
        # Second term: - dT/dq_a; third term: + dPi/dq_a
        eqs.append(rg.reduce(ddt - rg.d_dq(E.T, a) + rg.d_dq(E.Pi, a)))
    return eqs


def _unit_expr(S: Symbols, i: int, dim: int) -> sp.Matrix:
    if dim == 2:
        return sp.Matrix([sp.cos(S.phi[i]), sp.sin(S.phi[i])])
    c = sp.cos(S.psi[i])
    return sp.Matrix([c * sp.cos(S.phi[i]), c * sp.sin(S.phi[i]), sp.sin(S.psi[i])])


def derive_expr(st: Structure, rg: TrigRing, dl: Deadline) -> tuple[Energies, list]:
    """The textbook route: T and Pi as sympy expressions, ``sympy.diff`` and ``sympy.expand``."""
    S, n, dim = rg.S, st.nlinks, st.dim
    q, qd, qdd = S.q, S.qd, S.qdd
    ends: list[sp.Matrix] = []
    T, Pi = sp.Integer(0), sp.Integer(0)
    for i in range(n):
        p = st.parent[i]
        start = ends[p] if p >= 0 else sp.zeros(dim, 1)
        w = st.sign[i] * S.l[i] * _unit_expr(S, i, dim)
        ends.append(start + w)
        for b, frac in enumerate((0, S.n[i], 1)):
            dl.check()
            if st.zero_masses[i][b]:
                continue
            r = start + frac * w
            v = r.jacobian(q) * sp.Matrix(qd)
            T += S.m[i][b] * v.dot(v) / 2
            Pi += S.m[i][b] * S.g * r[-1]
    eqs = []
    for a in range(len(q)):
        dl.check()
        p_a = sp.diff(T, qd[a])
        ddt = sum(sp.diff(p_a, q[b]) * qd[b] + sp.diff(p_a, qd[b]) * qdd[b] for b in range(len(q)))
        eqs.append(rg.reduce(rg.from_expr(ddt - sp.diff(T, q[a]) + sp.diff(Pi, q[a]))))
    return Energies(rg.reduce(rg.from_expr(T)), rg.from_expr(Pi)), eqs
