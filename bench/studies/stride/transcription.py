"""The half stride as an NLP for IPOPT: trapezoidal collocation, contact-implicit, in CasADi SX.

**Variables.** The free coordinates (:mod:`exo_bench.bench.studies.stride.coordinates`) ``z, zd, zdd``
at the ``N + 1`` nodes of the half stride, and its duration ``T``; ``h = T / N``.

**At every node** (:func:`node_function`, one SX function of ``(q, qd, qdd)``):

* the floor's forces at the heels and toes from their positions and velocities (the smooth contact of
  :func:`exo_bench.models.simulation.contact.contact_force_expr`: no mode schedule; which points carry the
  body emerges), their generalised forces ``Q = J_c^T f_c`` (``J_c`` by CasADi's AD of the contact
  points' positions), and the actuators' generalised forces ``tau = ID(q, qd, qdd) - Q`` with ``ID``
  the equations' CasADi export (:func:`exo_bench.bench.studies.step.transcription.inverse_dynamics_function`);
* ``tau`` split into joint moments, rod forces and residuals by the linear map of
  :func:`exo_bench.bench.studies.stride.actuators.actuators` (taken from it on the identity, so the
  split is that function's); the residuals (HAT's angle, the root's angle and length: nothing holds the
  body up but the floor) are constrained to zero;
* the priced actuators' powers (six sagittal joints, four telescopic rods) and the effort.

**The join.** The accelerations are not mirrored: only coordinates and rates are. So a stride's node
accelerations, and the loads, may jump where its halves meet (an exo stride at 1.41 m/s solved so: left knee
power 256.9 W at ``t = T``, about 0 at ``t = 0``; accelerations off the mirror by up to 382 rad/s^2): the
end nodes' accelerations enter one trapezoidal defect each, at half weight, and the scheme's
node-to-node zig-zag of accelerations is free there. Mirroring them too (``za_0 = P za_N`` and the hips'
acceleration) was tried, twice, warm-started from human strides at 1.41 m/s: neither had converged after
3.7 and 4.5 min of CPU (13 and 14 min wall at load 8-10; stopped), where the same problem without it
converged in 74 s wall (load 3) from the stored stride; so it is not in the stored problem (not shown:
whether it converges given longer), and a sizing table's peaks at such a join would be the
transcription's, not the walk's. ``join_loads`` asks instead for the loads' continuity: the priced joints' moments and
the telescopic rods' forces at ``t = 0`` equal the mirror image of those at ``t = T``. **The exo variant's
stored problem has it** (:data:`~.problem.JOIN_LOADS`): its sizing table is what motors are bought from.
Without it (the exo stride stored until then, kept as the trial ``exo-join-free``) the exo's loads jumped
at the join by 49.5 N·m and 669 N and its largest joint power was 167.6 W (a knee's, at the join); with
it, from that stride, IPOPT converged in 25 s (load 4), the loads mirrored to 3e-13 N·m and 8e-13 N,
the largest joint power 107.9 W, objective 0.4473 (0.4379 without). The human variant's stored problem
does not have it: the human stride at 1.41 m/s solved with it (trial ``human-join-loads``) keeps its r
(0.72/0.84/0.94) but has 15 of 17 peaks within 2x (knee power in swing 2.2x, ankle power in stance
2.1x), where the stored one has 17; so the human strides' loads jump at the join (17.8 N·m and 150 N
at 1.41 m/s), and the report says so, computed (:mod:`~.constraints`).

**Objective.** Work per metre over body weight, positive and negative parts priced separately: each
power ``P`` is split exactly into ``U+ - U-`` with ``U+, U- >= 0`` (variables, in units of ``BW v``), whose
prices ``w_positive U+ + w_negative U-`` make one of them zero at the optimum, so the priced work is
:func:`~.actuators.work_terms`' without smoothing (``eps_power == 0``, the stored strides); or, with
``eps_power > 0`` (W), ``|P|`` smoothed as :func:`~.actuators.work_terms` does, ``sqrt(P^2 + eps^2)``: the
continuation's middle stage (:func:`~.problem.solve_stages`; with ``eps`` = 1 W from the effort-only
start IPOPT wandered for 500 iterations; with 10 W it converges, and the exact split from there lands on
a nearby optimum, where from the effort-only start it found a worse one). Plus the effort, averaged
over the half stride (trapezoidal weights). The telescopic rods' work is priced at ``w_rod_work`` times the
joints' (both parts), and each joint's moment in the effort is divided by its ``strength`` (N·m/kg,
:func:`strength_of`): :class:`~.problem.StrideSettings` says why.

**Constraints.** Trapezoidal defects ``z_{k+1} - z_k = h/2 (zd_k + zd_{k+1})`` and the same for the
rates; zero residuals at every node; joint ranges (linear); the symmetry (the end is the start mirrored,
the hips ``v T`` further on at the same height and velocity); the hips' x at ``t = 0`` (the walk is
invariant to a shift along the floor: it is pinned) and the right heel on the floor at ``t = 0`` (so
is its phase: ``t = 0`` is the right heel's touchdown). Rod strokes, rod rates, trunk angle and ``T`` are
variable bounds.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np

from exo_bench.bench.studies.stride.actuators import PRICED_JOINTS, actuators, join_pairs
from exo_bench.bench.studies.stride.coordinates import TELESCOPIC, FreeMap, mirror_matrix
from exo_bench.bench.studies.stride.data import contact_mask_order, contact_of
from exo_bench.bench.studies.stride.passive import passive_moment
from exo_bench.models.simulation.contact import contact_force_expr
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.simulation.contact import joints


@dataclass(frozen=True)
class Rows:
    """Where each quantity sits in a node's output vector."""

    residuals: slice
    moments: slice
    rod_forces: slice
    contact: slice
    hip_p: slice
    hip_v: slice
    heel_height: int
    powers: slice
    effort: int
    floor: int
    size: int


