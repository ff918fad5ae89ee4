"""The paper's matrix form (eqs. 5 and 17) of Lagrange's equations: reading the matrices off, and back.

Row ``i`` of block ``k`` is ``sum_j (A ddphi_j + B ddpsi_j + Lambda ddl_j + D dphi_j^2 + E dpsi_j^2
+ 2 G dphi_j dpsi_j + 2 H dphi_j dl_j + 2 K dpsi_j dl_j)[i, j] + g P[i]``. :func:`extract_matrices`
reads the matrices off the equations term by term and raises :class:`FormViolation` on any product
of rates that the form does not have (e.g. ``dphi_i dphi_j`` with ``i != j``, or ``dl_j^2``);
:func:`rebuild_equations` writes the equations back.
"""

from __future__ import annotations

import sympy as sp
from sympy import QQ

from exo_bench.lagrange.budget import Deadline
from exo_bench.lagrange.ring import TrigRing
from exo_bench.models.states.states import ACCELERATION, RATES, blocks, matrix_names
from exo_bench.models.mechanism.symbols import Symbols

#: blocks of coordinates (rows of the matrix form), in block order
BLOCKS = {dim: blocks(dim) for dim in (2, 3)}  # models.states.states: the block order, defined once
#: names of the matrices of eq. (5) (2D) and eq. (17) (3D)
MATRIX_NAMES = {dim: (*matrix_names(dim), "P") for dim in (2, 3)}


class FormViolation(ValueError):
    """An equation has a term that the paper's matrix form (eqs. 5, 17) cannot hold."""


# which matrix holds a term, and the factor in front of it in the form (2G, 2H, 2K)
# (all from the rate table of models.states.states)
_ACCEL = ACCELERATION
_SQUARE = {r[0]: name for name, (_, r) in RATES.items() if len(r) == 2 and r[0] == r[1]}
_PAIR = {frozenset(r): name for name, (_, r) in RATES.items() if len(r) == 2 and r[0] != r[1]}


def _rate_slots(rg: TrigRing) -> dict[int, tuple[str, str, int]]:
    """ring generator index of every rate and acceleration -> (order 'd'/'dd', block, link)."""
    S = rg.S
    out = {}
    for blk, d, dd in (("phi", S.dphi, S.ddphi), ("psi", S.dpsi, S.ddpsi), ("l", S.dl, S.ddl)):
        for j, (x, y) in enumerate(zip(d, dd)):
            out[rg.index[x]] = ("d", blk, j)
            out[rg.index[y]] = ("dd", blk, j)
    return out


def _classify(items: list[tuple[tuple[str, str, int], int]]) -> tuple[str, int, int] | None:
    """(matrix, column, factor in the form) of a product of rates given as ((order, block, link),
    exponent) pairs; None if the form has no slot for it."""
    if len(items) == 1:
        (order, blk, j), e = items[0]
        if order == "dd" and e == 1:
            return _ACCEL[blk], j, 1  # A, B, Lambda: accelerations
        if order == "d" and e == 2 and blk in _SQUARE:
            return _SQUARE[blk], j, 1  # D, E: squared angle rates
        return None
    if len(items) == 2:
        ((o1, b1, j1), e1), ((o2, b2, j2), e2) = items
        if o1 == o2 == "d" and e1 == e2 == 1 and j1 == j2 and b1 != b2:
            return _PAIR[frozenset((b1, b2))], j1, 2  # 2G, 2H, 2K: products of one link's rates
    return None


def extract_ring(rg: TrigRing, eqs: list, deadline: Deadline | None = None) -> dict[str, dict[str, list]]:
    """The matrix form of ring equations: ``{block: {name: rows of ring elements}}``."""
    S, R = rg.S, rg.R
    dim = 3 if S.psi else 2
    n = len(S.phi)
    slots = _rate_slots(rg)
    gi = rg.index[S.g]
    zero_out = sorted(slots) + [gi]
    out: dict[str, dict[str, list]] = {}
    for kb, blk in enumerate(BLOCKS[dim]):
        acc: dict[tuple[str, int, int], dict] = {}
        for i in range(n):
            if deadline is not None:
                deadline.check()
            for monom, coeff in eqs[kb * n + i].items():
                where = lambda: f"equation {blk}{i + 1}: term {R.from_dict({monom: coeff}).as_expr()}"
                items = [(slots[k], monom[k]) for k in slots if monom[k]]
                if not items:
                    if monom[gi] != 1:
                        raise FormViolation(
                            f"{where()}: a term without rates must be g times a function of "
                            "the coordinates (the g P column)"
                        )
                    slot = ("P", i, 0)
                    factor = 1
                else:
                    if monom[gi]:
                        raise FormViolation(f"{where()}: g times rates fits no matrix of the form")
                    found = _classify(items)
                    if found is None:
                        raise FormViolation(
                            f"{where()}: this product of rates fits no matrix of the form "
                            "(only accelerations, squared angle rates of one link and "
                            "products of one link's own rates appear)"
                        )
                    name, j, factor = found
                    slot = (name, i, j)
                exps = list(monom)
                for k in zero_out:
                    exps[k] = 0
                d = acc.setdefault(slot, {})
                m = tuple(exps)
                d[m] = d.get(m, 0) + coeff / QQ(factor)
        mats = {name: [[R.zero] * (1 if name == "P" else n) for _ in range(n)] for name in MATRIX_NAMES[dim]}
        for (name, i, j), d in acc.items():
            mats[name][i][j] = R.from_dict({m: c for m, c in d.items() if c})
        out[blk] = mats
    return out


