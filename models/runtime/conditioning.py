"""The conditioning test of forward dynamics, one for every method: answer within the error model, or refuse.

:mod:`exo_bench.models.mechanism.singularity` names where ``M`` is exactly singular (a rod of length zero, a
vertical rod, a massless link). Near those states ``M`` is regular but the answer of forward
dynamics can be anything: at ``psi3 = pi/2 - 1e-8`` the methods' accelerations differed by up to
79, each within rounding of its own ``M``. This module decides, from the mechanism and ``q`` alone
(so every method decides alike), whether the error model can vouch for an answer.

**The error model** (tests/conftest.py): every method computes each entry of ``M`` to
``K eps`` of its term scale ``|r_a| |mu_ij| |r_b| max(1, |angles|)``, with the lever arms ``r`` = ``l_i``
on an angle's rows and 1 on a length's, and ``h`` to ``K eps`` of its term scale. Write ``M = J^T
(mu (x) I) J`` (:mod:`exo_bench.models.simulation.forward_dynamics`): per link the columns of ``J`` are ``l_i
cos psi_i``, ``l_i`` and ``1`` times orthonormal directions. Equilibrated by its diagonal, ``M`` is
orthogonally similar to ``mu_s (x) I`` (``mu_s = D_mu^-1/2 mu D_mu^-1/2``), whatever the
configuration, but the rounding of an azimuth's entry, ``K eps l_i^2 mu_ii``, is ``K eps / cos^2
psi_i`` of the entry itself. The lengths drop out (every entry of a rod's rows scales with its
lever arm). So the error model's perturbations move the answer, in the equilibrated norm, by at
most ``K eps kappa`` relative, with the condition::

    kappa = cond(mu_s) * max(1, |angles|) / min_i cos^2 psi_i        (cos psi_i = 1 in 2D).

**The bound.** An answer whose bound ``K eps kappa`` exceeds :data:`FORWARD_RTOL` (three
significant digits) is refused: ``kappa > CONDITION_LIMIT = FORWARD_RTOL / (K eps) = 5.6e11``.
Within it, the answer of every method is the exact solution of a system within the error model
(its backward error ``|M qdd + h - tau|`` stays within the row scale: tests/test_forward_conditioning.py),
and the methods agree to ``K eps kappa``. ``cond(mu_s)`` is a property of the mechanism, estimated
once in O(n) by Hager's 1-norm estimator with the tree factor of ``mu``
(:mod:`exo_bench.models.mechanism.aggregates`): no dense matrix, no SVD. The per-sample part is O(n) and
vectorised over the samples: one cosine per rod.

**Tiny rods** are a genuine singularity, not a removable one: an angle's acceleration grows like
``1 / l_i`` (its rows of ``M`` like ``l_i^2``, its forces like ``l_i``), a pole at ``l_i = 0`` in these
coordinates (the rod vectors of :mod:`exo_bench.models.newton_euler.chart_free` have none). The
condition above does not see it (the lever arms scale it out), but floating point does: below
:data:`PIVOT_MIN` a rod's entries of ``M`` underflow and the divisions by ``l_i cos psi_i`` overflow. Such
a rod is refused naming the field ``l_i``. An answer that is not finite anyway (forces too large for
float64) is refused by :func:`check_finite`, naming the sample and the coordinate: never NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from exo_bench.models.mechanism.aggregates import link_aggregates
from exo_bench.models.mechanism.aggregates import end_point_mass, factor_end_point_mass, multiply_mu, solve_mu
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import split
from exo_bench.models.mechanism.singularity import SingularConfigurationError, massless_reason
from exo_bench.models.states.states import coordinate_names

EPS = float(np.finfo(float).eps)
#: Roundings per term of the error model: ``K`` of tests/conftest.py (a test checks that they are equal).
ROUNDINGS = 8
#: The largest relative error (equilibrated norm) of an answer that forward dynamics returns, by the
#: error model's bound ``K eps kappa``: three significant digits.
FORWARD_RTOL = 1e-3
#: ``kappa`` beyond which forward dynamics refuses: ``FORWARD_RTOL / (K eps)`` = 5.6e11.
CONDITION_LIMIT = FORWARD_RTOL / (ROUNDINGS * EPS)
#: Metres below which ``l_i |cos psi_i|`` (the smallest singular value of a rod's block of ``J``) is
#: refused: ``sqrt(tiny / eps)`` = 1.0e-146, so that the rod's entries of ``M``, ``mu_ii (l_i cos psi_i)^2``,
#: stay normal floats (full precision) for any mass coupling above ``eps`` kg.
PIVOT_MIN = math.sqrt(float(np.finfo(float).tiny) / EPS)
#: Samples named in one refusal (the count says the rest).
MAX_NAMED = 16


class NumericallySingularError(SingularConfigurationError):
    """Forward dynamics is refused: ``M`` is singular to working precision (or the answer is not finite).
    ``reasons`` lists, per offending sample, the link (and coordinate) and why."""

    def __init__(self, reasons: list[str], header: str = "the mass matrix is numerically singular"):
        self.reasons = reasons
        more = f" (and {len(reasons) - 1} more)" if len(reasons) > 1 else ""
        ValueError.__init__(self, f"forward dynamics is refused: {header}: {reasons[0]}{more}")


@dataclass(frozen=True)
class CouplingCondition:
    """The mechanism's part of ``kappa``: ``kappa`` estimates ``cond_1(mu_s)`` (``inf``: ``mu`` singular);
    ``link`` (0-based) has the smallest pivot of ``M_e`` relative to its diagonal, ``pivot``."""

    kappa: float
    link: int
    pivot: float


def _mu_diagonal(mech: Mechanism) -> np.ndarray:
    """``mu_ii = zeta_i + Theta(i)`` (:mod:`exo_bench.models.mechanism.aggregates`), O(n): descendants summed leaves first."""
    zeta, _, theta = link_aggregates(mech)
    below = np.zeros(mech.nlinks)
    for k in range(mech.nlinks - 1, -1, -1):
        p = mech.parent[k]
        if p >= 0:
            below[p] += theta[k] + below[k]
    return zeta + below


def coupling_condition(mech: Mechanism) -> CouplingCondition:
    """Estimate ``cond_1(mu_s)`` in O(n) (Hager's estimator of ``|mu_s^-1|_1``, as LAPACK's ``xLACON``,
    with at most five solves by the tree factor, plus Higham's alternating vector; ``|mu_s|_1`` exactly:
    ``mu >= 0`` entrywise, so its column sums are ``mu_s 1``)."""
    parent = np.asarray(mech.parent, dtype=np.int64)
    diag_e, off = end_point_mass(mech)
    pivot, mult, singular = factor_end_point_mass(mech)
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(diag_e > 0, pivot / np.where(diag_e > 0, diag_e, 1.0), 0.0)
    link = int(singular) if singular >= 0 else int(np.argmin(rel))
    dmu = _mu_diagonal(mech)
    if singular >= 0 or not (dmu > 0).all():
        return CouplingCondition(math.inf, link if singular >= 0 else int(np.argmin(dmu)), float(rel[link]))
    r = 1.0 / np.sqrt(dmu)
    norm = float(np.max(r * multiply_mu(parent, diag_e, off, r)))

    def inv(x: np.ndarray) -> np.ndarray:  # mu_s^-1 x = D^1/2 mu^-1 D^1/2 x
        return solve_mu(parent, pivot, mult, x / r) / r

    n = mech.nlinks
    x = np.full(n, 1.0 / n)
    est, last = 0.0, -1
    for _ in range(5):
        y = inv(x)
        est = max(est, float(np.abs(y).sum()))
        z = inv(np.where(y >= 0, 1.0, -1.0))
        j = int(np.argmax(np.abs(z)))
        if np.abs(z).max() <= z @ x or j == last:
            break
        x, last = np.zeros(n), j
        x[j] = 1.0
    alt = (-1.0) ** np.arange(n) * (1.0 + np.arange(n) / max(n - 1, 1))
    est = max(est, 2.0 * float(np.abs(inv(alt)).sum()) / (3.0 * n))
    return CouplingCondition(norm * est, link, float(rel[link]))


def singular_mass_reason(mech: Mechanism, k: int) -> str:
    """Why ``mu`` (``M_r``) is singular at link ``k`` (0-based), in the words of :mod:`exo_bench.models.mechanism.singularity`."""
    return (
        massless_reason(mech, k)
        if (mech.masses[k][1] == 0 and mech.masses[k][2] == 0 and k not in mech.parent)
        else f"link {k + 1} ({mech.names[k]}): zero mass: no mass moves with its end point while the other "
        "end points are held (M_r is singular)"
    )


def _bound() -> str:
    return f"> {CONDITION_LIMIT:.1e}, the bound where the error model's {ROUNDINGS} eps kappa exceeds {FORWARD_RTOL:g}"


def coupling_reason(mech: Mechanism, coupling: CouplingCondition) -> str | None:
    """The mechanism's own reason to refuse at every configuration, or None."""
    if math.isinf(coupling.kappa):
        return singular_mass_reason(mech, coupling.link)
    if coupling.kappa <= CONDITION_LIMIT:
        return None
    k = coupling.link
    return (
        f"link {k + 1} ({mech.names[k]}): at every configuration: the mass distribution's condition "
        f"~{coupling.kappa:.1e} {_bound()}: the pivot of its end point is {coupling.pivot:.2g} of its "
        "diagonal (almost no mass moves with it while the other end points are held)"
    )