def strength_of(s: Any, joint: str) -> float:
    """The strength (N·m/kg) dividing ``joint``'s moment in the effort: ``s.strength`` is (hip, knee,
    ankle); 1 each prices every joint's moment alike, per kg."""
    hip, knee, ankle = s.strength
    return float({"hip": hip, "knee": knee, "ankle": ankle}[joint.split("_", 1)[1]])


def node_function(mech: Mechanism, s: Any) -> tuple[ca.Function, Rows]:
    """``y(q, qd, qdd)``: every nonlinear quantity of one node (module docstring), and its :class:`Rows`."""
    from exo_bench.bench.studies.step.transcription import inverse_dynamics_function, kinematics_function

    n, dof, dim = mech.nlinks, mech.dof, 2
    q, qd, qdd = (ca.SX.sym(x, dof) for x in ("q", "qd", "qdd"))
    p, v, _ = kinematics_function(mech)(q, qd, qdd)
    at = lambda x, link: x[(3 * link + 2) * dim : (3 * link + 3) * dim]  # noqa: E731  the link's end mass
    links = contact_mask_order(mech)
    params = contact_of(s)
    f = ca.vertcat(*[contact_force_expr(at(p, i), at(v, i), params) for i in links])
    pc = ca.vertcat(*[at(p, i) for i in links])
    floor = ca.dot(f, ca.vertcat(*[at(v, i) for i in links]))  # W: the floor's power on the body
    tau = inverse_dynamics_function(mech)(q, qd, qdd) - ca.mtimes(ca.jacobian(pc, q).T, f)
    eye = actuators(mech, np.eye(dof))  # the split is linear: its matrix, row i the split of e_i
    moments = ca.mtimes(ca.DM(eye.moments.T), tau)
    rods = ca.mtimes(ca.DM(eye.forces.T), tau)
    residuals = ca.mtimes(ca.DM(eye.residuals.T), tau)
    js = joints(mech)
    rel = ca.vertcat(*[qd[link] - qd[ref] for link, ref, _ in js])
    tel = [eye.rod_names.index(r) for r in TELESCOPIC]
    rp = ca.vertcat(*[rods[k] * qd[n + mech.names.index(eye.rod_names[k])] for k in tel])
    priced = [eye.joint_names.index(j) for j in PRICED_JOINTS]
    mass, bw = mech.total_mass, mech.total_mass * mech.g
    active = _active_moments(mech, s, q, moments, priced)  # the net moments less the passive elements'
    powers = ca.vertcat(*[active[i] * rel[k] for i, k in enumerate(priced)], rp)
    strength = [strength_of(s, j) for j in PRICED_JOINTS]  # N·m/kg: each joint's effort in units of its strength
    effort = s.w_moment * ca.sumsqr(ca.vertcat(*[a / (mass * w) for a, w in zip(active, strength)]))
    effort += s.w_force * ca.sumsqr(ca.vertcat(*[rods[k] for k in tel]) / bw) + s.w_accel * ca.sumsqr(qdd)
    root = mech.names.index("root")
    hip_p, hip_v = at(p, root), at(v, root)
    heel = at(p, mech.names.index("right_heel"))[1]
    parts = [residuals, moments, rods, f, hip_p, hip_v, heel, powers, effort, floor]
    sizes = np.cumsum([0] + [x.numel() for x in parts])
    sl = [slice(int(a_), int(b_)) for a_, b_ in zip(sizes[:-1], sizes[1:])]
    rows = Rows(sl[0], sl[1], sl[2], sl[3], sl[4], sl[5], sl[6].start, sl[7], sl[8].start, sl[9].start, int(sizes[-1]))
    return ca.Function("stride_node", [q, qd, qdd], [ca.vertcat(*parts), tau]), rows


