"""The fit of the gait parameters of eq. (26) to normative level walking (run offline).

``python -m exo_bench.models.gait.gait_fit`` reruns the fit (about half a minute) and prints the
constants to store in :class:`exo_bench.models.gait.motion.GaitParams`; :func:`check_gait` measures what any
parameters achieve (the tests call it on the stored constants, not the optimiser).

**The model's roles.** Eq. (26) keeps link 1 on the support point O for the whole period: the
stance leg (links 1, 2: shin and thigh) is in single support all the time and the swing leg
(links 3, 4: thigh and shin, hanging from the hip) swings all the time. Over the first half
period the stance leg turns forward and the swing leg swings forward; over the second half both
run back along the same path (eq. 26 is symmetric in time about T/2). So the targets are:

1. **Segment angles over the phase** (sagittal, x-z projection; x is the direction the hip moves
   in the first half period): the angle of each of links 1-4 at every frame of Winter's walk
   (:mod:`exo_bench.models.gait.normative`, 1.41 m/s), time-normalised onto the first half period: the stance
   leg's shank and thigh over single support, the swing leg's thigh and shank over the swing phase.
   The angle of a link is that of its direction ``u`` (distal to proximal joint for every link of
   the exoskeleton, as in Winter's tables), counter-clockwise from +x. Residuals in degrees, each
   link weighted by 1/sqrt(frames) so that each contributes its mean square. Matching the curves,
   not only their ranges, fixes the direction of motion too: a fit to the smallest and largest angle
   alone (the first version of this fit) found a swing shank that swung backwards while the stance
   leg turned forwards. The ranges (smallest and largest angle) are reported against Winter's.
2. **Floor clearance**: every point mass of the swing leg (links 3, 4) at least
   :data:`CLEARANCE` above the floor z = 0 at every instant (a constraint).
3. **Cadence**: ``T`` is the stride time of the same walk, 0.987 s (121.6 steps/min). No other
   target depends on ``T`` (the others are geometric), so ``T`` is set to it, not searched.

and two bounds that are **our assumptions**, not data:

4. **Frontal plane**: eq. (26) gives each link's azimuth the amplitude ``j_i`` of its elevation,
   so a large or lopsided sagittal range swings the link sideways. Every point mass stays within
   :data:`LATERAL_BOUND` of the sagittal plane y = 0 (a constraint). 10 cm is our assumption, of
   the order of the step width of walking (the model has one hip point for both legs and the
   pelvis); Winter's tables are sagittal only. This bound is what keeps the fit from following the
   curves closer: with 5 cm the RMS residuals grow by about a third, and even without a bound the
   waveform of eq. (26) leaves residuals of about 9 deg on three of the four links.
5. **Rod lengths** stay near the anthropometric rest lengths of :data:`REST_LENGTHS` (residual
   scale 5 mm) and the stretch amplitude ``l`` near 0 (scale 0.5 %): the rods lengthen only as
   much as the other targets need. ``l_5*`` (the trunk) enters no target and stays at its rest
   length; ``j_5`` moves no point mass while the trunk stands vertical (``psi_5 = pi/2``) and is
   not fitted.

The optimiser is SLSQP (scipy) from :data:`STARTS` seeded random starts; the best feasible one
wins. The fit samples :data:`FIT_SAMPLES` instants per period; the clearance margin covers what
happens between them (the tests check 20 000 samples).
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, replace

import numpy as np

from exo_bench.models.mechanism.kinematics import point_mass_positions, unit_vectors
from exo_bench.models.gait.motion import GaitParams, gait
from exo_bench.models.gait.normative import WINTER
from exo_bench.models.mechanism.presets import exo5

#: Lowest height (m) of any swing-leg point mass the fit allows.
CLEARANCE = 0.01
#: Largest distance (m) of any point mass from the sagittal plane y = 0 (our assumption, see above).
LATERAL_BOUND = 0.10
#: Stature (m) of the anthropometric rest lengths.
STATURE = 1.75
#: Rest lengths l_1*..l_5* (m): Winter's segment-length fractions of stature (his Fig. 4.1, after
#: Drillis and Contini; not checked by us against the book): leg 0.246 H, thigh 0.245 H, hip to
#: shoulder 0.288 H (0.818 H - 0.530 H).
REST_LENGTHS = (0.246 * STATURE, 0.245 * STATURE, 0.245 * STATURE, 0.246 * STATURE, 0.288 * STATURE)
#: (Winter's segment, phase) that each of links 1-4 is fitted to.
SEGMENTS = (("leg", "single support"), ("thigh", "single support"), ("thigh", "swing"), ("leg", "swing"))
ROLES = ("stance shank, single support", "stance thigh, single support", "swing thigh, swing", "swing shank, swing")
SWING_LINKS = (2, 3)
FIT_SAMPLES = 400
STARTS = 16
SEED = 0
ANGLE_SCALE = 1.0  # deg
LENGTH_SCALE = 0.005  # m
STRETCH_SCALE = 0.005  # of the rest length
J5 = 0.05


@dataclass(frozen=True)
class GaitCheck:
    """What a set of gait parameters achieves against the targets."""

    angles: tuple[tuple[float, float], ...]  # (min, max) sagittal angle of links 1-4, degrees
    targets: tuple[tuple[float, float], ...]  # the normative (min, max), degrees
    rms: tuple[float, ...]  # RMS of model minus Winter over the phase, degrees
    lowest_swing_point: float  # m, over every swing-leg point mass and instant
    lowest_swing_at: float  # s
    lateral: float  # m, largest |y| of any point mass
    cadence: float  # steps/min, 120 / T

    @property
    def angle_residuals(self) -> tuple[tuple[float, float], ...]:
        """Model minus target, degrees, for the (min, max) of links 1-4."""
        return tuple((a[0] - b[0], a[1] - b[1]) for a, b in zip(self.angles, self.targets))


def sagittal_angles(q: np.ndarray) -> np.ndarray:
    """Sagittal angle (degrees, counter-clockwise from +x in the x-z plane) of every link's ``u``."""
    u, _, _ = unit_vectors(exo5(3), q)
    return np.degrees(np.arctan2(u[..., 2], u[..., 0]))


