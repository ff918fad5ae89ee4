"""The step's collocation problem as an NLP whose exact derivatives are built per node, once, and the
CasADi functions of the mechanism it is built from (inverse dynamics, kinematics, net joint loads).

**Why this form.** The problem was an ``Opti`` model expanded to one SX graph of all ``2N + 1``
collocation points; CasADi then differentiated that whole graph twice for IPOPT's exact Hessian. Profiled on
exo5-3d (3.8.2, 81 iterations, CPU seconds on a loaded 2-core host): building the expanded graph and its
Hessian took 8 s, IPOPT's linear algebra 8 s (its KKT system carried 2899 inequality rows, 1011 of them
simple bounds of one variable), the Hessian's evaluations 2-3 s. Three alternatives were refused:

* ``expand=False`` (an MX graph over ``point.map``): 2 s to build, but CasADi's Hessian of a mapped MX
  function evaluates 5-10x slower than the SX one (the solve took 76 iterations and 161 s wall, loaded);
* a ``Callback`` backed by the numpy analytic kernels (issue 36): it gives first derivatives only, so
  IPOPT would need a limited-memory Hessian, many more iterations and a looser convergence;
* CasADi's ``jit=True`` (gcc, the one compiler here): ``-O1`` of one point's Hessian (38k instructions)
  takes 23 s of CPU, more than the whole solve.

Here every nonlinear quantity of the problem is a function of one collocation point: the point's
outputs ``y_k = c(z_k)``, ``z_k = (q_k, qd_k, qdd_k)`` (the free coordinates), are the swing-leg heights,
the hip's forward velocity, the ground reaction's rows, the landing foot and the point's effort
(:func:`node_function`). The rest of the NLP, ``g = G(x, Y)``, is linear in the outputs ``Y`` with
constant coefficients ``J_Y = dG/dY`` and at most bilinear in the variables (``h = T / N`` times
rates). So, exactly:

    dg/dx = dG/dx + J_Y blockdiag_k(dc/dz (z_k))
    d2(sigma f + lam^T g)/dx2 = d2(lam^T G)/dx2 + blockdiag_k(d2(mu_k^T c)/dz2 (z_k)),
    mu = J_Y^T lam + sigma df/dY

with ``dc/dz`` and ``d2(mu^T c)/dz2`` derived symbolically (SX) for ONE point and mapped over the ``K``
points (``Function.map``): building costs the same for any ``N``, and the evaluations run the SX code of
one point ``K`` times. IPOPT gets them as ``jac_g``, ``grad_f`` and ``hess_lag``
(``tests/test_step_derivatives.py`` checks them against central differences of ``g`` and of the
Lagrangian's gradient). Simple bounds of one variable (segment and trunk angles, rod lengths, azimuths,
duration) are variable bounds, not constraint rows, and a swing-leg height has one row per point (the
larger of "above the floor" and "clearance"): the same feasible set in 1497 fewer rows (exo5-3d). IPOPT's
options are those the stored steps were solved with.

**Measured** (exo5-3d, ``exo-bench gait --solve``, the whole command, 2-core host shared with seven other
sessions, load about 10): 55 iterations; 4.4-4.7 s user + 1.1 s system CPU (IPOPT's own count: 3.7 s, of
which 0.7 s the Hessian, 0.1 s the Jacobian), median wall of 3 runs 21.6 s (IPOPT 14.3 s of it). The Opti
form on the same host: 81 iterations, 14.4 s CPU (14.8 s wall at load 0.9, 27-46 s at load 7-10). Under
that load the wall time says little: the goal of 5 s wall on an idle host is not measured here. The stored
steps are reproduced (3D: max ``|dq|`` 4.6e-7, ``|dT|`` 1.4e-8; 2D: 1.5e-7; the tolerance is 1e-6; which of the
nearby iterates IPOPT stops at moves with the roundings: 1.5e-7 to 9.5e-7 in 2D over this file's
versions) and every constraint, re-evaluated in numpy, holds to 2e-11. Those were steps stored at IPOPT's
tol 1e-8; they are now stored and re-solved at 1e-12 (60-63 iterations), the error model in
:data:`exo_bench.bench.studies.step.data.REPRODUCE_TOL`. With MUMPS's workspace at 20 % over its estimate
and the AMD ordering (problem.py) and the build's check read sparse, the whole ``exo-bench gait --solve``
took 4.24 s user + 0.12 s system CPU in 3D (57 iterations; 2D: 3.52 + 0.21 s) at load 19-20, where the wall
was 21 s (18 s in 2D); the wall of an idle host is not measured here (at most the CPU, about 4.4 s, as the
only work that is not CPU is reading files already cached). The stored steps are reproduced: 3D max
``|dq|`` 2.0e-10, ``|dT|`` 1.2e-11 s; 2D 2.1e-10, 1.3e-11 s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import casadi as ca
import numpy as np

from exo_bench.bench.studies.step.coordinates import angle_rows, swap_matrix
from exo_bench.models.mechanism.mechanism import Mechanism


#: Threads of the mapped Jacobian and Hessian (most of the evaluation time; the host has 2 cores).
THREADS = 2


@dataclass(frozen=True)
class Layout:
    """Where things are: ``x = (vec(Z), T)`` with ``Z`` of shape ``(nz, K)``, column ``k`` the point's
    free ``(q, qd, qdd)``; ``free`` are the mechanism's coordinates that are variables."""

    free: np.ndarray
    nf: int
    K: int
    N: int

    @property
    def nz(self) -> int:
        return 3 * self.nf

    @property
    def nx(self) -> int:
        return self.nz * self.K + 1


