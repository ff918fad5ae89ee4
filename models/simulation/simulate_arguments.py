"""The arguments of :func:`exo_bench.models.simulation.simulate.simulate`, checked before any work.

Each check raises ``ValueError("simulate: argument 'name': expected ..., got ...")``. What they rule
out is every combination that made ``simulate`` hang or answer nonsense: a time span that is not two
finite increasing numbers (``(0, nan)`` never ends), ``rtol`` of 0, NaN or below scipy's floor (scipy
raises it to 100 eps with a warning, or loops on NaN), ``atol`` not finite and positive (an error
scale of 0 or NaN), budgets that are not positive (``max_seconds=-1``), strings where numbers belong
(``"1"``), and a ``first_step`` outside the span. ``max_evaluations=None`` is the default budget
:data:`DEFAULT_MAX_EVALUATIONS`: no run is without one.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from exo_bench.models.simulation.forward_dynamics import IMPLICIT, INTEGRATORS
from exo_bench.models.runtime.prepared import PreparedModel

#: The Jacobians an implicit integrator can use: scipy's finite differences of the vectorised
#: right-hand side (``2 dof`` columns per Jacobian), or the analytic one of
#: :func:`exo_bench.models.simulation.simulate.make_jacobian`.
JACOBIANS = ("finite-difference", "analytic")
#: The smallest rtol: 100 machine epsilons, scipy's own floor (it raises smaller values to it).
RTOL_FLOOR = 100 * float(np.finfo(float).eps)
#: The budget of a run that states none, in right-hand-side evaluations (columns): 90 times the
#: largest run of the stability study (11,354 evaluations), seconds to minutes of work.
DEFAULT_MAX_EVALUATIONS = 1_000_000

__all__ = [
    "DEFAULT_MAX_EVALUATIONS",
    "IMPLICIT",
    "INTEGRATORS",
    "JACOBIANS",
    "RTOL_FLOOR",
    "SimulateArguments",
    "check_budget",
    "check_simulate_arguments",
]


@dataclass(frozen=True)
class SimulateArguments:
    """The checked arguments, as plain floats and ints, with the defaults filled in."""

    t_span: tuple[float, float]
    rtol: float
    atol: float
    max_evaluations: int
    max_seconds: float | None
    first_step: float | None


def _bad(name: str, expected: str, got: Any) -> ValueError:
    return ValueError(f"simulate: argument '{name}': expected {expected}, got {got!r}")


def _is_real(x: Any) -> bool:
    """A real number that is not a bool (nor a string, a Decimal, an array...)."""
    return isinstance(x, numbers.Real) and not isinstance(x, (bool, np.bool_))


def _real(name: str, x: Any, expected: str, ok: Callable[[float], bool]) -> float:
    if not _is_real(x) or not ok(float(x)):
        raise _bad(name, expected, x)
    return float(x)


def _positive(name: str, x: Any) -> float:
    return _real(name, x, "a finite number > 0", lambda v: math.isfinite(v) and v > 0)


def check_budget(max_evaluations: Any, max_seconds: Any, allow_none: bool = False) -> tuple[int | None, float | None]:
    """``(max_evaluations, max_seconds)`` checked: an integer >= 1 and a finite number > 0; ``None``
    is :data:`DEFAULT_MAX_EVALUATIONS` (``allow_none``: no limit) and no wall-time limit."""
    if max_evaluations is None:
        n = None if allow_none else DEFAULT_MAX_EVALUATIONS
    elif isinstance(max_evaluations, numbers.Integral) and not isinstance(max_evaluations, (bool, np.bool_)):
        n = int(max_evaluations)
        if n < 1:
            raise _bad("max_evaluations", "an integer >= 1 (or None for the default budget)", max_evaluations)
    else:
        raise _bad("max_evaluations", "an integer >= 1 (or None for the default budget)", max_evaluations)
    seconds = None if max_seconds is None else _positive("max_seconds", max_seconds)
    return n, seconds


def _t_span(t_span: Any) -> tuple[float, float]:
    expected = "two finite times (s), increasing: (t0, t1) with t0 < t1"
    if isinstance(t_span, (str, bytes)) or not hasattr(t_span, "__len__") or len(t_span) != 2:
        raise _bad("t_span", expected, t_span)
    a, b = t_span[0], t_span[1]
    if not (_is_real(a) and _is_real(b)) or not (math.isfinite(a) and math.isfinite(b) and float(a) < float(b)):
        raise _bad("t_span", expected, t_span)
    return float(a), float(b)


def check_simulate_arguments(
    model: Any,
    t_span: Any,
    controls: Any,
    integrator: Any,
    rtol: Any,
    atol: Any,
    max_evaluations: Any,
    max_seconds: Any,
    dense: Any,
    first_step: Any,
    jacobian: Any,
    clock: Any,
) -> SimulateArguments:
    """Every argument of ``simulate`` but the states (those are checked by
    :func:`exo_bench.models.mechanism.mechanism.as_states`), checked; the defaults filled in."""
    if not isinstance(model, PreparedModel):
        raise _bad("model", "a prepared model (exo_bench.prepare(mechanism, method))", type(model).__name__)
    if integrator not in INTEGRATORS:
        raise _bad("integrator", f"one of {', '.join(INTEGRATORS)}", integrator)
    if jacobian not in JACOBIANS:
        raise _bad("jacobian", f"one of {', '.join(JACOBIANS)}", jacobian)
    if jacobian == "analytic" and integrator not in IMPLICIT:
        raise _bad(
            "jacobian",
            f"'finite-difference' with {integrator} (only the implicit integrators, {', '.join(IMPLICIT)}, use one)",
            jacobian,
        )
    span = _t_span(t_span)
    if not callable(controls):
        raise _bad("controls", "a function (t, q, qd) -> tau", controls)
    if not callable(clock):
        raise _bad("clock", "a function () -> seconds", clock)
    if not isinstance(dense, (bool, np.bool_)):
        raise _bad("dense", "True or False", dense)
    rt = _real("rtol", rtol, f"a number >= {RTOL_FLOOR:.4g} (100 eps) and < 1", lambda v: RTOL_FLOOR <= v < 1.0)
    at = rt * 1e-3 if atol is None else _positive("atol", atol)
    n, seconds = check_budget(max_evaluations, max_seconds)
    assert n is not None
    first = None
    if first_step is not None:
        width = span[1] - span[0]
        first = _real(
            "first_step", first_step, f"None or a number in (0, {width:g}] (the span)", lambda v: 0 < v <= width
        )
    return SimulateArguments(span, rt, at, n, seconds, first)
