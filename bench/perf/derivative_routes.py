"""The derivative routes that bench/test_derivatives.py times: ours and the peers', each a call
``f(q, qd, x) -> (d/dq, d/dqd, d/dx)`` on ``(S, dof)`` arrays returning ``(S, dof, dof)`` arrays in the
paper's coordinates (``x = qdd`` for inverse dynamics, ``tau`` for forward dynamics).

* :func:`analytic` -- the analytic kernels of exo_bench.models.newton_euler.derivatives (issue 36), into
  preallocated ``out``; a kernel not built in this commit raises there, and the row says so;
* :func:`write_floor` -- the memory bandwidth floor: ``fill`` of the three ``(S, dof, dof)`` outputs;
* :func:`casadi_inverse` / :func:`casadi_forward` -- CasADi's AD of the factored closed forms
  (matrix_method/derivatives.py, today's path) and its implicit-function forward derivatives (LU);
* :func:`model_derivatives` -- ``prepare(mech, method).derivatives`` (whatever source it reports);
* :func:`central_differences` -- central differences of newton-euler's batched inverse dynamics
  (``6 dof`` states per sample in batched calls; step ``eps^(1/3) max(1, |x|)``, 1 for the linear qdd);
* :func:`mujoco_inverse_fd` -- MuJoCo's ``mjd_inverseFD`` on the exported MJCF, a loop over samples,
  mapped to the paper's coordinates by ``G`` (``J_paper = G^T J_mj^T G``: MuJoCo's are transposed);
  its warnings (a singular joint-space M in 3D, which the inverse does not use) are collected in
  ``call.warnings``, not written to ./MUJOCO_LOG.TXT;
* :func:`drake_autodiff` -- Drake's ``CalcInverseDynamics - CalcGravityGeneralizedForces`` on the
  AutoDiffXd plant, seeded with ``G`` (``3 dof`` directions), a loop over samples;
* :func:`pinocchio_rnea_derivatives` -- Pinocchio's ``computeRNEADerivatives`` on the mimic-joint model
  (it refuses mimic joints: the caller records the message).
"""

from __future__ import annotations

import numpy as np

from exo_bench.api import prepare
from exo_bench.models.mechanism.mechanism import Mechanism

EPS = float(np.finfo(float).eps)


def analytic(mech: Mechanism, kernel: str):
    from exo_bench.models.newton_euler.derivatives import prepare_inverse_derivatives

    d = prepare_inverse_derivatives(mech)

    def call(q, qd, qdd, out=None):
        return d(q, qd, qdd, out=out, kernel=kernel)

    return call


def write_floor(mech: Mechanism):
    """The memory bandwidth floor of a derivative call: ``fill`` of three ``(S, dof, dof)`` float64 arrays,
    allocated once per batch size (the bytes every route must write, and nothing else)."""
    d = mech.dof
    arrays: dict[int, tuple[np.ndarray, ...]] = {}

    def call(q, qd, qdd):
        S = q.shape[0]
        if S not in arrays:
            arrays[S] = tuple(np.empty((S, d, d)) for _ in range(3))
        out = arrays[S]
        for o in out:
            o.fill(1.0)
        return out

    return call


def casadi_inverse(mech: Mechanism):
    from exo_bench.matrix_method.derivatives import Derivatives

    d = Derivatives(mech)
    return lambda q, qd, qdd: d.inverse_dynamics(q, qd, qdd, check=False)


def casadi_forward(mech: Mechanism):
    from exo_bench.matrix_method.derivatives import Derivatives

    d = Derivatives(mech)
    return lambda q, qd, tau: d.forward_dynamics(q, qd, tau, check=False)[1:]


def model_derivatives(mech: Mechanism, method: str, forward: bool):
    """``prepare(mech, method).derivatives``'s call and its ``source`` text."""
    d = prepare(mech, method).derivatives
    if forward:
        return (lambda q, qd, tau: d.forward_dynamics(q, qd, tau, check=False)[1:]), d.source
    return (lambda q, qd, qdd: d.inverse_dynamics(q, qd, qdd, check=False)), d.source


