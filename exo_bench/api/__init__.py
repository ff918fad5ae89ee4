"""The library's interface: :func:`prepare`, and one :class:`MethodSpec` per method.

Layers (import-linter, pyproject.toml): :mod:`exo_bench.bench` <- :mod:`exo_bench.api` <-
:mod:`exo_bench.lagrange` | :mod:`exo_bench.matrix_method` <- :mod:`exo_bench.models`.

* :mod:`exo_bench.api.methods`: the :class:`MethodSpec` table, every per-method fact.
* :mod:`exo_bench.api.preparation`: :func:`prepare` and :class:`PreparedSet`.
* :mod:`exo_bench.api.cost_formulas`: each method's cost formulas.
* :mod:`exo_bench.api.cost_model`: memory and time estimated before a run, and the limits that refuse it.
"""

from exo_bench.api.methods import METHODS, MethodSpec, method_class, method_names, spec
from exo_bench.api.preparation import PreparedSet, prepare

__all__ = ["METHODS", "MethodSpec", "PreparedSet", "method_class", "method_names", "prepare", "spec"]
