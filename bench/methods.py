"""The registry of inverse-dynamics methods and :func:`prepare`, the library's entry point.

Each entry names a :class:`~exo_bench.models.prepared.PreparedModel` subclass. ``prepare(mechanism,
name, **options)`` builds it once (all per-mechanism work); its ``inverse_dynamics(q, qd, qdd)``
takes batch-first ``(samples, dof)`` (or one ``(dof,)``) arrays in the block order
``[phi..., psi..., l...]`` and returns ``[M_phi..., M_psi..., F...]``: the generalised forces of
the paper's absolute coordinates. Modules are imported lazily, so a scene that does not use a
method never imports (or derives) it.
"""

from __future__ import annotations

import importlib
from typing import Any

from exo_bench.models.mechanism import Mechanism
from exo_bench.models import prepared
from exo_bench.models.prepared import PreparedModel

#: method name -> (module, PreparedModel subclass, one-line description). The name says what runs.
METHODS: dict[str, tuple[str, str, str]] = {
    "pinocchio": ("exo_bench.models.pinocchio_backend", "PinocchioRNEA",
                  "Pinocchio RNEA on the generated URDF, tau = G^T tau_joint (option: threads)"),
    "lagrange": ("exo_bench.lagrange.prepared", "LagrangeModel",
                 "Lagrange II derived with sympy from the point masses' T and Pi, lambdified to numpy with cse "
                 "(options: budget, interrupt)"),
    "matrix": ("exo_bench.matrix_method.prepared", "MatrixProducts",
               "the matrix method: every matrix of eqs. (5)/(17) from the closed forms (corrected eq. (18), "
               "no division), then the products with the rates; compiled loops (option kernel: numba, the "
               "default, or numpy)"),
    "matrix-factored": ("exo_bench.matrix_method.prepared", "MatrixFactored",
                        "the matrix method's equations in factored form (no matrix formed); compiled loops "
                        "(option kernel: numba, the default, or numpy)"),
    "matrix-paper": ("exo_bench.matrix_method.prepared", "MatrixPaper",
                     "the matrix method with eq. (18) exactly as printed: WRONG in 3D by design (misprints, 0/0)"),
    "recurrence": ("exo_bench.matrix_method.prepared", "Recurrence",
                   "the recurrence of eqs. (22)-(26) for trees, then the products of eq. (5)/(17); compiled "
                   "loops (option kernel: numba, the default, or numpy)"),
    "newton-euler": ("exo_bench.models.newton_euler.prepared", "NewtonEuler",
                     "O(n) passes over the tree in the rod vectors r_i = s_i l_i u_i (M = J^T M_r J, M_r constant), "
                     "forward dynamics by M_r factored once; compiled loops (option kernel: numba, the default, "
                     "or numpy)"),
    "mujoco": ("exo_bench.models.mujoco_backend", "MujocoRNE",
               "MuJoCo's RNE (mj_kinematics, mj_comPos, mj_comVel, mj_rne) on the exported MJCF, tau = G^T tau_joint; "
               "a Python loop over the samples (optional extra [peers])"),
    "drake": ("exo_bench.models.drake_backend", "DrakeID",
              "Drake MultibodyPlant.CalcInverseDynamics minus CalcGravityGeneralizedForces, tau = G^T tau_joint; "
              "a Python loop over the samples (optional extra [peers])"),
}


def _derivatives(mechanism: Mechanism, method: str):
    from exo_bench.matrix_method.derivatives import derivatives_of  # noqa: PLC0415 - CasADi only when asked

    return derivatives_of(mechanism, method)


prepared.derivative_provider = _derivatives   # every prepared model's .derivatives (models.prepared)


#: Methods whose results are known to be wrong (kept to expose the paper's misprints).
KNOWN_WRONG = {"matrix-paper": "eq. (18) as printed has misprints: 3D results are wrong by design (reports/errata.md)"}


def method_names() -> list[str]:
    return list(METHODS)


def method_class(name: str) -> type[PreparedModel]:
    """The prepared-model class of a method; a clear ValueError for an unknown name."""
    if name not in METHODS:
        raise ValueError(f"method: expected one of {', '.join(METHODS)}, got {name!r}")
    module, cls, _ = METHODS[name]
    return getattr(importlib.import_module(module), cls)


def prepare(mechanism: Mechanism, method: str = "matrix-factored", **options: Any) -> PreparedModel:
    """Prepare ``mechanism`` for ``method`` once; call the result's ``inverse_dynamics``,
    ``mass_matrix`` and ``bias_forces`` as often as needed.

    ``options`` are the method's constructor arguments (``threads`` for pinocchio, ``budget`` and
    ``interrupt`` for lagrange, ``block`` and ``kernel`` for the matrix family); an unknown option is a ValueError.
    A lagrange derivation whose estimated time exceeds its ``budget`` (or whose memory exceeds what
    a run may use) is refused before it starts (:func:`bench.resources.check`, a ValueError naming
    the estimate and the budget).
    """
    cls = method_class(method)
    if method == "lagrange":   # refuse up front a derivation estimated over its budget or the memory
        from exo_bench.bench.resources import check  # noqa: PLC0415

        check(mechanism, method, 1, options)
    try:
        model = cls(mechanism, **options)
    except TypeError as e:
        if "unexpected keyword argument" in str(e):
            import inspect

            known = [p for p in inspect.signature(cls.__init__).parameters if p not in ("self", "mechanism")]
            raise ValueError(f"{method}: unknown option(s) {sorted(options)}: expected among {known or 'none'}") from None
        raise
    from exo_bench.bench.resources import chunk_samples  # noqa: PLC0415 - the calibrated chunk of this method

    model.chunk_samples = chunk_samples(mechanism, method)
    return model


class PreparedSet:
    """The prepared models of one run: ``models(mechanism, method)`` prepares on first use, with
    the run's options for that method (``{"lagrange": {"budget": 10.0}}``), and returns the same
    model afterwards. A study creates one per run and passes it down, so nothing is cached
    behind the caller's back and a failure to prepare (over budget) is raised where it is used."""

    def __init__(self, options: dict[str, dict] | None = None):
        self.options = {k: dict(v) for k, v in (options or {}).items()}
        self._models: dict[tuple, PreparedModel] = {}

    def __call__(self, mechanism: Mechanism, method: str) -> PreparedModel:
        key = (mechanism, method)
        if key not in self._models:
            self._models[key] = prepare(mechanism, method, **self.options.get(method, {}))
        return self._models[key]

    def clear(self) -> None:
        self._models.clear()
