"""Stability study, the cases: profiles (quick, full) and the families of extreme cases (a benign
baseline, near-vertical rods, the removable singularities of eq. (18), extreme lengths and masses,
large n, fast gaits), each a list of :class:`Case` (a mechanism and states); the verdict thresholds.
"""

from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np

from exo_bench.bench.studies.study import StabilityWarning
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.gait.motion import GaitParams
from exo_bench.models.gait.motion import gait
from exo_bench.models.gait.motion import planar_gait
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import chain
from exo_bench.models.mechanism.presets import exo5
from exo_bench.models.mechanism.presets import random_tree


EPS = float(np.finfo(float).eps)


#: Relative error (``max |tau - ref| / max |ref|``) above which a method is unusable on a case.
REL_UNUSABLE = 1e-6


#: Relative error above which a method is degraded (still usable, digits lost).
REL_DEGRADED = 1e-9


#: cond(M) (2-norm, SI units) from which forward dynamics is ill-conditioned.
COND_ILL = 1e6


#: cond(M) from which forward dynamics is numerically singular.
COND_SINGULAR = 1e12


class IllConditionedWarning(StabilityWarning):
    """A family's mass matrix is ill-conditioned or singular: forward dynamics loses digits or is
    undefined there."""


# ----------------------------------------------------------------------------- profiles
@dataclass(frozen=True)
class Profile:
    name: str
    samples: int  # states per case
    distances: tuple[float, ...]  # from pi/2 (vertical rods) and from eq. (18)'s singularities
    lengths: tuple[float, ...]  # scale of every rod
    one_length: tuple[float, ...]  # length of link 2 alone
    ratios: tuple[float, ...]  # mass ratio swing leg / rest
    large_n: tuple[int, ...]
    periods: tuple[float, ...]  # gait period T (s)
    lagrange_budget: float  # seconds of symbolic work per mechanism for `lagrange`
    wp_rtols: tuple[float, ...]  # round-trip work-precision grid (gait), every integrator
    rt_rtols: tuple[float, ...]  # the other round-trip cases (DOP853 and Radau)
    rt_integrators: tuple[str, ...]  # integrators of the other round-trip cases
    method_rtol: float  # per-method round trip (DOP853)
    energy_rtols: tuple[float, ...]
    stiff_k: tuple[float, ...]
    stiff_mass_scales: tuple[float, ...]  # tiny masses, at k = 1e4
    stiff_rtol: float
    stiff_budget: int  # right-hand-side evaluations before an integrator gives up
    full_cases: bool = False
    method_seconds: float = 120.0  # wall time per method per forward-dynamics run
    rt_cases: tuple[str, ...] = ()  # round-trip cases to run (empty: all of bench.forward.round_trip_cases)
    method_cases: tuple[str, ...] = ("exo5-2d planar gait", "tree4-3d random motion")  # every method's M, h
    energy_cases: tuple[str, ...] = ()  # conservative cases to run (empty: all)
    stiff_reference_rtol: float = 1e-9  # Radau reference of the stiff runs
    stiff_seconds: float = 30.0  # wall time per stiff run (and its reference)


QUICK = Profile(
    "quick",
    samples=3,
    distances=(1e-2, 1e-4, 1e-6, 1e-8, 1e-10, 1e-12, 0.0),
    lengths=(0.0, 1e-9, 1e-6, 1e-3, 1.0, 1e3, 1e6),
    one_length=(0.0, 1e-9, 1e-6, 1e-3, 1e3, 1e6),
    ratios=(1e-6, 1e-3, 1.0, 1e3, 1e6),
    large_n=(50, 100),
    periods=(1.1, 0.1, 0.01),
    lagrange_budget=10.0,
    wp_rtols=(1e-4, 1e-6, 1e-8, 1e-10, 1e-12),
    rt_rtols=(1e-6, 1e-8, 1e-10),
    rt_integrators=("DOP853", "Radau"),
    method_rtol=1e-8,
    energy_rtols=(1e-5, 1e-7, 1e-9),
    stiff_k=(1e4, 1e6, 1e8),
    stiff_mass_scales=(1e-4,),
    stiff_rtol=1e-6,
    stiff_budget=20_000,
    method_seconds=60.0,
)


