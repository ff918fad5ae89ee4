"""The matrix method in numpy, batched over samples: ``(samples, dof)`` in, ``(samples, dof)`` out.

* :func:`planar_matrices`: every matrix of eq. (5) from the closed forms of
  :mod:`exo_bench.matrix_method.closed_forms.planar`, ``(S, n, n)`` per matrix and ``(S, n)`` for ``P``.
* :func:`matrices`: in 3D, every matrix of eq. (17) from the planar ones of the same structure by
  the corrected transition formulas (18) of :mod:`exo_bench.matrix_method.closed_forms.transitions` (nothing divides).
* :func:`generalised_forces`: eq. (5)/(17), the products of the matrices with the rate vectors.
* :func:`inverse_dynamics` (method ``matrix``): the same equations evaluated in factored form,
  the fast path (see its docstring).
* :func:`paper_matrices`, :func:`inverse_dynamics_paper` (method ``matrix-paper``): eq. (18)
  exactly as printed (:data:`exo_bench.matrix_method.printed.TRANSITIONS`), divisions included.

Matrices are dicts ``block -> name -> array`` with blocks ``phi, l`` (+ ``psi`` in 3D) and names
``A, Lambda, D, H, P`` (+ ``B, E, G, K``), the convention of :mod:`lagrange`: row i of block k is
``sum_j (A phi''_j + B psi''_j + Lambda l''_j + D phi'_j^2 + E psi'_j^2 + 2G phi'_j psi'_j
+ 2H phi'_j l'_j + 2K psi'_j l'_j) + g P_i``.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np

from exo_bench.matrix_method.closed_forms import planar, transitions as spatial
from exo_bench.matrix_method.closed_forms.coefficients import signed_coupling, signed_gravity
from exo_bench.matrix_method.closed_forms.factored import forces_2d, forces_3d, kappa_2d, kappa_3d
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import ACCELERATION, RATES, as_states, split
from exo_bench.models.states.states import blocks as coordinate_blocks


def blocks(mech: Mechanism) -> tuple[str, ...]:
    return coordinate_blocks(mech.dim)


def _pair_geometry(phi: np.ndarray, l: np.ndarray):
    """``li (S,n,1), lj (S,1,n), C, S (S,n,n)`` with ``C_ij = cos(phi_i - phi_j)``."""
    d = phi[:, :, None] - phi[:, None, :]
    return l[:, :, None], l[:, None, :], np.cos(d), np.sin(d)


def planar_matrices(mech: Mechanism, q: np.ndarray) -> dict[str, dict[str, np.ndarray]]:
    """Eq. (5): the planar matrices of the model of the same structure at the angles ``phi`` and
    lengths ``l`` of ``q`` (in 3D the ``psi`` are ignored), from the closed forms."""
    phi, _, l = split(mech, np.asarray(q, dtype=float))
    return _planar(mech, phi, l, np.cos, np.sin, signed_coupling(mech), signed_gravity(mech))


def _planar(mech: Mechanism, phi, l, cos, sin, c, nu_s) -> dict[str, dict[str, np.ndarray]]:
    """The closed forms of :mod:`exo_bench.matrix_method.closed_forms.planar` on ``(S, n)`` arrays of any dtype."""
    d = phi[:, :, None] - phi[:, None, :]
    li, lj, C, S = l[:, :, None], l[:, None, :], cos(d), sin(d)
    out = {}
    for block, fns in planar.PAIRS.items():
        out[block] = {name: f(c, li, lj, C, S) for name, f in fns.items()}
        out[block]["P"] = planar.GRAVITY[block](nu_s, l, cos(phi), sin(phi))
    return out


def _straight(mech: Mechanism, q: np.ndarray) -> np.ndarray:
    """The same configuration with every ``phi = 0`` (all planar links parallel)."""
    q = np.array(q, dtype=float)
    q[:, : mech.nlinks] = 0.0
    return q


def matrices(mech: Mechanism, q) -> dict[str, dict[str, np.ndarray]]:
    """Every matrix of eq. (5) (2D) or eq. (17) (3D) at the configurations ``q`` ``(S, dof)``.

    3D: the planar matrices of the same structure, then the corrected transitions (18), with the
    quotients by ``cos(phi_i - phi_j)`` taken from the straightened planar model (no division).
    """
    q, _, _ = as_states(mech, q)
    flat = planar_matrices(mech, q)
    _, psi, l = split(mech, q)
    if psi is None:  # 2D
        return flat
    return spatial_from_planar(psi, l, flat, planar_matrices(mech, _straight(mech, q)), signed_gravity(mech))


def spatial_from_planar(psi: np.ndarray, l: np.ndarray, flat: dict, straight: dict, nu_s: np.ndarray) -> dict:
    """Eq. (18), corrected: the 3D matrices from the planar ones (``flat``, at the angles ``phi``
    and lengths ``l``) and those of the straightened model (``straight``, every ``phi = 0``), for
    the elevations ``psi`` ``(S, n)``.
    ``nu_s``: the gravity coefficients of the planar ``P`` (``2D p^phi_i = nu_s_i l_i cos phi_i``),
    which :data:`exo_bench.matrix_method.closed_forms.transitions.GRAVITY` evaluates at ``phi_i -> psi_i``."""
    cp, sp = np.cos(psi), np.sin(psi)
    t = spatial.transition_inputs(
        flat, straight, l[:, :, None], l[:, None, :], cp[:, :, None], sp[:, :, None], cp[:, None, :], sp[:, None, :]
    )
    out: dict[str, dict[str, np.ndarray]] = {b: {} for b in ("phi", "psi", "l")}
    for block, fns in spatial.PAIRS.items():
        for name, f in fns.items():
            if (block, name) != ("l", "D"):
                out[block][name] = f(t)
    out["l"]["D"] = spatial.d_l(np.swapaxes(out["phi"]["H"], -1, -2))
    for block, gravity in spatial.GRAVITY.items():
        out[block]["P"] = np.broadcast_to(gravity(nu_s, l, cp, sp), l.shape).copy()
    return out


def _by_block(mech: Mechanism, v: np.ndarray) -> dict[str, np.ndarray]:
    """``block -> (S, n)`` columns of ``v`` (no ``psi`` block in 2D)."""
    phi, psi, l = split(mech, v)
    return {"phi": phi, "l": l} if psi is None else {"phi": phi, "psi": psi, "l": l}


def generalised_forces(mech: Mechanism, mats: dict, qd, qdd) -> np.ndarray:
    """Eq. (5) / (17): ``tau`` from the matrices and the rates, ``(S, dof)``, block order."""
    first, second = _by_block(mech, qd), _by_block(mech, qdd)
    rows = []
    for block in blocks(mech):
        tau = mech.g * mats[block]["P"]  # gravity
        for name, m in mats[block].items():
            if name == "P":
                continue
            factor, r = RATES[name]
            x = second[r[0]] if len(r) == 1 else factor * first[r[0]] * first[r[1]]
            tau = tau + np.einsum("sij,sj->si", m, x)
        rows.append(tau)
    return np.concatenate(rows, axis=1)


def mass_matrix_from_matrices(mech: Mechanism, mats: dict) -> np.ndarray:
    """Eq. (5) / (17): the mass matrix ``(S, dof, dof)`` assembled from the matrices multiplying the
    second derivatives (row block k: ``[A_k, B_k, Lambda_k]``, :data:`exo_bench.models.states.states.ACCELERATION`)."""
    bl = blocks(mech)
    return np.concatenate([np.concatenate([mats[r][ACCELERATION[c]] for c in bl], axis=2) for r in bl], axis=1)


def in_tiles(mech: Mechanism, build, q, qd, qdd, tile: int | None = None) -> np.ndarray:
    """``generalised_forces(mech, build(mech, q_b), qd_b, qdd_b)`` over tiles of samples (default
    :data:`TILE`), so that the ``(tile, n, n)`` matrices stay in the CPU cache."""
    tile = tile or TILE
    out = np.empty_like(q)
    for s in range(0, q.shape[0], tile):
        b = slice(s, s + tile)
        out[b] = generalised_forces(mech, build(mech, q[b]), qd[b], qdd[b])
    return out


def inverse_dynamics_from_matrices(mech: Mechanism, q, qd, qdd) -> np.ndarray:
    """The matrix method step by step: :func:`matrices`, then :func:`generalised_forces`."""
    q, qd, qdd = as_states(mech, q, qd, qdd)
    return in_tiles(mech, matrices, q, qd, qdd)


def _cos_sin(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``cos x, sin x`` from one tangent of the half angle, ``h = tan(x/2)``:
    ``cos x = (1 - h)(1 + h) / (1 + h^2)``, ``sin x = 2h / (1 + h^2)``. numpy's float64 ``tan`` is
    vectorised and accurate to 1 ulp, so this is several times faster than ``cos`` and ``sin`` and
    accurate to a few 1e-16 absolute (tested against ``np.cos``/``np.sin``)."""
    h = np.tan(0.5 * x)
    d = 1.0 / (1.0 + h * h)
    return (1.0 - h) * (1.0 + h) * d, 2.0 * h * d


