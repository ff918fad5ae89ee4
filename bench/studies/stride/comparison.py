"""The stride against Winter's over the whole gait cycle: curves, r and RMS error, and the done-when checks.

**The cycle.** Both strides are cut at the right heel strike and resampled to :data:`BINS` bins of 1 % of
the cycle (:func:`cycle_means`): each bin holds the mean of the piecewise-linear curve over the bin, so the
bins' sum times the bin width is the trapezoidal integral of the samples over the cycle, exactly (an energy
per stride survives the resampling). Our heel strike and toe-off are where the right foot's vertical ground
force crosses :data:`CONTACT_THRESHOLD` body weights (the smooth contact is never exactly zero; Winter's
force plate reads 0 N in swing); Winter's are his frames 28 and 70.

**Quantities, in Winter's convention.** Sagittal net joint moments (N·m/kg), joint powers (W/kg), ground
reaction on the right foot (body weights), and segment angles (degrees). The moments are the model's joint
motors of :func:`exo_bench.bench.studies.stride.actuators.actuators`: the moment the reference link (HAT,
thigh, leg) exerts on the link (thigh, leg, foot) about +z, counter-clockwise positive with the walker moving
in +x. That is Winter's Table A.5 moment on the distal segment at its proximal joint (:mod:`.winter`), so the
curves are compared as they are, with no relabelling. The powers are ``moment x (omega_link -
omega_reference)`` on both sides (:func:`exo_bench.bench.studies.stride.actuators.powers`,
:func:`.winter.joint_powers`). The model's angles are Winter's segment angles by construction
(:func:`exo_bench.models.presets.human`: the vector from the distal to the proximal joint).

**Scale.** Each curve's RMS error is set beside Winter's own RMS over the cycle (a segment angle's about
its mean, so the scale is the angle's swing, not its offset from +x): the transcription is one subject,
with no inter-subject spread to compare with.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exo_bench.bench.studies.stride import winter
from exo_bench.bench.studies.stride.actuators import Actuators, actuators, powers, work_terms
from exo_bench.models.mechanism import Mechanism
from exo_bench.bench.studies.stride.evidence import (
    CONTACT_THRESHOLD,
    WINTER_DOUBLE_SUPPORT,
    WINTER_STANCE,
    contacts,
    absorbed,
    double_support,
    rod_travel,
    toe_share,
)
from exo_bench.models.normative import G

BINS = 100
#: A lift of the foot shorter than this fraction of the cycle (5 %: 49 ms in Winter's stride) is a bounce
#: within one stance, not a toe-off and a heel strike.
BOUNCE = 0.05
#: A peak is comparable when within this factor of Winter's, either way.
FACTOR = 2.0
#: A phase's peak is compared only when Winter's is at least this fraction of the curve's largest absolute value
#: (smaller ones, such as the ankle moment in swing, are at the transcription's rounding).
COMPARABLE = 0.1
R_MIN, GRF_PEAK, GRF_VALLEY, ROD_SHARE = 0.7, 1.0, 0.85, 0.25
JOINTS = ("hip", "knee", "ankle")
SEGMENTS = (("foot", "right_foot"), ("leg", "right_leg"), ("thigh", "right_thigh"), ("hat", "hat"))


@dataclass(frozen=True)
class Curve:
    """One quantity over the cycle (:data:`BINS` bins), ours and Winter's, with r and RMS error."""

    key: str
    unit: str
    ours: np.ndarray
    winter: np.ndarray

    @property
    def r(self) -> float:
        return pearson(self.ours, self.winter)

    @property
    def rms_error(self) -> float:
        return rms(self.ours - self.winter)

    @property
    def winter_rms(self) -> float:
        """Winter's curve's RMS over the cycle; an angle's about its mean (its swing, not its offset)."""
        return rms(self.winter - np.mean(self.winter)) if self.key.endswith("angle") else rms(self.winter)


@dataclass(frozen=True)
class Verdict:
    """A done-when check: whether it holds, its target, and the computed numbers it rests on."""

    name: str
    passed: bool
    target: str
    measured: str
    short: str = ""  # a column title for tables of many strides


