"""Forward-dynamics study, conservative and stiff systems: the energy drift of each integrator against its
bound, and the stiff rods (work against precision within an evaluation budget).
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from exo_bench.api import PreparedSet
from exo_bench.bench.studies.stability.forward_cases import ATOL_FACTOR, SpringCase, _models
from exo_bench.models.simulation import forward_dynamics as fd
from exo_bench.models.mechanism.aggregates import coupling
from exo_bench.models.mechanism.kinematics import kinetic_energy


def energy_gradient(case: SpringCase, y: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """``dE/dy (N, m)`` by central differences (one batched energy call)."""
    N, m = y.shape
    d = m // 2
    steps = h * np.maximum(1.0, np.abs(y))  # (N, m)
    Y = np.repeat(y[:, None, :], 2 * m, axis=1)  # (N, 2m, m)
    idx = np.arange(m)
    Y[:, idx, idx] += steps
    Y[:, m + idx, idx] -= steps
    E = case.energy(Y[..., :d].reshape(-1, d), Y[..., d:].reshape(-1, d)).reshape(N, 2 * m)
    return (E[:, :m] - E[:, m:]) / (2 * steps)


def energy_bound(case: SpringCase, sim: fd.Simulation) -> float:
    """First-order bound on ``|E(t) - E(0)|`` from the tolerance.

    It is ``sum_k |dE/dy(y_k)| . sqrt(m) (atol + rtol max(|y_k-1|, |y_k|))``. The exact flow conserves E, so ``E(y_k) - E(y_k-1) = E(y_k)
    - E(flow(y_k-1)) ~ dE/dy . l_k`` with ``l_k`` the local error: the sum telescopes, and nothing
    amplifies it."""
    if sim.steps == 0:
        return 0.0
    m = sim.y.shape[1]
    grad = np.abs(energy_gradient(case, sim.y[1:]))
    sc = sim.atol + sim.rtol * np.maximum(np.abs(sim.y[:-1]), np.abs(sim.y[1:]))
    return float((grad * sc).sum() * math.sqrt(m))


def _simulate_spring(
    case: SpringCase, integrator: str, rtol: float, method: str, models: PreparedSet | None, **budget
) -> fd.Simulation:  # budget: max_evaluations, max_seconds (and jacobian)
    """A spring case integrated from its initial state over its horizon with ``method``'s ``M`` and
    ``h`` (atol = ``ATOL_FACTOR`` rtol); ``budget``: ``max_evaluations``, ``max_seconds``."""
    return fd.simulate(
        _models(models)(case.mechanism, method),
        case.q0,
        case.qd0,
        (0.0, case.horizon),
        case.controls,
        integrator,
        rtol,
        ATOL_FACTOR * rtol,
        **budget,
    )


@dataclass
class EnergyRun:
    case: str
    integrator: str
    rtol: float
    sim: fd.Simulation
    drift: float = math.nan  # max_k |E(t_k) - E(0)|, J
    scale: float = math.nan  # max kinetic energy reached, J
    bound: float = math.nan

    @property
    def passed(self) -> bool:
        return self.sim.ok and self.drift <= self.bound


def energy_drift(
    case: SpringCase,
    integrator: str,
    rtol: float,
    method: str = "pinocchio",
    max_seconds: float | None = None,
    models: PreparedSet | None = None,
) -> EnergyRun:
    mech = case.mechanism
    d = mech.dof
    sim = _simulate_spring(case, integrator, rtol, method, models, max_seconds=max_seconds)
    run = EnergyRun(case.name, integrator, rtol, sim)
    if sim.steps:
        E = case.energy(sim.q(d), sim.qd(d))
        run.drift = float(np.abs(E - E[0]).max())
        run.scale = float(kinetic_energy(mech, sim.q(d), sim.qd(d)).max())
        run.bound = energy_bound(case, sim)
    return run


@dataclass
class StiffRun:
    case: str
    integrator: str
    rtol: float
    sim: fd.Simulation
    stiffness: float  # fastest rod rate sqrt(k / mu_ii), 1/s
    cond: float = math.nan  # cond(M) at the initial state
    error: float = math.nan  # |q(H) - q_ref(H)|, against a tight Radau run
    energy_change: float = math.nan  # max_k E(t_k) - E(0), J: the dampers only dissipate, so <= 0 up to rounding

    @property
    def solved(self) -> bool:
        return self.sim.ok


def stiff_run(
    case: SpringCase,
    integrator: str,
    rtol: float,
    max_evaluations: int,
    reference=None,
    method: str = "pinocchio",
    max_seconds: float | None = None,
    models: PreparedSet | None = None,
    jacobian: str = "finite-difference",
) -> StiffRun:
    mech = case.mechanism
    sim = _simulate_spring(
        case,
        integrator,
        rtol,
        method,
        models,
        max_evaluations=max_evaluations,
        max_seconds=max_seconds,
        jacobian=jacobian,
    )
    mu = np.diag(coupling(mech))
    cond = float(fd.condition_numbers(_models(models)(mech, "pinocchio").mass_matrix(case.q0[None]))[0][0])
    run = StiffRun(case.name, integrator, rtol, sim, float(math.sqrt(case.k / mu.min())), cond)
    d = mech.dof
    if sim.ok and reference is not None and reference.ok:
        run.error = float(np.abs(sim.y[-1, :d] - reference.y[-1, :d]).max())
    if sim.ok:
        E = case.energy(sim.q(d), sim.qd(d))
        run.energy_change = float((E - E[0]).max())
    return run
