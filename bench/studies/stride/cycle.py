"""A stride over its gait cycle beside Winter's: the cycle cut at the right heel strike, resampled into
bins, and every compared quantity as a :class:`Curve` (ours and Winter's, with r and RMS error).
:mod:`exo_bench.bench.studies.stride.comparison` compares them (the peaks, the done-when checks).

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
(:func:`exo_bench.models.mechanism.presets.human`: the vector from the distal to the proximal joint).

**Scale.** Each curve's RMS error is set beside Winter's own RMS over the cycle (a segment angle's about
its mean, so the scale is the angle's swing, not its offset from +x): the transcription is one subject,
with no inter-subject spread to compare with.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exo_bench.bench.studies.stride import winter
from exo_bench.bench.studies.stride.actuators import Actuators, actuators, powers
from exo_bench.bench.studies.stride.evidence import CONTACT_THRESHOLD
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.gait.normative import G

BINS = 100
#: A lift of the foot shorter than this fraction of the cycle (5 %: 49 ms in Winter's stride) is a bounce
#: within one stance, not a toe-off and a heel strike.
BOUNCE = 0.05
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
