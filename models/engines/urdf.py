"""URDF generation for any mechanism.

Every link ``k`` (1-based) of the mechanism becomes this kinematic chain:

* 3D, non-root only: ``Lk_undo``, a revolute *mimic* of the parent's ``psi`` joint
  (same axis, multiplier -1) that levels the frame again, so that the next joint
  measures an *absolute* azimuth as the paper does;
* ``Lk_phi``: revolute about z (value ``phi_k - phi_parent``);
* 3D only: ``Lk_psi``: revolute about -y (value ``psi_k``, the elevation of eq. 7);
* ``Lk_len``: prismatic along ``sign_k * x`` (value ``l_k``), ending at ``Lk_end``;
* ``Lk_mid``: prismatic *mimic* of ``Lk_len`` with multiplier ``n_k``: the sliding
  middle mass (omitted when ``m_k1 = 0``).

Point masses are inertial-only links with zero rotational inertia: ``m_k0`` on
``Lk_frame`` (the start of the rod), ``m_k1`` on ``Lk_mid``, ``m_k2`` on ``Lk_end``.
A zero mass adds no inertial element (and no body for the middle mass). A 2D
model has only z-revolute and in-plane prismatic joints; Pinocchio's gravity is
set to ``-y`` for it by the backend.

Pinocchio (via urdfdom) visits sibling joints in the order of their names, and a
mimic joint must come after the joint it mimics; ``len`` sorts before ``mid``.
"""

from __future__ import annotations

from exo_bench.models.files import xml_attr, xml_comment
from exo_bench.models.mechanism.mechanism import Mechanism

_LIMIT = '<limit effort="1e6" velocity="1e6" lower="-1e3" upper="1e3"/>'


def link_prefix(mech: Mechanism, i: int) -> str:
    """Prefix of every URDF element of link i (0-based): ``L<k>`` with k 1-based, zero-padded."""
    width = len(str(mech.nlinks))
    return f"L{i + 1:0{width}d}"


def _inertial(mass: float) -> str:
    if mass == 0.0:
        return ""
    return (
        f'<inertial><origin xyz="0 0 0" rpy="0 0 0"/><mass value="{mass!r}"/>'
        '<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>'
    )


def _link(name: str, mass: float = 0.0, comment: str = "") -> str:
    c = f"<!-- {comment} -->" if comment else ""
    return f'  <link name="{name}">{c}{_inertial(mass)}</link>'


def _joint(name: str, kind: str, parent: str, child: str, axis: str, mimic: tuple[str, float] | None = None) -> str:
    m = f'<mimic joint="{mimic[0]}" multiplier="{mimic[1]!r}" offset="0"/>' if mimic else ""
    return (
        f'  <joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="{axis}"/>{_LIMIT}{m}</joint>'
    )


def to_urdf(mech: Mechanism) -> str:
    """The URDF text of a mechanism (planar joints for 2D, spatial for 3D)."""
    lines = ['<?xml version="1.0"?>', f"<robot name={xml_attr(mech.name)}>", '  <link name="support"/>']
    for i in range(mech.nlinks):
        k = link_prefix(mech, i)
        p = mech.parent[i]
        m0, m1, m2 = mech.masses[i]
        lines.append(
            f"  <!-- link {i + 1}: {xml_comment(mech.names[i])}, parent {p + 1 if p >= 0 else 'support'}, "
            f"sign {mech.sign[i]:+d}, n = {mech.n[i]!r} -->"
        )
        base = f"{link_prefix(mech, p)}_end" if p >= 0 else "support"
        if mech.dim == 3:
            if p >= 0:
                pk = link_prefix(mech, p)
                lines.append(_joint(f"{k}_undo", "revolute", base, f"{k}_level", "0 -1 0", (f"{pk}_psi", -1.0)))
                lines.append(_link(f"{k}_level"))
                base = f"{k}_level"
            lines.append(_joint(f"{k}_phi", "revolute", base, f"{k}_yaw", "0 0 1"))
            lines.append(_link(f"{k}_yaw"))
            lines.append(_joint(f"{k}_psi", "revolute", f"{k}_yaw", f"{k}_frame", "0 -1 0"))
        else:
            lines.append(_joint(f"{k}_phi", "revolute", base, f"{k}_frame", "0 0 1"))
        axis = f"{mech.sign[i]} 0 0"
        lines.append(_link(f"{k}_frame", m0, "start mass m0"))
        lines.append(_joint(f"{k}_len", "prismatic", f"{k}_frame", f"{k}_end", axis))
        lines.append(_link(f"{k}_end", m2, "end mass m2"))
        if m1 > 0.0:
            lines.append(_joint(f"{k}_mid", "prismatic", f"{k}_frame", f"{k}_mid", axis, (f"{k}_len", mech.n[i])))
            lines.append(_link(f"{k}_mid", m1, "sliding middle mass m1"))
    lines.append("</robot>")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------------ size of the Pinocchio model and Data
#: Bytes of a ``pin.Data`` beyond its dense arrays: per joint, and once. Measured as the growth of
#: the peak RSS of a fresh process across ``pin.Data(model)`` minus the dense part of
#: :func:`data_bytes`, on 2D and 3D chains of 10 to 60 links (pin 4.1, x86-64): 10 to 15 kB per
#: joint and up to 0.5 MB once, rounded up.
DATA_BYTES_PER_JOINT = 20_000
DATA_BYTES_ONCE = 2**20


def pinocchio_model_size(mech: Mechanism) -> tuple[int, int]:
    """``(nv, njoints)`` of the Pinocchio model of :func:`to_urdf`, without building it: ``nv =
    dof`` (mimic joints have no velocity of their own); joints: the universe, then per link
    ``phi``, (3D) ``psi`` and, below the root, the mimic ``undo``, ``len``, and the mimic ``mid``
    when the middle mass is not zero."""
    n = mech.nlinks
    per_link = 2 if mech.dim == 2 else 3
    undo = sum(1 for p in mech.parent if p >= 0) if mech.dim == 3 else 0
    mid = sum(1 for m in mech.masses if m[1] > 0)
    return mech.dof, 1 + per_link * n + undo + mid


def data_bytes(nv: int, njoints: int) -> int:
    """Bytes of one ``pin.Data`` of a model with ``nv`` velocities and ``njoints`` joints (pin 4.1).

    Dense part, from the constructor (pinocchio/multibody/data.hxx): four ``nv^3`` tensors of
    second-order derivatives and the ``6 nv^2`` kinematic Hessians, allocated whatever algorithm
    runs; ten ``nv x nv`` matrices (M, Minv, C, U, dtau_dq, dtau_dv, ddq_dq, ddq_dv, ddq_dtau,
    sDUiJt); the ``nv x 10 (njoints - 1)`` joint-torque regressor and one ``6 x nv`` Fcrb per joint;
    all float64. Plus :data:`DATA_BYTES_PER_JOINT` per joint and :data:`DATA_BYTES_ONCE`. Against
    the peak RSS growth of ``pin.Data(model)`` (docs/pinocchio-memory.md): 3D chain of 60 links
    predicted 205 MB, measured 200 MB. ``model.createData()`` peaks at twice this (it returns a copy).
    """
    dense = 4 * nv**3 + 6 * nv**2 + 10 * nv**2 + 10 * nv * max(njoints - 1, 0) + 6 * nv * njoints
    return 8 * dense + DATA_BYTES_PER_JOINT * njoints + DATA_BYTES_ONCE


def pinocchio_data_bytes(mech: Mechanism) -> int:
    """:func:`data_bytes` of the mechanism's Pinocchio model, computed without building it."""
    return data_bytes(*pinocchio_model_size(mech))