#: Samples per tile of the fast path (a group of samples, not a coordinate block): the temporaries of
#: a tile, (n, TILE) floats each, stay in the CPU cache (and below the allocator's mmap threshold);
#: larger arrays are slower per sample.
TILE = 1024


def inverse_dynamics(mech: Mechanism, q, qd, qdd) -> np.ndarray:
    """Eq. (5) / (17) with the closed-form matrices, evaluated in factored form (method ``matrix``).

    Every element of every matrix is ``c_ij`` times a dot product of a row vector of link i and a
    column vector of link j (``3D a^phi_ij = c_ij (l_i u_phi_i) . (l_j u_phi_j)``, ...): the closed
    forms of :mod:`exo_bench.matrix_method.closed_forms.planar` and :mod:`exo_bench.matrix_method.closed_forms.transitions` are these dot products
    written out in sines and cosines. Summing eq. (17) over the matrices of a block first,

        tau_a,i = r_a,i . sum_j c_ij kappa_j,   kappa_j = sum_X (column of X at j) x^X_j
                = l_j u_phi phi'' + l_j u_psi psi'' + u l'' + l_j u_phiphi phi'^2 + l_j u_psipsi psi'^2
                  + 2 l_j u_phipsi phi' psi' + 2 u_phi phi' l' + 2 u_psi psi' l'   (of link j),

    with ``r_phi = l_i u_phi``, ``r_psi = l_i u_psi``, ``r_l = u_i``: the n x n work per sample is one
    product with the constant ``c`` per Cartesian axis, and no matrix is formed. Equal to
    :func:`inverse_dynamics_from_matrices` to rounding (tested).

    Batched: each tile of :data:`TILE` samples is one vectorised evaluation with the samples on
    the fast axis (``(n, TILE)`` rows); the loop runs over tiles, for cache locality.
    """
    q, qd, qdd = as_states(mech, q, qd, qdd)
    out = np.empty_like(q)
    kernel = _factored_2d if mech.dim == 2 else _factored_3d
    c, nu_s = signed_coupling(mech), signed_gravity(mech)[:, None]
    for s in range(0, q.shape[0], TILE):
        b = slice(s, s + TILE)
        out[b] = kernel(mech.nlinks, mech.g, c, nu_s, q[b].T.copy(), qd[b].T.copy(), qdd[b].T.copy()).T
    return out


