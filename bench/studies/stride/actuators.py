"""The human model's actuators, their powers, the stride objective's work and effort terms, and what each
actuator must deliver over a stride (:func:`sizing`, the report's actuator-sizing table).

The 2D human's angles are absolute (:func:`exo_bench.models.mechanism.presets.human`), so a joint moment ``tau_j``
between a link and its reference (:func:`exo_bench.models.simulation.contact.joints`: hips against HAT, knees,
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
from exo_bench.models.simulation.contact import joints


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


# The actuator-sizing table: what each joint motor and telescopic rod must deliver over a stride.


@dataclass(frozen=True)
class Row:
    """One actuator over one stride (units: N·m and W for a joint motor, N and W for a rod)."""

    actuator: str
    kind: str  # "joint motor" or "telescopic rod"
    unit: str  # of peak and rms: "N·m" or "N"
    peak: float
    rms: float
    power_max: float
    power_min: float
    energy_positive: float
    energy_negative: float


@dataclass(frozen=True)
class Sizing:
    """The sizing rows of one stored stride, and how it was solved."""

    variant: str
    speed: float
    period: float
    solve_seconds: float | None
    iterations: int | None  # over every stage of the solve
    rows: list[Row]
    stages: int = 1
    start: str = ""  # what the solve started from, when another stored stride


def time_rms(x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """``sqrt(1/T int x^2 dt)`` per column of ``x (K, ...)`` (trapezoidal)."""
    return np.sqrt(np.trapezoid(np.square(x), t, axis=0) / (t[-1] - t[0]))


def _rows(kind: str, unit: str, names, load: np.ndarray, power: np.ndarray, t: np.ndarray) -> list[Row]:
    pos, neg = work_terms(power, t)
    rms = time_rms(load, t)
    return [
        Row(
            name,
            kind,
            unit,
            float(np.max(np.abs(load[:, k]))),
            float(rms[k]),
            float(np.max(power[:, k])),
            float(np.min(power[:, k])),
            float(pos[k]),
            float(neg[k]),
        )
        for k, name in enumerate(names)
    ]


def sizing(mech: Mechanism, stride) -> Sizing:
    """The sizing rows of ``stride`` (a :class:`exo_bench.bench.studies.stride.data.StoredStride`)."""
    act = actuators(mech, stride.tau)
    Pj, Pr, _ = powers(mech, act, stride.qd)
    motors = [k for k, n in enumerate(act.joint_names) if not n.endswith("_arch")]
    rods = [k for k, n in enumerate(act.rod_names) if n in stride.telescopic]
    t = stride.t
    rows = _rows("joint motor", "N·m", [act.joint_names[k] for k in motors], act.moments[:, motors], Pj[:, motors], t)
    rows += _rows("telescopic rod", "N", [act.rod_names[k] for k in rods], act.forces[:, rods], Pr[:, rods], t)
    solver = stride.solver
    stages = solver.get("stages") or [solver]  # a staged solve stores each stage's iterations
    its = [st.get("iterations") for st in stages]
    seconds = solver.get("solve_seconds")
    start = solver.get("start")
    return Sizing(
        stride.variant,
        stride.speed,
        stride.period,
        None if seconds is None else float(seconds),
        None if None in its else int(sum(its)),
        rows,
        len(stages),
        f"the stored {start.get('variant')} stride at {start.get('speed')} m/s" if isinstance(start, dict) else "",
    )


__all__ = ["Row", "Sizing", "sizing", "time_rms"]
