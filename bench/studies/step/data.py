"""The stored step: reading and writing it, its constraints re-evaluated in numpy, and the walk it makes.

A stored step is ``bench/studies/step/data/<mechanism>-step.npz`` with the collocation points (``t``, ``q``,
``qd``, ``qdd``), the optimiser's loads there (``tau`` from the equations' CasADi export, net joint
``moments`` and ``forces``) and a JSON ``meta`` entry: the problem's settings
(:class:`exo_bench.bench.studies.step.problem.StepSettings`) and the provenance (commit, date, CasADi version, IPOPT's
status, iterations, constraint violation as IPOPT saw it, solve time on the host that solved it).

:func:`violations` re-evaluates every constraint from the stored arrays with numpy and the project's own
kinematics (:mod:`exo_bench.models.kinematics`) and joint loads (:mod:`exo_bench.models.joint_loads`): nothing of the
optimiser is reused, so a wrong store or a wrong CasADi model shows up there.

:func:`walking_motion` is one or more steps as a motion for a scene: each step after the first is the
stored one again (the leg swap relabels the links, so link 1 is always the stance shin; in 3D the other
leg is the mirror image, azimuths negated), with the support point moved to the new foot.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from exo_bench.bench.studies.step.problem import DEG, StepSettings, angle_rows, swap_matrix  # noqa: F401
from exo_bench.models.joint_loads import net_joint_loads
from exo_bench.models.kinematics import point_mass_positions, point_mass_velocities
from exo_bench.models.mechanism import Mechanism
from exo_bench.models.motion import Motion

DATA = Path(__file__).resolve().parent / "data"
#: ``exo-bench gait --solve`` reproduces the stored step when the duration and every coordinate at every
#: collocation point agree to this (s, rad, m): IPOPT stops at a relative optimality of 1e-8, and the
#: same problem from the same start on another machine takes other roundings on its way there.
REPRODUCE_TOL = 1e-6


@dataclass(frozen=True)
class StoredStep:
    mechanism: str
    settings: StepSettings
    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray
    moments: np.ndarray
    forces: np.ndarray
    meta: dict

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    @property
    def step_length(self) -> float:
        return self.settings.speed * self.duration


@dataclass(frozen=True)
class WalkingMotion(Motion):
    """A motion whose support point moves: ``origin (S, dim)`` is where O (the stance foot) stands."""

    origin: np.ndarray = None


def path_of(mechanism: str) -> Path:
    return DATA / f"{mechanism}-step.npz"


def save(solution, mech: Mechanism, path: Path | None = None, provenance: dict | None = None) -> Path:
    """Write a :class:`exo_bench.bench.studies.step.problem.Solution` (atomically)."""
    from exo_bench.bench.output.provenance import atomic_path

    path = Path(path) if path is not None else path_of(mech.name)
    meta = {
        "mechanism": mech.name,
        "settings": solution.settings.to_dict(),
        "solver": solution.stats,
        **(provenance or {}),
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            np.savez_compressed(
                f,
                t=solution.t,
                q=solution.q,
                qd=solution.qd,
                qdd=solution.qdd,
                tau=solution.tau,
                moments=solution.moments,
                forces=solution.forces,
                meta=np.array(json.dumps(meta)),
            )
    return path


def load(mechanism: str | Path) -> StoredStep:
    """The stored step of a mechanism name (``exo5-3d``) or an ``.npz`` path."""
    p = Path(mechanism) if str(mechanism).endswith(".npz") else path_of(str(mechanism))
    if not p.exists():
        known = ", ".join(sorted(x.name.removesuffix("-step.npz") for x in DATA.glob("*-step.npz")))
        raise ValueError(
            f"step: no stored step {str(mechanism)!r} (stored: {known or 'none'}; "
            "solve one with exo-bench gait --solve)"
        )
    with np.load(p, allow_pickle=False) as z:
        meta = json.loads(str(z["meta"]))
        arrays = {
            k: np.ascontiguousarray(z[k], dtype=float) for k in ("t", "q", "qd", "qdd", "tau", "moments", "forces")
        }
    return StoredStep(meta["mechanism"], StepSettings.from_dict(meta["settings"]), meta=meta, **arrays)


# ----------------------------------------------------------------------------- constraints in numpy
def _excess(x: np.ndarray) -> float:
    """The largest positive entry (0 when none): the violation of ``x <= 0``."""
    x = np.asarray(x, dtype=float)
    return float(max(x.max(initial=0.0), 0.0))


def violations(step: StoredStep, mech: Mechanism) -> dict[str, float]:
    """Every constraint of the problem, re-evaluated from the stored arrays: name -> largest violation
    (m, rad, s, N; 0 when met)."""
    s = step.settings
    q, qd, qdd, t = step.q, step.qd, step.qdd, step.t
    K, n, dim = len(t), mech.nlinks, mech.dim
    N = (K - 1) // 2
    h = step.duration / N
    e, m_, o = slice(0, K - 1, 2), slice(1, K, 2), slice(2, K, 2)
    out = {}
    out["grid (equal intervals)"] = float(np.abs(t - np.linspace(0, step.duration, K)).max())
    out["Hermite-Simpson: midpoint positions"] = float(
        np.abs(q[m_] - (q[e] + q[o]) / 2 - h / 8 * (qd[e] - qd[o])).max()
    )
    out["Hermite-Simpson: midpoint rates"] = float(
        np.abs(qd[m_] - (qd[e] + qd[o]) / 2 - h / 8 * (qdd[e] - qdd[o])).max()
    )
    out["Hermite-Simpson: positions (Simpson)"] = float(
        np.abs(q[o] - q[e] - h / 6 * (qd[e] + 4 * qd[m_] + qd[o])).max()
    )
    out["Hermite-Simpson: rates (Simpson)"] = float(
        np.abs(qd[o] - qd[e] - h / 6 * (qdd[e] + 4 * qdd[m_] + qdd[o])).max()
    )
    S = swap_matrix(mech)
    out["leg swap: coordinates"] = float(np.abs(q[0] - S @ q[-1]).max())
    out["leg swap: rates"] = float(np.abs(qd[0] - S @ qd[-1]).max())
    P = point_mass_positions(mech, q)
    V = point_mass_velocities(mech, q, qd)
    target = np.zeros(dim)
    target[0] = s.speed * step.duration
    out["landing point (one step length ahead)"] = float(np.abs(P[-1, 3, 2] - target).max())
    out["landing velocity (no impact)"] = float(np.abs(V[-1, 3, 2]).max())
    lo, hi = int(round(s.window * 2 * N)), int(round((1 - s.window) * 2 * N))
    z = P[:, 2:4, :, -1].reshape(K, 6)  # the swing leg's six point masses, height
    out["swing leg above the floor"] = _excess(-z[1 : K - 1])
    out[f"swing-leg clearance >= {s.clearance * 100:g} cm"] = _excess(s.clearance - z[lo : hi + 1])
    out["hip moves forward"] = _excess(-V[:, 1, 2, 0])
    _, F = net_joint_loads(mech, q, qd, qdd)
    bw = mech.total_mass * mech.g
    Fz, Fh = F[:, 0, -1], (np.abs(F[:, 0, 0]) if dim == 2 else np.hypot(F[:, 0, 0], F[:, 0, 1]))
    out["ground reaction pushes"] = _excess(s.min_support * bw - Fz)
    out["ground reaction in the friction cone"] = _excess(Fh - s.friction * Fz)
    th = q[:, angle_rows(mech)]
    rng = lambda x, lo_, hi_: _excess(np.concatenate([lo_ - x, x - hi_]))
    out["knee ranges (no hyperextension)"] = max(rng(th[:, 1] - th[:, 0], *s.knee), rng(th[:, 2] - th[:, 3], *s.knee))
    out["hip ranges"] = max(rng(th[:, 2] - th[:, 4], *s.hip), rng(th[:, 1] - th[:, 4], *s.hip))
    out["segment angles"] = max(rng(th[:, i], *s.segment) for i in range(4))
    out["trunk angle"] = rng(th[:, 4], *s.trunk)
    a, b, l5 = s.rest_lengths
    rest = np.array([a, b, b, a, l5])
    out["rod strokes"] = rng(q[:, -n:] - rest, -s.stroke, s.stroke)
    out["duration range"] = rng(np.array([step.duration]), *s.duration)
    if dim == 3:
        out["azimuths"] = _excess(np.abs(q[:, :n]) - s.azimuth)
    return out


def hip_path(step: StoredStep, mech: Mechanism) -> np.ndarray:
    """The hip (end of link 2) over the step, relative to O: ``(K, dim)``."""
    return point_mass_positions(mech, step.q)[:, 1, 2]


def lowest_swing_mass(step: StoredStep, mech: Mechanism) -> np.ndarray:
    """Height of the lowest swing-leg point mass at every collocation point, ``(K,)``."""
    P = point_mass_positions(mech, step.q)
    return P[:, 2:4, :, -1].reshape(len(step.t), 6).min(axis=1)


def walking_motion(step: StoredStep, mech: Mechanism, steps: int = 2) -> WalkingMotion:
    """``steps`` consecutive steps as one motion (the sample at each swap is not repeated: the state
    there is the same instant in other labels). Each step after the first is the stored one mirrored
    (3D azimuths negated) with O moved one step length forward (and, in 3D, the lateral foot position
    mirrored: it is 0, the step is sagittal)."""
    if steps < 1:
        raise ValueError(f"step: field 'steps': expected >= 1, got {steps}")
    ts, qs, qds, qdds, origins = [], [], [], [], []
    mirror = np.ones(mech.dof)
    if mech.dim == 3:
        mirror[: mech.nlinks] = -1.0
    foot = point_mass_positions(mech, step.q[-1:])[0, 3, 2]
    O = np.zeros(mech.dim)
    for k in range(steps):
        sl = slice(0, None) if k == 0 else slice(1, None)
        sign = mirror if k % 2 else np.ones(mech.dof)
        ts.append(step.t[sl] + k * step.duration)
        qs.append(step.q[sl] * sign)
        qds.append(step.qd[sl] * sign)
        qdds.append(step.qdd[sl] * sign)
        origins.append(np.tile(O, (len(ts[-1]), 1)))
        land = foot.copy()
        if mech.dim == 3 and k % 2:
            land[1] = -land[1]
        O = O + land
    return WalkingMotion(
        np.concatenate(ts),
        np.concatenate(qs),
        np.concatenate(qds),
        np.concatenate(qdds),
        origin=np.concatenate(origins),
    )


__all__ = [
    "DATA",
    "REPRODUCE_TOL",
    "StoredStep",
    "WalkingMotion",
    "hip_path",
    "load",
    "lowest_swing_mass",
    "path_of",
    "save",
    "violations",
    "walking_motion",
]
