"""Pinocchio backend: inverse dynamics, mass matrix and point positions in the paper's coordinates.

The model is built once per mechanism from :func:`exo_bench.models.engines.urdf.to_urdf` with mimic
joints (``buildModelFromXML(xml, mimic=True)``), and kept apart from the scratch
``Data``, as Pinocchio itself does.

**Memory: Pinocchio's ``Data`` grows as nv^3.** ``pin.Data(model)`` (``createData``) allocates,
and zero-fills, whatever algorithm will run: among its fields are four dense ``nv x nv x nv``
tensors of second-order derivatives (``d2tau_dqdq``, ``d2tau_dvdv``, ``d2tau_dqdv``,
``d2tau_dadq``) and the ``6 x nv x nv`` ``kinematic_hessians`` (pinocchio/multibody/data.hxx).
That is ``32 nv^3`` bytes whether or not those algorithms are ever called: 0.87 GB for a 3D
chain of 100 links (nv = 300), 23 GB for 300 links (nv = 900). ``model.createData()`` moreover
returns a copy, so its peak is twice that; ``pin.Data(model)`` builds in place, and is what the
backend uses. Neither the URDF's nesting nor
the mimic joints cause it (mimic joints make ``nv`` smaller: without them a 3D chain has
``nv = 5n - 1`` instead of ``3n``, and 4.4 times the memory); ``nv = dof`` is the least any
Pinocchio model of the mechanism can have. :func:`data_bytes` is the measured size, and the
backend checks it against the available memory before it creates a ``Data``
(:class:`PinocchioDataTooLarge`). Reproduction and the upstream report: docs/pinocchio-memory.md.

Every cache here holds models (kilobytes), never a ``Data``.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import pinocchio as pin

from exo_bench.models.mechanism.coordinate_maps import rowwise_product
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import as_states
from exo_bench.models.runtime.prepared import PreparedModel
from exo_bench.models.machine.memory import USABLE_SHARE, usable_memory
from exo_bench.models.machine.memory import check_count, check_thread_room, usable_cpus
from exo_bench.models.engines.urdf import (
    DATA_BYTES_PER_JOINT,  # noqa: F401
    data_bytes,  # noqa: F401
    link_prefix,  # noqa: F401
    pinocchio_data_bytes,  # noqa: F401
    pinocchio_model_size,  # noqa: F401
    to_urdf,  # noqa: F401
)


#: How errors name the option ``threads`` (bounded by :func:`exo_bench.models.machine.memory.max_count`).
THREADS_OPTION = "pinocchio: option 'threads'"


@dataclass(frozen=True, eq=False)
class PinocchioModel:
    """A mechanism's Pinocchio model, with the constant map ``G`` to joint coordinates.

    **Coordinates.** Pinocchio's joint coordinates are relative: link k's joints take
    ``phi_k - phi_parent``, ``psi_k`` and ``l_k`` (the 3D "undo" joint and the middle-mass
    joint are mimics, so they are not coordinates). The paper's coordinates are absolute
    angles. The map between the two is linear and constant,
    ``q_joint = G q_paper``, so also ``qd_joint = G qd_paper`` and ``qdd_joint = G qdd_paper``.
    Virtual work is the same in both sets, ``tau_joint . dq_joint = tau_paper . dq_paper`` for
    every ``dq_paper``, hence **``tau_paper = G^T tau_joint``** exactly, and the mass matrix
    transforms as ``M_paper = G^T M_joint G``. ``G`` is square and unit lower triangular up to
    ordering, so it is invertible.

    ``tau_joint`` holds the physical joint moments (each the sum over its subtree),
    ``tau_paper`` the generalised forces of the absolute angles (eq. 4 has ``M1 - M2`` on
    ``phi_1``).
    """

    mechanism: Mechanism
    model: pin.Model
    G: np.ndarray  # (nv, dof)
    joint_names: tuple[str, ...]  # name of the joint of each row of G
    frames: np.ndarray  # (n, 3) frame ids of the start, middle, end bodies (-1: no middle body)

    def create_data(self) -> pin.Data:
        """A new scratch ``Data`` (``32 nv^3`` bytes and more: :func:`data_bytes`), after checking
        that it fits in the available memory. Never cached here: the model cache would keep it."""
        check_data_fits(self.mechanism)
        return pin.Data(self.model)  # in place: createData() returns a copy, twice the peak

    @property
    def data(self) -> pin.Data:
        """A new scratch ``Data`` (see :meth:`create_data`)."""
        return self.create_data()


# ----------------------------------------------------------------------------- memory of Data
# The size formulas live in models/engines/urdf.py (no Pinocchio import needed to estimate them).
model_size = pinocchio_model_size
mechanism_data_bytes = pinocchio_data_bytes


class PinocchioDataTooLarge(MemoryError):
    """A ``pin.Data`` would not fit in the available memory; the message says how large it is,
    why, and what fits. ``budget`` names the limit (bytes)."""

    def __init__(self, mech: Mechanism, need: int, limit: int, count: int = 1):
        nv, nj = model_size(mech)
        self.need, self.limit, self.budget = need, limit, limit
        what = "one pin.Data" if count == 1 else f"{count} pin.Data (one per thread)"
        super().__init__(
            f"pinocchio: {what} for {mech.name!r} ({mech.dim}D, {mech.nlinks} links, nv = {nv}) needs "
            f"{_gb(need * count)}, more than the {_gb(limit)} of memory it may use ({USABLE_SHARE:.0%} of the memory available now, so "
            f"that the machine is not driven out of memory): Pinocchio allocates four nv^3 tensors in every Data "
            f"(docs/pinocchio-memory.md); use method matrix-factored"
        )


def _gb(x: float) -> str:
    return f"{x / 1e9:.2f} GB" if x >= 1e8 else f"{x / 1e6:.1f} MB"


def check_data_fits(mech: Mechanism, count: int = 1, limit: int | None = None) -> int:
    """Raise :class:`PinocchioDataTooLarge` unless ``count`` Data of the mechanism fit in ``limit``
    bytes (default: :func:`exo_bench.models.machine.memory.usable_memory`, a share of the available memory); return
    the bytes of one Data."""
    need = mechanism_data_bytes(mech)
    limit = usable_memory() if limit is None else limit
    if limit is not None and need * count > limit:
        raise PinocchioDataTooLarge(mech, need, limit, count)
    return need


@lru_cache(maxsize=64)
def build_model(mech: Mechanism) -> PinocchioModel:
    """Build (once per mechanism) the Pinocchio model from the generated URDF. The cache holds
    the model (kilobytes per link), never a ``Data``."""
    model = pin.buildModelFromXML(to_urdf(mech), mimic=True)
    model.gravity.linear = np.array([0.0, -mech.g, 0.0] if mech.dim == 2 else [0.0, 0.0, -mech.g])
    n = mech.nlinks
    G = np.zeros((model.nv, mech.dof))
    names = [""] * model.nv
    col = {"phi": 0, "psi": n, "l": (2 if mech.dim == 3 else 1) * n}
    frames = -np.ones((n, 3), dtype=int)
    for i in range(n):
        k = link_prefix(mech, i)
        p = mech.parent[i]
        rows = [("phi", i)] + ([("psi", i)] if mech.dim == 3 else []) + [("len", i)]
        for kind, _ in rows:
            jid = model.getJointId(f"{k}_{kind}")
            v = model.idx_vs[jid]
            names[v] = f"{k}_{kind}"
            if kind == "phi":
                G[v, col["phi"] + i] = 1.0  # phi_k ...
                if p >= 0:
                    G[v, col["phi"] + p] = -1.0  # ... minus phi_parent: a relative angle
            elif kind == "psi":
                G[v, col["psi"] + i] = 1.0  # psi_k is already absolute (the undo joint levels)
            else:
                G[v, col["l"] + i] = 1.0  # l_k
        frames[i, 0] = model.getFrameId(f"{k}_frame", pin.FrameType.BODY)
        frames[i, 2] = model.getFrameId(f"{k}_end", pin.FrameType.BODY)
        if mech.masses[i][1] > 0:
            frames[i, 1] = model.getFrameId(f"{k}_mid", pin.FrameType.BODY)
    return PinocchioModel(mech, model, G, tuple(names), frames)


def _joint_states(pm: PinocchioModel, q, qd, qdd):
    GT = np.ascontiguousarray(pm.G.T)
    return tuple(None if x is None else rowwise_product(x, GT) for x in (q, qd, qdd))


def joint_torques(mech: Mechanism, q, qd, qdd) -> np.ndarray:
    """RNEA in Pinocchio's joint coordinates: the physical joint moments and rod forces, ``(S, nv)``.

    Rows follow :attr:`PinocchioModel.joint_names`.
    """
    q, qd, qdd = as_states(mech, q, qd, qdd)
    pm = build_model(mech)
    data, model = pm.create_data(), pm.model
    qj, vj, aj = _joint_states(pm, q, qd, qdd)
    return np.stack([pin.rnea(model, data, qj[s], vj[s], aj[s]) for s in range(q.shape[0])])


def inverse_dynamics(mech: Mechanism, q, qd, qdd) -> np.ndarray:
    """Generalised forces ``[M_phi..., M_psi..., F...]`` in the paper's coordinates, ``(S, dof)``.

    One ``pin.rnea`` call per sample, then ``tau_paper = G^T tau_joint``.
    """
    return rowwise_product(joint_torques(mech, q, qd, qdd), build_model(mech).G)


def inverse_dynamics_parallel(mech: Mechanism, q, qd, qdd, threads: int | None = None) -> np.ndarray:
    """The same as :func:`inverse_dynamics`, batched through ``pin.rneaInParallel``."""
    q, qd, qdd = as_states(mech, q, qd, qdd)
    threads = check_count(THREADS_OPTION, usable_cpus() if threads is None else threads)
    pm = build_model(mech)
    need = check_data_fits(mech, threads + 1)  # the pool's Data, and one more while it copies them
    check_thread_room(THREADS_OPTION, threads, (threads + 1) * need)
    qj, vj, aj = _joint_states(pm, q, qd, qdd)
    f = lambda x: np.asfortranarray(x.T)
    tau = np.asfortranarray(np.zeros((pm.model.nv, q.shape[0])))
    pin.rneaInParallel(threads, pin.ModelPool(pm.model, threads), f(qj), f(vj), f(aj), tau)
    return rowwise_product(tau.T, pm.G)


def mass_matrix(mech: Mechanism, q) -> np.ndarray:
    """Mass matrix in the paper's coordinates, ``G^T M_joint G`` from CRBA, ``(S, dof, dof)``."""
    q, _, _ = as_states(mech, q)
    pm = build_model(mech)
    qj = rowwise_product(q, pm.G.T)
    data = pm.create_data()
    out = np.empty((q.shape[0], mech.dof, mech.dof))
    for s in range(q.shape[0]):
        out[s] = pm.G.T @ crba(pm.model, data, qj[s]) @ pm.G
    return out


