"""MuJoCo backend (method ``mujoco``): MuJoCo's recursive Newton-Euler on the exported MJCF.

The model is the file of :func:`exo_bench.models.engines.mjcf.to_mjcf`, compiled once per mechanism by
:func:`load_model`, which then puts the exact point masses back (zero masses and every rotational
inertia to 0, after the compiler's ``boundmass``/``boundinertia`` floors: models/engines/mjcf.py) and
disables everything that is not the rigid model: contacts, limits, equality constraints (the
ties of the middle masses and undo hinges, which the map ``G`` replaces exactly), every
constraint, passive forces (springs, dampers), friction loss, actuation; armature, damping and
stiffness are set to zero. Why the ties are not used: models/engines/mjcf.py.

Inverse dynamics per sample: ``qpos = G q``, ``qvel = G qd``, ``qacc = G qdd``, then MuJoCo's
stages ``mj_kinematics``, ``mj_comPos``, ``mj_comVel`` and ``mj_rne(flg_acc=1)`` (the
``M qacc + c(q, qvel)`` of its RNE, gravity included), and ``tau = G^T tau_mj`` (virtual work:
models/engines/mjcf.py). The mass matrix: ``mj_kinematics``, ``mj_comPos``, ``mj_makeM`` (CRB), then
``mj_fullM``, mapped ``G^T M_mj G``. A batch is a **Python loop over samples** (MuJoCo's Python
API takes one ``MjData`` state at a time): each sample costs four or five calls from Python into
MuJoCo, each a few microseconds of binding overhead besides MuJoCo's own work.

Optional: ``pip install 'exo-bench[peers]'``; without MuJoCo, :class:`MujocoRNE` raises a
ValueError naming the extra.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np

from exo_bench.models.mechanism.coordinate_maps import rowwise_product
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.engines.mjcf import JointMap, check_nesting, joint_map, to_mjcf
from exo_bench.models.runtime.prepared import MissingExtra, PreparedModel

if TYPE_CHECKING:  # imported at run time only by import_mujoco (mujoco ships no stubs: its names are Any)
    import mujoco

EXTRA = "pip install 'exo-bench[peers]'"


def import_mujoco():
    """The ``mujoco`` module, or :class:`MissingExtra` (a ValueError) that names the extra to install."""
    try:
        import mujoco
    except ImportError as e:
        raise MissingExtra(
            f"mujoco: MuJoCo is not installed (no module {e.name or e}): {EXTRA} to use method 'mujoco' "
            "and to check exported MJCF files"
        ) from None
    return mujoco


def compile_mjcf(text: str, what: str = "MJCF"):
    """``mujoco.MjModel`` of an MJCF text, with MuJoCo's warnings while it compiles kept out of the
    terminal and out of a MUJOCO_LOG.TXT in the working directory (compiling runs the model at
    ``qpos0``, where every length is zero and the mass matrix singular: a warning that says nothing
    about the file). A compile error is a ValueError with MuJoCo's message."""
    mujoco = import_mujoco()
    previous = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda msg: None)
    try:
        return mujoco.MjModel.from_xml_string(text)
    except ValueError as e:
        raise ValueError(f"{what}: MuJoCo cannot compile it: {' '.join(str(e).split())}") from None
    finally:
        mujoco.set_mju_user_warning(previous)


@dataclass(frozen=True, eq=False)
class MujocoModel:
    """A mechanism's compiled MuJoCo model (exact point masses, only the rigid model enabled),
    with ``G`` (``q_mj = G q_paper``) and the body ids of each link's start, middle (-1: none)
    and end masses."""

    mechanism: Mechanism
    model: mujoco.MjModel
    G: np.ndarray  # (nv, dof)
    map: JointMap
    bodies: np.ndarray  # (n, 3) body ids


