"""Forward-dynamics study, the cases: round-trip motions, conservative spring-rod cases and stiff
variants, the tolerance rules, and the run's prepared models.
"""

from __future__ import annotations

from dataclasses import dataclass
from collections.abc import Callable
import math

import numpy as np

from exo_bench.api import PreparedSet
from exo_bench.models.simulation import forward_dynamics as fd
from exo_bench.models.mechanism.aggregates import coupling
from exo_bench.models.mechanism.kinematics import total_energy
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.gait.motion import Motion
from exo_bench.models.gait.motion import planar_gait
from exo_bench.models.gait.motion import smooth_random_motion
from exo_bench.models.mechanism.presets import chain
from exo_bench.models.mechanism.presets import exo5
from exo_bench.models.mechanism.presets import random_tree


EPS = np.finfo(float).eps


#: atol = ATOL_FACTOR * rtol: a state component of 1e-2 (rad, m, rad/s, m/s) counts as small.
ATOL_FACTOR = 1e-2


#: The second run of a round trip uses rtol / TIGHTER to estimate the first run's global error.
TIGHTER = 100.0


ROUND_TRIP_RULE = (
    "max_t |q(t) - q*(t)| <= 2 E + F, where E = max_t |q_rtol(t) - q_rtol/100(t)| is the integrator's own "
    "global error, estimated from a second run at a 100x tighter tolerance that never looks at q*, and "
    "F = N_steps * G(H) * eps * max|y| is the round-off floor (every step may add a few eps * |y|, and a "
    "perturbation grows by at most G(H) = max_t ||Phi_q(t)||_inf over the horizon H). Why 2 E: if the "
    "tighter run's deviation is at most half the first run's (any convergent method whose error follows the "
    "tolerance, here 100x tighter), then err <= E + err/2. If the controls did not reproduce the motion, "
    "q* would not solve the ODE and the deviation would not shrink with the tolerance: the rule fails."
)


# ----------------------------------------------------------------------------- helpers
def _models(models: PreparedSet | None) -> PreparedSet:
    """The run's prepared models, or this process's default set (default options)."""
    return _DEFAULT_MODELS if models is None else models


_DEFAULT_MODELS = PreparedSet()


