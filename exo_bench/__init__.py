"""exo-bench: equations of motion of telescopic-rod skeletons (Borisov & Chigarev), computed,
cross-validated and benchmarked.

The library in one line::

    from exo_bench import prepare, presets
    model = prepare(presets.exo5(dim=3), "matrix-factored")
    tau = model.inverse_dynamics(q, qd, qdd)

Subpackages, in layers that only import downwards: :mod:`exo_bench.models` (mechanism data,
kinematics, URDF, Pinocchio, forward dynamics) <- :mod:`exo_bench.lagrange` and
:mod:`exo_bench.matrix_method` (independent of each other) <- :mod:`exo_bench.bench` (the method
registry, studies, reports and the command line).
"""

from __future__ import annotations

__version__ = "0.2.0"

__all__ = ["Mechanism", "load_mechanism", "method_names", "prepare", "presets", "__version__"]


def __getattr__(name: str):
    # Lazy: ``import exo_bench`` stays cheap, and a user who never prepares a Lagrange model never
    # imports sympy.
    if name in ("prepare", "method_names"):
        from exo_bench.api import methods

        return getattr(methods, name)
    if name == "Mechanism":
        from exo_bench.models.mechanism import Mechanism

        return Mechanism
    if name == "load_mechanism":
        from exo_bench.models.loading import load_mechanism

        return load_mechanism
    if name == "presets":
        from exo_bench.models import presets

        return presets
    raise AttributeError(f"module 'exo_bench' has no attribute {name!r}")
