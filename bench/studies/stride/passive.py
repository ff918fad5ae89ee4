"""Passive joint moments of the stride problem: what ligaments, joint capsules and relaxed muscles give
at the hips, knees and ankles for free, so the objective prices only the rest (the active moment).

A joint's net moment ``M`` (what the model's inverse dynamics returns and Winter's tables hold) is the
passive moment ``M_p(theta, theta_dot)`` plus the active one; the objective prices the active moment's
work and effort (:mod:`~exo_bench.bench.studies.stride.transcription`). ``theta`` is the joint's angle as
the moment's power counts it (the distal link's angle minus the proximal's,
:func:`exo_bench.models.simulation.contact.joints`), so ``M_p theta_dot`` is the passive element's power.

Two elements (:class:`~exo_bench.bench.studies.stride.problem.StrideSettings`):

* ``passive="anderson-pandy"``: the end-range moments of Anderson and Pandy (2001, J Biomech Eng 123:
  381), in the form and with the coefficients of Falisse et al.'s 3dpredictsim
  (github.com/antoinefalisse/3dpredictsim, PassiveMoments/PassiveMomentsData.m and
  CasADiFunctions/CasADiFunctions_all.m, read at the source):
  ``M_p = k1 exp(k2 (x - x_max)) + k3 exp(k4 (x - x_min))`` in N·m with ``x`` OpenSim's coordinate
  (hip flexion, knee angle with flexion negative, ankle dorsiflexion; rad, zero standing). Their viscous
  term (``- d x_dot``, ``d`` a parameter there) is left out: its value is not in those files.
* ``spring=(hip, knee, ankle)``: a linear spring about the standing angle, ``- k m (theta - theta_0)``
  (``k`` in N·m/kg/rad, ``m`` body mass): a probe of what parallel elasticity would change, not a value
  from a checked source.
"""

from __future__ import annotations

from typing import Any

from exo_bench.models.states.validation import _finite, _is_number

#: Anderson and Pandy's coefficients as 3dpredictsim tables them: joint -> ((k1, k2, k3, k4), (x_min, x_max)).
ANDERSON_PANDY = {
    "hip": ((-2.44, 5.05, 1.51, -21.88), (-0.6981, 1.81)),
    "knee": ((-6.09, 33.94, 11.03, -11.33), (-2.4, 0.13)),
    "ankle": ((-2.03, 38.11, 0.18, -12.12), (-0.74, 0.52)),
}
PASSIVE = ("none", "anderson-pandy")


JOINTS = ("hip", "knee", "ankle")


def check_passive(value: Any, where: str = "stride: field 'passive'") -> str:
    """``value`` if it names a passive model of :data:`PASSIVE`; a ValueError ``where: expected ..., got ...``."""
    if not (isinstance(value, str) and value in PASSIVE):
        raise ValueError(f"{where}: expected one of {', '.join(PASSIVE)}, got {value!r}")
    return value


def check_spring(value: Any, where: str = "stride: field 'spring'") -> Any:
    """``value`` if it is three springs (hip, knee, ankle; N·m/kg/rad), each a finite number >= 0 (a
    negative one would push the joint away from standing: not a passive element); a ValueError naming
    the joint otherwise."""
    if not (isinstance(value, tuple | list) and len(value) == len(JOINTS)):
        raise ValueError(f"{where}: expected 3 springs (hip, knee, ankle; N·m/kg/rad), got {value!r}")
    for joint, k in zip(JOINTS, value):
        if not (_is_number(k) and _finite(k) and k >= 0):
            raise ValueError(f"{where} of the {joint}: expected a finite number >= 0 (N·m/kg/rad), got {k!r}")
    return value


def opensim_coordinate(joint: str, theta: Any, theta_0: float) -> Any:
    """OpenSim's coordinate of ``joint`` ("hip", "knee", "ankle") from ``theta`` (the model's joint angle,
    ``theta_0`` standing), each increasing with ``theta``, so a moment conjugate to one is conjugate to the
    other: hip flexion is ``theta`` (thigh minus HAT, 0 standing); the knee's ``theta`` (leg minus thigh)
    is minus its flexion, as OpenSim's knee angle; the ankle's dorsiflexion is ``theta - theta_0``."""
    return theta - theta_0 if joint == "ankle" else theta


def passive_moment(s: Any, joint: str, theta: Any, theta_0: float, mass: float, exp: Any) -> Any:
    """The passive moment (N·m, conjugate to ``theta``) of ``joint`` under settings ``s``; ``exp`` is the
    exponential of the array kind (numpy's or CasADi's), so one formula serves both."""
    out = 0.0 * theta
    if check_passive(getattr(s, "passive", "none")) == "anderson-pandy":
        (k1, k2, k3, k4), (lo, hi) = ANDERSON_PANDY[joint]
        x = opensim_coordinate(joint, theta, theta_0)
        out = out + (k1 * exp(k2 * (x - hi)) + k3 * exp(k4 * (x - lo)))
    k = dict(zip(JOINTS, getattr(s, "spring", (0.0, 0.0, 0.0))))[joint]
    return out - k * mass * (theta - theta_0) if k else out


__all__ = ["ANDERSON_PANDY", "JOINTS", "PASSIVE", "check_passive", "check_spring", "passive_moment"]
