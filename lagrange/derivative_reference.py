"""The suite's 50-digit reference of the DERIVATIVES of the equations of motion.

**What it computes.** ``dtau/dq``, ``dtau/dqd``, ``M = dtau/dqdd`` (:func:`inverse_derivatives`) and,
by the implicit-function theorem at 50 digits, ``qdd``, ``dqdd/dq``, ``dqdd/dqd`` and ``M^-1``
(:func:`forward_derivatives`), for any tree in 2D or 3D with branch signs.

**How, and why it is independent.** The generalised forces are written by d'Alembert's principle on
the point masses, ``tau_a = sum_k m_k (d r_k / d q_a) . (r_k'' + g e_up)``, from the geometry of
:mod:`exo_bench.models.mechanism.mechanism` alone: link ``i`` starts at the end of its parent, ``w_i = s_i l_i
u_i(phi_i, psi_i)``, masses at fractions ``0, n_i, 1``. ``w_i''`` and ``d w_i / d q`` are hand-written
trigonometry of one unit vector (below); the masses' forces are summed over each link's subtree.
No code under test is used: not newton-euler's passes or its rod elements (spatial algebra), not the
matrix method's closed forms (mu, nu, eq. 6), not CasADi, not Lagrange's symbolic derivation (T and
Pi differentiated by sympy); its ``tau`` is checked against that derivation's 50-digit reference
(tests/test_derivatives_reference.py). The derivatives are then EXACT derivatives of this
arithmetic: forward-mode dual numbers, one tangent per input, so no step size and no truncation error.
A tangent is one array over the range of inputs its value depends on (a link's kinematics: its own
``3 dim`` inputs; sums along a path: the path's links), one numpy operation per dual operation. The
numbers are MPFR's through gmpy2 (the [test] extra) or, without it, mpmath's ``mpf`` (:func:`_backend`),
rounded alike to ``dps`` digits (``dps_to_prec``); the masses of a link are summed per power of their
fraction (``sum m_k A_k = (sum m_k) (start + g) + (sum m_k f_k) w''``: the same d'Alembert forces).

**Error model.** Inputs are float64, converted exactly; every operation rounds at ``dps``
digits (50 by default); a tangent entry is a sum of at most a few thousand products, so its error is
below ``10^(4 - dps)`` times the sum of the magnitudes of its terms. :func:`derivative_scale`
computes that sum of magnitudes in float64 by running the same formulas in magnitude arithmetic
(``|a b|' <= |a||b'| + |a'||b|``, ``|sin|, |cos| <= 1``), times ``max(1, |angles|)`` (a float64 code
rounds an angle ``a`` to ``eps |a|``): the scale of the error model of a float64 derivative against
this reference, ``|ours - ref| <= k eps scale``. At 50 digits the reference's own error is
``1e-46 * scale`` at most, 30 orders below float64's (tests compare 50 and 70 digits).

**Cost.** One dual evaluation per sample, ``O(n^2)`` numbers in a chain (the output's size), and
``O(dof^3)`` more for the forward derivatives' 50-digit solve (Gauss-Jordan, one vectorised elimination
per pivot). Measured per sample on the shared 2-core machine at load 12-15 (so slow by 3-5x): inverse
derivatives of a 3D chain of 30 links 0.8 s (the mpf dict-of-links duals before: 6.8-10.9 s in the same
process), of 100-link random trees 1.7 s (2D) and 4.5-5.5 s (3D), a 3D chain of 100 links 4.6-6.4 s, its
scale 0.6 s; forward derivatives 0.5 s at 10 links, 2.7 s at 20 (the solve grows as dof^3). The benchmark
takes the inverse reference to n = 100 and the forward one to n = 20 (bench/test_derivatives.py);
beyond, its rows say "no reference".
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import mpmath
import numpy as np
from mpmath.libmp import dps_to_prec, from_man_exp

from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import as_states


@dataclass(frozen=True)
class _Backend:
    """The multiple-precision numbers: MPFR through gmpy2 when it is installed (the [test] extra), else
    mpmath's ``mpf``. Both round every operation to ``dps_to_prec(dps)`` bits (mpmath's own conversion)."""

    name: str
    num: Callable  # a float64 as an exact number
    sin: Callable
    cos: Callable
    digits: Callable[[int], Any]  # dps -> context manager
    to_mpf: Callable  # a number -> mpmath.mpf, exactly


def _gmpy2_to_mpf(x) -> mpmath.mpf:
    man, exp = x.as_mantissa_exp()
    return mpmath.mp.make_mpf(from_man_exp(int(man), int(exp)))  # exact, whatever mpmath's precision


def _backend(prefer_gmpy2: bool = True) -> _Backend:
    """gmpy2's MPFR if importable and ``prefer_gmpy2``, else mpmath."""
    if prefer_gmpy2:
        try:
            import gmpy2
        except ImportError:
            pass
        else:
            return _Backend(
                "gmpy2",
                gmpy2.mpfr,
                gmpy2.sin,
                gmpy2.cos,
                lambda dps: gmpy2.context(precision=dps_to_prec(dps)),
                _gmpy2_to_mpf,
            )
    return _Backend("mpmath", mpmath.mpf, mpmath.sin, mpmath.cos, mpmath.workdps, lambda x: x)