def _cosines(mech: Mechanism, q: np.ndarray) -> np.ndarray:
    """``|cos psi_i|``, ``(S, n)`` (3D only)."""
    n = mech.nlinks
    return np.abs(np.cos(q[:, n : 2 * n]))


def condition_estimates(mech: Mechanism, q: np.ndarray, coupling: CouplingCondition, cos_psi=None) -> np.ndarray:
    """``kappa`` of every sample of ``q (S, dof)`` (module docstring), O(n) per sample, vectorised."""
    n = mech.nlinks
    angles = np.maximum(1.0, np.abs(q[:, :-n]).max(axis=1, initial=0.0))
    if mech.dim == 2:
        return coupling.kappa * angles
    c = _cosines(mech, q) if cos_psi is None else cos_psi
    with np.errstate(divide="ignore"):
        return coupling.kappa * angles / c.min(axis=1) ** 2


def _sample_reasons(mech, q, s, kappa, c, coupling) -> list[str]:
    """Why sample ``s`` is refused: a rod too short (field ``l_i``), else the largest factor of ``kappa``."""
    n = mech.nlinks
    _, psi, l = split(mech, q[s])
    cs = np.ones(n) if c is None else c[s]
    out = []
    with np.errstate(divide="ignore"):
        per_link = coupling.kappa * max(1.0, float(np.abs(q[s, :-n]).max(initial=0.0))) / cs**2
    for i in np.flatnonzero((l * cs < PIVOT_MIN) & (per_link <= CONDITION_LIMIT)):
        tilt = "" if psi is None else f" (l{i + 1} |cos psi{i + 1}| = {float(l[i] * cs[i]):.2g} m)"
        out.append(
            f"link {i + 1} ({mech.names[i]}): field 'l{i + 1}': rod length l{i + 1} = {float(l[i])!r} m{tilt} is "
            f"below {PIVOT_MIN:.1e} m: its angles' entries of M (~ l{i + 1}^2) underflow and their accelerations "
            f"grow like 1/l{i + 1} (a pole at l{i + 1} = 0, not removable in these coordinates)"
        )
    if kappa[s] <= CONDITION_LIMIT:
        return out
    angle = int(np.argmax(np.abs(q[s, :-n])))
    if psi is not None and 1.0 / cs.min() ** 2 >= abs(float(q[s, angle])):
        v = int(np.argmin(cs))
        out.append(
            f"link {v + 1} ({mech.names[v]}): psi{v + 1} = {float(psi[v])!r} is "
            f"{math.asin(min(1.0, float(cs[v]))):.2g} rad from vertical (|cos psi{v + 1}| = "
            f"{float(cs[v]):.2g}): condition ~{float(kappa[s]):.1e} {_bound()}: its azimuth phi{v + 1} moves "
            "almost no mass"
        )
    else:
        block, i = divmod(angle, n)
        name = ("phi", "psi")[block] + str(i + 1)
        out.append(
            f"link {i + 1} ({mech.names[i]}): {name} = {float(q[s, angle])!r} rad: condition "
            f"~{float(kappa[s]):.1e} {_bound()}: an angle this large carries a rounding of eps |{name}| = "
            f"{EPS * abs(float(q[s, angle])):.2g} rad into every method's sines and cosines"
        )
    return out


