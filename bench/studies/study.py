"""Running several inverse-dynamics methods along one motion, and comparing them with the 50-digit
reference (:func:`reference`).

A :class:`Study` is the plain result that scenes, plots, recordings and reports share: the
mechanism, the motion, and per method either its tau or the reason it was skipped or failed.
"""

from __future__ import annotations

import time
import traceback
from dataclasses import dataclass, field

import numpy as np

from exo_bench.api import prepare
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import force_names
from exo_bench.models.gait.motion import Motion
from exo_bench.models.runtime.prepared import MissingExtra


@dataclass
class MethodResult:
    method: str
    tau: np.ndarray | None = None  # (S, dof) generalised forces, paper's coordinates
    seconds_per_sample: float | None = None
    setup_seconds: float | None = None  # one-time cost: building models, deriving, compiling
    skipped: str | None = None  # why the method was not run (over budget, ...)
    missing_extra: bool = False  # skipped because its engine is not installed here (MissingExtra)
    error: str | None = None  # one line: why it failed

    @property
    def ok(self) -> bool:
        return self.tau is not None


@dataclass
class Study:
    name: str
    mechanism: Mechanism
    motion: Motion
    motion_label: str
    results: dict[str, MethodResult] = field(default_factory=dict)
    reference: str = "pinocchio"
    reference_label: str = ""  # which 50-digit reference the errors were measured against

    @property
    def force_names(self) -> list[str]:
        return force_names(self.mechanism)

    def ok_methods(self) -> list[str]:
        return [m for m, r in self.results.items() if r.ok]

    def tau(self, method: str) -> np.ndarray:
        """The method's tau, ``(S, dof)``; a method that was skipped or failed has none (ValueError)."""
        tau = self.results[method].tau
        if tau is None:
            raise ValueError(f"study {self.name!r}: method {method!r} has no tau (skipped or failed)")
        return tau

    def difference(self, method: str) -> np.ndarray:
        """``tau_method - tau_reference``, ``(S, dof)``."""
        return self.tau(method) - self.tau(self.reference)

    def agreement(self) -> dict[str, float]:
        """Largest ``|tau_method - tau_reference|`` relative to the largest ``|tau_reference|``, over the
        finite entries (NaN/Inf are counted by :meth:`nonfinite`, never folded into a number)."""
        ref = self.results.get(self.reference)
        if ref is None or not ref.ok:
            return {}
        scale = max(float(np.nanmax(np.abs(self.tau(self.reference)))), 1e-300)
        return {m: finite_max(np.abs(self.difference(m))) / scale for m in self.ok_methods()}

    def nonfinite(self, method: str) -> int:
        """How many entries of the method's tau are NaN or infinite."""
        return int(np.count_nonzero(~np.isfinite(self.tau(method))))


def one_line(e: BaseException) -> str:
    """An exception as one line, ``Type: message``, for reports and summaries."""
    return traceback.format_exception_only(type(e), e)[-1].strip()


def finite_max(a: np.ndarray) -> float:
    """The largest finite entry (NaN when there is none)."""
    a = np.asarray(a)[np.isfinite(a)]
    return float(a.max()) if a.size else float("nan")


class StabilityWarning(RuntimeWarning):
    """Base class of the stability suite's warnings."""


class UnusableMethodWarning(StabilityWarning):
    """A method returned NaN/Inf or lost more than the stated relative accuracy on a family, or its
    forward dynamics does not reproduce a motion."""


def run_methods(
    name: str,
    mech: Mechanism,
    motion: Motion,
    motion_label: str,
    methods: list[str],
    reference: str = "pinocchio",
    options: dict[str, dict] | None = None,
    limits=None,
    f_ext: np.ndarray | None = None,
) -> Study:
    """Run each method along the motion; a method that raises is recorded with its error and
    does not stop the others. ``options``: method -> its :func:`prepare` options. A method whose
    estimated memory or time exceeds ``limits`` (:class:`exo_bench.api.cost_model.Limits`; default: a share
    of the available memory) is recorded as skipped with the estimate, before it runs. ``f_ext``: forces
    at the point masses along the motion, ``(samples, links, 3, dim)``, given to every method
    (bench/studies/scene_motion.py)."""
    from exo_bench.api.cost_model import check

    study = Study(name, mech, motion, motion_label, reference=reference)
    S = motion.q.shape[0]
    options = options or {}
    for m in methods:
        try:
            check(mech, m, S, options.get(m, {}), limits)  # refuse before any work (ResourceLimit: a skip)
            t0 = time.perf_counter()
            model = prepare(mech, m, **options.get(m, {}))  # build / derive / compile once
            setup = time.perf_counter() - t0
            first = None if f_ext is None else f_ext[:1]
            model.inverse_dynamics(motion.q[:1], motion.qd[:1], motion.qdd[:1], f_ext=first)  # warm (first-call costs)
            t0 = time.perf_counter()
            tau = np.asarray(model.inverse_dynamics(motion.q, motion.qd, motion.qdd, f_ext=f_ext), dtype=float)
            dt = (time.perf_counter() - t0) / S
            study.results[m] = MethodResult(m, tau, dt, setup_seconds=setup)
        except Exception as e:  # noqa: BLE001 - one failing method must not lose the others
            skip = getattr(e, "skip_reason", None)
            if skip:
                study.results[m] = MethodResult(m, skipped=str(skip), missing_extra=isinstance(e, MissingExtra))
            else:
                study.results[m] = MethodResult(m, error=one_line(e))
    return study


# The 50-digit reference used wherever the suite reports an error.

DPS = 50
LAGRANGE_MAX_LINKS = {2: 6, 3: 5}  # beyond these, deriving costs more than a report should wait


def reference(mech: Mechanism, q, qd, qdd, budget: float = 30.0) -> tuple[np.ndarray, str]:
    """``(tau, label)``: 50-digit generalised forces rounded once to float64, and which reference."""
    if mech.nlinks <= LAGRANGE_MAX_LINKS[mech.dim]:
        try:
            from exo_bench.lagrange import high_precision as lref
            from exo_bench.lagrange import derive

            derive(mech, budget=budget)
            return lref.inverse_dynamics(mech, q, qd, qdd, dps=DPS), "Lagrange, mpmath 50 digits"
        except ImportError:
            pass
        except Exception as e:  # noqa: BLE001 - over budget: fall back, and say so in the label
            if not getattr(e, "skip_reason", None):
                raise
    from exo_bench.models.mechanism import virtual_work

    return virtual_work.inverse_dynamics(mech, q, qd, qdd, dps=DPS), "d'Alembert, mpmath 50 digits"
