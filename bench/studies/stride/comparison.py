"""The stride against Winter's over the whole gait cycle: the comparable peaks and the done-when checks,
on the curves of :mod:`exo_bench.bench.studies.stride.cycle` (how the cycle is cut and resampled, the
quantities in Winter's convention, and the scale each RMS error is set beside).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exo_bench.bench.studies.stride import winter
from exo_bench.bench.studies.stride.actuators import Actuators, actuators, powers, work_terms
from exo_bench.bench.studies.stride.cycle import (
    BINS,
    BOUNCE,
    JOINTS,
    SEGMENTS,
    UNITS,
    Curve,
    curves,
    cycle_means,
    gait_events,
    our_series,
    pearson,
    rms,
    winter_series,
)
from exo_bench.models.mechanism.mechanism import Mechanism
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

#: A peak is comparable when within this factor of Winter's, either way.
FACTOR = 2.0
#: A phase's peak is compared only when Winter's is at least this fraction of the curve's largest absolute value
#: (smaller ones, such as the ankle moment in swing, are at the transcription's rounding).
COMPARABLE = 0.1
R_MIN, GRF_PEAK, GRF_VALLEY, ROD_SHARE = 0.7, 1.0, 0.85, 0.25


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
    "BOUNCE",
    "CONTACT_THRESHOLD",
    "COMPARABLE",
    "FACTOR",
    "JOINTS",
    "SEGMENTS",
    "UNITS",
    "Comparison",
    "Curve",
    "Verdict",
    "compare",
    "contacts",
    "curves",
    "cycle_means",
    "double_hump",
    "double_support",
    "gait_events",
    "our_series",
    "pearson",
    "peak_table",
    "rms",
    "rod_share",
    "rod_travel",
    "toe_share",
    "winter_series",
]
