"""The methods of the suite, one :class:`MethodSpec` each: every fact the suite knows about a method.

Each spec names a :class:`~exo_bench.models.runtime.prepared.PreparedModel` subclass (imported lazily, so
a scene that does not use a method never imports, or derives, it), a one-line text of what runs,
whether its results are known to be wrong and why, its cost formulas
(:mod:`exo_bench.api.cost_formulas`), its colour in every figure, the values of its ``kernel``
option, its place among the methods offered as "a method that fits", and whether its symbolic
composition stays within budget at every size of the sweep. Everything that needs one of these
facts reads it from :data:`METHODS` (tests/test_method_table.py checks that no other table is left).

:func:`~exo_bench.api.preparation.prepare` builds a method's prepared model.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass

from exo_bench.api import cost_formulas as cost
from exo_bench.api.cost_formulas import CostModel
from exo_bench.matrix_method.kernels import (
    MATRIX_FACTORED_KERNELS,
    MATRIX_KERNELS,
    PRINTED_EQ18_WRONG,
    RECURRENCE_KERNELS,
)
from exo_bench.models.runtime.prepared import Kernel, kernel_options
from exo_bench.models.newton_euler.kernels import NEWTON_EULER_KERNELS
from exo_bench.models.runtime.prepared import PreparedModel


@dataclass(frozen=True)
class MethodSpec:
    """What the suite knows about one method. The name says what runs."""

    name: str
    #: Module and class of its :class:`~exo_bench.models.runtime.prepared.PreparedModel` subclass.
    module: str
    cls: str
    #: One line: what runs, and its options.
    text: str
    #: Its colour in every figure (Dark2: none is a link colour, none is the grey or black that
    #: thresholds use).
    colour: str = ""
    #: The cost formulas of :mod:`exo_bench.api.cost_formulas` (None: its arrays only).
    cost: CostModel | None = None
    #: Its kernels (:mod:`exo_bench.models.runtime.prepared`), the tuple its prepared-model class lists; the
    #: option ``kernel`` chooses among them by their ``option`` (empty: no such option).
    kernels: tuple[Kernel, ...] = ()
    #: Why its results are known to be wrong (None: they are not), in one line: the prepared-model class's
    #: ``known_wrong`` (the same constant; listed here too so that a report needs no class imported).
    known_wrong: str | None = None
    #: The longer reason a report gives where it disagrees with the other methods.
    why_it_disagrees: str | None = None
    #: Its rank among the methods offered as "a method that fits" a limit, best first (None:
    #: never offered, e.g. a method known to be wrong).
    fit_rank: int | None = None
    #: Its symbolic composition stays far inside the budget at every n of the sweep (3D n = 50 in
    #: about a minute): a benchmark row that composes only such methods needs no chain.
    composes_within_budget: bool = False
    #: Its preparation derives the equations within a time budget: its option ``budget`` (``--budget``,
    #: ``Limits.budget``), estimated and refused before the derivation starts.
    derivation_budget: bool = False
    #: Its option ``threads``: a pool of engine data per thread, estimated and refused before any is made.
    threads_option: bool = False
    #: Its forward dynamics forms no mass matrix (O(n) per sample): one row of work per sample where
    #: the others evaluate ``dof + 2`` inverse-dynamics rows to form ``M`` and ``h``.
    own_forward_dynamics: bool = False
    #: Where its mass matrix and bias forces come from when a study shows them exposed (None: its own
    #: mass matrix and bias forces, or those derived from its inverse dynamics).
    exposed_terms: str | None = None
    #: Held to the goals for the five-link 3D model (the performance report's "Goals" section): its
    #: place among those methods, first listed first (None: not held to them).
    paper_goal_rank: int | None = None
    #: For an engine (a rigid-body library beside ours): what one of its benchmark rows times.
    engine_row: str | None = None
    #: For an engine: the name of its bare per-call benchmark row (its own calls, no G maps, no wrapper).
    bare_row: str | None = None
    #: The optional extra it needs (``pip install '.[peers]'``; empty: the default install has it). The
    #: main job measures such a method only with ``--full`` (into ``reports/full/``): the default run's
    #: reports are the same on every machine (bench/cli/run.py).
    extra: str = ""

    @property
    def kernel_options(self) -> tuple[str, ...]:
        """The values of its option ``kernel``, the default first (empty: no such option)."""
        return kernel_options(self.kernels)

    def kernels_for(self, option: object = None) -> tuple[Kernel, ...]:
        """The kernels the option ``kernel`` runs (None: the default); empty for a value it does not
        take (its constructor names it)."""
        options = self.kernel_options
        chosen = options[0] if option is None and options else option
        return tuple(k for k in self.kernels if k.option == chosen)

    @property
    def compiled(self) -> bool:
        """Its default kernels are compiled (by numba) on first use."""
        return any(k.compiled for k in self.kernels_for())

    def load(self) -> type[PreparedModel]:
        """The prepared-model class (imports its module). A method with compiled kernels first checks
        numba's environment variables, before numba is imported (a ValueError naming the variable:
        :func:`exo_bench.models.machine.numba_runtime.environment_problem`), in numba's runtime set-up."""
        if any(k.compiled for k in self.kernels):
            importlib.import_module("exo_bench.models.machine.numba_runtime").ensure()
        return getattr(importlib.import_module(self.module), self.cls)