FULL = Profile(
    "full",
    samples=8,
    distances=(1e-1, 1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 0.0),
    lengths=(0.0, 1e-12, 1e-9, 1e-6, 1e-3, 1e-1, 1.0, 10.0, 1e3, 1e6),
    one_length=(0.0, 1e-12, 1e-9, 1e-6, 1e-3, 1e3, 1e6),
    ratios=(1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0, 10.0, 1e2, 1e3, 1e4, 1e5, 1e6),
    large_n=(50, 100),
    periods=(1.1, 0.5, 0.3, 0.1, 0.03, 0.01, 0.003),
    lagrange_budget=120.0,
    wp_rtols=(1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12),
    rt_rtols=(1e-6, 1e-8, 1e-10, 1e-12),
    rt_integrators=("RK45", "DOP853", "Radau", "BDF"),
    method_rtol=1e-10,
    energy_rtols=(1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10),
    stiff_k=(1e3, 1e4, 1e5, 1e6, 1e7, 1e8),
    stiff_mass_scales=(1e-2, 1e-4, 1e-6),
    stiff_rtol=1e-6,
    stiff_budget=200_000,
    full_cases=True,
    method_seconds=600.0,
    stiff_seconds=120.0,
)


# ----------------------------------------------------------------------------- cases
@dataclass(frozen=True, eq=False)
class Case:
    """A scene-like extreme case: a mechanism and states ``(samples, dof)``."""

    family: str
    series: str  # sub-series within the family (one line in the plots)
    label: str  # this case within the series
    x: float  # the swept parameter (distance, length, ratio, n, T)
    mechanism: Mechanism
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray


def _fmt(x: float) -> str:
    return "0" if x == 0 else f"{x:.0e}"


BASELINE = "benign baseline (control)"


def family_baseline(p: Profile) -> list[Case]:
    """Seeded random states of the paper's models and of random trees, away from every singularity
    (elevations within 1.2 rad of the horizontal, lengths 0.3 .. 1.2 m): the level every method
    reaches when nothing is extreme. A method unusable here is wrong, not unstable."""
    out = []
    for k, mech in enumerate((exo5(3), exo5(2), random_tree(6, 3, 1), random_tree(6, 2, 2))):
        q, qd, qdd = random_states(mech, p.samples, 50 + k)
        out.append(Case(BASELINE, "baseline", mech.name, math.nan, mech, q, qd, qdd))
    return out


def family_near_vertical(p: Profile) -> list[Case]:
    """exo5-3d with every elevation at ``pi/2 - d`` (vertical rods; the gait of eq. 26 lives
    there, its trunk exactly at pi/2), azimuths, lengths, rates random (seeded)."""
    mech = exo5(3)
    n = mech.nlinks
    out = []
    for k, d in enumerate(p.distances):
        q, qd, qdd = random_states(mech, p.samples, 100 + k)
        q[:, n : 2 * n] = math.pi / 2 - d
        out.append(Case("near-vertical rods", "psi = pi/2 - d", f"d = {_fmt(d)}", d, mech, q, qd, qdd))
    return out


def family_removable(p: Profile) -> list[Case]:
    """exo5-3d at the removable singularities of eq. (18) and at distance ``d`` from them:
    ``cos(phi_i - phi_j) = 0`` (consecutive azimuths pi/2 + d apart), ``cos phi_i = 0``
    (``phi_i = +-pi/2 + d``), ``sin phi_i = 0`` (``phi_i = d``; exactly 0 at d = 0)."""
    mech = exo5(3)
    n = mech.nlinks
    out = []
    for k, d in enumerate(p.distances):
        for series, seed in (("cos(phi_i - phi_j) = 0", 200), ("cos phi_i = 0", 300), ("sin phi_i = 0", 400)):
            q, qd, qdd = random_states(mech, p.samples, seed + k)
            rng = np.random.default_rng(seed + k)
            if series.startswith("cos(phi_i"):
                q[:, :n] = q[:, :1] + np.arange(n) * (math.pi / 2 + d)
            elif series.startswith("cos phi"):
                q[:, :n] = rng.choice([-1.0, 1.0], (p.samples, n)) * math.pi / 2 + d
            else:
                q[:, :n] = d
            out.append(
                Case("removable singularities of eq. (18)", series, f"{series}, d = {_fmt(d)}", d, mech, q, qd, qdd)
            )
    return out