def _widen(a: _Jet, b: _Jet, fa, fb):
    """``fa * a.d + fb * b.d`` on the union of the two ranges (either tangent may be None: zero)."""
    if a.d is None:
        return (None, 0) if b.d is None else (b.d if fb is None else b.d * fb, b.lo)
    da = a.d if fa is None else a.d * fa
    if b.d is None:
        return da, a.lo
    db = b.d if fb is None else b.d * fb
    if a.lo == b.lo and len(da) == len(db):
        return da + db, a.lo
    lo, hi = min(a.lo, b.lo), max(a.lo + len(da), b.lo + len(db))
    out = np.zeros(hi - lo, dtype=da.dtype)
    out[a.lo - lo : a.lo - lo + len(da)] = da
    out[b.lo - lo : b.lo - lo + len(db)] += db
    return out, lo


class _Jet:
    """A value and its tangents, exact forward mode. The inputs ``x = (q, qd, qdd)`` are numbered link
    by link (link ``i``'s ``3 dim`` inputs are ``3 dim i ...``); a tangent is one array over the range
    ``[lo, lo + len(d))`` of inputs that holds every one the value depends on (``d`` None: a constant).
    A link's kinematics depend on its own inputs only (a range of ``3 dim``), sums along a path on the
    path's links (a chain: a prefix): one numpy operation per jet operation, no dict of links."""

    __slots__ = ("v", "d", "lo")

    def __init__(self, v, d=None, lo: int = 0):
        self.v, self.d, self.lo = v, d, lo

    def __add__(self, o):
        if not isinstance(o, _Jet):
            return type(self)(self.v + o, self.d, self.lo)
        return type(self)(self.v + o.v, *_widen(self, o, None, None))

    __radd__ = __add__

    def __sub__(self, o):
        return self + (-o)

    def __neg__(self):
        return _Jet(-self.v, None if self.d is None else -self.d, self.lo)

    def __mul__(self, o):
        if isinstance(o, _Jet):
            return type(self)(self.v * o.v, *_widen(self, o, o.v, self.v))
        return type(self)(self.v * o, None if self.d is None else self.d * o, self.lo)

    __rmul__ = __mul__


class _Mag(_Jet):
    """Magnitude arithmetic: ``v`` and ``d`` bound the sums of ``|terms|`` of a value and its tangents."""

    __slots__ = ()

    def __add__(self, o):
        if not isinstance(o, _Jet):
            return _Mag(self.v + abs(o), self.d, self.lo)
        return _Mag(self.v + o.v, *_widen(self, o, None, None))

    __radd__ = __add__
    __sub__ = __add__

    def __neg__(self):
        return self

    def __mul__(self, o):
        if isinstance(o, _Jet):
            return _Mag(self.v * o.v, *_widen(self, o, o.v, self.v))
        return _Mag(self.v * abs(o), None if self.d is None else self.d * abs(o), self.lo)

    __rmul__ = __mul__


