"""The stored step: reading and writing it, its constraints re-evaluated in numpy, and the walk it makes.

A stored step is ``bench/studies/step/data/<file_stem(mechanism name)>-step.npz`` (:func:`path_of`: the name
is a key, never a path) with the collocation points (``t``, ``q``,
``qd``, ``qdd``), the optimiser's loads there (``tau`` from the equations' CasADi export, net joint
``moments`` and ``forces``) and a JSON ``meta`` entry: the problem's settings
(:class:`exo_bench.bench.studies.step.problem.StepSettings`) and the provenance (commit, date, CasADi version, IPOPT's
status, iterations, constraint violation as IPOPT saw it, solve time on the host that solved it), and the
mechanism it was solved for, with its digest: :func:`load` reuses it only for an equal mechanism
(:mod:`exo_bench.bench.studies.step.identity`).

:func:`violations` re-evaluates every constraint from the stored arrays with numpy and the project's own
kinematics (:mod:`exo_bench.models.mechanism.kinematics`) and joint loads (:mod:`exo_bench.models.mechanism.kinematics`): nothing of the
optimiser is reused, so a wrong store or a wrong CasADi model shows up there.

:func:`walking_motion` is one or more steps as a motion for a scene: each step after the first is the
stored one again (the leg swap relabels the links, so link 1 is always the stance shin; in 3D the other
leg is the mirror image, azimuths negated), with the support point moved to the new foot.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from exo_bench.bench.studies.step import identity
from exo_bench.bench.studies.step.problem import DEG, StepSettings, angle_rows, swap_matrix  # noqa: F401
from exo_bench.models.mechanism.kinematics import net_joint_loads
from exo_bench.models.mechanism.kinematics import point_mass_positions, point_mass_velocities
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.gait.motion import Motion
from exo_bench.models.files import check_name, file_stem

DATA = Path(__file__).resolve().parent / "data"
#: IPOPT's ``tol`` the stored steps are solved with (their ``settings.tol``), and so re-solved with by
#: ``exo-bench gait --solve``: the error model of :data:`REPRODUCE_TOL` holds for it.
SOLVE_TOL = 1e-12

#: ``exo-bench gait --solve`` reproduces the stored step when the duration and every coordinate at every
#: collocation point agree to this (s, rad, m).
#:
#: Error model. IPOPT stops at a scaled KKT error ``tol`` (``constr_viol_tol`` 1e-10), not at the optimum
#: x*: its distance from x* is what the conditioning of the KKT system at x* makes of that error, measured
#: here rather than computed (issue 36, exo5-2d and exo5-3d, max ``|dq|`` of a solve at ``tol`` against one at
#: 1e-12, itself about 1e-8 from x* by the model below): ``tol`` 1e-8: 7.5e-7 (2D), 9.7e-7 (3D); 1e-10:
#: 1.3e-7 (both). 100x
#: tighter moves it only about 6x: ``|x(tol) - x*| ~ C sqrt(tol)`` with C about 1e-2, as for an interior
#: point method at a solution where some constraint is weakly active (complementarity without strict
#: complementarity), and the free ``qdd`` (regularised by ``w_accel`` 1e-5 only) moves 1e3-1e4x more.
#: A 2D solve at 1e-8 from a start perturbed by 1e-9 (seeded) landed 1.03e-6 from x*. So two solves at
#: 1e-8 from different roundings may differ by up to twice 1e-6: the stored steps
#: solved at 1e-8 were 8.5e-7 (2D) and 1.4e-6 (3D) from x*, and a re-solve at 1e-8 landed 1.5e-7 to
#: 9.5e-7 from the 2D one: the old tolerance of 1e-6 could fail on another machine.
#:
#: Hence the steps are stored from a solve at :data:`SOLVE_TOL` = 1e-12 and re-solved at it (3-5
#: iterations more than at 1e-8): C sqrt(1e-12) is about 1e-8. Measured: a re-solve from starts
#: perturbed by 1e-9 (relative, seeded: other roundings, other paths) lands 2.4e-11, 2.0e-10 and 6.4e-10
#: (2D, 3 seeds), 1.9e-10 and 2.2e-10 (3D, 2 seeds) from the stored step, ``|dT|`` <= 4.1e-11 s; unperturbed,
#: on this host, 0. The bound, with the model's ~1e-8 for each of the two solves and a factor of 50 for
#: what a machine's roundings may do beyond the seeded ones, is 1e-6: about 1500x the largest measured
#: distance. It is checked only on T and q (qd and qdd are less
#: well determined: see above).
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
    path: str = ""  # the file it was read from

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    @property
    def step_length(self) -> float:
        return self.settings.speed * self.duration

    @property
    def file_name(self) -> str:
        """The stored file's name (in the data folder)."""
        return Path(self.path).name if self.path else f"{file_stem(self.mechanism)}-step.npz"


@dataclass(frozen=True)
class WalkingMotion(Motion):
    """A motion whose support point moves: ``origin (S, dim)`` is where O (the stance foot) stands."""

    origin: np.ndarray = field(kw_only=True)