def check_gait(params: GaitParams, samples: int = 20000) -> GaitCheck:
    """Measure the targets of the fit on ``samples`` instants of one period of ``params``."""
    mech = exo5(3)
    t = np.arange(samples) * (params.T / samples)
    q = gait(mech, t, params).q
    th = sagittal_angles(q)
    P = point_mass_positions(mech, q)
    z = P[:, list(SWING_LINKS)][..., 2].reshape(samples, -1).min(axis=1)
    k = int(np.argmin(z))
    targets = tuple(WINTER.angle_range(seg, phase) for seg, phase in SEGMENTS)
    rms = tuple(float(np.sqrt(np.mean(r**2))) for r in _curve_errors(params))
    return GaitCheck(
        tuple((float(th[:, i].min()), float(th[:, i].max())) for i in range(4)),
        targets,
        rms,
        float(z[k]),
        float(t[k]),
        float(np.abs(P[..., 1]).max()),
        120.0 / params.T,
    )


def _curve_errors(params: GaitParams) -> list[np.ndarray]:
    """Model minus Winter (degrees) at every frame of each link's phase, time-normalised onto the
    first half period."""
    out = []
    for i, (seg, phase) in enumerate(SEGMENTS):
        c = WINTER.curve(seg, phase)
        t = np.linspace(0.0, 0.5 * params.T, len(c))
        out.append(sagittal_angles(gait(exo5(3), t, params).q)[:, i] - c)
    return out


def _params(x: np.ndarray) -> GaitParams:
    return GaitParams(
        T=WINTER.stride_time.value,
        j=tuple(float(v) for v in x[0:4]) + (J5,),
        f=tuple(float(v) for v in x[4:8]),
        l_star=tuple(float(v) for v in x[8:12]) + (REST_LENGTHS[4],),
        l=float(x[12]),
    )


class _Problem:
    """Residuals and constraints of the fit on a fixed grid of instants."""

    def __init__(self, samples: int = FIT_SAMPLES):
        self.mech = exo5(3)
        self.t = np.arange(samples) * (WINTER.stride_time.value / samples)
        self._cache: tuple[bytes, np.ndarray, np.ndarray] | None = None

    def _geometry(self, x):
        key = np.asarray(x, dtype=float).tobytes()
        if self._cache is None or self._cache[0] != key:
            q = gait(self.mech, self.t, _params(x)).q
            self._cache = (key, sagittal_angles(q), point_mass_positions(self.mech, q))
        return self._cache[1], self._cache[2]

    def residuals(self, x) -> np.ndarray:
        r = [e / (ANGLE_SCALE * np.sqrt(len(e))) for e in _curve_errors(_params(x))]
        r += [(np.asarray(x[8:12]) - REST_LENGTHS[:4]) / LENGTH_SCALE]
        r += [np.array([x[12] / STRETCH_SCALE])]
        return np.concatenate(r)

    def objective(self, x) -> float:
        return float(np.sum(self.residuals(x) ** 2))

    def clearance(self, x) -> np.ndarray:
        _, P = self._geometry(x)
        return P[:, list(SWING_LINKS)][..., 2].reshape(len(self.t), -1).min(axis=1) - CLEARANCE

    def lateral(self, x) -> np.ndarray:
        _, P = self._geometry(x)
        return LATERAL_BOUND - np.abs(P[..., 1]).reshape(len(self.t), -1).max(axis=1)