class NumpyOps:
    """What the factored kernels need beyond elementwise arithmetic, for numpy ``(n, B)`` arrays:
    ``cos_sin`` (:func:`_cos_sin`), ``couple(c, parts)`` (``sum_j c_ij part_j`` per Cartesian axis,
    one product with ``c``) and ``rows(parts)`` (the blocks of tau stacked). The same kernels run on
    CasADi's symbols with another namespace (:mod:`exo_bench.matrix_method.export.casadi_functions`)."""

    cos_sin = staticmethod(_cos_sin)

    @staticmethod
    def couple(c, parts):
        return c @ np.stack(parts)

    @staticmethod
    def rows(parts):
        return np.concatenate(parts)


NUMPY_OPS = NumpyOps()


def _factored_2d(n, g, c, nu_s, x, xd, xdd, ops=NUMPY_OPS):
    """The planar kernel of :func:`inverse_dynamics` on ``(dof, B)`` blocks: the element functions of
    :mod:`exo_bench.matrix_method.closed_forms.factored` on ``(n, B)`` rows (``ops``: numpy by default,
    :class:`NumpyOps`; any namespace with the same three functions, e.g. CasADi's)."""
    phi, l, w, ld, wdd, ldd = x[:n], x[n:], xd[:n], xd[n:], xdd[:n], xdd[n:]
    cf, sf = ops.cos_sin(phi)
    f = ops.couple(c, list(kappa_2d(l, w, ld, wdd, ldd, cf, sf)))  # sum_j c_ij kappa_j
    return ops.rows(list(forces_2d(l, cf, sf, f[0], f[1], g * nu_s)))


def _factored_3d(n, g, c, nu_s, x, xd, xdd, ops=NUMPY_OPS):
    """The spatial kernel of :func:`inverse_dynamics` on ``(dof, B)`` blocks (``ops`` as in
    :func:`_factored_2d`)."""
    phi, psi, l = x[:n], x[n : 2 * n], x[2 * n :]
    w, v, ld = xd[:n], xd[n : 2 * n], xd[2 * n :]
    wdd, vdd, ldd = xdd[:n], xdd[n : 2 * n], xdd[2 * n :]
    cf, sf = ops.cos_sin(phi)
    cp, sp = ops.cos_sin(psi)
    f = ops.couple(c, list(kappa_3d(l, w, v, ld, wdd, vdd, ldd, cf, sf, cp, sp)))  # sum_j c_ij kappa_j, per axis
    return ops.rows(list(forces_3d(l, cf, sf, cp, sp, f[0], f[1], f[2], g * nu_s)))