def path_of(name: str, folder: Path | None = None) -> Path:
    """Where the step of the mechanism named ``name`` is stored: ``<folder>/<file_stem(name)>-step.npz``,
    ``folder`` the package's data folder by default. The name is a key, never a path: it goes through
    :func:`exo_bench.models.files.file_stem` (no separator, no ``..``, no leading dot), so the file is
    always inside ``folder``; a name that is not an acceptable name (:func:`exo_bench.models.files.check_name`:
    NUL and other control characters, ...) is refused."""
    check_name(name, "step: field 'mechanism.name'")
    folder = DATA if folder is None else Path(folder)
    return folder / f"{file_stem(name)}-step.npz"


def save(solution, mech: Mechanism, folder: Path | None = None, provenance: dict | None = None) -> Path:
    """Write a :class:`exo_bench.bench.studies.step.problem.Solution` of ``mech`` (atomically) as the stored
    step of its name in ``folder`` (the package's data folder by default), with the mechanism's definition
    and digest (:mod:`exo_bench.bench.studies.step.identity`): it is reused only for an equal mechanism."""
    from exo_bench.bench.output.provenance import atomic_path

    path = path_of(mech.name, folder)
    meta = {
        **identity.stored_identity(mech),
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


_ARRAYS = ("t", "q", "qd", "qdd", "tau", "moments", "forces")


def _read(path: Path) -> tuple[dict, dict[str, np.ndarray]]:
    """The meta (a JSON object) and the arrays of a stored step; a ValueError naming the file."""
    return read_stored(path, _ARRAYS, "step")


def read_stored(path: Path, names: tuple[str, ...], what: str) -> tuple[dict, dict[str, np.ndarray]]:
    """The JSON ``meta`` (an object with ``settings``) and the float arrays ``names`` of a stored ``what``
    (a step, a stride: bench/studies/stride/data.py reads its files with it), without pickle; a
    one-line ValueError naming the file otherwise."""
    try:
        with np.load(path, allow_pickle=False) as z:
            missing = [k for k in (*names, "meta") if k not in z.files]
            meta = None if missing else json.loads(str(z["meta"]))
            raw = {} if missing else {k: z[k] for k in names}
            dtypes = {k: a.dtype for k, a in raw.items()}  # not "0.3" nor 1+1j read as numbers:
            arrays = {k: np.ascontiguousarray(a, dtype=float) for k, a in raw.items() if a.dtype.kind in "iuf"}
    except (OSError, EOFError, KeyError, TypeError, ValueError, zipfile.BadZipFile) as e:
        raise ValueError(f"{what}: {path}: not a readable stored {what} ({type(e).__name__}: {e})") from None
    if missing:
        raise ValueError(f"{what}: {path}: expected the arrays {', '.join(names)} and meta, missing {missing}")
    for k in names:
        if k not in arrays:
            raise ValueError(f"{what}: {path}: field {k!r}: expected an array of real numbers, got dtype {dtypes[k]}")
    if not isinstance(meta, dict) or not isinstance(meta.get("settings"), dict):
        raise ValueError(f"{what}: {path}: field 'meta': expected an object with 'settings', got {type(meta).__name__}")
    return meta, arrays


def load(mechanism: Mechanism | str, folder: Path | None = None) -> StoredStep:
    """The stored step of ``mechanism`` (a :class:`exo_bench.models.mechanism.mechanism.Mechanism`, or a preset's
    name: ``exo5-3d``), looked up by its name in ``folder`` (the package's data folder by default,
    :func:`path_of`) and reused only if it was solved for an equal mechanism
    (:func:`exo_bench.bench.studies.step.identity.check_same`); else a one-line ValueError."""
    if isinstance(mechanism, str):
        from exo_bench.models.mechanism.presets import PRESETS

        if mechanism not in PRESETS:
            raise ValueError(f"step: field 'mechanism': expected a Mechanism or a preset name, got {mechanism!r}")
        mechanism = PRESETS[mechanism]()
    mech = mechanism
    p = path_of(mech.name, folder)
    if not p.is_file():
        known = ", ".join(sorted(x.name.removesuffix("-step.npz") for x in p.parent.glob("*-step.npz")))
        raise ValueError(
            f"step: no stored step for mechanism {mech.name!r} (looked for {p.name} in {p.parent}; stored: "
            f"{known or 'none'}); {identity.HOW_TO_SOLVE}"
        )
    meta, arrays = _read(p)
    identity.check_same(meta, mech, str(p))
    K = arrays["t"].shape
    shapes = {k: arrays[k].shape for k in ("q", "qd", "qdd", "tau")}
    if len(K) != 1 or any(s != (K[0], mech.dof) for s in shapes.values()):
        raise ValueError(f"step: {p}: expected t of (K,) and q, qd, qdd, tau of (K, {mech.dof}), got {K}, {shapes}")
    try:
        settings = StepSettings.from_dict(meta["settings"])
    except TypeError as e:
        raise ValueError(f"step: {p}: field 'meta.settings': {e}") from None
    return StoredStep(str(meta.get("mechanism", mech.name)), settings, meta=meta, path=str(p), **arrays)


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
    "SOLVE_TOL",
    "StoredStep",
    "WalkingMotion",
    "hip_path",
    "load",
    "lowest_swing_mass",
    "path_of",
    "read_stored",
    "save",
    "violations",
    "walking_motion",
]
