"""Are a scene's loads those of walking? Peak joint moments and rod forces beside Winter's.

For every joint of the model: the peak ``|net joint moment|`` (``models.joint_loads``: the moment the
parent side exerts on the subtree, about the joint) per kg of the model's mass, its sagittal
component, and the peak rod force ``F_k`` (the reference method's tau) in body weights, each
beside the normative peak of the joint or segment it plays in level walking
(:data:`exo_bench.models.gait.normative.WINTER`, one subject). The joint a link's start plays is read from the
link's name (the presets of the exoskeleton: ``stance_shin``, ``stance_thigh``, ``swing_thigh``,
``swing_shin``, ``trunk``); other links get no normative value.

The text says where this five-rod point-mass model cannot match a real gait and why, with the
numbers of the scene's motion (:func:`limitations`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from exo_bench.bench.studies.study import Study
from exo_bench.models.mechanism.kinematics import net_joint_loads, point_mass_accelerations, sagittal_moments
from exo_bench.models.mechanism.kinematics import point_mass_positions
from exo_bench.models.states.states import split
from exo_bench.models.gait.normative import SHORT_SOURCE, SOURCE, WINTER, Normative

#: The joint at the start of a link of the exoskeleton, the normative key of its moment and of its
#: rod's force, and whether the comparison means something (see :func:`limitations`).
ROLES: dict[str, tuple[str, str | None, str | None, str]] = {
    "stance_shin": ("stance ankle (support point O)", "ankle, stance", "ankle, stance", "stance"),
    "stance_thigh": ("stance knee", "knee, stance", "knee, stance", "stance"),
    "swing_thigh": ("swing hip", "hip, swing", "hip, swing", "swing"),
    "swing_shin": ("swing knee", "knee, swing", "knee, swing", "swing"),
    "trunk": ("stance hip (trunk on the stance thigh)", "hip, stance", None, "stance"),
}
MEANING = {
    "stance": "no: periodic single support on a point foot (see below)",
    "swing": "order of magnitude: the swing leg hangs from a hip that rocks more than in walking",
}
ROD_MEANING = {
    "stance": "the axial load yes (the body weight and its vertical acceleration); the net joint force no: "
    "it includes the horizontal force that stops and reverses the body",
    "swing": "order of magnitude: the swing leg's weight and its swing",
}


@dataclass(frozen=True)
class JointRow:
    link: int  # 0-based
    joint: str
    sagittal: float  # peak |sagittal net joint moment|, N·m/kg
    magnitude: float  # peak |net joint moment| (all axes), N·m/kg
    normative: Normative | None
    meaning: str


@dataclass(frozen=True)
class RodRow:
    link: int
    rod: str
    force: float  # peak |F_k|, body weights
    joint_force: float  # peak |net joint force| at the rod's start, body weights
    normative: Normative | None
    meaning: str


@dataclass(frozen=True)
class Plausibility:
    body_mass: float
    weight: float  # N: the body weight, mass times the mechanism's g
    reference: str
    joints: tuple[JointRow, ...]
    rods: tuple[RodRow, ...]
    hip_travel: float | None  # m, forward range of the hip (branch point) over the motion
    com_acceleration: float  # m/s^2, peak horizontal acceleration of the centre of mass
    walker: bool  # the links are the exoskeleton's (stance and swing legs)


def _reference(study: Study) -> str | None:
    ok = study.ok_methods()
    return study.reference if study.reference in ok else (ok[0] if ok else None)


def _hip(mech) -> int | None:
    """The link whose end is the hip: the parent of the first reversed link hanging from a forward one."""
    for i in range(mech.nlinks):
        p = mech.parent[i]
        if mech.sign[i] < 0 and p >= 0 and mech.sign[p] > 0:
            return p
    return None


def plausibility(study: Study) -> Plausibility | None:
    """The peaks of the study's motion beside Winter's; None when no method produced tau."""
    ref = _reference(study)
    if ref is None:
        return None
    mech, mo = study.mechanism, study.motion
    mass, bw = mech.total_mass, mech.total_mass * mech.g
    M, F = net_joint_loads(mech, mo.q, mo.qd, mo.qdd)
    sag = np.abs(sagittal_moments(mech, M)).max(axis=0) / mass
    mag = (np.linalg.norm(M, axis=-1) if mech.dim == 3 else np.abs(M)).max(axis=0) / mass
    jf = np.linalg.norm(F, axis=-1).max(axis=0) / bw
    _, _, rod = split(mech, study.tau(ref))
    with np.errstate(invalid="ignore"):
        rod_peak = np.nanmax(np.abs(rod), axis=0) / bw
    joints, rods = [], []
    for i, name in enumerate(mech.names):
        role = ROLES.get(name)
        joint = role[0] if role else f"joint {i + 1} (start of {name})"
        jn = WINTER.moments[role[1]] if role and role[1] else None
        fn = WINTER.forces[role[2]] if role and role[2] else None
        joints.append(JointRow(i, joint, float(sag[i]), float(mag[i]), jn, MEANING[role[3]] if role else ""))
        rods.append(
            RodRow(
                i,
                f"F{i + 1} {name}",
                float(rod_peak[i]),
                float(jf[i]),
                fn,
                (ROD_MEANING[role[3]] if fn else "no counterpart in Winter's tables") if role else "",
            )
        )
    P = point_mass_positions(mech, mo.q)
    A = point_mass_accelerations(mech, mo.q, mo.qd, mo.qdd)
    a_com = np.einsum("ib,sibd->sd", mech.mass_array, A) / mass
    horizontal = np.linalg.norm(a_com[:, :-1], axis=-1)
    hip = _hip(mech)
    travel = float(np.ptp(P[:, hip, 2, 0])) if hip is not None else None
    walker = all(n in ROLES for n in mech.names[:4]) and mech.nlinks >= 4
    return Plausibility(mass, bw, ref, tuple(joints), tuple(rods), travel, float(horizontal.max()), walker)


def _ratio(value: float, norm: Normative | None) -> str:
    if norm is None or norm.value == 0:
        return ""
    return f"{value / norm.value:.1f}×"


def _row(name: str, peak: float, second: float, normative: Normative | None, ratio: str, comparable: str) -> str:
    norm = f"{normative.value:.2f} ({normative.where})" if normative else "—"
    return f"| {name} | {peak:.2f} | {second:.2f} | {norm} | {ratio} | {comparable} |"


def tables(
    p: Plausibility,
    joint_cells: Callable[[JointRow], tuple[str, str]],
    rod_cells: Callable[[RodRow], tuple[str, str]],
) -> list[str]:
    """The joints' and the rods' tables (Markdown lines); ``joint_cells(row)`` and ``rod_cells(row)`` give
    each row's last two cells, the model over the normative peak and whether they are comparable."""
    lines = [
        "| joint | peak sagittal moment (N·m/kg) | peak moment, all axes (N·m/kg) | normative peak (N·m/kg) "
        "| model / normative | comparable? |",
        "|---|---|---|---|---|---|",
    ]
    lines += [_row(r.joint, r.sagittal, r.magnitude, r.normative, *joint_cells(r)) for r in p.joints]
    lines += [
        "",
        "| rod | peak rod force, axial (BW) | peak net joint force at its start (BW) | normative peak joint "
        "force (BW) | net joint force / normative | comparable? |",
        "|---|---|---|---|---|---|",
    ]
    lines += [_row(rod.rod, rod.force, rod.joint_force, rod.normative, *rod_cells(rod)) for rod in p.rods]
    return lines