@dataclass(frozen=True)
class _Arith:
    sin: Callable
    cos: Callable
    num: Callable  # a float64 parameter as a number of this arithmetic
    zero: Callable  # a constant zero, no tangents


def _exact(b: _Backend) -> _Arith:
    def jsin(x: _Jet) -> _Jet:
        return _Jet(b.sin(x.v), None if x.d is None else x.d * b.cos(x.v), x.lo)

    def jcos(x: _Jet) -> _Jet:
        return _Jet(b.cos(x.v), None if x.d is None else x.d * (-b.sin(x.v)), x.lo)

    return _Arith(jsin, jcos, b.num, lambda: _Jet(b.num(0.0)))


def _msincos(x: _Mag) -> _Mag:
    return _Mag(1.0, x.d, x.lo)


_MAGNITUDE = _Arith(_msincos, _msincos, abs, lambda: _Mag(0.0))


def _dot(a, b):
    out = a[0] * b[0]
    for x, y in zip(a[1:], b[1:]):
        out = out + x * y
    return out


def _link_terms(dim: int, sign: int, phi, psi, l, rates, accs, ar: _Arith):
    """``(w'', [dw/dphi, dw/dpsi, dw/dl])`` of ``w = sign l u(phi, psi)``: hand-written trigonometry.
    ``rates``/``accs`` are ``(phi', psi', l')``/``(phi'', psi'', l'')`` (no psi entries in 2D)."""
    c, s = ar.cos(phi), ar.sin(phi)
    if dim == 2:
        dphi, dl = rates
        ddphi, ddl = accs
        u, u_p = [c, s], [-s, c]
        ud = [x * dphi for x in u_p]
        udd = [x * ddphi - y * (dphi * dphi) for x, y in zip(u_p, u)]
        partials = [[sign * (l * x) for x in u_p], [sign * x for x in u]]
    else:
        dphi, dpsi, dl = rates
        ddphi, ddpsi, ddl = accs
        cp, sp = ar.cos(psi), ar.sin(psi)
        u = [cp * c, cp * s, sp]
        u_p = [-(cp * s), cp * c, None]  # d u / d phi
        u_s = [-(sp * c), -(sp * s), cp]  # d u / d psi
        u_pp = [-u[0], -u[1], None]
        u_ps = [sp * s, -(sp * c), None]
        u_ss = [-u[0], -u[1], -sp]
        pp, ps, ss = dphi * dphi, dphi * dpsi, dpsi * dpsi
        ud, udd = [], []
        for k in range(3):
            if k < 2:
                ud.append(u_p[k] * dphi + u_s[k] * dpsi)
                udd.append(u_p[k] * ddphi + u_s[k] * ddpsi + u_pp[k] * pp + 2 * (u_ps[k] * ps) + u_ss[k] * ss)
            else:
                ud.append(u_s[k] * dpsi)
                udd.append(u_s[k] * ddpsi + u_ss[k] * ss)
        zero = ar.zero()
        partials = [
            [sign * (l * x) if x is not None else zero for x in u_p],
            [sign * (l * x) for x in u_s],
            [sign * x for x in u],
        ]
    wdd = [sign * (ddl * a + 2 * (dl * b) + l * e) for a, b, e in zip(u, ud, udd)]
    return wdd, partials


