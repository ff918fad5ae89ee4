"""exo-bench: equations of motion of telescopic-rod skeletons (Borisov & Chigarev), computed,
cross-validated and benchmarked.

The library in one line::

    from exo_bench import prepare, presets
    model = prepare(presets.exo5(dim=3), "matrix-factored")
    tau = model.inverse_dynamics(q, qd, qdd)

**The public API is the names in** :data:`__all__`, importable from here (``from exo_bench import
simulate``) and listed with what each is in docs/guide/public-api.md. Everything else (the modules
under ``exo_bench.models``, ``.lagrange``, ``.matrix_method``, ``.api`` and ``.bench``) is internal: it
may move or change without notice.

The names load lazily (:func:`__getattr__`): ``import exo_bench`` imports no numpy, sympy, casadi or
pinocchio, and a user who never prepares a Lagrange model never imports sympy. :data:`_LAZY` is the one
table of where each name lives; the ``TYPE_CHECKING`` imports below repeat it for type checkers and IDEs
(tests/test_public_api.py checks that the three lists agree).

Subpackages, in layers that only import downwards: :mod:`exo_bench.models` (mechanism data,
kinematics, URDF, Pinocchio, forward dynamics) <- :mod:`exo_bench.lagrange` and
:mod:`exo_bench.matrix_method` (independent of each other) <- :mod:`exo_bench.api` (:func:`prepare`,
one :class:`~exo_bench.api.methods.MethodSpec` per method, the cost model) <- :mod:`exo_bench.bench`
(studies, benchmarks, reports and the command line).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # what IDEs and type checkers see; at run time the names load lazily (__getattr__)
    from exo_bench.api.cost_model import ResourceLimit
    from exo_bench.api.methods import MethodSpec, method_names
    from exo_bench.api.preparation import prepare
    from exo_bench.bench.cli.equations import render as render_equations
    from exo_bench.bench.cli.equations import write_equations
    from exo_bench.bench.studies.step.data import load as load_step
    from exo_bench.bench.studies.step.data import violations as step_violations
    from exo_bench.lagrange.budget import BudgetExceeded
    from exo_bench.matrix_method.export.casadi_functions import casadi_functions
    from exo_bench.models.mechanism import presets
    from exo_bench.models.runtime.external_forces import forces_at
    from exo_bench.models.simulation.forward_dynamics import prescribed_controls, rod_spring_damper
    from exo_bench.models.mechanism.kinematics import net_joint_loads, sagittal_moments
    from exo_bench.models.mechanism.presets import load_mechanism, save_mechanism
    from exo_bench.models.mechanism.mechanism import Mechanism
    from exo_bench.models.machine.memory import CallTooLarge
    from exo_bench.models.engines.mjcf import MjcfTooDeep, to_mjcf
    from exo_bench.models.gait.motion import GaitParams, Motion, gait, planar_gait, random_states, smooth_random_motion
    from exo_bench.models.engines.pinocchio_backend import PinocchioDataTooLarge, joint_torques
    from exo_bench.models.engines.pinocchio_backend import build_model as pinocchio_model
    from exo_bench.models.runtime.prepared import MissingExtra, PreparedModel
    from exo_bench.models.simulation.forward_dynamics import Simulation, simulate
    from exo_bench.models.mechanism.singularity import SingularConfigurationError
    from exo_bench.models.engines.urdf import to_urdf

__version__ = "0.2.0"

__all__ = [
    "__version__",  # the package's version (also in pyproject.toml)
    # preparing a model
    "prepare",  # prepare(mechanism, method) -> a PreparedModel: inverse/forward dynamics, M, h, derivatives
    "PreparedModel",  # the class of what prepare returns (for type hints)
    "method_names",  # the methods prepare accepts, in the order of the reports
    "MethodSpec",  # the facts of one method (cost model, what it supports)
    # mechanisms
    "Mechanism",  # a skeleton of telescopic rods: links, masses, fractions, g
    "presets",  # the paper's models and the human models: presets.exo5(dim=3), presets.PRESETS...
    "load_mechanism",  # a preset's name or a mechanism JSON file -> Mechanism
    "save_mechanism",  # Mechanism -> a JSON file that load_mechanism reads back
    # states and motions, batch-first (samples, dof)
    "random_states",  # seeded random (q, qd, qdd) of any mechanism
    "smooth_random_motion",  # a seeded smooth Motion of any mechanism, with exact derivatives
    "gait",  # the paper's gait, eq. (26), of the five-link 3D exoskeleton, as a Motion
    "planar_gait",  # eq. (26) in the sagittal plane, for the 2D five-link models
    "Motion",  # t, q, qd, qdd of a motion
    "GaitParams",  # the parameters of eq. (26) (the defaults fitted to Winter's walk)
    "forces_at",  # external forces at the point masses (f_ext), built by link name and point
    # forward simulation
    "simulate",  # integrate M(q) qdd + h(q, qd) = controls(t, q, qd) under a budget of evaluations
    "Simulation",  # what simulate returns: the accepted steps, status and cost
    "prescribed_controls",  # controls: the inverse dynamics of a prescribed motion, on the fly
    "rod_spring_damper",  # controls: passive spring-dampers on every rod
    # loads
    "net_joint_loads",  # net joint moments and forces of gait analysis, from the point masses
    "sagittal_moments",  # net joint moments in the sagittal plane, with Winter's sign
    "joint_torques",  # Pinocchio's RNEA in its relative joint coordinates (G^-T tau)
    "pinocchio_model",  # the Pinocchio model built from the generated URDF, with its joint names
    # exports
    "to_urdf",  # the URDF text of a mechanism
    "to_mjcf",  # MuJoCo's MJCF text of a mechanism
    "render_equations",  # the equations as text: {file name: text} in latex, python, c or casadi
    "write_equations",  # the same written into a folder, atomically (exo-bench equations)
    "casadi_functions",  # the equations as casadi.Function objects (the extra [casadi])
    # the stored predicted walking step
    "load_step",  # the stored step of a mechanism (exo5-2d, exo5-3d), no solve
    "step_violations",  # every constraint of a stored step re-evaluated in numpy
    # errors a user catches
    "SingularConfigurationError",  # ValueError: forward dynamics at a singular mass matrix
    "MissingExtra",  # ValueError: a method's optional engine (MuJoCo, Drake) is not installed
    "ResourceLimit",  # ValueError: prepare's estimate exceeds the memory or time limit, refused before work
    "BudgetExceeded",  # ValueError: the Lagrange derivation did not finish within its time budget
    "CallTooLarge",  # MemoryError: a call's arrays would not fit in memory, refused before work
    "PinocchioDataTooLarge",  # MemoryError: a pin.Data would not fit in memory
    "MjcfTooDeep",  # ValueError: the MJCF nests deeper than MuJoCo's parser reads
]

#: name -> (module, attribute or None for the module itself), imported on first use. The one place that
#: says where a public name lives.
_LAZY: dict[str, tuple[str, str | None]] = {
    "prepare": ("exo_bench.api.preparation", "prepare"),
    "PreparedModel": ("exo_bench.models.runtime.prepared", "PreparedModel"),
    "method_names": ("exo_bench.api.methods", "method_names"),
    "MethodSpec": ("exo_bench.api.methods", "MethodSpec"),
    "Mechanism": ("exo_bench.models.mechanism.mechanism", "Mechanism"),
    "presets": ("exo_bench.models.mechanism.presets", None),
    "load_mechanism": ("exo_bench.models.mechanism.presets", "load_mechanism"),
    "save_mechanism": ("exo_bench.models.mechanism.presets", "save_mechanism"),
    "random_states": ("exo_bench.models.gait.motion", "random_states"),
    "smooth_random_motion": ("exo_bench.models.gait.motion", "smooth_random_motion"),
    "gait": ("exo_bench.models.gait.motion", "gait"),
    "planar_gait": ("exo_bench.models.gait.motion", "planar_gait"),
    "Motion": ("exo_bench.models.gait.motion", "Motion"),
    "GaitParams": ("exo_bench.models.gait.motion", "GaitParams"),
    "forces_at": ("exo_bench.models.runtime.external_forces", "forces_at"),
    "simulate": ("exo_bench.models.simulation.forward_dynamics", "simulate"),
    "Simulation": ("exo_bench.models.simulation.forward_dynamics", "Simulation"),
    "prescribed_controls": ("exo_bench.models.simulation.forward_dynamics", "prescribed_controls"),
    "rod_spring_damper": ("exo_bench.models.simulation.forward_dynamics", "rod_spring_damper"),
    "net_joint_loads": ("exo_bench.models.mechanism.kinematics", "net_joint_loads"),
    "sagittal_moments": ("exo_bench.models.mechanism.kinematics", "sagittal_moments"),
    "joint_torques": ("exo_bench.models.engines.pinocchio_backend", "joint_torques"),
    "pinocchio_model": ("exo_bench.models.engines.pinocchio_backend", "build_model"),
    "to_urdf": ("exo_bench.models.engines.urdf", "to_urdf"),
    "to_mjcf": ("exo_bench.models.engines.mjcf", "to_mjcf"),
    "render_equations": ("exo_bench.bench.cli.equations", "render"),
    "write_equations": ("exo_bench.bench.cli.equations", "write_equations"),
    "casadi_functions": ("exo_bench.matrix_method.export.casadi_functions", "casadi_functions"),
    "load_step": ("exo_bench.bench.studies.step.data", "load"),
    "step_violations": ("exo_bench.bench.studies.step.data", "violations"),
    "SingularConfigurationError": ("exo_bench.models.mechanism.singularity", "SingularConfigurationError"),
    "MissingExtra": ("exo_bench.models.runtime.prepared", "MissingExtra"),
    "ResourceLimit": ("exo_bench.api.cost_model", "ResourceLimit"),
    "BudgetExceeded": ("exo_bench.lagrange.budget", "BudgetExceeded"),
    "CallTooLarge": ("exo_bench.models.machine.memory", "CallTooLarge"),
    "PinocchioDataTooLarge": ("exo_bench.models.engines.pinocchio_backend", "PinocchioDataTooLarge"),
    "MjcfTooDeep": ("exo_bench.models.engines.mjcf", "MjcfTooDeep"),
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
