"""exo-bench: equations of motion of telescopic-rod skeletons (Borisov & Chigarev), computed,
cross-validated and benchmarked.

The library in one line::

    from exo_bench import prepare, presets
    model = prepare(presets.exo5(dim=3), "matrix-factored")
    tau = model.inverse_dynamics(q, qd, qdd)

Subpackages, in layers that only import downwards: :mod:`exo_bench.models` (mechanism data,
kinematics, URDF, Pinocchio, forward dynamics) <- :mod:`exo_bench.lagrange` and
:mod:`exo_bench.matrix_method` (independent of each other) <- :mod:`exo_bench.api` (:func:`prepare`,
one :class:`~exo_bench.api.methods.MethodSpec` per method, the cost model) <- :mod:`exo_bench.bench`
(studies, benchmarks, reports and the command line).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # what IDEs and type checkers see; at run time the names load lazily (__getattr__)
    from exo_bench.api.methods import MethodSpec, method_names
    from exo_bench.api.preparation import prepare
    from exo_bench.models.mechanism import presets
    from exo_bench.models.mechanism.loading import load_mechanism
    from exo_bench.models.mechanism.mechanism import Mechanism

__version__ = "0.2.0"

__all__ = ["Mechanism", "MethodSpec", "load_mechanism", "method_names", "prepare", "presets", "__version__"]

#: name -> (module, attribute or None for the module itself), imported on first use.
_LAZY: dict[str, tuple[str, str | None]] = {
    "prepare": ("exo_bench.api.preparation", "prepare"),
    "method_names": ("exo_bench.api.methods", "method_names"),
    "MethodSpec": ("exo_bench.api.methods", "MethodSpec"),
    "Mechanism": ("exo_bench.models.mechanism.mechanism", "Mechanism"),
    "load_mechanism": ("exo_bench.models.mechanism.loading", "load_mechanism"),
    "presets": ("exo_bench.models.mechanism.presets", None),
}


def __getattr__(name: str) -> Any:
    # Lazy: ``import exo_bench`` stays cheap, and a user who never prepares a Lagrange model never
    # imports sympy.
    if name not in _LAZY:
        raise AttributeError(f"module 'exo_bench' has no attribute {name!r}")
    import importlib

    module, attr = _LAZY[name]
    mod = importlib.import_module(module)
    return mod if attr is None else getattr(mod, attr)


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
