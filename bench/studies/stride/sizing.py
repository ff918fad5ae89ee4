"""The actuator-sizing table: what each joint motor and telescopic rod must deliver over a stride.

For every actuator of a stored stride (:mod:`exo_bench.bench.studies.stride.data`) — the joint motors at
the hips, knees and ankles (the arch is the foot's fixed shape, not an actuator) and the telescopic rods
(``meta["telescopic"]``: thighs and legs) — from the actuators' split of the optimiser's generalised
forces (:func:`exo_bench.bench.studies.stride.actuators.actuators`):

* peak ``|torque|`` (N·m) or ``|force|`` (N), and its RMS over the stride, ``sqrt(1/T int x^2 dt)``
  (trapezoidal, like every integral here);
* peak positive and peak negative power (W): a joint's ``tau (w_link - w_reference)``, a rod's ``F dl/dt``;
* energy per stride, positive and negative (J, both >= 0):
  :func:`exo_bench.bench.studies.stride.actuators.work_terms`, whose difference is the net work.

Each stride's row block carries its solve's wall time and iterations from the stored provenance
(``meta["solver"]``: summed over the stages of a staged solve, and what it started from when that was
another stored stride), measured on the host that solved it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exo_bench.bench.studies.stride.actuators import actuators, powers, work_terms
from exo_bench.models.mechanism.mechanism import Mechanism


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
