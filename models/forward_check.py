"""The per-sample part of forward dynamics' checks as compiled passes, deciding only the common case;
the one-sample call that fuses them with newton-euler's forward passes is
:mod:`exo_bench.models.newton_euler.forward_fused`.

:meth:`exo_bench.models.prepared.PreparedModel.check_regular` refuses a state where ``M`` is exactly
singular (:mod:`exo_bench.models.singularity`: a rod of length zero, a vertical rod) or singular to
working precision (:mod:`exo_bench.models.conditioning`: ``kappa`` beyond ``CONDITION_LIMIT``, a rod
whose ``l_i |cos psi_i|`` is below ``PIVOT_MIN``). Both are O(n) per sample; in numpy they cost
microseconds a call and, for a batch, a Python loop over the samples. The ``clear`` of :func:`checks`
answers one question in one compiled pass over ``q``: is every sample clear of all of them by a
relative :data:`MARGIN`? Only then does the caller return at once. Otherwise the exact numpy checks run
as before and decide (and name the sample, the link and the reason): the verdicts and the messages are
theirs. The margin covers the few ulps by which numba's ``cos`` and the products here may differ from
numpy's; a state within it of a bound pays the exact check, never a different verdict. Its ``finite``
is the check of an answer (:func:`exo_bench.models.conditioning.check_finite` names the sample and the
coordinate once it says no).

:data:`DONE`, :data:`EXACT` and :data:`NOT_FINITE` are the answers of that fused call.

The mechanism's own part (``mu`` singular, or its condition beyond the bound: every configuration is
refused) is decided once per model by the caller, which passes ``cond(mu_s)`` (``inf`` where it
refuses) in the ``plan`` (:func:`plan`), with the bounds: nothing of another module is frozen into the
machine code (numba caches it keyed on this file; newton-euler's fused call, which inlines
:func:`_row_clear` and :func:`_finite`, is keyed on it too: models/numba_cache.py).
"""

from __future__ import annotations

import functools
import math
from typing import Any, NamedTuple

import numpy as np

from exo_bench.models.numba_runtime import JIT, ensure, jit_disabled

ensure()  # numba's runtime set-up (models/numba_runtime.py), before the first kernel is defined

from numba import njit, types  # noqa: E402


#: Relative distance from every bound within which the exact numpy checks decide.
MARGIN = 1e-6
#: The answers of :func:`checked_forward`.
DONE, EXACT, NOT_FINITE = 0, 1, 2
#: The entries of a plan: ``g``, ``dim``, ``cond(mu_s)`` (inf: refused), and the bounds moved by
#: :data:`MARGIN` towards refusing: ``CONDITION_LIMIT``, ``PIVOT_MIN``, ``COS_VERTICAL``.
_G, _DIM, _KAPPA, _LIMIT, _PIVOT, _VERTICAL = range(6)
#: The length of a plan.
PLAN_SIZE = 6

_LEAN: Any = {**JIT, "_nrt": False}  # Any: numba's stubs do not list _nrt


def plan(g: float, dim: int, kappa: float) -> np.ndarray:
    """The plan of one mechanism (module docstring); ``kappa``: ``cond(mu_s)``, inf where the mechanism
    itself is refused."""
    from exo_bench.models.conditioning import CONDITION_LIMIT, PIVOT_MIN
    from exo_bench.models.singularity import COS_VERTICAL

    bounds = (CONDITION_LIMIT * (1.0 - MARGIN), PIVOT_MIN * (1.0 + MARGIN), COS_VERTICAL * (1.0 + MARGIN))
    return np.array([g, dim, kappa, *bounds], dtype=np.float64)


def plan_of(mech: Any, coupling: Any) -> np.ndarray:
    """:func:`plan` of a mechanism whose ``cond(mu_s)`` is ``coupling``
    (:class:`~exo_bench.models.conditioning.CouplingCondition`): its own part decided here, once per model
    (:func:`~exo_bench.models.singularity.mechanism_reasons`, :func:`~exo_bench.models.conditioning.coupling_reason`)."""
    from exo_bench.models.conditioning import coupling_reason
    from exo_bench.models.singularity import mechanism_reasons

    mine = not mechanism_reasons(mech) and coupling_reason(mech, coupling) is None
    return plan(mech.g, mech.dim, coupling.kappa if mine else math.inf)


