"""Computed evidence beside the stride's verdicts (:mod:`.comparison`): how the feet meet the floor and
how far the telescopic rods move, from the stored stride alone (:mod:`~exo_bench.bench.studies.stride.data`)."""

from __future__ import annotations

import numpy as np

from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.gait.normative import HEEL_CONTACT, NEXT_HEEL_CONTACT, SINGLE_SUPPORT, TOE_OFF

#: A foot is on the ground while its vertical force exceeds this many body weights.
CONTACT_THRESHOLD = 0.02
#: Winter's double support, % of the stride: frames 28-36 and 62-70 of 28-97 (his left-foot events are
#: estimated by symmetry, :data:`exo_bench.models.gait.normative.SINGLE_SUPPORT`).
WINTER_DOUBLE_SUPPORT = (
    100.0 * ((SINGLE_SUPPORT[0] - HEEL_CONTACT) + (TOE_OFF - SINGLE_SUPPORT[1])) / (NEXT_HEEL_CONTACT - HEEL_CONTACT)
)


WINTER_STANCE = 100.0 * (TOE_OFF - HEEL_CONTACT) / (NEXT_HEEL_CONTACT - HEEL_CONTACT)


def double_support(stride) -> float:
    """% of the stride (time-weighted over the stored nodes' intervals, by their midpoints) in which both
    feet's vertical forces exceed :data:`CONTACT_THRESHOLD` body weights."""
    on = (stride.grf[:, :, 1] > CONTACT_THRESHOLD * stride.body_weight).all(axis=1)
    both = (on[1:] & on[:-1]) + 0.5 * (on[1:] ^ on[:-1])
    return float(100.0 * np.sum(both * np.diff(stride.t)) / (stride.t[-1] - stride.t[0]))


def contacts(stride, foot: int = 0) -> tuple[int, float]:
    """How many separate contacts a foot (0: right) makes over the periodic stride, and the % of the stride
    it is on the ground (vertical force above :data:`CONTACT_THRESHOLD` body weights; node midpoints)."""
    on = stride.grf[:-1, foot, 1] > CONTACT_THRESHOLD * stride.body_weight
    k = int(np.count_nonzero(on & ~np.roll(on, 1)))
    frac = (on.astype(float) + np.roll(on, -1)) / 2.0  # node k's interval [t_k, t_k+1]: 1 on both ends, 1/2 on one
    return k, float(100.0 * np.sum(frac * np.diff(stride.t)) / (stride.t[-1] - stride.t[0]))


def toe_share(stride) -> float:
    """The right toe's share of the right foot's vertical impulse over the stride (contact points in the
    order of :data:`exo_bench.bench.studies.stride.data.CONTACTS`: right heel, right toe, ...)."""
    heel, toe = (np.trapezoid(stride.contact[:, k, 1], stride.t) for k in (0, 1))
    return float(toe / (heel + toe)) if heel + toe > 0 else float("nan")


def floor_work(mech: Mechanism, stride) -> float:
    """The floor's work on the body over the stride (J; negative: absorbed), the contact forces times their
    points' velocities summed over the heels and toes (trapezoidal in time). Its Hertz part is elastic and
    returns what it stores over a periodic stride, so what is left is the contact's damping and friction:
    energy the body loses at the floor and the objective does not price."""
    from exo_bench.bench.studies.stride.data import contact_mask_order
    from exo_bench.models.mechanism.kinematics import point_mass_velocities

    v = point_mass_velocities(mech, stride.q, stride.qd)[:, contact_mask_order(mech), 2, :]
    return float(np.trapezoid(np.einsum("kpd,kpd->k", stride.contact, v), stride.t))


def negative_joint_work(curves: dict, period: tuple[float, float], mass: float) -> tuple[float, float]:
    """The hips', knees' and ankles' negative work per stride (J, both legs: twice the right leg's), ours and
    Winter's scaled to ``mass``, from the cycle's power curves (W/kg, bin means); ``period`` (ours, his) in s."""
    out = []
    for side, T in zip(("ours", "winter"), period):
        p = np.stack([getattr(curves[f"{j} power"], side) for j in ("hip", "knee", "ankle")])
        out.append(float(2.0 * mass * np.minimum(p, 0.0).sum() * T / p.shape[1]))
    return out[0], out[1]


def absorbed(mech: Mechanism, stride, cs: dict) -> str:
    """Where the stride's energy is absorbed, as text: at the floor (unpriced unless ``w_floor``) and by the
    hips, knees and ankles, beside Winter's joints at this body mass (``cs``: the compared curves)."""
    from exo_bench.bench.studies.stride import winter

    wt = winter.table()["t"]
    ours, his = negative_joint_work(cs, (stride.t[-1] - stride.t[0], float(wt[-1] - wt[0])), mech.total_mass)
    return (
        f"the floor's contact absorbs {-floor_work(mech, stride):.1f} J per stride (its damping and friction), "
        f"the hips, knees and ankles {-ours:.1f} J (Winter's, at this body mass, {-his:.1f} J)"
    )


def rod_travel(mech: Mechanism, stride) -> str:
    """The telescopic rods' largest length range over the stride (cm) and largest rate (m/s), as text."""
    rods = [mech.nlinks + mech.names.index(r) for r in stride.telescopic]
    if not rods:
        return "no telescopic rods"
    span = float(np.max(np.ptp(stride.q[:, rods], axis=0))) * 100.0
    rate = float(np.max(np.abs(stride.qd[:, rods])))
    return f"their length ranges over at most {span:.2f} cm, at rates up to {rate:.3g} m/s"


__all__ = [
    "absorbed",
    "CONTACT_THRESHOLD",
    "WINTER_DOUBLE_SUPPORT",
    "WINTER_STANCE",
    "contacts",
    "double_support",
    "floor_work",
    "negative_joint_work",
    "rod_travel",
    "toe_share",
]