def conditioning_reasons(mech: Mechanism, q: np.ndarray, coupling: CouplingCondition, cos_psi=None) -> list[str]:
    """``"sample s: ..."`` reasons to refuse forward dynamics at validated ``q (S, dof)`` (the first
    :data:`MAX_NAMED` offending samples); empty where every answer is within the bound. The exactly
    singular states (:mod:`exo_bench.models.mechanism.singularity`) are for the caller to name first."""
    whole = coupling_reason(mech, coupling)
    if whole is not None:
        return [f"sample 0: {whole}"]
    n = mech.nlinks
    if q.shape[0] == 0:
        return []
    c = None if mech.dim == 2 else (_cosines(mech, q) if cos_psi is None else cos_psi)
    # the whole batch at once first (reductions, no temporaries): the common case passes here
    ang = q[:, :-n]
    worst_angle = max(1.0, float(ang.max(initial=0.0)), -float(ang.min(initial=0.0)))
    worst_cos = 1.0 if c is None else float(c.min())
    if (
        worst_cos > 0
        and coupling.kappa * worst_angle / worst_cos**2 <= CONDITION_LIMIT
        and float(q[:, -n:].min()) * worst_cos >= PIVOT_MIN
    ):
        return []
    kappa = condition_estimates(mech, q, coupling, c)
    pivots = q[:, -n:] if c is None else q[:, -n:] * c
    bad = (kappa > CONDITION_LIMIT) | (pivots < PIVOT_MIN).any(axis=1)
    out: list[str] = []
    for s in np.flatnonzero(bad)[:MAX_NAMED]:
        out.extend(f"sample {s}: {r}" for r in _sample_reasons(mech, q, int(s), kappa, c, coupling))
    return out