def _forces(mech: Mechanism, x: list, ar: _Arith) -> list:
    """``tau`` (list of ``dof`` numbers of the arithmetic ``ar``) from ``x = q + qd + qdd`` by d'Alembert."""
    n, dim, dof = mech.nlinks, mech.dim, mech.dof
    q, qd, qdd = x[:dof], x[dof : 2 * dof], x[2 * dof :]
    blocks = [(k * n) for k in range(dim)]  # [phi, (psi,) l] block starts
    g = ar.num(mech.g)
    partials, own, sub = [], [], []  # per link: dw/dq, sum f m A, sum m A
    end_acc: list = []
    for i in range(n):
        idx = [b + i for b in blocks]
        psi = q[idx[1]] if dim == 3 else None
        wdd, dw = _link_terms(
            dim, mech.sign[i], q[idx[0]], psi, q[idx[-1]], [qd[k] for k in idx], [qdd[k] for k in idx], ar
        )
        p = mech.parent[i]
        start = end_acc[p] if p >= 0 else None
        end_acc.append(wdd if start is None else [a + b for a, b in zip(start, wdd)])
        # the masses m_k at fractions f_k accelerate at A_k = start + f_k w'' (+ g e_up for their weight):
        # sum_k m_k A_k and sum_k m_k f_k A_k, summed as (sum m_k f_k^p) times start + g e_up and w''
        P, S = None, None
        mf = [(ar.num(m), ar.num(f)) for m, f in zip(mech.masses[i], (0.0, mech.n[i], 1.0)) if m != 0.0]
        if mf:
            m0, m1, m2 = (_dot([m for m, _ in mf], [f**p if p else 1 for _, f in mf]) for p in range(3))
            up = list(start) if start is not None else [ar.zero() for _ in range(dim)]
            up[-1] = up[-1] + g
            S = [m0 * a + m1 * w for a, w in zip(up, wdd)]
            if m1 != 0:
                P = [m1 * a + m2 * w for a, w in zip(up, wdd)]
        zero = [ar.zero() for _ in range(dim)]
        partials.append(dw)
        own.append(P or zero)
        sub.append(S or zero)
    for i in range(n - 1, 0, -1):  # subtree sums: children come after their parents
        p = mech.parent[i]
        if p >= 0:
            sub[p] = [a + b for a, b in zip(sub[p], sub[i])]
    tau: list = [None] * dof
    for i in range(n):
        F = own[i]
        for c in mech.children[i]:
            F = [a + b for a, b in zip(F, sub[c])]
        for b, dw in zip(blocks, partials[i]):
            tau[b + i] = _dot(dw, F)
    return tau


def _seeded(mech: Mechanism, values, lift: Callable, kind: type, one) -> list:
    """One jet per input ``x = q + qd + qdd`` (API order), its tangent the unit vector of that input:
    input ``which * dof + b * n + i`` (``which`` of q, qd, qdd; block ``b``; link ``i``) is number
    ``3 dim i + dim which + b`` (:class:`_Jet`)."""
    n, dim, dof = mech.nlinks, mech.dim, mech.dof
    dtype = object if kind is _Jet else float
    out = []
    for k, v in enumerate(values):
        which, a = divmod(k, dof)
        b, i = divmod(a, n)
        out.append(kind(lift(v), np.array([one], dtype=dtype), 3 * dim * i + dim * which + b))
    return out


def _order(mech: Mechanism) -> np.ndarray:
    """``order[c]``: the input number (:func:`_seeded`) of column ``c`` of ``d/d(q, qd, qdd)`` in API order."""
    n, dim, dof = mech.nlinks, mech.dim, mech.dof
    which, a = np.divmod(np.arange(3 * dof), dof)
    b, i = np.divmod(a, n)
    return 3 * dim * i + dim * which + b


def _jacobians(mech: Mechanism, tau: list, dtype) -> tuple:
    """``(tau, dtau/dq, dtau/dqd, M)`` of the jets ``tau``, arrays of ``dtype`` (zeros: ``0``)."""
    d = mech.dof
    val = np.array([t.v for t in tau], dtype=dtype)
    rows = np.zeros((d, 3 * d), dtype=dtype)
    for r, t in enumerate(tau):
        if t.d is not None:
            rows[r, t.lo : t.lo + len(t.d)] = t.d
    J = rows[:, _order(mech)]
    return val, J[:, :d], J[:, d : 2 * d], J[:, 2 * d :]


