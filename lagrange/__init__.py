"""Lagrange's equations of the second kind for the rod models, derived with sympy.

The suite's independent symbolic check of the matrix method: :func:`derive` builds T and Pi from
the point masses' geometry and differentiates them; :mod:`exo_bench.lagrange.numeric` evaluates the result
with numpy, :mod:`exo_bench.lagrange.high_precision` at 50 significant digits with mpmath, and
:mod:`exo_bench.lagrange.peer` builds the same equations with ``sympy.physics.mechanics`` as a peer.

What belongs here, one module each: the derivation (``derivation``, in the ring of ``ring``, its
matrices read off by ``matrix_form``), the time budgets of all symbolic work (``budget``), numeric
evaluation (``numeric``, ``high_precision``, and ``prepared``: the method ``lagrange``), the
50-digit reference of the derivatives (``derivative_reference``) and the peer (``peer``). This
package's names below are its public interface, defined in those modules.
"""

from exo_bench.lagrange.budget import BudgetExceeded
from exo_bench.lagrange.derivation import Derivation, clear_cache, derive
from exo_bench.lagrange.matrix_form import FormViolation, extract_matrices, rebuild_equations
from exo_bench.lagrange.ring import canonical_form

__all__ = [
    "BudgetExceeded",
    "Derivation",
    "FormViolation",
    "canonical_form",
    "clear_cache",
    "derive",
    "extract_matrices",
    "rebuild_equations",
]