#: Every method, by name, in the order reports list them.
METHODS: dict[str, MethodSpec] = {
    s.name: s
    for s in (
        MethodSpec(
            "pinocchio",
            "exo_bench.models.engines.pinocchio_backend",
            "PinocchioRNEA",
            "Pinocchio RNEA on the generated URDF, tau = G^T tau_joint (option: threads)",
            colour="#1b9e77",
            cost=cost.PINOCCHIO,
            fit_rank=3,
            threads_option=True,
            exposed_terms="CRBA, nonLinearEffects",
            engine_row="a Python loop over `pin.rnea` per sample (the G maps one matmul over the batch; "
            "`pinocchio-parallel`: `rneaInParallel` on a ModelPool)",
            bare_row="pin.rnea (bare)",
        ),
        MethodSpec(
            "lagrange",
            "exo_bench.lagrange.prepared",
            "LagrangeModel",
            "Lagrange II derived with sympy from the point masses' T and Pi, lambdified to numpy with cse "
            "(options: budget, interrupt)",
            colour="#e6ab02",
            cost=cost.LAGRANGE,
            fit_rank=5,
            derivation_budget=True,
        ),
        MethodSpec(
            "matrix",
            "exo_bench.matrix_method.prepared",
            "MatrixProducts",
            "the matrix method: every matrix of eqs. (5)/(17) from the closed forms (corrected eq. (18), "
            "no division), then the products with the rates; compiled loops (option kernel: numba, the "
            "default, or numpy)",
            colour="#d95f02",
            cost=cost.MATRIX,
            kernels=MATRIX_KERNELS,
            fit_rank=2,
            paper_goal_rank=1,
            composes_within_budget=True,
        ),
        MethodSpec(
            "matrix-factored",
            "exo_bench.matrix_method.prepared",
            "MatrixFactored",
            "the matrix method's equations in factored form (no matrix formed); compiled loops "
            "(option kernel: numba, the default, or numpy)",
            colour="#7570b3",
            cost=cost.MATRIX_FACTORED,
            kernels=MATRIX_FACTORED_KERNELS,
            fit_rank=0,
            paper_goal_rank=0,
        ),
        MethodSpec(
            "matrix-paper",
            "exo_bench.matrix_method.prepared",
            "MatrixPaper",
            "the matrix method with eq. (18) exactly as printed: WRONG in 3D by design (misprints, 0/0)",
            colour="#e7298a",
            cost=cost.MATRIX_PAPER,
            known_wrong=PRINTED_EQ18_WRONG,
            why_it_disagrees="it evaluates eq. (18) exactly as printed, misprints included: see "
            "reports/errata.md (3D g^l and k^l) and reports/stability.md",
        ),
        MethodSpec(
            "recurrence",
            "exo_bench.matrix_method.prepared",
            "Recurrence",
            "the recurrence of eqs. (22)-(26) for trees, then the products of eq. (5)/(17); compiled "
            "loops (option kernel: numba, the default, or numpy)",
            colour="#66a61e",
            cost=cost.RECURRENCE,
            kernels=RECURRENCE_KERNELS,
            fit_rank=4,
            composes_within_budget=True,
        ),
        MethodSpec(
            "newton-euler",
            "exo_bench.models.newton_euler.prepared",
            "NewtonEuler",
            "O(n) passes over the tree in the rod vectors r_i = s_i l_i u_i (M = J^T M_r J, M_r constant), "
            "forward dynamics by M_r factored once; compiled loops (option kernel: numba, the default, or numpy)",
            colour="#b15928",
            cost=cost.NEWTON_EULER,
            kernels=NEWTON_EULER_KERNELS,
            fit_rank=1,
            own_forward_dynamics=True,
        ),
        MethodSpec(
            "mujoco",
            "exo_bench.models.engines.mujoco_backend",
            "MujocoRNE",
            "MuJoCo's RNE (mj_kinematics, mj_comPos, mj_comVel, mj_rne) on the exported MJCF, tau = G^T tau_joint; "
            "a Python loop over the samples (optional extra [peers])",
            colour="#a6761d",
            cost=cost.MUJOCO,
            engine_row="a Python loop over MuJoCo's `mj_kinematics`, `mj_comPos`, `mj_comVel` and `mj_rne` per "
            "sample (four calls through the bindings each), on the exported MJCF with every constraint "
            "off; the G maps one matmul over the batch",
            bare_row="mj_rne (bare)",
            extra="peers",
        ),
        MethodSpec(
            "drake",
            "exo_bench.models.engines.drake_backend",
            "DrakeID",
            "Drake MultibodyPlant.CalcInverseDynamics minus CalcGravityGeneralizedForces, tau = G^T tau_joint; "
            "a Python loop over the samples (optional extra [peers])",
            colour="#1f78b4",
            cost=cost.DRAKE,
            engine_row="a Python loop over Drake's `SetPositions`, `SetVelocities`, `CalcInverseDynamics` and "
            "`CalcGravityGeneralizedForces` per sample (four calls through pybind11, each checking and "
            "invalidating the context's cache), on a plant built in code; the G maps one matmul over "
            "the batch",
            bare_row="CalcInverseDynamics (bare)",
            extra="peers",
        ),
    )
}