def _check_dps(dps) -> int:
    if not isinstance(dps, (int, np.integer)) or isinstance(dps, bool) or dps < 15:
        raise ValueError(f"derivative reference: field 'dps': expected an integer number of digits >= 15, got {dps!r}")
    return int(dps)


def _sample(mech: Mechanism, x, b: _Backend) -> tuple:
    """``(tau, dtau/dq, dtau/dqd, M)`` at one sample ``x`` (floats or numbers of ``b``), object arrays of
    ``b``'s numbers (structural zeros: the int ``0``), within ``b.digits``."""
    xs = _seeded(mech, x, b.num, _Jet, b.num(1.0))  # a float64 as a number is exact
    return _jacobians(mech, _forces(mech, xs, _exact(b)), object)


def _inverse(mech: Mechanism, q, qd, qdd, dps: int, convert: Callable, dtype, backend: _Backend) -> tuple:
    dps = _check_dps(dps)
    q, qd, qdd = as_states(mech, q, qd, qdd, source="derivative reference")
    S, d = q.shape[0], mech.dof
    tau, out = np.empty((S, d), dtype=dtype), [np.empty((S, d, d), dtype=dtype) for _ in range(3)]
    with backend.digits(dps):
        for s in range(S):  # one dual evaluation per sample
            parts = _sample(mech, [*q[s], *qd[s], *qdd[s]], backend)
            tau[s], out[0][s], out[1][s], out[2][s] = (convert(a) for a in parts)
    return (tau, *out)


def _as_mpf(b: _Backend) -> Callable:
    def convert(a: np.ndarray) -> np.ndarray:
        return np.array([b.to_mpf(b.num(x)) for x in a.ravel()], dtype=object).reshape(a.shape)

    return convert


def inverse_derivatives_mpf(mech: Mechanism, q, qd, qdd, dps: int = 50, backend: _Backend | None = None):
    """``(tau, dtau_dq, dtau_dqd, M)`` at ``dps`` digits, object arrays of ``mpmath.mpf`` (exact copies of
    the backend's numbers): ``(S, dof)`` and ``(S, dof, dof)`` three times (``J[s, i, j] = d tau_i / d x_j``)."""
    b = backend or _backend()
    return _inverse(mech, q, qd, qdd, dps, _as_mpf(b), object, b)


def _to_float(a: np.ndarray) -> np.ndarray:
    return np.vectorize(float, otypes=[float])(a).reshape(a.shape)


def inverse_derivatives(mech: Mechanism, q, qd, qdd, dps: int = 50, backend: _Backend | None = None):
    """``(dtau_dq, dtau_dqd, M)`` computed at ``dps`` digits and rounded to float64, ``(S, dof, dof)``."""
    return _inverse(mech, q, qd, qdd, dps, _to_float, float, backend or _backend())[1:]