def exact_model(mech: Mechanism, model) -> None:
    """Put the exact point masses back into a compiled model of :func:`exo_bench.models.engines.mjcf.to_mjcf` and
    disable everything but the rigid model (in place)."""
    mujoco = import_mujoco()
    jm = joint_map(mech)
    for i, names in enumerate(jm.bodies):
        for name, mass in zip(names, mech.masses[i]):
            if name is not None:
                b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
                model.body_mass[b] = float(mass)  # the compiler raised 0 to BOUND
    model.body_inertia[:] = 0.0  # point masses: zero rotational inertia
    model.body_ipos[:] = 0.0
    model.dof_armature[:] = 0.0
    model.dof_damping[:] = 0.0
    model.jnt_stiffness[:] = 0.0
    model.dof_frictionloss[:] = 0.0
    D = mujoco.mjtDisableBit
    model.opt.disableflags |= int(
        D.mjDSBL_CONTACT
        | D.mjDSBL_LIMIT
        | D.mjDSBL_EQUALITY
        | D.mjDSBL_CONSTRAINT
        | D.mjDSBL_FRICTIONLOSS
        | D.mjDSBL_SPRING
        | D.mjDSBL_DAMPER
        | D.mjDSBL_ACTUATION
    )


@lru_cache(maxsize=64)
def load_model(mech: Mechanism) -> MujocoModel:
    """Compile (once per mechanism) the exported MJCF and make it exact (:func:`exact_model`)."""
    check_nesting(mech)  # MjcfTooDeep: deeper than MuJoCo's XML parser reads (known without MuJoCo)
    mujoco = import_mujoco()
    model = compile_mjcf(to_mjcf(mech), f"MJCF of {mech.name!r}")
    exact_model(mech, model)
    jm = joint_map(mech)
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j) for j in range(model.njnt)]
    if names != list(jm.joints) or model.nv != jm.G.shape[0] or list(model.jnt_dofadr) != list(range(model.njnt)):
        raise RuntimeError(f"mujoco: the compiled joints {names} are not the order of models.mjcf.joint_map")
    body = lambda name: -1 if name is None else mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
    bodies = np.array([[body(x) for x in names3] for names3 in jm.bodies], dtype=int)
    return MujocoModel(mech, model, jm.G, jm, bodies)


def body_positions(mech: Mechanism, q: np.ndarray) -> np.ndarray:
    """World positions of every point mass from MuJoCo's ``mj_kinematics`` (``d.xpos`` of the start,
    middle and end bodies), ``(S, n, 3, dim)``; a zero middle mass (no body) is interpolated."""
    mujoco = import_mujoco()
    mm = load_model(mech)
    data = mujoco.MjData(mm.model)
    q = np.atleast_2d(np.asarray(q, dtype=float))
    out = np.empty((q.shape[0], mech.nlinks, 3, mech.dim))
    for s in range(q.shape[0]):
        data.qpos[:] = mm.G @ q[s]
        mujoco.mj_kinematics(mm.model, data)
        for i in range(mech.nlinks):
            a, b, c = mm.bodies[i]
            start, end = data.xpos[a].copy(), data.xpos[c].copy()
            mid = data.xpos[b].copy() if b >= 0 else start + mech.n[i] * (end - start)
            out[s, i] = np.stack([start, mid, end])[:, : mech.dim]
    return out