def family_lengths(p: Profile) -> list[Case]:
    """exo5-3d with every rod scaled to ``L * U(0.5, 1.5)``, and with link 2 alone at length ``L``."""
    mech = exo5(3)
    n = mech.nlinks
    out = []
    for k, L in enumerate(p.lengths):
        q, qd, qdd = random_states(mech, p.samples, 500 + k)
        rng = np.random.default_rng(500 + k)
        q[:, -n:] = L * rng.uniform(0.5, 1.5, (p.samples, n))
        # Rates of the lengths scale with them, so that the motion stays the same shape.
        qd[:, -n:] *= L
        qdd[:, -n:] *= L
        out.append(
            Case("very short and very long rods", "every rod ~ L", f"every rod ~ L = {_fmt(L)} m", L, mech, q, qd, qdd)
        )
    for k, L in enumerate(p.one_length):
        q, qd, qdd = random_states(mech, p.samples, 600 + k)
        q[:, mech.dof - n + 1] = L  # l_2
        out.append(Case("very short and very long rods", "link 2 at L", f"l2 = {_fmt(L)} m", L, mech, q, qd, qdd))
    return out


def _scaled(mech: Mechanism, links: tuple[int, ...], r: float, name: str) -> Mechanism:
    masses = [tuple(r * x for x in m) if i in links else m for i, m in enumerate(mech.masses)]
    return mech.replace(masses=tuple(masses), name=name)


def family_masses(p: Profile) -> list[Case]:
    """exo5-3d with the swing leg's masses (links 3 and 4) multiplied by ``r``; with zero middle
    masses; with a massless swing shin (no middle or end mass: its coordinates move nothing)."""
    base = exo5(3)
    out = []
    for k, r in enumerate(p.ratios):
        mech = _scaled(base, (2, 3), r, f"exo5-3d, swing leg masses x{r:g}")
        q, qd, qdd = random_states(mech, p.samples, 700 + k)
        out.append(Case("mass ratios", "swing leg masses x r", f"r = {r:.0e}", r, mech, q, qd, qdd))
    zero_mid = base.replace(masses=tuple((m0, 0.0, m2) for m0, _, m2 in base.masses), name="exo5-3d, no middle masses")
    q, qd, qdd = random_states(zero_mid, p.samples, 790)
    out.append(Case("mass ratios", "special", "zero middle masses", math.nan, zero_mid, q, qd, qdd))
    m = list(base.masses)
    m[3] = (m[3][0], 0.0, 0.0)
    massless = base.replace(masses=tuple(m), name="exo5-3d, massless swing shin")
    q, qd, qdd = random_states(massless, p.samples, 791)
    out.append(Case("mass ratios", "special", "massless swing shin (m41 = m42 = 0)", math.nan, massless, q, qd, qdd))
    return out


def family_large_n(p: Profile) -> list[Case]:
    """Seeded 3D chains and random trees of n = 50 (and 100 in the full profile) links."""
    out = []
    for n in p.large_n:
        for mech in (chain(n, 3, seed=n), random_tree(n, 3, seed=n)):
            q, qd, qdd = random_states(mech, p.samples, 800 + n)
            kind = "chain" if mech.is_chain() else "random tree"
            out.append(Case("large n", kind, f"{kind}, n = {n}", float(n), mech, q, qd, qdd))
    return out


def family_fast_gaits(p: Profile) -> list[Case]:
    """The gait of eq. (26) (exo5-3d) and its planar version (exo5-2d) at periods ``T``, sampled
    over one period: rates grow like 1/T, accelerations like 1/T^2."""
    out = []
    for mech, fn, series in ((exo5(3), gait, "exo5-3d gait (eq. 26)"), (exo5(2), planar_gait, "exo5-2d planar gait")):
        for T in p.periods:
            t = np.linspace(0.0, T, max(p.samples, 4), endpoint=False)
            m = fn(mech, t, GaitParams(T=T))
            out.append(Case("fast gaits", series, f"{series.split()[0]}, T = {T:g} s", T, mech, m.q, m.qd, m.qdd))
    return out


FAMILIES = {
    BASELINE: family_baseline,
    "near-vertical rods": family_near_vertical,
    "removable singularities of eq. (18)": family_removable,
    "very short and very long rods": family_lengths,
    "mass ratios": family_masses,
    "large n": family_large_n,
    "fast gaits": family_fast_gaits,
}