# ----------------------------------------------------------------- as printed
def paper_matrices(mech: Mechanism, q, table=None, exact: bool = False) -> dict[str, dict[str, np.ndarray]]:
    """Eq. (17) matrices by eq. (18) **exactly as printed**, evaluated literally.

    The planar inputs are the closed forms of :func:`planar_matrices` (the paper prints only
    eq. (6) of them). Divisions by ``cos(phi_i - phi_j)``, ``cos phi_i`` and ``sin phi_i`` are
    evaluated as written, so an exact zero divisor gives 0/0 = NaN, which is returned, not hidden.
    In floating point only ``sin phi_i`` at ``phi_i = 0`` is an exact zero (no double makes ``cos``
    vanish); ``exact=True`` evaluates with exact arithmetic instead, as a computer-algebra system
    would: ``q`` is then an array of sympy numbers (e.g. ``pi/2``) and the result an object array
    of sympy numbers (``nan`` for 0/0).
    ``table`` (default :data:`exo_bench.matrix_method.printed.TRANSITIONS`) lets a test swap printed lines for
    corrected ones. A 2D model has no transitions: its matrices are the planar closed forms.
    """
    from exo_bench.matrix_method import printed

    cos: Callable[[np.ndarray], np.ndarray]
    sin: Callable[[np.ndarray], np.ndarray]
    if exact:
        import sympy as sp

        q = np.asarray(q, dtype=object)
        if q.ndim == 1:
            q = q[None, :]
        cos, sin = np.vectorize(sp.cos, otypes=[object]), np.vectorize(sp.sin, otypes=[object])
        to_exact = np.vectorize(sp.Rational, otypes=[object])
        phi, _, l = split(mech, q)
        flat = _planar(mech, phi, l, cos, sin, to_exact(signed_coupling(mech)), to_exact(signed_gravity(mech)))
    else:
        q, _, _ = as_states(mech, q)
        cos, sin = np.cos, np.sin
        flat = planar_matrices(mech, q)
    if mech.dim == 2:
        return flat
    table = printed.TRANSITIONS if table is None else table
    t = printed.transition_namespace(mech, q, flat, cos=cos, sin=sin)
    out: dict[str, dict[str, np.ndarray]] = {b: {} for b in ("phi", "psi", "l")}
    with np.errstate(invalid="ignore", divide="ignore"):
        for f in table:  # in printed order: later lines may use earlier 3D ones
            if f.fn is None:
                continue  # the mu lines name the right-hand sides, no matrix
            value = f.fn(t)
            shape = q.shape[:1] + ((mech.nlinks,) if f.name == "P" else (mech.nlinks, mech.nlinks))
            out[f.block][f.name] = np.broadcast_to(value, shape).astype(object if exact else float)
            setattr(t, f"{f.name}_{f.block}_3d", out[f.block][f.name])
    return out


def inverse_dynamics_paper(mech: Mechanism, q, qd, qdd) -> np.ndarray:
    """Method ``matrix-paper``: eq. (17) with the matrices of eq. (18) exactly as printed.

    Where a printed line divides by an exact zero (``sin phi_i = 0`` at ``phi_i = 0``; in floating
    point ``cos`` is never exactly 0) the forces are NaN and a :class:`RuntimeWarning` names the
    samples. Where a printed line is wrong (see ``reports/errata.md``) the forces are wrong.
    """
    q, qd, qdd = as_states(mech, q, qd, qdd)
    return warn_paper_nan(generalised_forces(mech, paper_matrices(mech, q), qd, qdd), stacklevel=3)


def warn_paper_nan(tau: np.ndarray, stacklevel: int = 2) -> np.ndarray:
    """Say which samples of a ``matrix-paper`` result are NaN (0/0 of eq. (18) as printed), never
    hide them; return ``tau`` unchanged."""
    bad = np.isnan(tau).any(axis=1)
    if bad.any():
        idx = np.flatnonzero(bad)
        warnings.warn(
            f"matrix-paper: eq. (18) as printed divides 0/0 at {idx.size} sample(s) "
            f"(first: {idx[:5].tolist()}); their forces are NaN",
            RuntimeWarning,
            stacklevel=stacklevel + 1,
        )
    return tau
