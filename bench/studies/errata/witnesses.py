"""Errata study, the witnesses: Lagrange and Pinocchio, and every matrix of eq. (5)/(17) read off them."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import sympy as sp

from exo_bench.matrix_method.numpy_kernels import matrix as numeric
from exo_bench.models.engines import pinocchio_backend as pb
from exo_bench.models.states import equation_form
from exo_bench.models.mechanism.mechanism import Mechanism


def _blocks(mech: Mechanism) -> tuple[str, ...]:
    return equation_form.blocks(mech.dim)


#: The matrices multiplying a block's rate squared (D: phi'^2, E: psi'^2) and a product of two
#: blocks' rates (G, H, K), from the form of the equations (equation_form.RATES).
_SQUARED = {r[0]: name for name, (_, r) in equation_form.RATES.items() if len(r) == 2 and r[0] == r[1]}
_MIXED = {r: name for name, (_, r) in equation_form.RATES.items() if len(r) == 2 and r[0] != r[1]}


def pinocchio_matrices(mech: Mechanism, q: np.ndarray) -> dict[str, dict[str, np.ndarray]]:
    """Every matrix of eq. (5)/(17) read off Pinocchio, ``block -> name -> (S, n, n)`` (``P``: ``(S, n)``).

    ``A, B, Lambda`` are blocks of the mass matrix. With ``h(qd)`` the bias forces and ``e`` unit
    rates of link j: ``D[:, j] = h(e_phi) - h(0)``, ``E[:, j] = h(e_psi) - h(0)``,
    ``2G[:, j] = h(e_phi + e_psi) - h(e_phi) - h(e_psi) + h(0)`` and likewise ``H`` (phi, l) and
    ``K`` (psi, l); ``g P = h(0)``. This presumes the form of eq. (17) (only products of a link's
    own rates); :func:`form_residual` measures how far Pinocchio is from it.
    """
    S, n = q.shape[0], mech.nlinks
    off = {b: k * n for k, b in enumerate(_blocks(mech))}
    M = pb.mass_matrix(mech, q)
    variants = [()] + [(a,) for a in _blocks(mech)] + [pair for pair in _pairs(mech)]
    rates = []
    for j in range(n):
        for v in variants:
            qd = np.zeros_like(q)
            for b in v:
                qd[:, off[b] + j] = 1.0
            rates.append(qd)
    # rates[j * len(variants) + k]: link j, variant k
    h = pb.bias_forces(mech, np.tile(q, (len(rates), 1)), np.concatenate(rates)).reshape(n, len(variants), S, mech.dof)
    h0 = h[0, 0]
    idx = {v: k for k, v in enumerate(variants)}
    out: dict[str, dict[str, np.ndarray]] = {}
    rows = lambda b: slice(off[b], off[b] + n)
    single, mixed = _SQUARED, _MIXED
    for b in _blocks(mech):
        m = {"A": M[:, rows(b), rows("phi")], "Lambda": M[:, rows(b), rows("l")], "P": h0[:, rows(b)] / mech.g}
        if mech.dim == 3:
            m["B"] = M[:, rows(b), rows("psi")]
        for a, name in single.items():
            if a in off:
                m[name] = np.stack([h[j, idx[(a,)], :, rows(b)] - h0[:, rows(b)] for j in range(n)], -1)
        for (a, c), name in mixed.items():
            if a in off and c in off:
                m[name] = np.stack(
                    [
                        0.5
                        * (
                            h[j, idx[(a, c)], :, rows(b)]
                            - h[j, idx[(a,)], :, rows(b)]
                            - h[j, idx[(c,)], :, rows(b)]
                            + h0[:, rows(b)]
                        )
                        for j in range(n)
                    ],
                    -1,
                )
        out[b] = m
    return out


def _pairs(mech: Mechanism) -> list[tuple[str, ...]]:
    return [pair for pair in _MIXED if set(pair) <= set(_blocks(mech))]


def form_residual(mech: Mechanism, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> float:
    """``|tau_pinocchio - eq. (17) with pinocchio_matrices|`` relative: 0 to rounding when Pinocchio's
    dynamics has exactly the paper's matrix form."""
    tau = pb.inverse_dynamics(mech, q, qd, qdd)
    form = numeric.generalised_forces(mech, pinocchio_matrices(mech, q), qd, qdd)
    return float(np.abs(form - tau).max() / np.abs(tau).max())


class PinocchioWitness:
    name = "pinocchio"

    def matrices(self, mech: Mechanism, q):
        return pinocchio_matrices(mech, q)

    def equations(self, mech: Mechanism, q, qd, qdd):
        return pb.inverse_dynamics(mech, q, qd, qdd)


@lru_cache(maxsize=256)
def _lagrange_compiled(mech: Mechanism, budget: float):
    """Lagrange's matrices and equations of a mechanism, lambdified (cached)."""
    from exo_bench.lagrange import derive

    d = derive(mech, symbolic_parameters=False, budget=budget)
    S = d.symbols
    mats = {
        (b, name): (M.shape, sp.lambdify(list(S.q), list(M), modules="numpy", cse=True))
        for b, ms in d.matrices.items()
        for name, M in ms.items()
    }
    eqs = sp.lambdify(list(S.q + S.qd + S.qdd), list(d.equations), modules="numpy", cse=True)
    return mats, eqs


class LagrangeWitness:
    """Lagrange's matrices and equations, lambdified once per mechanism."""

    name = "lagrange"

    def __init__(self, budget: float = 60.0):
        self.budget = budget

    def _compiled(self, mech: Mechanism):
        return _lagrange_compiled(mech, self.budget)

    def matrices(self, mech: Mechanism, q):
        mats, _ = self._compiled(mech)
        S = q.shape[0]
        out: dict[str, dict[str, np.ndarray]] = {}
        for (b, name), ((r, c), f) in mats.items():
            vals = np.stack([np.broadcast_to(np.asarray(v, dtype=float), (S,)) for v in f(*q.T)], -1)
            out.setdefault(b, {})[name] = vals.reshape(S, r) if name == "P" else vals.reshape(S, r, c)
        return out

    def equations(self, mech: Mechanism, q, qd, qdd):
        _, f = self._compiled(mech)
        S = q.shape[0]
        return np.stack([np.broadcast_to(np.asarray(v, dtype=float), (S,)) for v in f(*q.T, *qd.T, *qdd.T)], -1)