def _solve(M: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``M^-1 B`` for object arrays of one backend's numbers (within its digits): Gauss-Jordan with
    partial pivoting, one vectorised elimination per pivot. A singular ``M`` raises ZeroDivisionError."""
    d = M.shape[0]
    A = np.concatenate([M, B], axis=1)
    for k in range(d):
        p = k + int(np.argmax([abs(x) for x in A[k:, k]]))
        if A[p, k] == 0:
            raise ZeroDivisionError(f"derivative reference: the mass matrix is singular (pivot {k})")
        if p != k:
            A[[k, p]] = A[[p, k]]
        A[k, k:] = A[k, k:] * (1 / A[k, k])
        col = A[:, k].copy()
        col[k] = 0
        A[:, k:] -= np.outer(col, A[k, k:])
    return A[:, d:]


def forward_derivatives(mech: Mechanism, q, qd, tau, dps: int = 50, backend: _Backend | None = None):
    """``(qdd, dqdd_dq, dqdd_dqd, Minv)`` at ``dps`` digits, rounded to float64: ``qdd = M^-1 (tau - h)``
    solved at ``dps`` digits, then ``dqdd/dx = -M^-1 dtau/dx`` at ``(q, qd, qdd)``. A singular ``M``
    raises ZeroDivisionError (the reference judges states the code under test accepts)."""
    dps = _check_dps(dps)
    b = backend or _backend()
    q, qd, tau = as_states(mech, q, qd, tau, source="derivative reference")
    S, d = q.shape[0], mech.dof
    out = [np.empty((S, d)), np.empty((S, d, d)), np.empty((S, d, d)), np.empty((S, d, d))]
    with b.digits(dps):
        for s in range(S):
            h, _, _, M = _sample(mech, [*q[s], *qd[s], *([0.0] * d)], b)
            rhs = np.array([b.num(t) - x for t, x in zip(tau[s], h)], dtype=object)[:, None]
            X = _solve(M, np.concatenate([np.eye(d, dtype=int).astype(object), rhs], axis=1))
            Minv, qdd = X[:, :d], X[:, d]
            _, Jq, Jqd, _ = _sample(mech, [*q[s], *qd[s], *qdd], b)
            out[0][s] = _to_float(qdd)
            out[1][s] = _to_float(-Minv.dot(Jq))
            out[2][s] = _to_float(-Minv.dot(Jqd))
            out[3][s] = _to_float(Minv)
    return tuple(out)


def derivative_scale(mech: Mechanism, q, qd, qdd) -> tuple[np.ndarray, ...]:
    """The error model's scales of ``(dtau_dq, dtau_dqd, M)``, ``(S, dof, dof)`` float64: the sums of
    ``|terms|`` of every entry in this module's formulas (magnitude arithmetic) times
    ``max(1, |angles|)`` of the sample. A float64 derivative agrees with the reference to
    ``k * eps * scale`` (module docstring)."""
    q, qd, qdd = as_states(mech, q, qd, qdd, source="derivative scale")
    S, d = q.shape[0], mech.dof
    out = [np.empty((S, d, d)) for _ in range(3)]
    angles = q[:, : d - mech.nlinks]
    for s in range(S):
        xs = _seeded(mech, np.abs(np.concatenate([q[s], qd[s], qdd[s]])), float, _Mag, 1.0)
        J = np.hstack(_jacobians(mech, _forces(mech, xs, _MAGNITUDE), float)[1:])
        grow = max(1.0, float(np.max(np.abs(angles[s]), initial=0.0)))
        for k in range(3):
            out[k][s] = J[:, k * d : (k + 1) * d] * grow
    return tuple(out)


def error_ratio(ours: np.ndarray, ref: np.ndarray, scale: np.ndarray) -> float:
    """``max |ours - ref| / (eps * scale)``: the error in units of the error model (NaN anywhere: inf)."""
    diff = np.abs(np.asarray(ours, dtype=float) - ref)
    if not np.all(np.isfinite(diff)):
        return math.inf
    unit = np.finfo(float).eps * scale
    ratio = np.divide(diff, unit, out=np.where(diff > 0, math.inf, 0.0), where=unit > 0)
    return float(np.max(ratio, initial=0.0))


def max_relative_error(ours: np.ndarray, ref: np.ndarray) -> float:
    """``max |ours - ref| / max |ref|`` per sample, the largest over samples (NaN anywhere: inf)."""
    ours, ref = np.asarray(ours, dtype=float), np.asarray(ref, dtype=float)
    diff = np.abs(ours - ref).reshape(ref.shape[0], -1)
    if not np.all(np.isfinite(diff)):
        return math.inf
    top = np.abs(ref).reshape(ref.shape[0], -1).max(axis=1)
    return float(np.max(diff.max(axis=1) / np.where(top > 0, top, 1.0), initial=0.0))
