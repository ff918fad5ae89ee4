"""Drake backend (method ``drake``): ``MultibodyPlant.CalcInverseDynamics`` on the mechanism.

**The plant is built in code**, joint by joint, not parsed from the generated URDF: Drake's URDF
parser turns each ``<mimic>`` tag into a *coupler constraint* (checked with Drake 1.51: the URDF of
fig2a-3d gives 3 constraints, and a floating base unless the support is welded), which Drake's
constraint solvers enforce in simulation and ``CalcInverseDynamics`` (an unconstrained RNE on the
tree) ignores. So, as for MuJoCo (models/engines/mjcf.py), the joints that the URDF makes mimics (the 3D "undo"
hinge that levels a child's frame, the middle mass's slide) are joints of their own here, and
Drake's coordinates are linear in the paper's, ``q_dk = G q_paper``; on a motion in the image of
``G``, virtual work gives ``tau_paper = G^T tau_dk`` and ``M_paper = G^T M_dk G`` exactly (the
constraint forces that would keep the motion there lie in the null space of ``G^T``).

Per link ``k``, bodies and joints as in the URDF (models/engines/urdf.py): 3D non-root: revolute ``undo``
about ``-y`` (value ``-psi_parent``) into a massless ``level`` body; revolute ``phi`` about ``z``
(``phi_k - phi_parent``) into a massless ``yaw`` body (2D: straight into ``frame``); 3D: revolute
``psi`` about ``-y`` (``psi_k``) into ``frame``, which carries ``m_k0``; prismatic ``len`` along
``sign_k x`` (``l_k``) into ``end`` (``m_k2``); prismatic ``mid`` along ``sign_k x`` (``n_k l_k``)
into ``mid`` (``m_k1``, omitted when zero). Point masses are ``SpatialInertia(m, 0, UnitInertia(0,
0, 0))``: Drake accepts zero rotational inertia and massless bodies (checked with Drake 1.51),
so no floor is needed. Joint damping is 0 and limits are infinite; the plant is continuous
(``time_step = 0``) and has no geometry, so no contact.

Inverse dynamics per sample: ``SetPositions``, ``SetVelocities`` (every call: Drake caches the
kinematics in its context and recomputes what the new state invalidates), then
``CalcInverseDynamics(context, G qdd, zero MultibodyForces) - CalcGravityGeneralizedForces``
(Drake's inverse dynamics leaves gravity out: it is an applied force there). Mass matrix:
``CalcMassMatrix``. A batch is a **Python loop over samples**: each costs four calls into Drake
through pybind11, and Drake's own ``MultibodyForces``/cache bookkeeping, tens of microseconds
beside the RNE itself.

Optional: ``pip install 'exo-bench[peers]'``; without Drake, :class:`DrakeID` raises a ValueError
naming the extra.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np

from exo_bench.models.mechanism.coordinate_maps import rowwise_product
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.runtime.prepared import MissingExtra, PreparedModel
from exo_bench.models.engines.urdf import link_prefix

if TYPE_CHECKING:  # pydrake ships stubs; at run time it is imported only by import_drake
    from pydrake.multibody.plant import MultibodyPlant
    from pydrake.multibody.tree import Joint, RigidBody

EXTRA = "pip install 'exo-bench[peers]'"


def import_drake():
    """``(MultibodyPlant, tree module)`` of pydrake, or :class:`MissingExtra` (a ValueError) that names the extra."""
    try:
        from pydrake.multibody import plant, tree
    except ImportError as e:
        raise MissingExtra(
            f"drake: Drake is not installed (no module {e.name or e}): {EXTRA} to use method 'drake'"
        ) from None
    return plant, tree


@dataclass(frozen=True, eq=False)
class DrakePlant:
    """A mechanism's finalized plant, ``G`` (``q_dk = G q_paper``), the joint name of each row of
    ``G``, and the body names of each link's start, middle (None) and end masses."""

    mechanism: Mechanism
    plant: MultibodyPlant
    G: np.ndarray
    joints: tuple[str, ...]
    bodies: tuple[tuple[str, str | None, str], ...]