def bullets(p: Plausibility, ratio: Callable[[float, Normative], str]) -> list[str]:
    """The compact text's lines, one a joint and one a rod, each beside walking where it has a normative
    value (``ratio(value, normative)``: the model over the normative peak)."""
    lines = []
    for r in p.joints:
        norm = f", walking {r.normative.value:.2f} ({ratio(r.sagittal, r.normative)})" if r.normative else ""
        lines.append(f"- {r.joint}: {r.sagittal:.2f} N·m/kg sagittal{norm}")
    for rod in p.rods:
        norm = (
            (
                f"; net joint force {rod.joint_force:.2f} BW, walking {rod.normative.value:.2f} "
                f"({ratio(rod.joint_force, rod.normative)})"
            )
            if rod.normative
            else ""
        )
        lines.append(f"- {rod.rod}: {rod.force:.2f} BW along the rod{norm}")
    return lines


def limitations(p: Plausibility) -> list[str]:
    """Where this model cannot match a real gait, and why (with the scene's numbers)."""
    travel = f"{p.hip_travel:.2f} m" if p.hip_travel is not None else "far"
    return [
        "**No feet.** The stance leg stands on a point, O. In walking the centre of pressure rolls from "
        "heel to toe under a foot; here the whole body's moment about O is the stance ankle's moment.",
        "**No double support.** The swing leg never touches the floor, so the stance leg alone carries and "
        "accelerates the body for the whole period; in walking the next foot takes the load over.",
        f"**A periodic single-support phase.** Eq. (26) is symmetric in time about T/2: over the second half "
        f"period the motion runs back along the first. The hip moves {travel} forward and back over O and "
        f"the centre of mass accelerates horizontally by up to {p.com_acceleration:.1f} m/s², where in "
        f"walking it keeps moving forward (at {WINTER.speed.value} m/s in Winter's walk). Stopping and "
        "reversing the body about a point foot is what makes the stance ankle and knee moments several "
        "times Winter's: **those numbers are not comparable with walking**.",
        "**Meaningful**: the axial forces of the stance rods (the body weight and its vertical acceleration, "
        "about one body weight as the leg's load in walking) and the order of magnitude of the swing-leg loads.",
        f"Normative values: {SOURCE}; one subject ({WINTER.stride_time.value} s stride, "
        f"{WINTER.cadence:.1f} steps/min, {WINTER.speed.value} m/s), one stride: a factor of about 1.5 is "
        "within normal variation between people, several times is not.",
    ]