def matrices_expr(mats: dict[str, dict[str, list]]) -> dict[str, dict[str, sp.Matrix]]:
    return {
        blk: {name: sp.Matrix([[x.as_expr() for x in row] for row in rows]) for name, rows in m.items()}
        for blk, m in mats.items()
    }


def extract_matrices(equations, symbols: Symbols, deadline: Deadline | None = None) -> dict[str, dict[str, sp.Matrix]]:
    """The paper's matrices (eq. 5 in 2D, eq. 17 in 3D) read off equations given in block order.

    Row ``i`` of block ``k`` is ``sum_j (A ddphi_j + B ddpsi_j + Lambda ddl_j + D dphi_j^2
    + E dpsi_j^2 + 2 G dphi_j dpsi_j + 2 H dphi_j dl_j + 2 K dpsi_j dl_j)[i, j] + g P[i]``.
    ``g`` must be a symbol in the equations (it tells the potential terms apart); the
    equations must be polynomials in the sines and cosines of the angles, the lengths, rates,
    accelerations and the shared parameter symbols. Entries come out in the normal form of
    :func:`canonical_form`.

    Raises :class:`FormViolation` naming the equation and the term when a term fits no slot:
    a product of rates of two different links, ``dl_j^2``, a rate times an acceleration, a
    rate-free term without ``g``, or ``g`` times a rate.
    """
    S = symbols
    dim = 3 if S.psi else 2
    n = len(S.phi)
    if len(equations) != dim * n:
        raise ValueError(
            f"extract_matrices: field 'equations': expected {dim * n} equations "
            f"(block order {', '.join(BLOCKS[dim])}), got {len(equations)}"
        )
    rg = TrigRing(S, dim)
    eqs = []
    for k, e in enumerate(equations):
        try:
            eqs.append(rg.reduce(rg.from_expr(sp.expand_trig(sp.sympify(e)))))
        except (ValueError, sp.polys.polyerrors.PolynomialError) as err:
            raise ValueError(
                f"extract_matrices: equation {k + 1}: expected a polynomial in sines and cosines "
                f"of the angles, lengths, rates and the shared parameter symbols: {err}"
            ) from None
    return matrices_expr(extract_ring(rg, eqs, deadline))


def rebuild_equations(
    matrices: dict[str, dict[str, sp.Matrix]], symbols: Symbols, g: sp.Expr | None = None
) -> tuple[sp.Expr, ...]:
    """The equations written back from the matrix form (the inverse of :func:`extract_matrices`);
    ``g`` defaults to the symbol (pass :attr:`exo_bench.lagrange.derivation.Derivation.g` for substituted parameters)."""
    S = symbols
    g = S.g if g is None else g
    dim = 3 if S.psi else 2
    n = len(S.phi)
    out = []
    for blk in BLOCKS[dim]:
        M = matrices[blk]
        for i in range(n):
            e = g * M["P"][i, 0]
            for j in range(n):
                e += M["A"][i, j] * S.ddphi[j] + M["Lambda"][i, j] * S.ddl[j]
                e += M["D"][i, j] * S.dphi[j] ** 2 + 2 * M["H"][i, j] * S.dphi[j] * S.dl[j]
                if dim == 3:
                    e += M["B"][i, j] * S.ddpsi[j] + M["E"][i, j] * S.dpsi[j] ** 2
                    e += 2 * M["G"][i, j] * S.dphi[j] * S.dpsi[j] + 2 * M["K"][i, j] * S.dpsi[j] * S.dl[j]
            out.append(e)
    return tuple(out)