@lru_cache(maxsize=64)
def build_plant(mech: Mechanism) -> DrakePlant:
    """Build and finalize (once per mechanism) the plant described in the module docstring."""
    mbp, tree = import_drake()
    plant = mbp.MultibodyPlant(0.0)
    plant.mutable_gravity_field().set_gravity_vector([0.0, -mech.g, 0.0] if mech.dim == 2 else [0.0, 0.0, -mech.g])
    n = mech.nlinks
    psi0, l0 = n, (2 if mech.dim == 3 else 1) * n
    zero = tree.UnitInertia(0.0, 0.0, 0.0)
    joints: list[tuple[Joint, dict[int, float]]] = []
    ends: dict[int, RigidBody] = {}

    def body(name: str, mass: float = 0.0) -> RigidBody:
        return plant.AddRigidBody(name, tree.SpatialInertia(float(mass), np.zeros(3), zero))

    def joint(kind, name, parent, child, axis, coef):
        joints.append(
            (plant.AddJoint(kind(name, parent.body_frame(), child.body_frame(), np.asarray(axis, float))), coef)
        )

    bodies = []
    for i in range(n):  # parents come before their children
        k, p = link_prefix(mech, i), mech.parent[i]
        m0, m1, m2 = mech.masses[i]
        base = ends[p] if p >= 0 else plant.world_body()
        if mech.dim == 3:
            if p >= 0:
                level = body(f"{k}_level")
                joint(tree.RevoluteJoint, f"{k}_undo", base, level, [0, -1, 0], {psi0 + p: -1.0})
                base = level
            yaw = body(f"{k}_yaw")
            joint(tree.RevoluteJoint, f"{k}_phi", base, yaw, [0, 0, 1], {i: 1.0} if p < 0 else {i: 1.0, p: -1.0})
            frame = body(f"{k}_frame", m0)
            joint(tree.RevoluteJoint, f"{k}_psi", yaw, frame, [0, -1, 0], {psi0 + i: 1.0})
        else:
            frame = body(f"{k}_frame", m0)
            joint(tree.RevoluteJoint, f"{k}_phi", base, frame, [0, 0, 1], {i: 1.0} if p < 0 else {i: 1.0, p: -1.0})
        axis = [float(mech.sign[i]), 0.0, 0.0]
        ends[i] = body(f"{k}_end", m2)
        joint(tree.PrismaticJoint, f"{k}_len", frame, ends[i], axis, {l0 + i: 1.0})
        if m1 > 0.0:
            mid = body(f"{k}_mid", m1)
            joint(tree.PrismaticJoint, f"{k}_mid", frame, mid, axis, {l0 + i: float(mech.n[i])})
        bodies.append((f"{k}_frame", f"{k}_mid" if m1 > 0.0 else None, f"{k}_end"))
    plant.Finalize()
    G = np.zeros((plant.num_velocities(), mech.dof))
    names = [""] * plant.num_velocities()
    for j, coef in joints:
        v = j.velocity_start()
        if j.position_start() != v:
            raise RuntimeError(f"drake: joint {j.name()} has position index {j.position_start()} != velocity index {v}")
        names[v] = j.name()
        for c, x in coef.items():
            G[v, c] = x
    if plant.num_positions() != plant.num_velocities():
        raise RuntimeError("drake: the plant has more positions than velocities")
    return DrakePlant(mech, plant, G, tuple(names), tuple(bodies))


def body_positions(mech: Mechanism, q: np.ndarray) -> np.ndarray:
    """World positions of every point mass from Drake's body poses, ``(S, n, 3, dim)``; a zero middle
    mass (no body) is interpolated."""
    dp = build_plant(mech)
    plant = dp.plant
    ctx = plant.CreateDefaultContext()
    q = np.atleast_2d(np.asarray(q, dtype=float))
    out = np.empty((q.shape[0], mech.nlinks, 3, mech.dim))
    for s in range(q.shape[0]):
        plant.SetPositions(ctx, dp.G @ q[s])
        for i, (a, b, c) in enumerate(dp.bodies):
            X = lambda name: plant.EvalBodyPoseInWorld(ctx, plant.GetBodyByName(name)).translation()
            start, end = X(a), X(c)
            # pydrake's stubs put the shape in ndarray's dtype slot (ndarray[float64[3, 1]]): mypy refuses its arithmetic
            mid = X(b) if b is not None else start + mech.n[i] * (end - start)  # type: ignore[misc, unused-ignore]  # (unused without drake)
            out[s, i] = np.stack([start, mid, end])[:, : mech.dim]
    return out