def markdown(p: Plausibility) -> str:
    """The scene report's section: two tables and the limitations."""
    lines = [
        "## Plausibility: the loads beside level walking",
        "",
        f"Peak net joint moments (the moment the parent side exerts on everything beyond the joint, "
        f"about the joint; `models/mechanism/kinematics.py`) per kg of the model's {p.body_mass:.4g} kg, and "
        f"peak rod forces ({p.reference}) in body weights (BW = {p.weight:.0f} N), beside the "
        f"normative peak of the joint each plays in level walking ({SHORT_SOURCE}).",
        "",
    ]
    lines += tables(
        p,
        lambda r: (_ratio(r.sagittal, r.normative), r.meaning or "—"),
        lambda rod: (_ratio(rod.joint_force, rod.normative), rod.meaning or "—"),
    )
    lines += [
        "",
        "The rod force is the actuator's force along the rod; the net joint force is the whole force the "
        "parent side exerts at the joint (its magnitude), like Winter's intersegmental force.",
    ]
    if p.walker:
        lines += ["", "Where this five-rod point-mass model cannot match a real gait:", ""]
        lines += [f"- {x}" for x in limitations(p)]
    else:
        lines += [
            "",
            "This mechanism's links are not the exoskeleton's stance and swing legs, so no joint has a "
            "normative value.",
        ]
    return "\n".join(lines) + "\n"


def text(p: Plausibility) -> str:
    """A compact version for the rerun recording's description (Markdown)."""
    lines = [
        f"Peak net joint moments (N·m/kg of {p.body_mass:.4g} kg) and rod forces (body weights)"
        + (f" beside level walking ({SHORT_SOURCE}):" if p.walker else ":"),
        "",
    ]
    lines += bullets(p, _ratio)
    if p.walker:
        lines += [
            "",
            "Not comparable with walking: the stance ankle and knee moments (no feet, no double support, "
            f"a periodic single-support phase: the hip moves {p.hip_travel:.2f} m forward and back over the "
            "support point). See the scene report for the reasons.",
        ]
    return "\n".join(lines)


__all__ = ["JointRow", "Plausibility", "RodRow", "bullets", "limitations", "markdown", "plausibility", "tables", "text"]
