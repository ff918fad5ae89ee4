"""Holding the human model's posture, and its ground contact, as controls for ``simulate``.

:func:`exo_bench.models.mechanism.presets.human` floats (a massless root rod places the hips), so it stands only
on its heels and toes (:mod:`exo_bench.models.simulation.contact`) and only if its joints hold. Its angles are
absolute, so a joint moment ``tau`` between a link and the link it turns against (its reference)
is the generalised force ``+tau`` on the link's angle and ``-tau`` on the reference's: internal, it
changes no total momentum. The joints of the 2D model: each hip (thigh against HAT: the pelvis is
part of HAT), knee (leg against thigh), ankle (foot against leg) and arch (heel against foot, the
foot's own stiffness). Every rod but the root's is held at its length by a rod force. The root's
angle and length carry no force: O holds nothing up.

:func:`hold` is a proportional-derivative hold of all of those about a reference posture, the plain
controller a standing test needs (not a model of muscles); :func:`ground_reaction` is the floor's force
at the heels and toes in the layout of ``f_ext``, for ``simulate(..., f_ext=...)`` and every method's
inverse and forward dynamics (:mod:`exo_bench.models.runtime.external_forces`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from exo_bench.models.simulation.contact import DEFAULT_CONTACT, ContactParameters, ground_forces
from exo_bench.models.mechanism.kinematics import point_mass_positions, point_mass_velocities
from exo_bench.models.mechanism.mechanism import Mechanism

Controls = Callable[[float, np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Gains:
    """Stiffness and damping of the hold: joints (N·m/rad, N·m·s/rad), the arch (the same units), and
    rods (N/m, N·s/m)."""

    joint: tuple[float, float] = (3000.0, 100.0)
    arch: tuple[float, float] = (1000.0, 5.0)
    rod: tuple[float, float] = (2e5, 2e3)


def joints(mech: Mechanism) -> list[tuple[int, int, str]]:
    """``(link, reference, kind)`` of every joint of :func:`exo_bench.models.mechanism.presets.human`."""
    ix = {name: i for i, name in enumerate(mech.names)}
    if mech.dim != 2 or not {"root", "hat", "right_heel", "left_heel"} <= set(ix):
        raise ValueError(f"posture: mechanism {mech.name!r}: expected the 2D human preset (presets.human(2))")
    out = []
    for side in ("right", "left"):
        out += [(ix[f"{side}_thigh"], ix["hat"], "joint"), (ix[f"{side}_leg"], ix[f"{side}_thigh"], "joint")]
        out += [(ix[f"{side}_foot"], ix[f"{side}_leg"], "joint"), (ix[f"{side}_heel"], ix[f"{side}_foot"], "arch")]
    return out


def contact_points(mech: Mechanism) -> np.ndarray:
    """The mask ``(links, 3)`` of the heels' and toes' contact points (the end masses of the heel and foot rods)."""
    mask = np.zeros((mech.nlinks, 3), dtype=bool)
    for i, name in enumerate(mech.names):
        if name.endswith(("_heel", "_foot")):
            mask[i, 2] = True
    return mask


def hold(mech: Mechanism, q_ref: np.ndarray, gains: Gains = Gains()) -> Controls:
    """Controls holding every joint angle and rod length of the 2D human at those of ``q_ref (1, dof)``."""
    n = mech.nlinks
    js = joints(mech)
    q_ref = np.asarray(q_ref, dtype=float).reshape(1, -1)
    rods = np.array([i for i in range(n) if mech.names[i] != "root"])
    kp_l, kd_l = gains.rod

    def controls(t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        tau = np.zeros_like(q)
        for i, r, kind in js:
            kp, kd = gains.joint if kind == "joint" else gains.arch
            m = -kp * ((q[:, i] - q[:, r]) - (q_ref[:, i] - q_ref[:, r])) - kd * (qd[:, i] - qd[:, r])
            tau[:, i] += m
            tau[:, r] -= m
        tau[:, n + rods] = -kp_l * (q[:, n + rods] - q_ref[:, n + rods]) - kd_l * qd[:, n + rods]
        return tau

    return controls


def ground_reaction(mech: Mechanism, q: np.ndarray, qd: np.ndarray, params: ContactParameters = DEFAULT_CONTACT):
    """The floor's forces on the heels and toes in the layout of ``f_ext``, ``(samples, links, 3, dim)``."""
    return ground_forces(
        point_mass_positions(mech, q), point_mass_velocities(mech, q, qd), contact_points(mech), params
    )


def centre_of_mass(mech: Mechanism, q: np.ndarray) -> np.ndarray:
    """The whole body's centre of mass, ``(samples, dim)``."""
    w = mech.mass_array / mech.total_mass
    return np.einsum("lk,slkd->sd", w, point_mass_positions(mech, q))


def balanced_standing(mech: Mechanism, stature: float = 1.75) -> np.ndarray:
    """:func:`exo_bench.models.mechanism.presets.human_standing` leaning forward about the ankles until the centre of
    mass is above the middle of the heel and toe contact points (upright, it is above the ankles, 5 cm
    from the heels: on soft contact the body then rocks back onto its heels and falls; people stand
    leaning a few degrees forward). Secant iterations on the lean; the centre of mass's horizontal
    position is nearly linear in it, so three suffice to 1e-12 m."""
    from exo_bench.models.mechanism.presets import human_standing

    mask = contact_points(mech)

    def offset(lean: float) -> float:
        q = human_standing(mech, stature, lean)
        feet = point_mass_positions(mech, q)[0][mask][:, 0]
        return float(centre_of_mass(mech, q)[0, 0] - 0.5 * (feet.min() + feet.max()))

    a, b = 0.0, 0.05
    fa, fb = offset(a), offset(b)
    for _ in range(8):
        if fb == fa or abs(fb) < 1e-13:
            break
        a, b, fa = b, b - fb * (b - a) / (fb - fa), fb
        fb = offset(b)
    return human_standing(mech, stature, b)