class DrakeID(PreparedModel):
    """Method ``drake``: ``CalcInverseDynamics - CalcGravityGeneralizedForces`` on a plant built in
    code, ``tau = G^T tau_dk``; a Python loop over the samples, the state set on every call.

    Prepared once: the plant (:func:`build_plant`), ``G``, and per thread a context and a zero
    ``MultibodyForces``. ``mass_matrix`` is ``CalcMassMatrix`` mapped ``G^T M G``. No options."""

    method = "drake"

    @classmethod
    def sample_bytes(cls, nlinks: int, dim: int) -> float:
        return 8.0 * 20 * dim * nlinks  # the cost model's figure (exo_bench.api.cost_formulas)

    def __init__(self, mechanism: Mechanism):
        super().__init__(mechanism)
        _, self._tree = import_drake()
        dp = build_plant(mechanism)
        self.plant = dp.plant
        self.G = np.ascontiguousarray(dp.G)
        self.GT = np.ascontiguousarray(dp.G.T)
        self.joint_names = dp.joints
        self._local = threading.local()

    def _scratch(self):
        s = getattr(self._local, "scratch", None)
        if s is None:
            s = self._local.scratch = (self.plant.CreateDefaultContext(), self._tree.MultibodyForces(self.plant))
        return s

    def joint_torques(self, q, qd, qdd) -> np.ndarray:
        """Drake's generalised forces in its joint coordinates, gravity included, ``(S, nv)``."""
        plant = self.plant
        ctx, forces = self._scratch()
        qj, vj, aj = rowwise_product(q, self.GT), rowwise_product(qd, self.GT), rowwise_product(qdd, self.GT)
        out = np.empty_like(qj)
        for s in range(q.shape[0]):
            plant.SetPositions(ctx, qj[s])
            plant.SetVelocities(ctx, vj[s])
            # pydrake's stubs put the shape in ndarray's dtype slot (ndarray[float64[m, 1]]): mypy refuses its arithmetic
            out[s] = plant.CalcInverseDynamics(ctx, aj[s], forces) - plant.CalcGravityGeneralizedForces(ctx)  # type: ignore[misc, unused-ignore]  # (unused without drake)
        return out

    def _inverse_dynamics(self, q, qd, qdd):
        return rowwise_product(self.joint_torques(q, qd, qdd), self.G)

    def _mass_matrix(self, q):
        plant = self.plant
        ctx, _ = self._scratch()
        qj = rowwise_product(q, self.GT)
        out = np.empty((q.shape[0], self._dof, self._dof))
        for s in range(q.shape[0]):
            plant.SetPositions(ctx, qj[s])
            out[s] = self.GT @ plant.CalcMassMatrix(ctx) @ self.G
        return out

    def _external_forces(self, q, f):
        """``Q`` of forces ``f`` ``(S, links, 3, dim)`` at the point masses by Drake's applied spatial
        forces: each added to a ``MultibodyForces`` at its body's origin (the point mass) in world axes
        (``RigidBody.AddInForce``); at rest ``CalcInverseDynamics(0, forces) = -J^T F`` (Drake leaves
        gravity out of it), so ``Q_dk`` is its negative and ``Q = G^T Q_dk``. A middle point without a
        body splits its force onto the start and the end (:func:`exo_bench.models.runtime.external_forces.point_forces`)."""
        from pydrake.multibody.math import SpatialForce

        from exo_bench.models.runtime.external_forces import point_forces

        plant, mech = self.plant, self._mechanism
        ctx, _ = self._scratch()
        forces = self._tree.MultibodyForces(plant)
        names = build_plant(mech).bodies
        qj, zero = rowwise_product(q, self.GT), np.zeros(plant.num_velocities())
        out = np.empty_like(qj)
        for s in range(q.shape[0]):
            plant.SetPositions(ctx, qj[s])
            plant.SetVelocities(ctx, zero)
            forces.SetZero()
            for i, b, force in point_forces(mech, f[s]):
                body = plant.GetBodyByName(names[i][b])
                body.AddInForce(ctx, np.zeros(3), SpatialForce(np.zeros(3), force), plant.world_frame(), forces)
            out[s] = -plant.CalcInverseDynamics(ctx, zero, forces)
        return rowwise_product(out, self.G)