def _state0(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    return motion.q[:1], motion.qd[:1]


# ----------------------------------------------------------------------------- round trip
@dataclass(frozen=True, eq=False)
class RoundTripCase:
    name: str
    mechanism: Mechanism
    motion_of_t: Callable[[np.ndarray], Motion]
    horizon: float
    description: str


def round_trip_cases(full: bool = False) -> list[RoundTripCase]:
    """The prescribed motions of the round trip.

    * the planar gait (eq. 26 in the sagittal plane) of the five-link exoskeleton over 0.3 s: the
      stance leg and trunk stand upright, an inverted multi-link pendulum, so open-loop
      perturbations grow about 10x per 0.05 s; 0.3 s keeps the growth G near 1e4;
    * smooth random motions of seeded random trees (2D and 3D) over 1 s.
    """
    e2 = exo5(2)
    t2, t3 = random_tree(4, 2, 5), random_tree(4, 3, 5)
    cases = [
        RoundTripCase(
            "exo5-2d planar gait",
            e2,
            lambda t: planar_gait(e2, t),
            0.3,
            "eq. (26) in the sagittal plane, T = 1.1 s, first 0.3 s",
        ),
        RoundTripCase(
            "tree4-2d random motion",
            t2,
            lambda t: smooth_random_motion(t2, t, 3),
            1.0,
            "smooth random motion (seed 3) of random_tree(4, 2, 5), 1 s",
        ),
        RoundTripCase(
            "tree4-3d random motion",
            t3,
            lambda t: smooth_random_motion(t3, t, 3),
            1.0,
            "smooth random motion (seed 3) of random_tree(4, 3, 5), 1 s",
        ),
    ]
    if full:
        t5 = random_tree(6, 3, 11)
        cases.append(
            RoundTripCase(
                "tree6-3d random motion",
                t5,
                lambda t: smooth_random_motion(t5, t, 4),
                1.0,
                "smooth random motion (seed 4) of random_tree(6, 3, 11), 1 s",
            )
        )
    return cases


# ----------------------------------------------------------------------------- conservative case
@dataclass(frozen=True, eq=False)
class SpringCase:
    name: str
    mechanism: Mechanism
    q0: np.ndarray
    qd0: np.ndarray
    k: float
    c: np.ndarray | float
    l_rest: np.ndarray
    horizon: float
    description: str

    @property
    def controls(self) -> fd.Controls:
        return fd.rod_spring_damper(self.mechanism, self.k, self.c, self.l_rest)

    def energy(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """``T + Pi + V_spring`` per sample."""
        return total_energy(self.mechanism, q, qd) + fd.spring_energy(self.mechanism, q, self.k, self.l_rest)


def conservative_cases() -> list[SpringCase]:
    """Passive mechanisms (no actuators) with springs in the rods, no damping.

    Without a restoring force the telescopes of a free mechanism collapse (``l -> 0``, where M is
    singular) or extend without bound, so the rods carry springs ``F = -k (l - l*)`` at a moderate
    ``k`` (rod modes of 10-60 rad/s, not stiff); their energy ``k/2 (l - l*)^2`` joins ``T + Pi``.
    """
    e2 = exo5(2)
    g = planar_gait(e2, np.array([0.0]))
    t3 = random_tree(4, 3, 5)
    rng = np.random.default_rng(7)
    n = t3.nlinks
    q3 = np.concatenate([rng.uniform(-math.pi, math.pi, n), rng.uniform(-0.8, 0.8, n), rng.uniform(0.4, 1.0, n)])
    qd3 = rng.uniform(-1.0, 1.0, 3 * n) * np.r_[np.ones(2 * n), 0.1 * np.ones(n)]
    return [
        SpringCase(
            "exo5-2d passive fall",
            e2,
            g.q[0],
            g.qd[0],
            2e3,
            0.0,
            g.q[0, -5:],
            0.5,
            "the five-link exoskeleton released from the gait's initial state, rods on springs "
            "k = 2e3 N/m at their initial length, 0.5 s",
        ),
        SpringCase(
            "tree4-3d passive swing",
            t3,
            q3,
            qd3,
            2e3,
            0.0,
            q3[-n:],
            1.0,
            "random_tree(4, 3, 5) from a seeded random state, rods on springs k = 2e3 N/m, 1 s",
        ),
    ]


# ----------------------------------------------------------------------------- stiff variants
def hanging_chain(mass_scale: float = 1.0) -> tuple[Mechanism, np.ndarray]:
    """A planar three-link chain hanging from the support point, released from rest at
    angles -pi/2 + (0.5, 0.3, -0.4); ``mass_scale`` multiplies the masses of the last link."""
    base = chain(3, 2)
    masses = list(base.masses)
    m0, m1, m2 = masses[-1]
    masses[-1] = (mass_scale * m0, mass_scale * m1, mass_scale * m2)
    name = "chain3-2d hanging" + ("" if mass_scale == 1 else f", last link masses x{mass_scale:g}")
    mech = base.replace(masses=tuple(masses), name=name)
    q0 = np.array([-math.pi / 2 + 0.5, -math.pi / 2 + 0.3, -math.pi / 2 - 0.4, 0.43, 0.43, 0.43])
    return mech, q0


def stiff_case(k: float, mass_scale: float = 1.0, horizon: float = 1.0) -> SpringCase:
    """Critically damped stiff rods: ``c_i = 2 sqrt(k mu_ii)`` with ``mu_ii`` the mass that moves
    along rod i (the diagonal of M for ``l_i``), so each rod mode decays at ``sqrt(k / mu_ii)``
    without ringing: a stiff, not an oscillatory, problem."""
    mech, q0 = hanging_chain(mass_scale)
    mu = np.diag(coupling(mech))
    c = 2.0 * np.sqrt(k * mu)
    return SpringCase(
        f"{mech.name}, k = {k:.0e}",
        mech,
        q0,
        np.zeros_like(q0),
        k,
        c,
        q0[-3:],
        horizon,
        f"{mech.name}: rods on critically damped springs k = {k:.0e} N/m, "
        f"fastest rod mode {math.sqrt(k / mu.min()):.2e} rad/s",
    )