@dataclass(frozen=True)
class Comparison:
    curves: dict[str, Curve]
    stance: tuple[float, float]  # stance fraction (%), ours and Winter's
    heel_strike: float  # s, our heel strike within the stored stride
    peaks: list[tuple[str, float, float]]  # (peak, ours, Winter's), comparable ones
    verdicts: list[Verdict]


def pearson(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson's correlation of two curves (nan when either is constant)."""
    a, b = np.asarray(a, float) - np.mean(a), np.asarray(b, float) - np.mean(b)
    den = float(np.sqrt(np.sum(a * a) * np.sum(b * b)))
    return float(np.sum(a * b) / den) if den > 0 else float("nan")


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


def _check_cycle(t: np.ndarray, start: float, period: float) -> None:
    if t.ndim != 1 or len(t) < 2 or not np.all(np.diff(t) > 0):
        raise ValueError(f"stride comparison: field 't': expected strictly increasing times, got {t!r}")
    if abs(t[-1] - t[0] - period) > 1e-9 * max(1.0, period):
        raise ValueError(f"stride comparison: field 't': expected one period {period} s, got {t[-1] - t[0]} s")
    if not t[0] <= start <= t[-1]:
        raise ValueError(f"stride comparison: field 'start': expected within [{t[0]}, {t[-1]}] s, got {start}")


def cycle_means(t: np.ndarray, y: np.ndarray, start: float, period: float, bins: int = BINS) -> np.ndarray:
    """``(bins, ...)``: the mean of the piecewise-linear ``y (K, ...)`` over each bin of the cycle
    ``[start, start + period]``, the samples ``t (K,)`` spanning one period and repeated beyond it."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    _check_cycle(t, start, period)
    te = np.concatenate([t, t[1:] + period])
    ye = np.concatenate([y, y[1:]], axis=0)
    h = np.diff(te).reshape(-1, *([1] * (ye.ndim - 1)))
    C = np.concatenate([np.zeros((1, *ye.shape[1:])), np.cumsum(0.5 * h * (ye[1:] + ye[:-1]), axis=0)])
    edges = start + period * np.arange(bins + 1) / bins
    i = np.clip(np.searchsorted(te, edges, side="right") - 1, 0, len(te) - 2)
    s = (edges - te[i]).reshape(-1, *([1] * (ye.ndim - 1)))
    slope = (ye[i + 1] - ye[i]) / h[i]
    at = C[i] + ye[i] * s + 0.5 * slope * s * s
    return np.diff(at, axis=0) / (period / bins)


def gait_events(
    t: np.ndarray, fy: np.ndarray, weight: float, threshold: float = CONTACT_THRESHOLD
) -> tuple[float, float]:
    """``(heel strike, toe-off)`` times of the longest contact of a foot with vertical force ``fy (K,)``
    over one periodic cycle ``t``: where ``fy`` crosses ``threshold x weight`` up and down (interpolated);
    contacts apart by less than :data:`BOUNCE` of the cycle are one (the foot bounced)."""
    f = np.asarray(fy, float) - threshold * weight
    T = t[-1] - t[0]
    on = f[:-1] > 0
    if on.all() or not on.any():
        raise ValueError(f"stride comparison: the foot never {'leaves' if on.all() else 'touches'} the ground")
    k = np.arange(len(on))
    up = k[on & ~np.roll(on, 1)]
    down = k[~on & np.roll(on, 1)]

    def cross(j: int) -> float:  # between samples j - 1 and j (periodic)
        a, b = f[j - 1] if j > 0 else f[-2], f[j]
        ta = t[j - 1] if j > 0 else t[-2] - T
        return float(ta + (t[j] - ta) * a / (a - b))

    ups, downs = [cross(j) for j in up], [cross(j) for j in down]
    runs = sorted((u, min((d - u) % T for d in downs)) for u in ups)  # (touch-down, duration), in time order
    merged = True
    while merged and len(runs) > 1:  # a lift shorter than BOUNCE of the cycle does not end the stance
        merged = False
        for i in range(len(runs)):
            (u, dur), (u2, dur2) = runs[i], runs[(i + 1) % len(runs)]
            gap = (u2 - (u + dur)) % T
            if gap < BOUNCE * T:
                runs[i] = (u, dur + gap + dur2)
                del runs[(i + 1) % len(runs)]
                merged = True
                break
    u, dur = max(runs, key=lambda r: r[1])
    return u % T + t[0], (u + dur) % T + t[0]


def _angle_deg(ours_rad: np.ndarray, winter_deg: np.ndarray) -> np.ndarray:
    d = np.degrees(np.unwrap(ours_rad))
    return d - 360.0 * np.round((np.mean(d) - np.mean(winter_deg)) / 360.0)


def our_series(mech: Mechanism, stride, act: Actuators | None = None) -> dict[str, np.ndarray]:
    """Per sample of the stored stride, the quantities of the comparison in Winter's units."""
    act = actuators(mech, stride.tau) if act is None else act
    P, _, _ = powers(mech, act, stride.qd)
    mass, bw = mech.total_mass, stride.body_weight
    out = {}
    for j in JOINTS:
        c = act.joint_names.index(f"right_{j}")
        out[f"{j} moment"] = act.moments[:, c] / mass
        out[f"{j} power"] = P[:, c] / mass
    out["vertical GRF"] = stride.grf[:, 0, 1] / bw
    out["fore-aft GRF"] = stride.grf[:, 0, 0] / bw
    for seg, link in SEGMENTS:
        out[f"{seg} angle"] = stride.q[:, mech.names.index(link)]  # radians, converted against Winter's
    return out


def winter_series() -> dict[str, np.ndarray]:
    """Winter's quantities per frame (28-97), in the units of :func:`our_series` (angles in degrees)."""
    tab = winter.table()
    P = winter.joint_powers(tab)
    out = {}
    for j in JOINTS:
        out[f"{j} moment"] = tab[f"{j}_m"] / winter.MASS
        out[f"{j} power"] = P[j] / winter.MASS
    out["vertical GRF"] = tab["grf_y"] / (winter.MASS * G)
    out["fore-aft GRF"] = tab["grf_x"] / (winter.MASS * G)
    for seg, _ in SEGMENTS:
        out[f"{seg} angle"] = tab[seg]
    return out


UNITS = {"moment": "N·m/kg", "power": "W/kg", "GRF": "BW", "angle": "deg"}


def curves(
    mech: Mechanism, stride, act: Actuators | None = None, start: float | None = None
) -> tuple[dict[str, Curve], float, float]:
    """Every compared curve, our heel strike (s) and our toe-off (s); ``start``: the heel strike, when
    not found from the right foot's vertical force (:func:`gait_events`)."""
    ours = our_series(mech, stride, act)
    t = stride.t
    hs, to = gait_events(t, stride.grf[:, 0, 1], stride.body_weight)
    hs = hs if start is None else float(start)
    w = winter_series()
    wt = winter.table()["t"]
    out = {}
    for key, w_y in w.items():
        wb = cycle_means(wt, w_y, wt[0], wt[-1] - wt[0])
        y = _angle_deg(ours[key], w_y) if key.endswith("angle") else ours[key]
        out[key] = Curve(key, UNITS[key.split()[-1]], cycle_means(t, y, hs, t[-1] - t[0]), wb)
    return out, hs, to


def double_hump(fy: np.ndarray) -> tuple[list[tuple[int, float]], tuple[int, float] | None]:
    """Over a stance ``fy`` (bins from heel strike to toe-off): the highest value of each half, the loading
    and the push-off hump (bin, value), and the lowest value between them; the humps alone and None when
    that lowest value is one of them (one hump, no valley between)."""
    x = np.asarray(fy, float)
    mid = len(x) // 2
    a, b = int(np.argmax(x[:mid])), mid + int(np.argmax(x[mid:]))
    v = a + int(np.argmin(x[a : b + 1]))
    humps = [(a, float(x[a])), (b, float(x[b]))]
    return humps, (None if v in (a, b) else (v, float(x[v])))


def _peak(label: str, x: np.ndarray) -> float:
    """``max |x|``, ``max x`` or ``min x`` (label ``|max|``, ``max``, ``min``)."""
    return float(np.max(np.abs(x)) if label == "|max|" else np.max(x) if label == "max" else np.min(x))


def peak_table(cs: dict[str, Curve], stance: tuple[float, float]) -> list[tuple[str, float, float]]:
    """``(name, ours, Winter's)`` of every comparable peak: max ``|moment|`` per phase, the positive and the
    negative power peaks per phase, and the ground force's extremes in stance (see :data:`COMPARABLE`)."""
    pct = (np.arange(BINS) + 0.5) * 100.0 / BINS
    phases = {"stance": (pct < stance[0], pct < stance[1]), "swing": (pct >= stance[0], pct >= stance[1])}
    out = []
    for key, c in cs.items():
        if key.endswith("angle"):
            continue
        scale = COMPARABLE * float(np.max(np.abs(c.winter)))
        for phase, (mo, mw) in phases.items():
            if key.endswith("GRF") and phase == "swing":
                continue
            for label in ("|max|",) if key.endswith("moment") else ("max", "min"):
                w, o = (_peak(label, x) for x in (c.winter[mw], c.ours[mo]))
                if (-w if label == "min" else w) >= max(scale, np.finfo(float).tiny):  # a min peak is negative
                    out.append((f"{key}, {phase}, {label}", o, w))
    return out


def rod_share(mech: Mechanism, stride, act: Actuators | None = None) -> tuple[float, float, float]:
    """``(share, rods' positive work J, all actuators' positive work J)`` over the stored stride."""
    act = actuators(mech, stride.tau) if act is None else act
    Pj, Pr, _ = powers(mech, act, stride.qd)
    wj, _ = work_terms(Pj, stride.t)
    wr, _ = work_terms(Pr, stride.t)
    total = float(wj.sum() + wr.sum())
    return (float(wr.sum()) / total if total > 0 else float("nan")), float(wr.sum()), total


def compare(mech: Mechanism, stride, start: float | None = None) -> Comparison:
    """The stride against Winter's: every curve, the comparable peaks, and the done-when verdicts
    (``start``: as :func:`curves`)."""
    act = actuators(mech, stride.tau)
    cs, hs, to = curves(mech, stride, act, start)
    T = stride.t[-1] - stride.t[0]
    tab = winter.table()
    w_stance = (
        100.0
        * (tab["t"][list(tab["frame"]).index(winter.STANCE_FRAMES[1])] - tab["t"][0])
        / (tab["t"][-1] - tab["t"][0])
    )
    stance = (100.0 * ((to - hs) % T) / T, float(w_stance))
    peaks = peak_table(cs, stance)
    return Comparison(cs, stance, hs, peaks, verdicts(mech, stride, cs, peaks, act, stance[0]))


def verdicts(mech, stride, cs: dict[str, Curve], peaks, act: Actuators, stance_end: float) -> list[Verdict]:
    """Issue 37's four done-when checks and whether the stance is a walking one (read with the ground
    force's humps), each with the numbers it rests on (``stance_end``: our
    toe-off, % of the cycle)."""
    out = []
    bad = [(n, o / w) for n, o, w in peaks if not (1 / FACTOR <= o / w <= FACTOR)]
    worst = ", ".join(f"{n}: {r:.2f}x" for n, r in sorted(bad, key=lambda p: abs(np.log(abs(p[1]) + 1e-300)))[::-1])
    out.append(
        Verdict(
            "every comparable peak within 2x of Winter's",
            not bad,
            f"ours / Winter's in [{1 / FACTOR:g}, {FACTOR:g}] for each of {len(peaks)} peaks",
            f"{len(peaks) - len(bad)} of {len(peaks)} within"
            + (f"; outside: {worst}; " + absorbed(mech, stride, cs) if bad else ""),
            short="peaks within 2x",
        )
    )
    fy = cs["vertical GRF"].ours
    hump, valley = double_hump(fy[: int(round(stance_end * BINS / 100.0))])
    ok = valley is not None and min(p for _, p in hump) >= GRF_PEAK and valley[1] <= GRF_VALLEY
    pk = ", ".join(f"{p:.2f} BW at {i + 0.5:.1f} %" for i, p in hump)
    measured = f"highest of each half of stance {pk}" + (
        f", valley {valley[1]:.2f} BW at {valley[0] + 0.5:.1f} %"
        if valley
        else " (no lower value between them: one hump)"
    )
    ds, (k, on) = double_support(stride), contacts(stride)
    measured += (
        f"; stance {stance_end:.1f} % of the cycle (the right foot's longest contact, bounces under {BOUNCE:.0%} of the cycle within; it touches the ground {k} "
        f"time(s), {on:.1f} % in all), double support {ds:.1f} % (Winter's {WINTER_DOUBLE_SUPPORT:.1f} %)"
    )
    if not ok:  # the knee's yield as the body is loaded shapes the humps: a stiff stance knee vaults
        ours, his = stance_knee_flexion(cs), stance_knee_flexion(cs, winters=True)
        measured += f"; stance knee yield in the first 30 % of the cycle: {ours:.1f} deg (Winter's {his:.1f} deg)"
    out.append(
        Verdict(
            "vertical GRF: two peaks >= 1.0 BW, valley <= 0.85 BW",
            ok,
            f"peaks >= {GRF_PEAK} BW, valley <= {GRF_VALLEY} BW",
            measured,
            short="GRF two humps",
        )
    )
    rs = {j: cs[f"{j} moment"].r for j in JOINTS}
    lags = {j: best_lag(cs[f"{j} moment"]) for j in JOINTS}
    measured = "; ".join(
        f"{j} r = {r:.2f}" + (f" (best r {lags[j][1]:.2f} shifted by {lags[j][0]:+d} %)" if not r >= R_MIN else "")
        for j, r in rs.items()
    )
    if not all(r >= R_MIN for r in rs.values()):  # where the floor pushes the foot decides the moments
        measured += f"; the right toe carries {toe_share(stride):.1%} of the right foot's vertical impulse"
    out.append(
        Verdict(
            "hip, knee and ankle moments correlate with Winter's",
            all(r >= R_MIN for r in rs.values()),
            f"r >= {R_MIN}",
            measured,
            short="moments r >= 0.7",
        )
    )
    out.append(
        Verdict(
            "a walking stance (not in issue 37's list; read with the GRF check)",
            stance_end > 50.0 and ds > 0.0,
            "stance > 50 % of the cycle, both feet down at once for a while",
            f"stance {stance_end:.1f} % (Winter's {WINTER_STANCE:.1f} %), double support {ds:.1f} % "
            f"(Winter's {WINTER_DOUBLE_SUPPORT:.1f} %)",
            short="walking stance",
        )
    )
    share, wr, total = rod_share(mech, stride, act)
    out.append(
        Verdict(
            f"rods' share of positive mechanical work ({stride.variant} variant)",
            share <= ROD_SHARE,
            f"<= {ROD_SHARE:.0%}",
            f"{share:.1%}: rods {wr:.1f} J of {total:.1f} J positive work per stride; " + rod_travel(mech, stride),
            short="rods <= 25 % of positive work",
        )
    )
    return out


def stance_knee_flexion(cs: dict[str, Curve], winters: bool = False) -> float:
    """The knee's yield as the body is loaded: the largest knee flexion (thigh angle - leg angle,
    degrees) in the first 30 % of the cycle minus the flexion at heel strike (bin means of the angles)."""
    thigh, leg = cs["thigh angle"], cs["leg angle"]
    flex = (thigh.winter - leg.winter) if winters else (thigh.ours - leg.ours)
    return float(np.max(flex[: int(0.3 * BINS)]) - flex[0])


def best_lag(c: Curve) -> tuple[int, float]:
    """``(shift in bins, r)``: the circular shift of our curve that correlates best with Winter's."""
    rs = [pearson(np.roll(c.ours, k), c.winter) for k in range(-BINS // 2, BINS // 2)]
    k = int(np.nanargmax(rs))
    return k - BINS // 2, float(rs[k])


__all__ = [
    "BINS",
    "Comparison",
    "Curve",
    "Verdict",
    "compare",
    "curves",
    "cycle_means",
    "double_hump",
    "gait_events",
    "pearson",
    "peak_table",
    "rms",
    "rod_share",
]
