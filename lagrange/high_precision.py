"""The suite's high-precision reference: the Lagrange II equations evaluated with mpmath.

The equations of :func:`exo_bench.lagrange.derive` hold the mechanism's parameters as exact Rationals equal
to their float64 values; here they are lambdified to mpmath (with common-subexpression
elimination) and evaluated at ``dps`` significant decimal digits (50 by default). Float64 inputs
are converted to ``mpf`` exactly, so the only rounding left is mpmath's at ``dps`` digits: the
result is the exact generalised force of the float64 model at the float64 state to about
``dps`` digits, less what cancellation inside the sums costs (tens of digits at most for sane
states), which is why 50 digits is a safe reference for float64 methods.

:func:`inverse_dynamics` rounds the result to float64 (correctly rounded from the mpf);
:func:`inverse_dynamics_mpf` returns the mpf values themselves. One Python call per sample: the
reference is meant for subsamples (hundreds, not millions, of states).
"""

from __future__ import annotations

import mpmath
import numpy as np

from exo_bench.lagrange.derivation import Derivation
from exo_bench.lagrange.numeric import Lambdified, lambdify_within_budget
from exo_bench.lagrange.numeric import clear_cache as numeric_clear_cache
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import as_states


def _equations(d: Derivation) -> tuple[list, list]:
    S = d.symbols
    return list(S.q + S.qd + S.qdd), list(d.equations)


def compile_reference(mech: Mechanism, budget: float | None = None) -> Lambdified:
    """The equations lambdified to mpmath (cached per mechanism; precision is set at call time)."""
    return lambdify_within_budget(mech, "mpmath reference", budget, _equations, modules="mpmath")


def inverse_dynamics_mpf(mech: Mechanism, q, qd, qdd, dps: int = 50, budget: float | None = None) -> np.ndarray:
    """Generalised forces at ``dps`` significant digits, an object array of ``mpmath.mpf``,
    ``(samples, dof)``. Inputs are float64 arrays, converted to mpf exactly."""
    if not isinstance(dps, (int, np.integer)) or isinstance(dps, bool) or dps < 15:
        raise ValueError(f"reference: field 'dps': expected an integer number of digits >= 15, got {dps!r}")
    q, qd, qdd = as_states(mech, q, qd, qdd)
    fn = compile_reference(mech, budget).fn
    x = np.concatenate([q, qd, qdd], axis=1)
    out = np.empty((q.shape[0], mech.dof), dtype=object)
    with mpmath.workdps(int(dps)):
        for s in range(x.shape[0]):  # mpmath is scalar: one call per sample
            row = fn(*[mpmath.mpf(float(v)) for v in x[s]])  # mpf(float) is exact
            out[s] = [mpmath.mpf(v) for v in row]
    return out


def inverse_dynamics(mech: Mechanism, q, qd, qdd, dps: int = 50, budget: float | None = None) -> np.ndarray:
    """Generalised forces computed at ``dps`` significant digits and rounded to float64, ``(samples, dof)``."""
    tau = inverse_dynamics_mpf(mech, q, qd, qdd, dps=dps, budget=budget)
    return np.vectorize(float, otypes=[float])(tau).reshape(tau.shape)


def clear_cache() -> None:
    """Forget the lambdified equations (numpy's and mpmath's: one cache, :mod:`exo_bench.lagrange.numeric`)."""
    numeric_clear_cache()
