"""Prescribed motions with analytic first and second time derivatives.

* :func:`gait` is the paper's eq. (26) for the five-link exoskeleton.
* :func:`planar_gait` is its sagittal-plane version for the 2D scenes: the
  elevation formulas of eq. (26) become the planar angles (the azimuths vanish).
* :func:`smooth_random_motion` gives a seeded smooth motion for any mechanism.

All return a :class:`Motion` of batch-first arrays ``(samples, dof)`` in the
block order ``[phi..., psi..., l...]``. Arbitrary motions are simply arrays:
``Motion(t, q, qd, qdd)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import as_states


@dataclass(frozen=True)
class Motion:
    t: np.ndarray  # (S,)
    q: np.ndarray  # (S, dof)
    qd: np.ndarray  # (S, dof)
    qdd: np.ndarray  # (S, dof)


@dataclass(frozen=True)
class GaitParams:
    """Parameters of eq. (26), which the paper does not print. The defaults are the shipped gait,
    ``winter-fit-v1``: fitted to normative level walking by :mod:`exo_bench.models.gait.gait_fit` (rerun it with
    ``python -m exo_bench.models.gait.gait_fit``; ``tests/test_gait_fit.py`` re-checks the constraints).

    Values (radians, metres, seconds):

    * ``T = 0.987 s``: one stride of Winter's walk (121.6 steps/min at 1.41 m/s, Winter 2009,
      Appendix A; :mod:`exo_bench.models.gait.normative`). No other target depends on T, so it is not searched.
    * ``j``, ``f``: amplitudes and phases of links 1-4, fitted so that each link's sagittal angle over
      the first half period follows Winter's curve of the segment it plays: the stance shank and
      thigh over single support, the swing thigh and shank over the swing phase.
    * ``j_5 = 0.05``: not fitted; with ``psi_5 = pi/2`` the trunk's azimuth moves no point mass.
    * ``l_star``: rest lengths, fitted near Winter's anthropometric fractions of a 1.75 m stature
      (leg 0.246 H, thigh 0.245 H, hip to shoulder 0.288 H; ``l_5*`` enters no target).
    * ``l``: the rods' stretch amplitude, fitted near 0 (the rods stretch only if a target needs it).

    Targets: the segment-angle curves (residual scale 1 deg); every swing-leg point mass at least
    1 cm above the floor (constraint); every point mass within 10 cm of the sagittal plane (our
    assumption, a constraint); rest lengths near anthropometry (scale 5 mm). What the stored values
    achieve (the output of ``models.gait_fit.describe``; a test checks that it is still true):

    ::

        T = 0.987 s (121.6 steps/min; target 0.987 s, 121.6 steps/min at 1.41 m/s)
        link 1 (stance shank, single support): RMS 9.6 deg over the phase; range 73.1 to 96.7 deg, Winter 58.7 to 91.9 deg (residual +14.4, +4.8)
        link 2 (stance thigh, single support): RMS 3.5 deg over the phase; range 79.4 to 100.5 deg, Winter 73.1 to 106.9 deg (residual +6.3, -6.4)
        link 3 (swing thigh, swing): RMS 8.9 deg over the phase; range 84.2 to 110.9 deg, Winter 82.5 to 115.7 deg (residual +1.7, -4.8)
        link 4 (swing shank, swing): RMS 13.4 deg over the phase; range 60.3 to 115.8 deg, Winter 36.8 to 112.0 deg (residual +23.5, +3.8)
        lowest swing-leg point mass: 1.00 cm at t = 0.327 s (target >= 1 cm)
        largest |y| of any point mass: 10.00 cm (bound 10 cm)
        rest lengths (0.4301, 0.4285, 0.4264, 0.4239, 0.504) m (anthropometric (0.4305, 0.4287, 0.4287, 0.4305, 0.504)), stretch l = 0.0

    The fit's residual: SLSQP from 16 seeded starts (12 met both constraints) ends at an objective
    of 365 (``models.gait_fit.objective``: the sum of the squared scaled residuals, of which the
    four angle curves give 92, 12, 79 and 180, i.e. their RMS in degrees squared, and the rest
    lengths 2).

    Eq. (26)'s waveform cannot follow Winter's curves closer: it gives each azimuth the amplitude of
    its elevation, so a lopsided sagittal range swings the link sideways (the 10 cm bound binds),
    and a segment whose range is not centred on the vertical turns back within the half period.

    The parameters used before the fit are :data:`GAITS` ``["paper-assumed-v1"]`` (the swing foot
    reaches 1.7 cm below the floor).
    """

    T: float = 0.987
    j: tuple[float, ...] = (0.3082, 0.1875, 0.3663, 0.5624, 0.05)
    f: tuple[float, ...] = (0.3891, -0.1036, 1.269, 0.9269)
    l_star: tuple[float, ...] = (0.4301, 0.4285, 0.4264, 0.4239, 0.504)
    l: float = 0.0


#: The paper's assumptions before the fit (anthropometry, no data): T = 1.1 s; amplitudes
#: 0.3-0.4 rad; phases f1 = f4 = pi/2, f2 = f3 = 0 (each elevation swings monotonically between
#: pi/2 - j and pi/2 + j each half period); rest lengths of a 1.75 m person; rods stretch +-2 %.
PAPER_ASSUMED_V1 = GaitParams(
    T=1.1,
    j=(0.35, 0.30, 0.40, 0.35, 0.05),
    f=(math.pi / 2, 0.0, 0.0, math.pi / 2),
    l_star=(0.43, 0.43, 0.43, 0.43, 0.50),
    l=0.02,
)

#: Named gaits a scene can select (``[motion] gait = "paper-assumed-v1"``); the first is the default.
GAITS: dict[str, GaitParams] = {"winter-fit-v1": GaitParams(), "paper-assumed-v1": PAPER_ASSUMED_V1}
DEFAULT_GAIT = "winter-fit-v1"


def _sin_chain(a, a1, a2):
    """sin(a(t)) and its first two time derivatives."""
    s, c = np.sin(a), np.cos(a)
    return s, c * a1, -s * a1**2 + c * a2


def _cos_chain(a, a1, a2):
    """cos(a(t)) and its first two time derivatives."""
    s, c = np.sin(a), np.cos(a)
    return c, -s * a1, -c * a1**2 - s * a2


def _gait_angles(t: np.ndarray, p: GaitParams):
    """Elevations psi_1..psi_5 and azimuths phi_1..phi_5 of eq. (26), each with (x, x', x'')."""
    w = 2 * math.pi / p.T
    sw, cw = np.sin(w * t), np.cos(w * t)
    h = math.pi / 2
    zero = np.zeros_like(t)
    # a_minus = f - (1 - cos wt) pi/2 and a_plus = f - (1 + cos wt) pi/2, with derivatives
    am = lambda f: (f - (1 - cw) * h, -h * w * sw, -h * w * w * cw)
    ap = lambda f: (f - (1 + cw) * h, h * w * sw, h * w * w * cw)
    j, f = p.j, p.f
    psi = []
    for fn, a, ji in (
        (_sin_chain, am(f[0]), j[0]),
        (_cos_chain, am(f[1]), j[1]),
        (_cos_chain, ap(f[2]), j[2]),
        (_sin_chain, ap(f[3]), j[3]),
    ):
        x, x1, x2 = fn(*a)
        psi.append((h + ji * x, ji * x1, ji * x2))
    psi.append((zero + h, zero, zero))  # psi_5 = pi/2: the trunk stands vertical
    s_, c_ = (sw, w * cw, -w * w * sw), (cw, -w * sw, -w * w * cw)
    phi = [
        tuple(j[0] * x for x in s_),
        tuple(j[1] * x for x in c_),
        tuple(j[2] * x for x in c_),
        tuple(j[3] * x for x in s_),
        tuple(j[4] * x for x in c_),
    ]
    sgn = (1, 1, 1, -1, 1)  # l_4 = l_4* (1 - l sin wt), the others with +
    lens = [tuple(ls * (d + k * p.l * x) for d, x in zip((1.0, 0.0, 0.0), s_)) for ls, k in zip(p.l_star, sgn)]
    return phi, psi, lens


def _stack(blocks):
    """[[(x, x', x'') per coordinate] per block] -> q, qd, qdd of shape (S, dof)."""
    cols = [c for b in blocks for c in b]
    return tuple(np.stack([c[k] for c in cols], axis=-1) for k in range(3))


def _check_five(mech: Mechanism, dim: int, what: str) -> None:
    if mech.nlinks != 5 or mech.dim != dim:
        raise ValueError(
            f"{what}: mechanism {mech.name!r}: expected a {dim}D five-link model "
            f"(eq. 26 prescribes five links), got {mech.dim}D with {mech.nlinks} link(s)"
        )


def gait(mech: Mechanism, t: np.ndarray, params: GaitParams = GaitParams()) -> Motion:
    """Eq. (26): the spatial gait of the five-link exoskeleton, with analytic derivatives."""
    _check_five(mech, 3, "gait")
    t = np.asarray(t, dtype=float)
    phi, psi, lens = _gait_angles(t, params)
    q, qd, qdd = _stack([phi, psi, lens])
    return Motion(t, q, qd, qdd)


def planar_gait(mech: Mechanism, t: np.ndarray, params: GaitParams = GaitParams()) -> Motion:
    """Eq. (26) in the sagittal plane, for a 2D model of up to five links.

    The planar angle of link i follows the elevation ``psi_i`` of eq. (26) (link 5, the
    trunk, stays vertical) and the length follows ``l_i``. Links beyond the fifth are not
    defined by the paper and are refused.
    """
    if mech.dim != 2 or mech.nlinks > 5:
        raise ValueError(
            f"planar_gait: mechanism {mech.name!r}: expected a 2D model with at most 5 links, "
            f"got {mech.dim}D with {mech.nlinks} link(s)"
        )
    t = np.asarray(t, dtype=float)
    _, psi, lens = _gait_angles(t, params)
    n = mech.nlinks
    q, qd, qdd = _stack([psi[:n], lens[:n]])
    return Motion(t, q, qd, qdd)


def smooth_random_motion(
    mech: Mechanism, t: np.ndarray, seed: int, harmonics: int = 3, length_range: tuple[float, float] = (0.3, 1.2)
) -> Motion:
    """A seeded smooth motion: every coordinate is a constant plus a few harmonics.

    Angles move by up to about one radian around random means (elevations stay within
    (-1.2, 1.2) rad, away from the vertical where the azimuth is undefined); lengths stay
    inside ``length_range``.
    """
    rng = np.random.default_rng(seed)
    t = np.asarray(t, dtype=float)
    n = mech.nlinks
    blocks = ["phi", "psi", "l"] if mech.dim == 3 else ["phi", "l"]
    cols = []
    for b in blocks:
        for _ in range(n):
            if b == "l":
                lo, hi = length_range
                mean, amp = 0.5 * (lo + hi), 0.5 * (hi - lo) / harmonics
            elif b == "psi":
                mean, amp = rng.uniform(-0.6, 0.6), 0.6 / harmonics
            else:
                mean, amp = rng.uniform(-math.pi, math.pi), 1.0 / harmonics
            x, x1, x2 = np.full_like(t, mean), np.zeros_like(t), np.zeros_like(t)
            for k in range(1, harmonics + 1):
                a, w, ph = amp * rng.uniform(0.2, 1.0), k * rng.uniform(0.5, 2.0), rng.uniform(0, 2 * math.pi)
                x = x + a * np.sin(w * t + ph)
                x1 = x1 + a * w * np.cos(w * t + ph)
                x2 = x2 - a * w * w * np.sin(w * t + ph)
            cols.append((x, x1, x2))
    q, qd, qdd = _stack([cols])
    return Motion(t, q, qd, qdd)


def random_states(mech: Mechanism, samples: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Seeded random states ``(q, qd, qdd)``, each ``(samples, dof)``: angles in (-pi, pi),
    elevations in (-1.2, 1.2), lengths in (0.3, 1.2), rates and accelerations in (-2, 2)."""
    rng = np.random.default_rng(seed)
    n = mech.nlinks
    q = rng.uniform(-math.pi, math.pi, (samples, mech.dof))
    if mech.dim == 3:
        q[:, n : 2 * n] = rng.uniform(-1.2, 1.2, (samples, n))
    q[:, -n:] = rng.uniform(0.3, 1.2, (samples, n))
    qd = rng.uniform(-2, 2, (samples, mech.dof))
    qdd = rng.uniform(-2, 2, (samples, mech.dof))
    return q, qd, qdd


def from_arrays(mech: Mechanism, t, q, qd, qdd, source: str = "motion") -> Motion:
    """An arbitrary motion given as arrays, validated at the edge."""
    q, qd, qdd = as_states(mech, q, qd, qdd, source)
    t = np.asarray(t, dtype=float)
    if t.shape != (q.shape[0],):
        raise ValueError(f"{source}: field 't': expected shape ({q.shape[0]},), got {t.shape}")
    return Motion(t, q, qd, qdd)