def _vector(params: GaitParams) -> np.ndarray:
    """The fitted values of ``params`` as the optimiser's vector (the inverse of :func:`_params`)."""
    return np.array(params.j[:4] + tuple(params.f) + params.l_star[:4] + (params.l,), dtype=float)


def objective(params: GaitParams, samples: int = FIT_SAMPLES) -> float:
    """The fit's objective at ``params``: the sum of the squared scaled residuals (each link's angle
    curve in units of :data:`ANGLE_SCALE` per sqrt(frame), the rest lengths in :data:`LENGTH_SCALE`,
    the stretch in :data:`STRETCH_SCALE`). The constraints are not in it (see :func:`check_gait`)."""
    return _Problem(samples).objective(_vector(params))


BOUNDS = [(0.0, 1.5)] * 4 + [(-math.pi, math.pi)] * 4 + [(0.9 * a, 1.1 * a) for a in REST_LENGTHS[:4]] + [(0.0, 0.1)]


@dataclass(frozen=True)
class FitResult:
    params: GaitParams
    check: GaitCheck
    objective: float
    starts: int
    feasible: int


def fit_gait(starts: int = STARTS, seed: int = SEED, samples: int = FIT_SAMPLES) -> FitResult:
    """Fit ``j_1..j_4, f_1..f_4, l_1*..l_4*, l`` (``T`` from the cadence, see the module text)."""
    from scipy.optimize import minimize

    prob = _Problem(samples)
    rng = np.random.default_rng(seed)
    cons = [{"type": "ineq", "fun": prob.clearance}, {"type": "ineq", "fun": prob.lateral}]
    best, feasible = None, 0
    for _ in range(starts):
        x0 = np.concatenate([rng.uniform(0.1, 1.2, 4), rng.uniform(-math.pi, math.pi, 4), REST_LENGTHS[:4], [0.01]])
        res = minimize(
            prob.objective, x0, method="SLSQP", bounds=BOUNDS, constraints=cons, options={"maxiter": 500, "ftol": 1e-10}
        )
        ok = prob.clearance(res.x).min() >= -1e-6 and prob.lateral(res.x).min() >= -1e-6
        feasible += ok
        if ok and (best is None or res.fun < best.fun):
            best = res
    if best is None:
        raise RuntimeError(f"gait fit: none of {starts} starts met the clearance and lateral constraints")
    params = _params(best.x)
    return FitResult(params, check_gait(params), float(best.fun), starts, feasible)


def rounded(params: GaitParams, digits: int = 4) -> GaitParams:
    """The parameters as stored: rounded to ``digits`` decimals."""
    r = lambda v: tuple(round(float(a), digits) for a in v)
    return replace(params, j=r(params.j), f=r(params.f), l_star=r(params.l_star), l=round(params.l, digits))


def describe(params: GaitParams, check: GaitCheck | None = None) -> str:
    """The targets and what ``params`` achieve, as text (the fit's report)."""
    c = check or check_gait(params)
    lines = [
        f"T = {params.T} s ({c.cadence:.1f} steps/min; target {WINTER.stride_time.value} s, "
        f"{WINTER.cadence:.1f} steps/min at {WINTER.speed.value} m/s)"
    ]
    for i, role in enumerate(ROLES):
        (a, b), (lo, hi) = c.angles[i], c.targets[i]
        lines.append(
            f"link {i + 1} ({role}): RMS {c.rms[i]:.1f} deg over the phase; range {a:.1f} to {b:.1f} deg, "
            f"Winter {lo:.1f} to {hi:.1f} deg (residual {a - lo:+.1f}, {b - hi:+.1f})"
        )
    lines.append(
        f"lowest swing-leg point mass: {100 * c.lowest_swing_point:.2f} cm at t = {c.lowest_swing_at:.3f} s "
        f"(target >= {100 * CLEARANCE:.0f} cm)"
    )
    lines.append(f"largest |y| of any point mass: {100 * c.lateral:.2f} cm (bound {100 * LATERAL_BOUND:.0f} cm)")
    lines.append(
        f"rest lengths {params.l_star} m (anthropometric {tuple(round(x, 4) for x in REST_LENGTHS)}), "
        f"stretch l = {params.l}"
    )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    res = fit_gait()
    p = rounded(res.params)
    print(f"{res.feasible} of {res.starts} starts feasible; objective {res.objective:.4g}")
    print(describe(p))
    print(f"\nGaitParams(T={p.T}, j={p.j}, f={p.f}, l_star={p.l_star}, l={p.l})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