def crba(model: pin.Model, data: pin.Data, qj: np.ndarray) -> np.ndarray:
    """The symmetric joint-space mass matrix by ``pin.crba``, correct when ``data`` is reused.

    On a model with a mimic joint (every 3D model with more than one link) pin 4.1's CRBA reads
    ``data.Fcrb`` as left by the previous call, so a reused ``Data`` gives a wrong matrix (the
    reproduction is in docs/pinocchio-memory.md). Zeroing ``Fcrb`` first gives the fresh-Data
    result at ``O(njoints nv)`` cost instead of a new ``Data`` (``32 nv^3`` bytes) per sample.
    """
    for F in data.Fcrb:
        F[...] = 0.0
    M = pin.crba(model, data, qj)
    return np.triu(M) + np.triu(M, 1).T  # CRBA fills the upper triangle


def bias_forces(mech: Mechanism, q, qd) -> np.ndarray:
    """Coriolis, centrifugal and gravity forces ``h(q, qd)`` in the paper's coordinates, ``(S, dof)``."""
    q, qd, _ = as_states(mech, q, qd)
    pm = build_model(mech)
    data = pm.create_data()
    qj, vj, _ = _joint_states(pm, q, qd, None)
    return rowwise_product(
        np.stack([pin.nonLinearEffects(pm.model, data, qj[s], vj[s]) for s in range(q.shape[0])]), pm.G
    )