@njit(**_LEAN)
def _row_clear(q, start, dof, n, p):
    """Sample at ``q[start : start + dof]`` (flat): every entry finite and every bound cleared by
    :data:`MARGIN`."""
    top, nonfinite = 1.0, 0.0
    for j in range(start, start + dof - n):
        top = max(top, abs(q[j]))
        nonfinite += q[j] - q[j]  # NaN exactly where some entry is NaN or inf
    low_cos, low_pivot = 1.0, math.inf
    for i in range(n):
        c = abs(math.cos(q[start + n + i])) if p[_DIM] == 3.0 else 1.0
        low_cos = min(low_cos, c)
        low_pivot = min(low_pivot, q[start + dof - n + i] * c)
        nonfinite += q[start + dof - n + i] - q[start + dof - n + i]
    return (
        nonfinite == 0.0
        and low_cos > p[_VERTICAL]
        and low_pivot >= p[_PIVOT]
        and p[_KAPPA] * top <= p[_LIMIT] * (low_cos * low_cos)
    )


@njit(**_LEAN)
def _finite(a):
    """Every entry of ``a`` is finite (``x - x`` is NaN exactly for NaN and inf)."""
    acc = 0.0
    for j in range(a.shape[0]):
        acc += a[j] - a[j]
    return acc == 0.0


@njit(**_LEAN)
def clear_1d(q, n, p):
    """One validated sample ``(dof,)``: :func:`_row_clear`."""
    return _row_clear(q, 0, q.shape[0], n, p)


@njit(**_LEAN)
def clear_2d(q, n, p):
    """A validated C-ordered batch ``(samples, dof)``: every sample :func:`_row_clear`."""
    dof = q.shape[1]
    flat = q.reshape(q.size)
    for s in range(q.shape[0]):
        if not _row_clear(flat, s * dof, dof, n, p):
            return False
    return True


@njit(**_LEAN)
def finite_1d(a):
    """Every entry of the flat ``a`` is finite."""
    return _finite(a)


class Entries(NamedTuple):
    """The compiled entry points (or the same functions run by Python under ``NUMBA_DISABLE_JIT``)."""

    clear_1d: Any
    clear_2d: Any
    finite_1d: Any


@functools.cache
def entries() -> Entries:
    """Resolved (compiled, or loaded from numba's on-disk cache) on the first call in a process."""
    if jit_disabled():
        return Entries(clear_1d, clear_2d, finite_1d)
    one, two, n = types.Array(types.float64, 1, "C"), types.Array(types.float64, 2, "C"), types.int64
    return Entries(
        clear_1d.compile((one, n, one)),
        clear_2d.compile((two, n, one)),
        finite_1d.compile((one,)),
    )


def checks(n: int, p: np.ndarray) -> tuple[Any, Any]:
    """``(clear, finite)`` of one mechanism's plan ``p``: ``clear(q)``, every sample of validated ``q``
    (``(dof,)`` or ``(samples, dof)``) clears the bounds by :data:`MARGIN` (False: the exact checks
    decide); ``finite(a)``, every entry of the answer ``a`` is finite (False:
    :func:`~exo_bench.models.conditioning.check_finite` decides). Arrays that are not C-ordered float64
    are left to the exact checks."""
    e = entries()
    by_ndim: tuple[Any, ...] = (None, e.clear_1d, e.clear_2d)
    f8, fin = np.dtype(np.float64), e.finite_1d

    def clear(q: np.ndarray) -> bool:
        if q.dtype is not f8 or not q.flags.c_contiguous or not 0 < q.ndim < 3:
            return False
        return bool(by_ndim[q.ndim](q, n, p))

    def finite(a: np.ndarray) -> bool:
        return a.dtype is f8 and a.flags.c_contiguous and bool(fin(a.reshape(-1)))

    return clear, finite


def checked_entry(model: Any, fused: Any, lead: tuple, forward_one: Any) -> Any:
    """``forward_checked(q, qd, tau) -> qdd`` of a kernel whose compiled call
    ``fused(*lead, plan, q, qd, tau, qdd)`` runs the checks and its forward dynamics of one sample,
    answering :data:`DONE`, :data:`EXACT` or :data:`NOT_FINITE` (newton-euler's ``tree-forward``,
    matrix-factored's ``cholesky-forward``). Near a bound the model's exact ``check_regular`` decides
    and names why, then ``forward_one(q, qd, tau, out)`` (the same arithmetic) runs; an answer that
    is not finite is named by :func:`~exo_bench.models.conditioning.check_finite`."""
    from exo_bench.models.conditioning import check_finite

    dof = model.dof

    def forward_checked(q, qd, tau):
        checks = model._forward_checks or model._resolve_forward_checks()  # the plan: once per model
        qdd = np.empty(dof)
        if (code := fused(*lead, model.forward_plan, q, qd, tau, qdd)) == EXACT:  # near a bound
            model.check_regular(q.reshape(1, -1))  # the exact checks decide, naming why (one sample as a batch)
            code = DONE if checks[1](forward_one(q, qd, tau, qdd)) else NOT_FINITE
        if code == NOT_FINITE:
            check_finite(model.mechanism, qdd)
        return qdd

    return forward_checked
