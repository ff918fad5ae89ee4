"""The registry of inverse-dynamics methods, all with one signature and one coordinate order.

Each entry is ``f(mechanism, q, qd, qdd) -> tau`` with batch-first ``(samples, dof)`` arrays in
the block order ``[phi..., psi..., l...]`` and tau in ``[M_phi..., M_psi..., F...]``: the
generalised forces of the paper's absolute coordinates. Modules are imported lazily, so a
scene that does not use a method never imports (or derives) it.
"""

from __future__ import annotations

import importlib
from typing import Callable

import numpy as np

from exo_bench.models.mechanism import Mechanism

#: method name -> (module, function, one-line description)
METHODS: dict[str, tuple[str, str, str]] = {
    "pinocchio": ("exo_bench.models.pinocchio_backend", "inverse_dynamics", "Pinocchio RNEA on the generated URDF, tau = G^T tau_joint"),
    "lagrange": ("exo_bench.lagrange.numeric", "inverse_dynamics", "Lagrange II derived with sympy from the point masses' T and Pi, lambdified to numpy with cse"),
    "matrix": ("exo_bench.matrix_method.numeric", "inverse_dynamics", "the matrix method: closed-form matrices of eqs. (5)/(17), corrected eq. (18) without divisions, batched numpy"),
    "matrix-paper": ("exo_bench.matrix_method.numeric", "inverse_dynamics_paper", "the matrix method with eq. (18) exactly as printed (misprints and 0/0 included)"),
    "recurrence": ("exo_bench.matrix_method.recurrence", "inverse_dynamics", "the recurrence of eqs. (22)-(26) for trees, then eq. (5)/(17)"),
}

InverseDynamics = Callable[[Mechanism, np.ndarray, np.ndarray, np.ndarray], np.ndarray]


def method_names() -> list[str]:
    return list(METHODS)


def get_method(name: str) -> InverseDynamics:
    """The inverse-dynamics function of a method; a clear ValueError for an unknown name."""
    if name not in METHODS:
        raise ValueError(f"method: expected one of {', '.join(METHODS)}, got {name!r}")
    module, func, _ = METHODS[name]
    return getattr(importlib.import_module(module), func)