def method_names() -> list[str]:
    """The names of every method, in the order reports list them."""
    return list(METHODS)


def spec(name: str) -> MethodSpec:
    """The spec of a method; a clear ValueError for an unknown name."""
    if name not in METHODS:
        raise ValueError(f"method: expected one of {', '.join(METHODS)}, got {name!r}")
    return METHODS[name]


def method_class(name: str) -> type[PreparedModel]:
    """The prepared-model class of a method; a clear ValueError for an unknown name."""
    return spec(name).load()


def preference() -> tuple[str, ...]:
    """The methods offered as "a method that fits", best first (correct ones only)."""
    ranked = sorted((s.fit_rank, s.name) for s in METHODS.values() if s.fit_rank is not None)
    return tuple(name for _, name in ranked)


def known_wrong() -> dict[str, str]:
    """Methods whose results are known to be wrong, with the reason."""
    return {s.name: s.known_wrong for s in METHODS.values() if s.known_wrong}


def compiled_methods() -> tuple[str, ...]:
    """Methods whose default kernels are compiled (the matrix family, newton-euler), best first."""
    ranked = sorted(
        (s.fit_rank if s.fit_rank is not None else len(METHODS), i, s.name)
        for i, s in enumerate(METHODS.values())
        if s.compiled
    )
    return tuple(name for _, _, name in ranked)


def matrix_family() -> tuple[str, ...]:
    """The matrix method's compiled methods (the paper's method, its factored form and the
    recurrence; not matrix-paper), best first: the family the scaling report holds to its goals."""
    return tuple(m for m in compiled_methods() if METHODS[m].module == "exo_bench.matrix_method.prepared")


def composes_within_budget() -> frozenset[str]:
    """Methods whose symbolic composition stays within budget at every n of the sweep."""
    return frozenset(s.name for s in METHODS.values() if s.composes_within_budget)


def method_colour(method: str) -> str | None:
    """The colour of ``method`` in every figure (None: a method not in the table)."""
    s = METHODS.get(method)
    return s.colour if s is not None and s.colour else None


def known_wrong_warning(method: str, dim: int) -> str | None:
    """The one-line warning every result of a method known to be wrong carries (None: not wrong)."""
    s = METHODS.get(method)
    if s is None or not s.known_wrong:
        return None
    if dim == 3:
        return f"exo-bench: warning: method {method!r}: {s.known_wrong}"
    return (
        f"exo-bench: warning: method {method!r} is eq. (18) exactly as printed, kept to expose the paper's "
        "misprints: wrong in 3D by design; this 2D result is the closed forms (reports/errata.md)"
    )


def derives_within_budget(method: str) -> bool:
    """Whether ``method`` derives its equations within a time budget (its option ``budget``)."""
    s = METHODS.get(method)
    return s is not None and s.derivation_budget


def budgeted_methods() -> tuple[str, ...]:
    """The methods that derive their equations within a time budget (``--budget``)."""
    return tuple(s.name for s in METHODS.values() if s.derivation_budget)


def paper_goal_methods() -> tuple[str, ...]:
    """The methods held to the goals for the five-link 3D model, in the order the report lists them."""
    ranked = sorted((s.paper_goal_rank, s.name) for s in METHODS.values() if s.paper_goal_rank is not None)
    return tuple(name for _, name in ranked)