def _active_moments(mech: Mechanism, s: Any, q: Any, moments: Any, priced: list[int]) -> list:
    """The priced joints' active moments: each net moment less its passive element's
    (:func:`~exo_bench.bench.studies.stride.passive.passive_moment`, about the standing posture)."""
    from exo_bench.models.simulation.contact import balanced_standing

    q0 = balanced_standing(mech, s.stature)[0]
    js = joints(mech)
    out = []
    for k, name in zip(priced, PRICED_JOINTS):
        link, ref, _ = js[k]
        theta, theta_0 = q[link] - q[ref], float(q0[link] - q0[ref])
        out.append(moments[k] - passive_moment(s, name.split("_", 1)[1], theta, theta_0, mech.total_mass, ca.exp))
    return out


@dataclass
class NLP:
    """``x = (vec(Z), T, vec(U+), vec(U-))``: ``Z (N + 1, 3 nz)`` the nodes' ``(z, zd, zdd)``, ``U+, U- (N + 1,
    npow) >= 0`` the positive and negative parts of the priced powers in units of ``BW v``."""

    nlp: dict
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    nz: int
    N: int
    npow: int
    unit: float  # W: body weight times speed

    def x0(self, T: float, z: np.ndarray, zd: np.ndarray, zdd: np.ndarray, powers: np.ndarray) -> np.ndarray:
        """The variables of a half stride, its priced powers ``(N + 1, 10)`` (W) split into their two parts
        (none when ``npow`` is 0: the smoothed objective has no slack variables)."""
        u = np.asarray(powers, dtype=float) / self.unit
        parts = [np.maximum(u, 0).ravel() + 1e-4, np.maximum(-u, 0).ravel() + 1e-4] if self.npow else []
        return np.concatenate([np.concatenate([z, zd, zdd], axis=1).ravel(), [T], *parts])

    def split(self, x: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
        x = np.asarray(x, dtype=float).ravel()
        nz, nZ = self.nz, (self.N + 1) * 3 * self.nz
        Z = x[:nZ].reshape(self.N + 1, 3 * nz)
        return float(x[nZ]), Z[:, :nz], Z[:, nz : 2 * nz], Z[:, 2 * nz :]


def joint_rows(mech: Mechanism, fm: FreeMap, s: Any) -> list[tuple[np.ndarray, float, float]]:
    """``(a, lo, hi)`` with ``lo <= a . z <= hi``: hip flexion (thigh minus HAT), knee flexion (thigh
    minus leg) and ankle (foot minus leg, from standing) of both legs."""
    out = []
    for side in ("right", "left"):
        for pos, neg, (lo, hi), off in (
            ("thigh", "hat", s.hip, 0.0),
            ("thigh", "leg", s.knee, 0.0),
            ("foot", "leg", s.ankle, s.ankle_standing),
        ):
            a = np.zeros(fm.nz)
            a[fm.index(f"{side}_{pos} angle")] += 1.0
            a[fm.index(f"{neg} angle" if neg == "hat" else f"{side}_{neg} angle")] -= 1.0
            out.append((a, lo + off, hi + off))
    return out


def build(mech: Mechanism, fm: FreeMap, s: Any) -> tuple[NLP, ca.Function, Rows]:
    """The half stride's NLP (module docstring) for settings ``s`` (:class:`~.problem.StrideSettings`)."""
    node, rows = node_function(mech, s)
    N, nz = s.intervals, fm.nz
    smooth = s.eps_power > 0  # |P| ~ sqrt(P^2 + eps^2); else the exact split with slack variables
    npow = 0 if smooth else rows.powers.stop - rows.powers.start
    nZ = (N + 1) * 3 * nz
    x = ca.SX.sym("x", nZ + 1 + 2 * npow * (N + 1))
    Z = ca.reshape(x[:nZ], 3 * nz, N + 1)
    T = x[nZ]
    Up = ca.reshape(x[nZ + 1 : nZ + 1 + npow * (N + 1)], npow, N + 1)
    Un = ca.reshape(x[nZ + 1 + npow * (N + 1) :], npow, N + 1)
    unit = mech.total_mass * mech.g * s.speed
    h = T / N
    zq, zv, za = Z[:nz, :], Z[nz : 2 * nz, :], Z[2 * nz :, :]
    E, c = ca.DM(fm.E), ca.DM(fm.c)
    Y = [node(ca.mtimes(E, zq[:, k]) + c, ca.mtimes(E, zv[:, k]), ca.mtimes(E, za[:, k]))[0] for k in range(N + 1)]
    g: list = []
    lb: list = []
    ub: list = []

    def add(expr, lo, hi) -> None:
        e = ca.vec(expr)
        g.append(e)
        lb.append(np.broadcast_to(np.asarray(lo, dtype=float), (e.numel(),)))
        ub.append(np.broadcast_to(np.asarray(hi, dtype=float), (e.numel(),)))

    add(zq[:, 1:] - zq[:, :-1] - h / 2 * (zv[:, 1:] + zv[:, :-1]), 0, 0)
    add(zv[:, 1:] - zv[:, :-1] - h / 2 * (za[:, 1:] + za[:, :-1]), 0, 0)
    bw = mech.total_mass * mech.g
    for k, y in enumerate(Y):
        add(y[rows.residuals] / bw, 0, 0)  # in body weights (and body weight x 1 m): scaled as the defects
        if not smooth:
            add(y[rows.powers] / unit - (Up[:, k] - Un[:, k]), 0, 0)  # each power's positive and negative part
    A = np.stack([a for a, _, _ in joint_rows(mech, fm, s)])
    lo_j = np.array([lo for _, lo, _ in joint_rows(mech, fm, s)])
    hi_j = np.array([hi for _, _, hi in joint_rows(mech, fm, s)])
    add(
        ca.mtimes(ca.DM(A), zq),
        np.repeat(lo_j[:, None], N + 1, 1).T.ravel(),
        np.repeat(hi_j[:, None], N + 1, 1).T.ravel(),
    )
    # symmetry: every free coordinate but the root's mirrored; the hips v T on, same height and velocity
    P = mirror_matrix(fm)
    keep = [i for i, name in enumerate(fm.names) if not name.startswith("root")]
    add((zq[:, 0] - ca.mtimes(ca.DM(P), zq[:, N]))[keep], 0, 0)
    add((zv[:, 0] - ca.mtimes(ca.DM(P), zv[:, N]))[keep], 0, 0)
    y0, yN = Y[0], Y[N]
    add(yN[rows.hip_p][0] - y0[rows.hip_p][0] - s.speed * T, 0, 0)
    add(yN[rows.hip_p][1] - y0[rows.hip_p][1], 0, 0)
    add(yN[rows.hip_v] - y0[rows.hip_v], 0, 0)
    if getattr(s, "join_loads", False):  # the actuators' loads continuous across the mirrored join
        mirrored, scale = join_pairs(mech), [mech.total_mass, bw]
        for part, (a, b), unit_ in zip((rows.moments, rows.rod_forces), mirrored, scale):
            add((y0[part][a] - yN[part][b]) / unit_, 0, 0)
    add(y0[rows.hip_p][0], s.hip_x0, s.hip_x0)
    add(y0[rows.heel_height], 0, 0)
    w = np.full(N + 1, 1.0 / N)
    w[[0, -1]] /= 2
    price = [1.0] * len(PRICED_JOINTS) + [float(s.w_rod_work)] * len(TELESCOPIC)
    if smooth:
        P = ca.horzcat(*[y[rows.powers] for y in Y]) / unit
        a = ca.sqrt(P**2 + (s.eps_power / unit) ** 2)  # as actuators.work_terms smooths |P|
        work = ca.sum1(ca.DM(price) * (s.w_positive * (a + P) / 2 + s.w_negative * (a - P) / 2))
    else:
        c = ca.DM(price)  # (npow, 1): the joints' work at 1, the rods' at w_rod_work
        work = s.w_positive * ca.sum1(c * Up) + s.w_negative * ca.sum1(c * Un)  # (1, N + 1): work per metre over BW
    f = sum(float(w[k]) * (work[k] + Y[k][rows.effort]) for k in range(N + 1))
    if s.w_floor:  # the floor's absorbed work per metre over BW (its elastic part returns over the stride)
        f += s.w_floor * sum(float(w[k]) * -Y[k][rows.floor] / unit for k in range(N + 1))
    lbz, ubz = _variable_bounds(mech, fm, s)
    slack = 2 * npow * (N + 1)
    lbx = np.concatenate([np.tile(lbz, N + 1), [s.period[0] / 2], np.zeros(slack)])
    ubx = np.concatenate([np.tile(ubz, N + 1), [s.period[1] / 2], np.full(slack, np.inf)])
    nlp = {"x": x, "f": f, "g": ca.vertcat(*g)}
    return NLP(nlp, lbx, ubx, np.concatenate(lb), np.concatenate(ub), nz, N, npow, unit), node, rows


def _variable_bounds(mech: Mechanism, fm: FreeMap, s: Any) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of one node's ``(z, zd, zdd)``: trunk angle, rod strokes about rest, rod rates."""
    nz = fm.nz
    lo, hi = np.full(3 * nz, -np.inf), np.full(3 * nz, np.inf)
    k = fm.index("hat angle")
    lo[k], hi[k] = s.trunk
    k = fm.index("root length")
    lo[k], hi[k] = 0.3, 10.0  # the hips stay away from O (the polar chart's pole)
    for r in TELESCOPIC:
        k = fm.index(f"{r} length")
        rest = s.rest_lengths[r.split("_", 1)[1]]
        lo[k], hi[k] = rest - s.stroke, rest + s.stroke
        lo[nz + k], hi[nz + k] = -s.rate, s.rate
    return lo, hi


__all__ = ["NLP", "PRICED_JOINTS", "Rows", "build", "join_pairs", "joint_rows", "node_function"]
