"""The recurrence of eqs. (22)-(26): the matrices of n+1 links from those of n links.

Eq. (23), ``A_{n+1} = A_n + delta A_n``, with ``A_n`` padded by a zero row and column (24) and
``delta A_n`` of eq. (25) for a chain: ``theta_{n+1} l_i l_j C_ij`` on the old block,
``eta_{n+1} l_i l_{n+1} C_{i,n+1}`` in the new row and column, ``zeta_{n+1} l_{n+1}^2`` in the corner.

**Generalised to trees and to every matrix.** Every planar element is ``c_ij`` times a geometric
factor of links i and j (:mod:`exo_bench.matrix_method.closed_forms.planar`), and adding link ``k`` (parent among the
earlier links) changes ``c`` only where it changes the masses riding on two rods
(:func:`exo_bench.matrix_method.closed_forms.coefficients.recurrence_increments`): ``theta_k s_i s_j`` on pairs of
ancestors of ``k`` (its mass joins ``Theta`` of each), ``eta_k s_i s_k`` between an ancestor and
``k``, ``zeta_k`` in the corner, and nothing on any other row or column. So ``delta X_n`` is the
closed form of ``X`` evaluated with those increments, on the rows and columns of k's ancestors and
of k itself; the gravity vector gains ``theta_k s_i`` on the ancestors and ``eta_k s_k`` for k. For
a chain every earlier link is an ancestor and this is eq. (25) for ``A_phi``.

The planar recurrence runs twice, at the configuration and for the straightened model (every
``phi = 0``), and the 3D matrices of n+1 links follow by the corrected transitions (18):
``2D A_n -> 2D A_{n+1} -> 3D A_{n+1}`` (eq. 26).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

import numpy as np

from exo_bench.matrix_method.closed_forms import planar
from exo_bench.matrix_method.numpy_kernels import matrix as _numeric
from exo_bench.matrix_method.closed_forms.coefficients import generic_recurrence_increments, recurrence_increments
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import as_states, split

if TYPE_CHECKING:  # the symbolic half imports sympy where it runs: the numeric method imports none
    import sympy as sp

    from exo_bench.matrix_method import symbolic as _symbolic
    from exo_bench.matrix_method.symbolic import Element, Generators


# ------------------------------------------------------------------ numeric
def planar_step(
    mech: Mechanism,
    k: int,
    mats: dict,
    nu_s: np.ndarray,
    l: np.ndarray,
    C: np.ndarray,
    S: np.ndarray,
    cos_phi: np.ndarray,
    sin_phi: np.ndarray,
) -> None:
    """Eqs. (23)-(25) for trees, in place: add link ``k`` to the planar matrices ``mats``
    (``block -> name -> (N, N, samples)``, ``P``: ``(N, samples)``) of links ``0..k-1``.

    Samples are on the last axis here, so that the block of rows and columns a step touches is
    contiguous. The arrays are allocated for all N links and zero beyond the links already added,
    which is the padding of eq. (24); ``delta X`` touches only the rows and columns of k's ancestors
    and k. ``l, cos_phi, sin_phi`` are ``(N, samples)``, ``C, S`` ``(N, N, samples)``; ``nu_s`` ``(N,)``
    accumulates the gravity coefficients the same way.
    """
    idx, dc, dnu = recurrence_increments(mech, k)
    block = np.ix_(idx, idx)
    li, lj = l[idx][:, None, :], l[idx][None, :, :]
    Cs, Ss = C[block], S[block]
    dc = dc[:, :, None]
    for b, fns in planar.PAIRS.items():
        for name, f in fns.items():
            mats[b][name][block] += f(dc, li, lj, Cs, Ss)  # delta X_n (25)
        mats[b]["P"][idx] += planar.GRAVITY[b](dnu[:, None], l[idx], cos_phi[idx], sin_phi[idx])
    nu_s[idx] += dnu


def planar_sequence(mech: Mechanism, q: np.ndarray, straight: bool = False) -> Iterator[tuple[int, dict, np.ndarray]]:
    """Yield ``(n, planar matrices of links 0..n-1, nu_s)`` for n = 1..N, each grown from the
    previous one by :func:`planar_step`; matrices as ``(samples, n, n)`` (``P``: ``(samples, n)``)
    views, valid until the next step. ``straight``: the straightened model (every ``phi = 0``)."""
    phi, _, l = split(mech, q)
    phi, l = phi.T, np.ascontiguousarray(l.T)  # (N, samples)
    if straight:
        phi = np.zeros_like(phi)
    N, samples = mech.nlinks, q.shape[0]
    d = phi[:, None, :] - phi[None, :, :]
    C, S = np.cos(d), np.sin(d)
    cos_phi, sin_phi = np.cos(phi), np.sin(phi)
    mats = {b: {name: np.zeros((N, N, samples)) for name in fns} for b, fns in planar.PAIRS.items()}
    for b in mats:
        mats[b]["P"] = np.zeros((N, samples))
    nu_s = np.zeros(N)
    for k in range(N):
        planar_step(mech, k, mats, nu_s, l, C, S, cos_phi, sin_phi)
        n = k + 1
        yield (
            n,
            {
                b: {name: (np.moveaxis(m[:n, :n], -1, 0) if name != "P" else m[:n].T) for name, m in ms.items()}
                for b, ms in mats.items()
            },
            nu_s[:n],
        )


def matrix_sequence(mech: Mechanism, q, every: bool = True) -> Iterator[tuple[int, dict]]:
    """Yield ``(n, every matrix of eq. 5 or 17 for links 0..n-1)`` for n = 1..N (only n = N
    when ``every`` is false): the planar recurrence, then in 3D the transitions (18) (eq. 26)."""
    q, _, _ = as_states(mech, q)
    _, psi, l = split(mech, q)
    flat = planar_sequence(mech, q)
    if psi is None:  # 2D
        yield from ((n, mats) for n, mats, _ in flat if every or n == mech.nlinks)
        return
    straight = planar_sequence(mech, q, straight=True)
    for (n, mats, nu_s), (_, mats0, _) in zip(flat, straight):  # in step: each yields views until its next step
        if every or n == mech.nlinks:
            yield n, _numeric.spatial_from_planar(psi[:, :n], l[:, :n], mats, mats0, nu_s)


def matrices(mech: Mechanism, q) -> dict[str, dict[str, np.ndarray]]:
    """Every matrix of the full model by the recurrence (copies, safe to keep)."""
    ((_, last),) = matrix_sequence(mech, q, every=False)  # one item, n = N
    return {b: {name: np.array(m) for name, m in ms.items()} for b, ms in last.items()}


def inverse_dynamics(mech: Mechanism, q, qd, qdd) -> np.ndarray:
    """Method ``recurrence``: the matrices by eqs. (23)-(26), then eq. (5)/(17), ``(S, dof)``."""
    q, qd, qdd = as_states(mech, q, qd, qdd)
    return _numeric.in_tiles(mech, matrices, q, qd, qdd)


# ------------------------------------------------------------------ symbolic
def _symbolic_planar(
    mech: Mechanism, G: Generators, straight: bool
) -> tuple[_symbolic.Entries, _symbolic.Gravity, dict[int, Element]]:
    """The planar recurrence on ring elements: ``(entries, gravity, nu_s)`` of the full model,
    ``entries[block][name][(i, j)]`` grown link by link."""
    params = G.parameters(mech)
    entries: _symbolic.Entries = {b: {name: {} for name in fns} for b, fns in planar.PAIRS.items()}
    gravity: _symbolic.Gravity = {b: {} for b in planar.GRAVITY}
    nu_s: dict[int, Element] = {}
    for k in range(mech.nlinks):
        idx, dc, dnu = generic_recurrence_increments(mech, params, k)
        for a, i in enumerate(idx):
            for b, j in enumerate(idx):
                C, Sn = (1, 0) if straight else (G.C(i, j), G.S(i, j))
                for blk, fns in planar.PAIRS.items():
                    for name, f in fns.items():
                        delta = f(dc[a][b], G["l", i], G["l", j], C, Sn)  # delta X_n (25)
                        old = entries[blk][name].get((i, j))
                        entries[blk][name][(i, j)] = delta if old is None else old + delta
            nu_s[i] = dnu[a] if i not in nu_s else nu_s[i] + dnu[a]
            for blk, gravity_of in planar.GRAVITY.items():
                delta = gravity_of(dnu[a], G["l", i], G["cphi", i], G["sphi", i])
                gravity[blk][i] = delta if i not in gravity[blk] else gravity[blk][i] + delta
    return entries, gravity, nu_s


def _symbolic_form(mech: Mechanism, G: Generators) -> tuple[_symbolic.Entries, _symbolic.Gravity]:
    from exo_bench.matrix_method import symbolic as _symbolic

    now, gravity, nu_s = _symbolic_planar(mech, G, straight=False)
    if mech.dim == 2:
        return now, gravity
    straight, _, _ = _symbolic_planar(mech, G, straight=True)
    pairs = list(now["phi"]["A"])
    entries = _symbolic.spatial_entries(G, now, straight, pairs)
    return entries, _symbolic.spatial_gravity(G, [nu_s[i] for i in range(mech.nlinks)], range(mech.nlinks))


def symbolic_matrices(mech: Mechanism, symbolic_parameters: bool = False) -> dict[str, dict[str, sp.Matrix]]:
    """Every matrix by the recurrence, as sympy matrices (convention of :mod:`lagrange`)."""
    from exo_bench.matrix_method import symbolic as _symbolic
    from exo_bench.matrix_method.symbolic import generators

    G = generators(mech.nlinks, mech.dim, symbolic_parameters)
    return _symbolic.to_matrices(G, mech.nlinks, *_symbolic_form(mech, G))


def compose_equations(mech: Mechanism, symbolic_parameters: bool = False) -> tuple[sp.Expr, ...]:
    """The equations of motion composed by the recurrence (23)-(26) and eq. (5)/(17); the same
    expressions as :func:`exo_bench.matrix_method.symbolic.compose_equations`."""
    from exo_bench.matrix_method import symbolic as _symbolic
    from exo_bench.matrix_method.symbolic import generators

    G = generators(mech.nlinks, mech.dim, symbolic_parameters)
    return _symbolic.equations_from_entries(G, mech, *_symbolic_form(mech, G))