@dataclass
class Transcription:
    """The NLP: ``nlp`` (x, f, g as MX), its bounds, and the exact derivatives for IPOPT."""

    layout: Layout
    nlp: dict
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    derivatives: dict  # {"jac_g", "grad_f", "hess_lag"}: casadi.Functions named as nlpsol expects

    def x0(self, T: float, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """The variables of a trajectory ``(K, dof)`` of duration ``T``."""
        f = self.layout.free
        return np.concatenate([np.concatenate([q[:, f], qd[:, f], qdd[:, f]], axis=1).ravel(), [T]])

    def split(self, x: np.ndarray) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
        """``(T, Zq, Zv, Za)``: the duration and the free coordinates ``(K, nf)`` of ``x``."""
        lay = self.layout
        Z = np.asarray(x, dtype=float).ravel()[: lay.nz * lay.K].reshape(lay.K, lay.nz)
        return float(np.asarray(x).ravel()[-1]), Z[:, : lay.nf], Z[:, lay.nf : 2 * lay.nf], Z[:, 2 * lay.nf :]


def layout(mech: Mechanism, intervals: int, azimuth: float) -> Layout:
    """3D with the azimuths fixed at 0: they are no variables (as equality constraints they would repeat the
    leg swap's and the landing's azimuth rows, and IPOPT's KKT matrix would be singular)."""
    n, dof = mech.nlinks, mech.dof
    planar3d = mech.dim == 3 and azimuth == 0
    free = np.arange(n, dof) if planar3d else np.arange(dof)
    return Layout(free, len(free), 2 * intervals + 1, intervals)


def _full(mech: Mechanism, lay: Layout, v):
    """The mechanism's coordinates from the free ones (the fixed azimuths are 0)."""
    return ca.vertcat(ca.SX.zeros(mech.dof - lay.nf), v) if lay.nf < mech.dof else v


def node_function(mech: Mechanism, s, lay: Layout, point: ca.Function) -> tuple[ca.Function, dict[str, slice]]:
    """``y = c(z)``: every nonlinear quantity the problem takes from one collocation point, and the rows of
    each (``heights``: the 6 swing-leg point masses' heights; ``hip``: the hip's forward velocity;
    ``Fz``, ``cone``: the ground reaction's vertical component and friction-cone rows, ``>= 0``; ``foot_p``,
    ``foot_v``: the swing foot's position and velocity on the walking axes; ``effort``: the objective's
    integrand)."""
    dim, n, dof = mech.dim, mech.nlinks, mech.dof
    mass, bw = mech.total_mass, mech.total_mass * mech.g
    z = ca.SX.sym("z", lay.nz)
    q, qd, qdd = (_full(mech, lay, z[i * lay.nf : (i + 1) * lay.nf]) for i in range(3))
    tau, M, F, P, Pd = point(q, qd, qdd)
    planar = dim == 2 or lay.nf < dof
    heights = [P[(3 * i + pm) * dim + dim - 1] for i in (2, 3) for pm in range(3)]
    Fx, Fz = F[0], F[dim - 1]
    if planar:  # the lateral force is 0 identically in a planar step: a linear cone
        cone = [s.friction * Fz + Fx, s.friction * Fz - Fx]
    else:
        cone = [(s.friction * Fz) ** 2 - Fx**2 - F[1] ** 2]
    axes = [0, dim - 1] if planar and dim == 3 else list(range(dim))  # planar 3D: y is 0 identically
    foot = slice((3 * 3 + 2) * dim, (3 * 3 + 3) * dim)  # link 4, end mass
    effort = s.w_moment * ca.sumsqr(M / mass) + s.w_force * ca.sumsqr(tau[dof - n :] / bw) + s.w_accel * ca.sumsqr(qdd)
    parts = {
        "heights": heights,
        "hip": [Pd[(3 * 1 + 2) * dim]],
        "Fz": [Fz],
        "cone": cone,
        "foot_p": [P[foot][a] for a in axes],
        "foot_v": [Pd[foot][a] for a in axes],
        "effort": [effort],
    }
    rows, y, start = {}, [], 0
    for name, exprs in parts.items():
        rows[name] = slice(start, start + len(exprs))
        y += exprs
        start += len(exprs)
    return ca.Function("step_node", [z], [ca.vertcat(*y)], ["z"], ["y"]), rows


def effort_residuals(mech: Mechanism, s, lay: Layout, point: ca.Function) -> ca.Function:
    """``r(z)`` with ``effort = |r|^2`` (:func:`node_function`): the weighted moments, rod forces and
    accelerations, linear in ``qdd``. The effort's Hessian is ``2 (J_r^T J_r + sum_i r_i d2r_i/dz2)``: the
    product ``J_r^T J_r`` taken as a sparse product of the points' Jacobians costs a third of CasADi's SX
    Hessian of the sum of squares (33k instructions a point, where the rest of the Hessian takes 0.8k)."""
    n, dof = mech.nlinks, mech.dof
    z = ca.SX.sym("z", lay.nz)
    q, qd, qdd = (_full(mech, lay, z[i * lay.nf : (i + 1) * lay.nf]) for i in range(3))
    tau, M, _, _, _ = point(q, qd, qdd)
    r = ca.vertcat(
        math.sqrt(s.w_moment) * M / mech.total_mass,
        math.sqrt(s.w_force) * tau[dof - n :] / (mech.total_mass * mech.g),
        math.sqrt(s.w_accel) * qdd,
    )
    return ca.Function("step_effort_residuals", [z], [r], ["z"], ["r"])


def _simpson(lay: Layout) -> np.ndarray:
    wts = np.ones(lay.K)
    wts[1::2] = 4.0
    wts[2:-1:2] = 2.0
    return wts / (6 * lay.N)


def _constraints(mech: Mechanism, s, lay: Layout, rows: dict[str, slice], xs, Ys):
    """``G(x, Y)`` and its bounds, and the variables' bounds."""
    n, dof, K, N, nf = mech.nlinks, mech.dof, lay.K, lay.N, lay.nf
    Z = ca.reshape(xs[: lay.nz * K], lay.nz, K)
    T = xs[-1]
    h = T / N
    Xq, Xv, Xa = Z[:nf, :], Z[nf : 2 * nf, :], Z[2 * nf :, :]
    g: list = []
    lb: list = []
    ub: list = []

    def add(expr, lo: float, hi: float) -> None:
        e = ca.vec(expr)
        g.append(e)
        lb.append(np.full(e.numel(), lo))
        ub.append(np.full(e.numel(), hi))

    # Hermite-Simpson, separated form
    e, m_, o = slice(0, K - 1, 2), slice(1, K, 2), slice(2, K, 2)  # interval starts, midpoints, ends
    add(Xq[:, m_] - ((Xq[:, e] + Xq[:, o]) / 2 + h / 8 * (Xv[:, e] - Xv[:, o])), 0, 0)
    add(Xv[:, m_] - ((Xv[:, e] + Xv[:, o]) / 2 + h / 8 * (Xa[:, e] - Xa[:, o])), 0, 0)
    add(Xq[:, o] - Xq[:, e] - h / 6 * (Xv[:, e] + 4 * Xv[:, m_] + Xv[:, o]), 0, 0)
    add(Xv[:, o] - Xv[:, e] - h / 6 * (Xa[:, e] + 4 * Xa[:, m_] + Xa[:, o]), 0, 0)
    # leg swap, landing point and no impact
    Sf = ca.DM(swap_matrix(mech)[np.ix_(lay.free, lay.free)])
    add(Xq[:, 0] - ca.mtimes(Sf, Xq[:, K - 1]), 0, 0)
    add(Xv[:, 0] - ca.mtimes(Sf, Xv[:, K - 1]), 0, 0)
    fp = Ys[rows["foot_p"], K - 1]
    add(fp[0] - s.speed * T, 0, 0)
    add(fp[1:], 0, 0)
    add(Ys[rows["foot_v"], K - 1], 0, 0)
    # swing-leg clearance: at 0 and T the landing conditions fix the foot's height
    lo, hi = int(round(s.window * 2 * N)), int(round((1 - s.window) * 2 * N))
    clear = np.zeros(K)
    clear[lo : hi + 1] = s.clearance  # from lift-off to touch-down above the floor, between them by clearance
    for r in range(rows["heights"].start, rows["heights"].stop):
        add(Ys[r, 1 : K - 1] - ca.DM(clear[1 : K - 1]).T, 0, np.inf)
    add(Ys[rows["hip"], :], 0, np.inf)  # the hip moves forward
    add(Ys[rows["Fz"], :], s.min_support * mech.total_mass * mech.g, np.inf)  # the ground pushes
    add(Ys[rows["cone"], :], 0, np.inf)  # in the friction cone
    # knee and hip ranges (linear); the other ranges are the variables' bounds
    off = dof - nf
    th = [Xq[int(r) - off, :] for r in angle_rows(mech)]
    for a, b, rng in ((1, 0, s.knee), (2, 3, s.knee), (2, 4, s.hip), (1, 4, s.hip)):
        add(th[a] - th[b], *rng)
    lbz, ubz = np.full((3, nf), -np.inf), np.full((3, nf), np.inf)
    a_, b_, l5 = s.rest_lengths
    for i, r in enumerate(angle_rows(mech)):
        lbz[0, int(r) - off], ubz[0, int(r) - off] = s.segment if i < 4 else s.trunk
    for i, L in enumerate((a_, b_, b_, a_, l5)):
        lbz[0, dof - n + i - off], ubz[0, dof - n + i - off] = L - s.stroke, L + s.stroke
    if off == 0 and mech.dim == 3:
        lbz[0, :n], ubz[0, :n] = -s.azimuth, s.azimuth
    lbx = np.concatenate([np.tile(lbz.ravel(), K), [s.duration[0]]])
    ubx = np.concatenate([np.tile(ubz.ravel(), K), [s.duration[1]]])
    return ca.vertcat(*g), np.concatenate(lb), np.concatenate(ub), lbx, ubx


def build(mech: Mechanism, s, point: ca.Function) -> Transcription:
    """The step's NLP with its exact derivatives (module docstring), for ``point = (tau, M, F, p, v)(q,
    qd, qdd)`` of one collocation point."""
    lay = layout(mech, s.intervals, s.azimuth)
    K, nz = lay.K, lay.nz
    cfun, rows = node_function(mech, s, lay, point)
    ny = cfun.size1_out(0)
    # G(x, Y), linear in Y: its constant J_Y, and its own derivatives in x (no Y in them: checked by Function)
    xs, Ys = ca.SX.sym("x", lay.nx), ca.SX.sym("Y", ny, K)
    G, lbg, ubg, lbx, ubx = _constraints(mech, s, lay, rows, xs, Ys)
    JY = ca.evalf(ca.jacobian(G, ca.vec(Ys)))
    cols, vals = np.asarray(JY.sparsity().get_col()), np.asarray(JY.nonzeros())  # sparse: dense took 0.8 s CPU
    assert not vals[cols % ny == rows["effort"].start].any(), "no constraint takes the effort"
    lam = ca.SX.sym("lam", G.numel())
    G_fun = ca.Function("step_G", [xs, Ys], [G])
    Gx_fun = ca.Function("step_G_x", [xs], [ca.jacobian(G, xs)])
    Gxx_fun = ca.Function("step_G_xx", [xs, lam], [ca.hessian(ca.dot(lam, G), xs)[0]])
    FY = np.zeros((ny, K))
    FY[rows["effort"].start, :] = _simpson(lay)
    # one point's derivatives, mapped
    z, mu = ca.SX.sym("z", nz), ca.SX.sym("mu", ny)
    yz = cfun(z)
    cse = {"cse": True}  # common subexpressions merged: 13 % fewer instructions in the Hessian
    e = rows["effort"].start
    assert e == ny - 1, "the effort is the points' last output"
    # no constraint takes the effort (its row of J_Y is 0): its row of dy/dz is left empty (845 instructions
    # a point instead of 5724), its gradient is grad_f's
    dy = ca.vertcat(ca.jacobian(yz[:e], z), ca.SX(1, nz))
    jmap = ca.Function("step_node_jac", [z], [dy], cse).map(K, "thread", THREADS)
    gmap = ca.Function("step_node_grad", [z], [ca.gradient(yz[e], z)], cse).map(K)
    # the Hessian of mu^T y: the constraints' rows and the effort's second-order part symbolically, the
    # effort's J_r^T J_r as a product below (effort_residuals)
    rfun = effort_residuals(mech, s, lay, point)
    r = rfun(z)
    nr = r.numel()
    nu_sym = ca.SX.sym("nu", nr)
    H = ca.hessian(ca.dot(mu[:e], yz[:e]) + ca.dot(nu_sym, r), z)[0]
    H = ca.substitute(H, nu_sym, 2 * mu[e] * r)
    hess_one = ca.Function("step_node_hess", [z, mu], [H], cse)
    hmap = hess_one.map(K, "thread", THREADS)
    jrmap = ca.Function("step_effort_jac", [z], [ca.jacobian(r, z)], cse).map(K, "thread", THREADS)
    # the NLP and its derivatives, in MX
    x, p = ca.MX.sym("x", lay.nx), ca.MX.sym("p", 0)
    lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", G.numel())
    Z = ca.reshape(x[: nz * K], nz, K)
    Y = cfun.map(K)(Z)
    g, f = G_fun(x, Y), ca.dot(ca.DM(FY), Y)
    dY = ca.horzcat(ca.diagcat(*ca.horzsplit(jmap(Z), nz)), ca.MX(ny * K, 1))  # dvec(Y)/dx
    jac = Gx_fun(x) + ca.mtimes(ca.DM(JY), dY)
    grad = ca.vertcat(ca.vec(gmap(Z) * ca.repmat(ca.DM(_simpson(lay)).T, nz, 1)), 0)
    MU = ca.reshape(ca.mtimes(ca.DM(JY).T, lam_g), ny, K) + lam_f * ca.DM(FY)
    Jr = ca.diagcat(*ca.horzsplit(jrmap(Z), nz))  # (nr K, nz K), block diagonal
    weights = ca.diag(ca.vec(ca.repmat(2 * MU[e, :], nr, 1)))  # 2 mu_e of each point, on its residuals
    gauss_newton = ca.mtimes(Jr.T, ca.mtimes(weights, Jr))
    hess = ca.diagcat(*ca.horzsplit(hmap(Z, MU), nz), ca.MX(1, 1)) + ca.diagcat(gauss_newton, ca.MX(1, 1))
    hess = hess + Gxx_fun(x, lam_g)
    derivatives = {
        "jac_g": ca.Function("nlp_jac_g", [x, p], [g, jac], ["x", "p"], ["g", "jac_g_x"]),
        "grad_f": ca.Function("nlp_grad_f", [x, p], [f, grad], ["x", "p"], ["f", "grad_f_x"]),
        "hess_lag": ca.Function(
            "nlp_hess_l", [x, p, lam_f, lam_g], [ca.triu(hess)], ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"]
        ),
    }
    return Transcription(lay, {"x": x, "f": f, "g": g}, lbx, ubx, lbg, ubg, derivatives)


# The CasADi functions the step optimisation calls.


def inverse_dynamics_function(mech: Mechanism) -> ca.Function:
    """``tau = ID(q, qd, qdd)``: generalised forces of the paper's coordinates, as a ``casadi.Function``:
    the equations' CasADi export (:mod:`exo_bench.matrix_method.export.casadi_functions`, the factored closed forms of
    ``matrix-factored`` run on CasADi symbols)."""
    from exo_bench.matrix_method.export.casadi_functions import casadi_functions

    return casadi_functions(mech).inverse_dynamics


def _ident(mech: Mechanism) -> str:
    return "".join(c if c.isalnum() else "_" for c in mech.name)


def _unit(mech: Mechanism, q, i: int):
    n = mech.nlinks
    if mech.dim == 2:
        phi = q[i]
        return ca.vertcat(ca.cos(phi), ca.sin(phi))
    phi, psi = q[i], q[n + i]
    return ca.vertcat(ca.cos(psi) * ca.cos(phi), ca.cos(psi) * ca.sin(phi), ca.sin(psi))


def _positions(mech: Mechanism, q) -> list:
    """Point-mass positions (eq. 7): mass b of link i at ``end(parent) + frac_b * sign_i l_i u_i``."""
    n = mech.nlinks
    lengths = q[-n:]
    fr = mech.fractions
    ends: list = []
    out: list = []
    for i in range(n):
        w = mech.sign[i] * lengths[i] * _unit(mech, q, i)
        start = ends[mech.parent[i]] if mech.parent[i] >= 0 else ca.SX.zeros(mech.dim)
        ends.append(start + w)
        out += [start + float(fr[i, b]) * w for b in range(3)]
    return out


def _kinematics(mech: Mechanism, q, qd, qdd):
    p = _positions(mech, q)
    P = ca.vertcat(*p)
    v = ca.jtimes(P, q, qd)
    a = ca.jtimes(v, q, qd) + ca.jtimes(v, qd, qdd)
    d = mech.dim
    return p, [v[d * k : d * (k + 1)] for k in range(len(p))], [a[d * k : d * (k + 1)] for k in range(len(p))]


def _mass_forces(mech: Mechanism, a: list) -> list:
    """``m (a - g)`` of every point mass (gravity ``-g`` along the last axis)."""
    g = np.zeros(mech.dim)
    g[-1] = -mech.g
    m = mech.mass_array
    return [float(m[k // 3, k % 3]) * (a[k] - g) for k in range(len(a))]


def kinematics_function(mech: Mechanism) -> ca.Function:
    """``(p, v, a) = K(q, qd, qdd)``: every point mass's position, velocity and acceleration."""
    q, qd, qdd = (ca.SX.sym(s, mech.dof) for s in ("q", "qd", "qdd"))
    p, v, a = _kinematics(mech, q, qd, qdd)
    return ca.Function(
        f"{_ident(mech)}_kinematics",
        [q, qd, qdd],
        [ca.vertcat(*p), ca.vertcat(*v), ca.vertcat(*a)],
        ["q", "qd", "qdd"],
        ["p", "v", "a"],
    )


def _cross(a, b):
    return ca.vertcat(a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def net_loads_function(mech: Mechanism) -> ca.Function:
    """``(M, F) = L(q, qd, qdd)``: the net joint moment and force at the start of every link, exerted by
    the parent side on the link's subtree (:mod:`exo_bench.models.mechanism.kinematics`)."""
    from exo_bench.models.mechanism.kinematics import subtree

    q, qd, qdd = (ca.SX.sym(s, mech.dof) for s in ("q", "qd", "qdd"))
    p, _, a = _kinematics(mech, q, qd, qdd)
    f = _mass_forces(mech, a)
    Ms, Fs = [], []
    for k in range(mech.nlinks):
        r = p[3 * k]
        m = ca.SX.zeros(3 if mech.dim == 3 else 1)
        F = ca.SX.zeros(mech.dim)
        for i in subtree(mech, k):
            for b in range(3):
                arm, fj = p[3 * i + b] - r, f[3 * i + b]
                m += _cross(arm, fj) if mech.dim == 3 else arm[0] * fj[1] - arm[1] * fj[0]
                F += fj
        Ms.append(m)
        Fs.append(F)
    return ca.Function(
        f"{_ident(mech)}_net_loads", [q, qd, qdd], [ca.vertcat(*Ms), ca.vertcat(*Fs)], ["q", "qd", "qdd"], ["M", "F"]
    )


__all__ = [
    "Layout",
    "Transcription",
    "build",
    "inverse_dynamics_function",
    "kinematics_function",
    "layout",
    "net_loads_function",
    "node_function",
]
