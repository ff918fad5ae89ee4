"""Numeric evaluation of the Lagrange II equations: lambdified to numpy with common-subexpression
elimination, batched over samples.

Every function takes states as batch-first ``(samples, dof)`` arrays in block order (validated by
:func:`exo_bench.models.states.states.as_states`) and a time ``budget`` in seconds for the symbolic work
(derivation plus ``lambdify``) the first time a mechanism is seen; the compiled functions are
cached per mechanism. Over budget, :class:`exo_bench.lagrange.BudgetExceeded` carries a ``skip_reason``.
``budget=None`` means :data:`DEFAULT_BUDGET` (120 s). The prepared model
(:class:`exo_bench.lagrange.prepared.LagrangeModel`) takes the budget as a constructor option.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from collections.abc import Callable

import numpy as np
import sympy as sp

from exo_bench.lagrange.budget import BudgetAlarm, BudgetExceeded, time_budget
from exo_bench.lagrange.derivation import Derivation, derive
from exo_bench.models.machine.memory import BoundedCache
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import as_states

DEFAULT_BUDGET = 120.0


def default_budget() -> float:
    """Seconds allowed for the symbolic work when no budget is given: :data:`DEFAULT_BUDGET`."""
    return DEFAULT_BUDGET


@dataclass(frozen=True)
class Lambdified:
    fn: Callable
    seconds: float  # wall time of the lambdify call


# Bounded memos (models/machine/memory.py): four functions per mechanism, of the latest eight or so.
_CACHE: BoundedCache[tuple[Mechanism, str], Lambdified] = BoundedCache(32)
_FAILED: BoundedCache[tuple[Mechanism, str], float] = BoundedCache(256)  # seconds an unfinished compilation ran


def _columns(fn: Callable, args: list[np.ndarray], samples: int, width: int) -> np.ndarray:
    """Call a lambdified function on columns and stack its outputs into ``(samples, width)``."""
    out = np.empty((samples, width))
    for k, col in enumerate(fn(*args)):
        out[:, k] = col  # broadcasts constant entries
    return out


def lambdify_within_budget(
    mech: Mechanism,
    what: str,
    budget: float | None,
    build: Callable[[Derivation], tuple[list, list]],
    modules: str = "numpy",
) -> Lambdified:
    """``sympy.lambdify(*build(derive(mech)), modules=modules, cse=True)``, the derivation and the
    lambdify together within ``budget`` seconds (None: :func:`default_budget`), cached per
    ``(mech, what)``; an attempt that ran out of budget is remembered, so that a second call with no
    more budget than it spent fails at once. The one place the suite turns Lagrange's equations
    into a function (numpy here, mpmath for :mod:`exo_bench.lagrange.high_precision`)."""
    key = (mech, what)
    if key not in _CACHE:
        budget = default_budget() if budget is None else budget
        with time_budget(budget, f"Lagrange II {what} (derivation and lambdify)", mech.nlinks, mech.dim) as dl:
            if dl.remaining <= _FAILED.get(key, 0.0):  # no time left, or no more than an earlier attempt ran
                raise dl.exceeded(
                    note=f"; an earlier attempt ran {_FAILED[key]:.2f} s without finishing" if key in _FAILED else ""
                )
            try:
                d = derive(mech, symbolic_parameters=False, budget=budget)
                args, exprs = build(d)
                t0 = time.perf_counter()
                fn = sp.lambdify(args, exprs, modules=modules, cse=True)
            except (BudgetExceeded, BudgetAlarm):
                _FAILED[key] = max(_FAILED.get(key, 0.0), dl.elapsed)
                raise
            _CACHE[key] = Lambdified(fn, time.perf_counter() - t0)
    return _CACHE[key]


def compile_equations(mech: Mechanism, budget: float | None = None) -> Lambdified:
    """The lambdified equations ``tau(q..., qd..., qdd...)`` of a mechanism (cached); call once
    outside a timed loop to separate the symbolic cost from the evaluation."""
    return lambdify_within_budget(
        mech, "equations", budget, lambda d: (list(d.symbols.q + d.symbols.qd + d.symbols.qdd), list(d.equations))
    )


def inverse_dynamics(mech: Mechanism, q, qd, qdd, budget: float | None = None) -> np.ndarray:
    """Generalised forces ``[M_phi..., M_psi..., F...]`` from Lagrange II, ``(samples, dof)``."""
    q, qd, qdd = as_states(mech, q, qd, qdd)
    c = compile_equations(mech, budget)
    return _columns(c.fn, [*q.T, *qd.T, *qdd.T], q.shape[0], mech.dof)


def _mass_matrix_build(d):
    M = d.mass_matrix
    return list(d.symbols.q), [M[a, b] for a in range(M.rows) for b in range(M.cols)]


def mass_matrix(mech: Mechanism, q, budget: float | None = None) -> np.ndarray:
    """The mass matrix ``d tau / d qdd`` (row block k: ``[A_k, B_k, Lambda_k]``), ``(samples, dof, dof)``."""
    q, _, _ = as_states(mech, q)
    c = lambdify_within_budget(mech, "mass matrix", budget, _mass_matrix_build)
    return _columns(c.fn, list(q.T), q.shape[0], mech.dof**2).reshape(-1, mech.dof, mech.dof)


def _bias_build(d):
    S = d.symbols
    zero = {x: 0 for x in S.qdd}
    return list(S.q + S.qd), [e.xreplace(zero) for e in d.equations]


def bias_forces(mech: Mechanism, q, qd, budget: float | None = None) -> np.ndarray:
    """Velocity and gravity terms ``tau(q, qd, 0)`` (the ``D, E, G, H, K, P`` part), ``(samples, dof)``."""
    q, qd, _ = as_states(mech, q, qd)
    c = lambdify_within_budget(mech, "bias forces", budget, _bias_build)
    return _columns(c.fn, [*q.T, *qd.T], q.shape[0], mech.dof)


def clear_cache() -> None:
    _CACHE.clear()
    _FAILED.clear()


__all__ = [
    "DEFAULT_BUDGET",
    "default_budget",
    "bias_forces",
    "clear_cache",
    "compile_equations",
    "inverse_dynamics",
    "mass_matrix",
]
