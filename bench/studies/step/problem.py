"""One walking step of the five-link exoskeleton by direct collocation (Hermite-Simpson, IPOPT).

**The model walks on a point foot.** Link 1 (stance shin) stands on the support point O; its joint there
is the stance ankle, actuated like every other joint, and every rod is actuated along its length. The
system is therefore fully actuated: every trajectory is dynamically possible, and the loads along it are
its inverse dynamics. The optimiser chooses the trajectory; the loads are ``tau = ID(q, qd, qdd)`` from the
equations' CasADi export (:func:`exo_bench.bench.studies.step.transcription.inverse_dynamics_function`) and the net joint loads
of :mod:`exo_bench.models.mechanism.kinematics` (:func:`exo_bench.bench.studies.step.transcription.net_loads_function`). Like OpenSim Moco's
example2DWalking, opty's gait2d and Ackermann & van den Bogert (2010), it solves for one step with
left/right swap periodicity, a prescribed average speed and an effort objective.

**Transcription.** Hermite-Simpson collocation in separated form on ``N`` intervals of equal length
``h = T / N`` (free duration ``T``): the states ``x = (q, qd)`` and the accelerations ``qdd`` (the
controls) at the ``2N + 1`` nodes and interval midpoints, with for each interval::

    q_m  = (q_0 + q_1) / 2 + h/8 (qd_0 - qd_1)      q_1 - q_0   = h/6 (qd_0 + 4 qd_m + qd_1)
    qd_m = (qd_0 + qd_1) / 2 + h/8 (qdd_0 - qdd_1)  qd_1 - qd_0 = h/6 (qdd_0 + 4 qdd_m + qdd_1)

and Simpson's rule for the objective.

**Leg swap.** At the end the swing foot (end of link 4) lands one step length ``D = v T`` ahead of O
with zero velocity (no impact), and the state is the start's with stance and swing exchanged and the
origin moved to the new foot. With rod vectors ``r_i = sign_i l_i u_i`` the new stance shin is the old
swing shin reversed, ``r'_1 = -r_4``; likewise ``r'_2 = -r_3``, ``r'_3 = -r_2``, ``r'_4 = -r_1`` and the
trunk stays, ``r'_5 = r_5``. Links 3 and 4 have ``sign = -1`` and links 1 and 2 ``sign = +1``, so the
minus signs are absorbed by the signs and the map is a relabelling of coordinates: ``phi`` (2D), ``psi``
and ``l`` of links (1, 2, 3, 4, 5) take the values of links (4, 3, 2, 1, 5); in 3D the other leg is the
mirror image (``y -> -y``), so the azimuths also change sign (:func:`swap_matrix`). Positions
are relative to O, so the origin's move needs no coordinate: it is the condition on the landing point.

**What is free and what is bounded** is :class:`StepSettings`, stored with the solution. The NLP that IPOPT
solves, with its exact derivatives, is :mod:`exo_bench.bench.studies.step.transcription`.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from exo_bench.bench.output.interrupts import SolveFailed, check as check_interrupt
from exo_bench.bench.studies.step.coordinates import angle_rows, swap_matrix
from exo_bench.models.mechanism.mechanism import Mechanism

DEG = math.pi / 180


@dataclass(frozen=True)
class StepSettings:
    """The step problem's settings (SI units, angles in radians). Every value is stored with the solution.

    * ``speed``: the prescribed average speed, the step length over the step's duration (Winter's walk:
      1.41 m/s; :mod:`exo_bench.models.gait.normative`).
    * ``duration``: the range of the free duration of one step (Winter's step, half his 0.987 s stride, is
      0.49 s; his single support is 0.37 s of it).
    * ``clearance``: the lowest swing-leg point mass stays at least this high between lift-off and
      touch-down. The foot leaves the floor at t = 0 and lands at t = T with zero velocity, so it cannot
      be 1 cm high at those instants: lift-off and touch-down are the first and last ``window`` of the
      step (10 % of 0.49 s is 49 ms, less than each of Winter's double supports, 107 ms), where it only
      stays above the floor.
    * ``rest_lengths``: shin, thigh and trunk rods (Winter's anthropometric fractions of a 1.75 m
      stature, as :class:`exo_bench.models.gait.motion.GaitParams` states); ``stroke``: each rod may change its length
      by at most this much either way.
    * ``knee``: knee flexion, thigh angle minus shin angle, both legs: 0 means straight, and no
      hyperextension. ``hip``: thigh angle minus trunk angle (positive flexes the hip). ``segment``:
      every leg segment's angle from the walking direction; ``trunk``: the trunk's.
    * ``friction``: the ground reaction at O (the net joint force of link 1) pushes (vertical component
      at least ``min_support`` body weights) and stays in this friction cone.
    * ``azimuth``: 3D only: the bound on every azimuth. The step is in the sagittal plane (step width 0),
      and the azimuths are fixed at 0 when ``azimuth == 0``: every leg rod passes the vertical, where the
      chart of eq. (7) is singular and an azimuth moves nothing.
    * Objective, per second of walking: ``w_moment`` times the sum over joints of ``|net joint moment|^2`` in
      (N·m/kg)^2, ``w_force`` times the sum over rods of the rod force^2 in body weights^2, and
      ``w_accel`` times the sum of qdd^2 (a small regulariser), each averaged over the step (Simpson).
    """

    dim: int = 2
    intervals: int = 50
    speed: float = 1.41
    duration: tuple[float, float] = (0.35, 0.65)
    clearance: float = 0.01
    window: float = 0.1
    rest_lengths: tuple[float, float, float] = (0.4305, 0.4287, 0.504)
    stroke: float = 0.02
    knee: tuple[float, float] = (0.0, 70 * DEG)
    hip: tuple[float, float] = (-30 * DEG, 60 * DEG)
    segment: tuple[float, float] = (20 * DEG, 160 * DEG)
    trunk: tuple[float, float] = (60 * DEG, 120 * DEG)
    friction: float = 1.0
    min_support: float = 0.0
    azimuth: float = 0.0
    w_moment: float = 1.0
    w_force: float = 1.0
    w_accel: float = 1e-5
    tol: float = 1e-12  # IPOPT's tol: data.SOLVE_TOL, the error model of data.REPRODUCE_TOL

    def to_dict(self) -> dict:
        return asdict(self)

    @staticmethod
    def from_dict(d: dict) -> StepSettings:
        values: dict[str, Any] = {k: tuple(v) if isinstance(v, list) else v for k, v in d.items()}  # from JSON
        return StepSettings(**values)


@dataclass
class Solution:
    """A solved step: the collocation points and the optimiser's loads there."""

    settings: StepSettings
    t: np.ndarray  # (2N + 1,) nodes and midpoints
    q: np.ndarray  # (2N + 1, dof)
    qd: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray  # (2N + 1, dof) the optimiser's inverse dynamics
    moments: np.ndarray  # (2N + 1, n) in 2D, (2N + 1, n, 3) in 3D: net joint moments
    forces: np.ndarray  # (2N + 1, n, dim): net joint forces
    stats: dict = field(default_factory=dict)

    @property
    def duration(self) -> float:
        return float(self.t[-1])

    @property
    def step_length(self) -> float:
        return self.settings.speed * self.duration


def _check(mech: Mechanism, settings: StepSettings) -> None:
    if (
        mech.nlinks != 5
        or mech.dim != settings.dim
        or mech.names[:5] != ("stance_shin", "stance_thigh", "swing_thigh", "swing_shin", "trunk")
    ):
        raise ValueError(
            f"step: mechanism {mech.name!r}: expected the five-link exoskeleton exo5-{settings.dim}d "
            f"(stance shin, stance thigh, swing thigh, swing shin, trunk), got {mech.dim}D with links "
            f"{list(mech.names)}"
        )
    if settings.intervals < 50:
        raise ValueError(f"step: field 'intervals': expected >= 50, got {settings.intervals}")


# ----------------------------------------------------------------------------- initial guess
def _two_link(foot: np.ndarray, hip: np.ndarray, a: float, b: float) -> tuple[np.ndarray, np.ndarray]:
    """Sagittal angles (shin, thigh) of a leg from its foot to the hip, knee forward (x ahead)."""
    d = hip - foot
    r = np.minimum(np.hypot(d[:, 0], d[:, 1]), 0.999 * (a + b))
    th = np.arctan2(d[:, 1], d[:, 0])
    alpha = np.arccos(np.clip((a * a + r * r - b * b) / (2 * a * r), -1, 1))
    shin = th - alpha
    knee = foot + a * np.stack([np.cos(shin), np.sin(shin)], axis=-1)
    e = hip - knee
    return shin, np.arctan2(e[:, 1], e[:, 0])


def initial_guess(mech: Mechanism, s: StepSettings, T: float = 0.5):
    """An inverted-pendulum step: the hip moves forward over O at constant speed on a circle of 97 % of
    the leg's length, the swing foot travels from ``-D`` to ``D`` on a 6 cm arch, trunk upright; both legs
    by two-link inverse kinematics, knees forward. ``(t, q, qd, qdd)`` at the ``2N + 1`` points."""
    N = s.intervals
    t = np.linspace(0.0, T, 2 * N + 1)
    x = t / T
    D = s.speed * T
    a, b, l5 = s.rest_lengths
    L = 0.97 * (a + b)
    hx = -D / 2 + D * x
    hip = np.stack([hx, np.sqrt(L * L - hx * hx)], axis=-1)
    foot = np.stack([-D + 2 * D * x, 0.06 * np.sin(math.pi * x)], axis=-1)
    sh1, th1 = _two_link(np.zeros_like(hip), hip, a, b)
    sh2, th2 = _two_link(foot, hip, a, b)
    ang = np.stack([sh1, th1, th2, sh2, np.full_like(x, math.pi / 2)], axis=-1)
    lengths = np.tile([a, b, b, a, l5], (len(t), 1))
    if mech.dim == 2:
        q = np.concatenate([ang, lengths], axis=1)
    else:
        q = np.concatenate([np.zeros_like(ang), ang, lengths], axis=1)
    qd = np.gradient(q, t, axis=0)
    qdd = np.gradient(qd, t, axis=0)
    return t, q, qd, qdd


# ----------------------------------------------------------------------------- the problem
def solve(mech: Mechanism, settings: StepSettings, inverse_dynamics=None, verbose: bool = False) -> Solution:
    """Build and solve the collocation problem; raise ``RuntimeError`` (one line) when IPOPT fails.

    ``inverse_dynamics``: a function ``mech -> casadi.Function tau = ID(q, qd, qdd)``, by default
    :func:`exo_bench.bench.studies.step.transcription.inverse_dynamics_function`. The NLP and its exact
    derivatives, built per collocation point and mapped, are :mod:`exo_bench.bench.studies.step.transcription`;
    IPOPT's tolerances are the stored step's."""
    import casadi as ca

    from exo_bench.bench.studies.step import transcription

    _check(mech, settings)
    s = settings
    point = _point_function(mech, (inverse_dynamics or transcription.inverse_dynamics_function)(mech))
    n, dim, K = mech.nlinks, mech.dim, 2 * s.intervals + 1
    nlp = transcription.build(mech, s, point)  # exact derivatives per collocation point, mapped
    t0, q0, qd0, qdd0 = initial_guess(mech, s)
    opts: dict[str, Any] = {
        "ipopt.tol": s.tol,
        "ipopt.constr_viol_tol": 1e-10,
        "ipopt.acceptable_iter": 0,
        "ipopt.bound_relax_factor": 0.0,
        "ipopt.max_iter": 3000,
        "ipopt.mu_strategy": "adaptive",
        # MUMPS's workspace 20 % over its estimate (IPOPT's default 1000 % made each factorization fault in
        # pages: system time) and the AMD ordering: exo5-3d's solve 4.1-4.4 -> 3.2 s CPU (IPOPT's own count,
        # loaded host); 57 iterations instead of 60, 2e-10 from the stored step (REPRODUCE_TOL 1e-6). SPRAL,
        # the other solver in CasADi's IPOPT, took 34 s; the probing and LOQO mu oracles 93-111 iterations
        "ipopt.mumps_mem_percent": 20,
        "ipopt.mumps_pivot_order": 0,
        "ipopt.print_level": 5 if verbose else 0,
        "print_time": verbose,
        "ipopt.sb": "yes",
        **nlp.derivatives,
    }
    solver = ca.nlpsol("step", "ipopt", nlp.nlp, opts)
    t_start = time.perf_counter()
    res = solver(x0=nlp.x0(float(t0[-1]), q0, qd0, qdd0), lbx=nlp.lbx, ubx=nlp.ubx, lbg=nlp.lbg, ubg=nlp.ubg)
    seconds = time.perf_counter() - t_start
    st = solver.stats()
    if not st.get("success"):
        check_interrupt()  # IPOPT stopped by Ctrl-C or SIGTERM: interrupted, not "did not solve"
        raise SolveFailed(
            f"step: IPOPT did not solve the {mech.name} step: {st.get('return_status')} after "
            f"{st.get('iter_count')} iterations ({seconds:.1f} s)",
            st,
        )
    xv = np.asarray(res["x"], dtype=float).ravel()
    Tv, zq, zv, za = nlp.split(xv)
    t = np.linspace(0.0, Tv, K)
    q, qd, qdd = (np.zeros((K, mech.dof)) for _ in range(3))
    for full, part in ((q, zq), (qd, zv), (qdd, za)):
        full[:, nlp.layout.free] = part
    tau_v, Mv, Fv, _, _ = (np.asarray(o, dtype=float).T for o in point.map(K)(q.T, qd.T, qdd.T))
    Fv = Fv.reshape(K, n, dim)
    Mv = Mv.reshape(K, n, 3) if dim == 3 else Mv.reshape(K, n)
    g = np.asarray(res["g"], dtype=float).ravel()
    stats = {
        "status": st.get("return_status"),
        "success": bool(st.get("success")),
        "iterations": int(st["iter_count"]),
        "solve_seconds": seconds,
        "objective": float(res["f"]),
        "casadi": ca.__version__,  # type: ignore[attr-defined]  # casadi's stubs omit __version__
        "constraint_violation": _violation(np.concatenate([g, xv]), nlp),
    }
    return Solution(s, t, q, qd, qdd, tau_v, Mv, Fv, stats)


def _point_function(mech: Mechanism, ID):
    """Everything the problem needs at one collocation point, as one SX function (one derivative for all):
    ``(tau, M, F, p, v)`` (:mod:`exo_bench.bench.studies.step.transcription`)."""
    import casadi as ca

    from exo_bench.bench.studies.step import transcription

    q, qd, qdd = (ca.SX.sym(x, mech.dof) for x in ("q", "qd", "qdd"))
    M, F = transcription.net_loads_function(mech)(q, qd, qdd)
    p, v, _ = transcription.kinematics_function(mech)(q, qd, qdd)
    return ca.Function("step_point", [q, qd, qdd], [ID(q, qd, qdd), M, F, p, v])


def _violation(values: np.ndarray, nlp) -> float:
    """The largest violation of the problem's constraints and variable bounds at ``values = (g, x)``."""
    lb, ub = np.concatenate([nlp.lbg, nlp.lbx]), np.concatenate([nlp.ubg, nlp.ubx])
    return float(max(np.maximum(lb - values, 0).max(initial=0.0), np.maximum(values - ub, 0).max(initial=0.0)))


__all__ = ["Solution", "StepSettings", "angle_rows", "initial_guess", "solve", "swap_matrix"]