def check_conditioning(mech: Mechanism, q: np.ndarray, coupling: CouplingCondition, cos_psi=None) -> None:
    """Raise :class:`NumericallySingularError` where :func:`conditioning_reasons` names a sample."""
    reasons = conditioning_reasons(mech, q, coupling, cos_psi)
    if reasons:
        raise NumericallySingularError(reasons)


def check_finite(mech: Mechanism, qdd: np.ndarray, field: str = "qdd") -> None:
    """Raise :class:`NumericallySingularError` naming the sample and the coordinate where an answer
    ``(S, dof)`` (or ``(dof,)``) is not finite: never NaN or inf returned. O(n) per sample."""
    a = np.atleast_2d(qdd)
    ok = np.isfinite(a).all(axis=1)
    if ok.all():
        return
    names = coordinate_names(mech)
    reasons = []
    for s in np.flatnonzero(~ok)[:MAX_NAMED]:
        j = int(np.flatnonzero(~np.isfinite(a[s]))[0])
        reasons.append(
            f"sample {s}: field '{field}' coordinate {names[j]} (link {j % mech.nlinks + 1}, "
            f"{mech.names[j % mech.nlinks]}): not finite ({float(a[s, j])!r}): the forces or rates are too large "
            "for float64 at this state"
        )
    raise NumericallySingularError(reasons, header="the answer is not finite")