class MujocoRNE(PreparedModel):
    """Method ``mujoco``: MuJoCo's RNE (``mj_kinematics``, ``mj_comPos``, ``mj_comVel``,
    ``mj_rne``) on the exported MJCF, ``tau = G^T tau_mj``; a Python loop over the samples.

    Prepared once: the compiled model (:func:`load_model`), ``G``, and per thread an ``MjData``.
    ``mass_matrix`` is MuJoCo's CRB (``mj_makeM``, ``mj_fullM``) mapped ``G^T M G``;
    ``bias_forces`` is ``mj_rne`` with ``flg_acc=0``. No options."""

    method = "mujoco"

    @classmethod
    def sample_bytes(cls, nlinks: int, dim: int) -> float:
        return 8.0 * 20 * dim * nlinks  # the cost model's figure (exo_bench.api.cost_formulas)

    def __init__(self, mechanism: Mechanism):
        super().__init__(mechanism)
        mm = load_model(mechanism)  # first: a depth MuJoCo cannot read is refused with or without MuJoCo
        self._mj = import_mujoco()
        self.mj_model = mm.model
        self.G = np.ascontiguousarray(mm.G)
        self.GT = np.ascontiguousarray(mm.G.T)
        self._local = threading.local()

    @property
    def data(self):
        """This thread's ``MjData`` (created on first use in each thread)."""
        d = getattr(self._local, "data", None)
        if d is None:
            d = self._local.data = self._mj.MjData(self.mj_model)
        return d

    def joint_torques(self, q, qd, qdd, acc: bool = True) -> np.ndarray:
        """MuJoCo's generalised forces in its own joint coordinates, ``(S, nv)``."""
        mj, model, data = self._mj, self.mj_model, self.data
        qj, vj = rowwise_product(q, self.GT), rowwise_product(qd, self.GT)
        aj = rowwise_product(qdd, self.GT) if acc else None
        out = np.empty((q.shape[0], model.nv))
        flg = 1 if acc else 0
        for s in range(q.shape[0]):
            data.qpos[:] = qj[s]
            data.qvel[:] = vj[s]
            if aj is not None:  # acc
                data.qacc[:] = aj[s]
            mj.mj_kinematics(model, data)
            mj.mj_comPos(model, data)
            mj.mj_comVel(model, data)
            mj.mj_rne(model, data, flg, out[s])
        return out

    def _inverse_dynamics(self, q, qd, qdd):
        return rowwise_product(self.joint_torques(q, qd, qdd), self.G)

    def _bias_forces(self, q, qd):
        return rowwise_product(self.joint_torques(q, qd, None, acc=False), self.G)

    def _mass_matrix(self, q):
        mj, model, data = self._mj, self.mj_model, self.data
        Mj = np.empty((model.nv, model.nv))
        out = np.empty((q.shape[0], self._dof, self._dof))
        qj = rowwise_product(q, self.GT)
        for s in range(q.shape[0]):
            data.qpos[:] = qj[s]
            mj.mj_kinematics(model, data)
            mj.mj_comPos(model, data)
            mj.mj_makeM(model, data)
            mj.mj_fullM(model, data, Mj)
            out[s] = self.GT @ Mj @ self.G
        return out

    def _external_forces(self, q, f):
        """``Q`` of forces ``f`` ``(S, links, 3, dim)`` at the point masses by MuJoCo's own
        ``xfrc_applied`` (force and torque at each body's centre of mass, world axes: the point mass,
        so no torque; MuJoCo's warnings while it runs are kept out of a MUJOCO_LOG.TXT): ``mj_forward`` at rest gives ``qfrc_smooth = J^T xfrc - qfrc_bias``, so
        ``Q_mj = qfrc_smooth + qfrc_bias`` and ``Q = G^T Q_mj``. A middle point without a body splits
        its force onto the start and the end (:func:`exo_bench.models.runtime.external_forces.point_forces`)."""
        from exo_bench.models.runtime.external_forces import point_forces

        mj, model, data = self._mj, self.mj_model, self.data
        bodies = load_model(self._mechanism).bodies
        qj = rowwise_product(q, self.GT)
        out = np.empty((q.shape[0], model.nv))
        previous = mj.get_mju_user_warning()  # mj_forward solves for qacc: its warnings about M say nothing here
        mj.set_mju_user_warning(lambda msg: None)
        try:
            for s in range(q.shape[0]):
                data.qpos[:], data.qvel[:], data.xfrc_applied[:] = qj[s], 0.0, 0.0
                for i, b, force in point_forces(self._mechanism, f[s]):
                    data.xfrc_applied[bodies[i, b], :3] += force
                mj.mj_forward(model, data)
                out[s] = data.qfrc_smooth + data.qfrc_bias
        finally:
            data.xfrc_applied[:] = 0.0
            mj.set_mju_user_warning(previous)
        return rowwise_product(out, self.G)