def point_mass_positions(mech: Mechanism, q) -> np.ndarray:
    """World positions of every point mass from Pinocchio's frames, ``(S, n, 3, dim)``.

    A middle mass of zero has no body; its point is interpolated at fraction ``n`` so that
    the stick figure is still complete.
    """
    q, _, _ = as_states(mech, q)
    pm = build_model(mech)
    data = pm.create_data()
    qj = rowwise_product(q, pm.G.T)
    n = mech.nlinks
    out = np.empty((q.shape[0], n, 3, mech.dim))
    for s in range(q.shape[0]):
        pin.framesForwardKinematics(pm.model, data, qj[s])
        for i in range(n):
            start = data.oMf[int(pm.frames[i, 0])].translation
            end = data.oMf[int(pm.frames[i, 2])].translation
            mid = (
                data.oMf[int(pm.frames[i, 1])].translation
                if pm.frames[i, 1] >= 0
                else start + mech.n[i] * (end - start)
            )
            out[s, i] = np.stack([start, mid, end])[:, : mech.dim]
    return out


class PinocchioRNEA(PreparedModel):
    """Method ``pinocchio``: ``pin.rnea`` on the generated URDF's model, ``tau = G^T tau_joint``.

    Prepared once: the Pinocchio model (:func:`build_model`), ``G``, and per thread a ``Data``
    (never shared between threads). Options:

    * ``threads`` (default 1): batches of more than one sample go through ``pin.rneaInParallel``
      with this many threads and a ``ModelPool`` built once; 1 loops ``pin.rnea`` in Python.

    ``mass_matrix`` is CRBA (:func:`crba`: ``data.Fcrb`` zeroed before each call, as pin 4.1's CRBA
    on a mimic joint reads what the previous call left there) and ``bias_forces`` is
    ``nonLinearEffects``, both mapped by ``G``.

    **Memory.** Each ``Data`` is :func:`data_bytes` (``32 nv^3`` bytes and more); the model holds
    one per thread that calls it, plus ``threads`` in the ``ModelPool`` when ``threads > 1``. The
    constructor checks that they fit in the available memory and raises
    :class:`PinocchioDataTooLarge` (a ``MemoryError`` with a one-line message) when they do not.
    """

    method = "pinocchio"

    @classmethod
    def sample_bytes(cls, nlinks: int, dim: int) -> float:
        n, d = nlinks, dim
        return 8.0 * (10 * d * n)

    def __init__(self, mechanism: Mechanism, threads: int = 1):
        threads = check_count(THREADS_OPTION, threads)  # 1 to 4 per CPU (models/machine/memory.py)
        super().__init__(mechanism, threads=threads)
        self.threads = threads
        # this thread's Data, and the pool's (its construction copies one more: threads + 1 at its peak)
        self.data_bytes = check_data_fits(mechanism, 1 + (threads + 1 if threads > 1 else 0))
        if threads > 1:  # OpenMP's threads: their stacks and the pool's Data within ulimit -v, before any starts
            check_thread_room(THREADS_OPTION, threads, (threads + 1) * self.data_bytes)
        pm = build_model(mechanism)
        self.pin_model: pin.Model = pm.model
        self.G: np.ndarray = np.ascontiguousarray(pm.G)
        self.GT: np.ndarray = np.ascontiguousarray(pm.G.T)
        self.joint_names = pm.joint_names
        self._local = threading.local()
        self._pool = pin.ModelPool(pm.model, self.threads) if self.threads > 1 else None

    @property
    def data(self) -> pin.Data:
        """This thread's scratch ``Data`` (created on first use in each thread)."""
        d = getattr(self._local, "data", None)
        if d is None:
            d = self._local.data = pin.Data(self.pin_model)  # in place (createData(): twice the peak)
        return d

    def joint_torques(self, q, qd, qdd, check: bool = True) -> np.ndarray:
        """The physical joint moments and rod forces ``(S, nv)`` (rows: :attr:`joint_names`)."""
        if check:
            q, qd, qdd = as_states(self._mechanism, q, qd, qdd)
        GT = self.GT
        qj, vj, aj = rowwise_product(q, GT), rowwise_product(qd, GT), rowwise_product(qdd, GT)
        if self._pool is not None and q.shape[0] > 1:
            f = lambda x: np.asfortranarray(x.T)
            tau = np.zeros((self.pin_model.nv, q.shape[0]), order="F")
            pin.rneaInParallel(self.threads, self._pool, f(qj), f(vj), f(aj), tau)
            return tau.T
        model, data = self.pin_model, self.data
        out = np.empty((q.shape[0], self.pin_model.nv))
        for s in range(q.shape[0]):
            out[s] = pin.rnea(model, data, qj[s], vj[s], aj[s])
        return out

    def _inverse_dynamics(self, q, qd, qdd):
        return rowwise_product(self.joint_torques(q, qd, qdd, check=False), self.G)

    def _mass_matrix(self, q):
        qj = rowwise_product(q, self.GT)
        out = np.empty((q.shape[0], self._dof, self._dof))
        model, data = self.pin_model, self.data
        for s in range(q.shape[0]):
            out[s] = self.GT @ crba(model, data, qj[s]) @ self.G
        return out

    def _bias_forces(self, q, qd):
        qj, vj = rowwise_product(q, self.GT), rowwise_product(qd, self.GT)
        model, data = self.pin_model, self.data
        out = np.empty((q.shape[0], self.pin_model.nv))  # (0, nv) for no samples
        for s in range(q.shape[0]):
            out[s] = pin.nonLinearEffects(model, data, qj[s], vj[s])
        return rowwise_product(out, self.G)

    def _external_forces(self, q, f):
        """``Q`` of forces ``f`` ``(S, links, 3, dim)`` at the point masses by Pinocchio's own ``fext``:
        ``-rnea(q, 0, 0, fext)`` on the model without gravity, ``fext`` a spatial force per joint in its
        local frame (the point force ``R^T f`` with the moment ``R^T ((P - p) x f)`` about the joint at
        ``p``, ``P`` the frame of the point mass); a middle point without a body (zero mass) splits its
        force ``(1 - n) : n`` onto the start and the end, which does the same virtual work."""
        from exo_bench.models.runtime.external_forces import point_forces

        pm = build_model(self._mechanism)
        model = getattr(self, "_no_gravity", None)
        if model is None:
            model = self._no_gravity = pin.Model(self.pin_model)
            model.gravity.linear = np.zeros(3)
        data, mech = self.data, self._mechanism
        qj, zero = rowwise_product(q, self.GT), np.zeros(model.nv)
        out = np.empty((q.shape[0], model.nv))
        for s in range(q.shape[0]):
            pin.framesForwardKinematics(model, data, qj[s])
            fext = [pin.Force.Zero() for _ in range(model.njoints)]
            for i, b, force in point_forces(mech, f[s]):
                frame = model.frames[int(pm.frames[i, b])]
                oMi = data.oMi[frame.parentJoint]
                lever = data.oMf[int(pm.frames[i, b])].translation - oMi.translation
                fext[frame.parentJoint] += pin.Force(oMi.rotation.T @ force, oMi.rotation.T @ np.cross(lever, force))
            out[s] = -pin.rnea(model, data, qj[s], zero, zero, fext)
        return rowwise_product(out, self.G)