def central_differences(mech: Mechanism, rows_per_call: int = 4096):
    model = prepare(mech, "newton-euler")
    d = mech.dof
    eye = np.eye(d)

    def call(q, qd, qdd):
        S = q.shape[0]
        out = [np.empty((S, d, d)) for _ in range(3)]
        chunk = max(1, rows_per_call // (6 * d))
        for s0 in range(0, S, chunk):
            sl = slice(s0, min(S, s0 + chunk))
            k = sl.stop - sl.start
            hs = [np.cbrt(EPS) * np.maximum(1.0, np.abs(x[sl])) for x in (q, qd)] + [np.ones((k, d))]
            base = [np.repeat(x[sl], 6 * d, axis=0).reshape(k, 3, 2, d, d) for x in (q, qd, qdd)]
            for w in range(3):  # which input is stepped: +h e_j, then -h e_j
                step = hs[w][:, :, None] * eye[None]
                base[w][:, w, 0] += step
                base[w][:, w, 1] -= step
            tau = model.inverse_dynamics(*(b.reshape(-1, d) for b in base), check=False).reshape(k, 3, 2, d, d)
            for w in range(3):
                diff = (tau[:, w, 0] - tau[:, w, 1]) / (2 * hs[w][:, :, None])  # [sample, j, i]
                out[w][sl] = diff.transpose(0, 2, 1)
        return tuple(out)

    return call


def mujoco_inverse_fd(mech: Mechanism, eps: float = 1e-6):
    import mujoco

    from exo_bench.models.engines.mujoco_backend import MujocoRNE

    m = MujocoRNE(mech)
    model, data, G = m.mj_model, m.data, m.G
    nv = model.nv
    J = [np.zeros((nv, nv)) for _ in range(3)]

    warnings: list[str] = []  # MuJoCo's warnings, kept here rather than in ./MUJOCO_LOG.TXT

    def call(q, qd, qdd):
        S, d = q.shape
        out = [np.empty((S, d, d)) for _ in range(3)]
        qj, vj, aj = q @ G.T, qd @ G.T, qdd @ G.T
        before = mujoco.get_mju_user_warning()
        mujoco.set_mju_user_warning(lambda msg: warnings.append(str(msg)) if len(warnings) < 10 else None)
        try:
            for s in range(S):
                data.qpos[:], data.qvel[:], data.qacc[:] = qj[s], vj[s], aj[s]
                mujoco.mjd_inverseFD(model, data, eps, False, J[0], J[1], J[2], None, None, None, None)
                for k in range(3):
                    out[k][s] = G.T @ J[k].T @ G
        finally:
            mujoco.set_mju_user_warning(before)
        return tuple(out)

    call.warnings = warnings  # type: ignore[attr-defined]
    return call


def drake_autodiff(mech: Mechanism):
    from pydrake.autodiffutils import AutoDiffXd, ExtractGradient, InitializeAutoDiff
    from pydrake.multibody.tree import MultibodyForces_

    from exo_bench.models.engines.drake_backend import DrakeID

    m = DrakeID(mech)
    plant = m.plant.ToAutoDiffXd()
    ctx = plant.CreateDefaultContext()
    forces = MultibodyForces_[AutoDiffXd](plant)
    G = m.G
    nv, d = G.shape
    Z = np.zeros((nv, d))
    seeds = (np.hstack([G, Z, Z]), np.hstack([Z, G, Z]), np.hstack([Z, Z, G]))

    def call(q, qd, qdd):
        S = q.shape[0]
        out = [np.empty((S, d, d)) for _ in range(3)]
        for s in range(S):
            qa, va, aa = (InitializeAutoDiff(G @ x[s], g).ravel() for x, g in zip((q, qd, qdd), seeds))
            plant.SetPositions(ctx, qa)
            plant.SetVelocities(ctx, va)
            tau = plant.CalcInverseDynamics(ctx, aa, forces) - plant.CalcGravityGeneralizedForces(ctx)
            Jx = G.T @ ExtractGradient(tau)
            for k in range(3):
                out[k][s] = Jx[:, k * d : (k + 1) * d]
        return tuple(out)

    return call


def pinocchio_rnea_derivatives(mech: Mechanism):
    import pinocchio as pin

    from exo_bench.models.engines.pinocchio_backend import build_model

    pm = build_model(mech)
    data, G = pm.create_data(), pm.G

    def call(q, qd, qdd):
        S, d = q.shape
        out = [np.empty((S, d, d)) for _ in range(3)]
        for s in range(S):
            pin.computeRNEADerivatives(pm.model, data, G @ q[s], G @ qd[s], G @ qdd[s])
            for k, J in enumerate((data.dtau_dq, data.dtau_dv, data.M)):
                out[k][s] = G.T @ J @ G
        return tuple(out)

    return call
