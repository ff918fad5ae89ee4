"""The human model's actuators, their powers, and the stride objective's work and effort terms.

The 2D human's angles are absolute (:func:`exo_bench.models.mechanism.presets.human`), so a joint moment ``tau_j``
between a link and its reference (:func:`exo_bench.models.simulation.posture.joints`: hips against HAT, knees,
ankles, arches) enters the generalised forces as ``+tau_j`` on the link's angle and ``-tau_j`` on the
reference's: ``Q_angles = A tau_joints + r``. Solved from the leaves up (heel, foot, leg, thigh), every
joint moment is one of the angle rows; what the joints cannot supply is the residual ``r``: HAT's
angle (the sum of HAT's row and the hip moments) and the root's angle and length. A motion the model can
perform with its own actuators and the floor's forces has zero residuals; a collocation problem
constrains them to zero, and :func:`actuators` reports them, never hides them.

Powers: a joint's ``tau_j (w_link - w_reference)``, a rod's ``F_l dl/dt``; their sum plus the residuals'
powers is ``tau . qd`` exactly (tests/test_stride_actuators.py), which is ``d(T + Pi)/dt`` minus the
external forces' power. The objective prices positive and negative work separately
(:func:`work_terms`; with a smoothing power ``eps`` for a differentiable problem, ``|P| ~ sqrt(P^2 +
eps^2)``) and effort as the mean squared moment and force.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exo_bench.bench.studies.stride.coordinates import TELESCOPIC
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.simulation.posture import joints


#: The joints the objective prices (the arch is not an actuator: it holds the rigid foot).
PRICED_JOINTS = tuple(f"{s}_{j}" for s in ("right", "left") for j in ("hip", "knee", "ankle"))


@dataclass(frozen=True)
class Actuators:
    """Per sample: joint moments ``(S, joints)`` (N·m) with the joints' names, rod forces ``(S, rods)`` (N)
    of the rods named, and the residual generalised forces ``(S, 3)``: HAT's angle (N·m), the root's angle
    (N·m) and length (N)."""

    joint_names: tuple[str, ...]
    moments: np.ndarray
    rod_names: tuple[str, ...]
    forces: np.ndarray
    residuals: np.ndarray


def _joint_name(mech: Mechanism, link: int, kind: str) -> str:
    side, part = mech.names[link].split("_", 1)
    return f"{side}_" + {"thigh": "hip", "leg": "knee", "foot": "ankle", "heel": "arch"}[part]


def actuators(mech: Mechanism, tau: np.ndarray) -> Actuators:
    """Split generalised forces ``tau (S, dof)`` of the 2D human into joint moments, rod forces and residuals."""
    tau = np.atleast_2d(np.asarray(tau, dtype=float))
    n = mech.nlinks
    js = joints(mech)  # ValueError unless the 2D human
    left = tau[:, :n].copy()  # what the angles' rows still need
    moments = np.zeros((tau.shape[0], len(js)))
    for k in reversed(range(len(js))):  # heel, foot, leg, thigh per side: every link's own row is final
        link, ref, _ = js[k]
        moments[:, k] = left[:, link]
        left[:, link] = 0.0
        left[:, ref] += moments[:, k]
    hat, root = mech.names.index("hat"), mech.names.index("root")
    rods = [i for i in range(n) if i != root]
    residuals = np.stack([left[:, hat], left[:, root], tau[:, n + root]], axis=1)
    names = tuple(_joint_name(mech, link, kind) for link, _, kind in js)
    return Actuators(names, moments, tuple(mech.names[i] for i in rods), tau[:, n + np.array(rods)], residuals)


def powers(mech: Mechanism, act: Actuators, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(joint powers (S, joints), rod powers (S, rods), residual powers (S, 3))`` in watts at rates ``qd``."""
    qd = np.atleast_2d(qd)
    n = mech.nlinks
    js = joints(mech)
    rel = np.stack([qd[:, link] - qd[:, ref] for link, ref, _ in js], axis=1)
    rods = np.array([mech.names.index(r) for r in act.rod_names])
    hat, root = mech.names.index("hat"), mech.names.index("root")
    res_rates = np.stack([qd[:, hat], qd[:, root], qd[:, n + root]], axis=1)
    return act.moments * rel, act.forces * qd[:, n + rods], act.residuals * res_rates


def work_terms(power: np.ndarray, t: np.ndarray, eps: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Positive and negative work (J, both >= 0) of each actuator over ``t`` (trapezoidal rule) from its
    power ``(S, actuators)``: ``(P + |P|) / 2`` and ``(|P| - P) / 2``, with ``|P| ~ sqrt(P^2 + eps^2)`` when
    ``eps > 0`` (a differentiable objective; ``eps`` in watts, each term then overstates by at most
    ``eps / 2`` per second)."""
    a = np.sqrt(power**2 + eps**2) if eps > 0 else np.abs(power)
    return np.trapezoid((power + a) / 2, t, axis=0), np.trapezoid((a - power) / 2, t, axis=0)


def join_pairs(mech: Mechanism) -> list[tuple[list[int], list[int]]]:
    """For the priced joints' moments and the telescopic rods' forces: ``(a, b)`` index lists into a node's
    moments and rod forces, ``b`` the mirror image (right and left exchanged) of ``a``."""
    eye = actuators(mech, np.eye(mech.dof))
    swap = lambda n: n.replace("right_", "@").replace("left_", "right_").replace("@", "left_")  # noqa: E731
    out = []
    for names, chosen in ((eye.joint_names, PRICED_JOINTS), (eye.rod_names, TELESCOPIC)):
        out.append(([names.index(n) for n in chosen], [names.index(swap(n)) for n in chosen]))
    return out
