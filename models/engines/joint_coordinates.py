"""Joint coordinates of a study's forces: the moments in the joints and the rod forces.

A study's ``tau`` are the generalised forces of the paper's *absolute* angles (eq. 4 has
``M1 - M2`` on ``phi_1``). The physical moments in the joints are ``tau_joint = G^-T tau`` with
``G`` the constant map ``q_joint = G q`` of :func:`exo_bench.models.engines.pinocchio_backend.build_model`:
each joint turns link k relative to its parent (azimuth ``phi_k - phi_parent``; in 3D also the
elevation ``psi_k``; the prismatic joint ``l_k``). The rod forces ``F_k`` are the same in both
sets, because the column of ``G`` of ``l_k`` is a unit vector, so ``F_k = tau_joint[len_k] = tau[l_k]``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np

from exo_bench.models.mechanism.mechanism import Mechanism

if TYPE_CHECKING:
    pass

_JOINT = re.compile(r"L(\d+)_(phi|psi|len)$")


_SYMBOL = {"phi": "Mφ", "psi": "Mψ", "len": "F"}


# ----------------------------------------------------------------------------- joint quantities
@dataclass(frozen=True, eq=False)
class JointBasis:
    """Pinocchio's joint coordinates of a mechanism and the map to them.

    ``tau_joint = tau @ G_inv`` (row vectors) converts generalised forces of the paper's absolute
    angles into the physical joint moments and rod forces, rows named by ``names``.
    """

    names: tuple[str, ...]  # Pinocchio joint names, e.g. "L1_phi", "L1_psi", "L1_len"
    labels: tuple[str, ...]  # "Mψ1 stance_shin", "F1 stance_shin", ...
    link: tuple[int, ...]  # 0-based link of each joint
    kind: tuple[str, ...]  # "phi", "psi" or "len"
    G_inv: np.ndarray  # (dof, dof)
    moment_rows: tuple[int, ...]  # joint rows that are moments (revolute joints)
    force_rows: tuple[int, ...]  # joint rows that are rod forces (prismatic joints), link order


@lru_cache(maxsize=64)
def joint_basis(mech: Mechanism) -> JointBasis:
    """The joint coordinates of ``mech`` (built once per mechanism)."""
    from exo_bench.models.engines.pinocchio_backend import build_model

    pm = build_model(mech)
    G = np.asarray(pm.G, dtype=float)
    if G.shape != (mech.dof, mech.dof):
        raise ValueError(f"{mech.name}: joint map G: expected shape ({mech.dof}, {mech.dof}), got {G.shape}")
    links, kinds, labels = [], [], []
    for name in pm.joint_names:
        m = _JOINT.match(name)
        if m is None:
            raise ValueError(f"{mech.name}: joint name {name!r}: expected L<k>_phi, L<k>_psi or L<k>_len")
        i, kind = int(m.group(1)) - 1, m.group(2)
        links.append(i)
        kinds.append(kind)
        labels.append(f"{_SYMBOL[kind]}{i + 1} {mech.names[i]}")
    moment_rows = tuple(r for r, k in enumerate(kinds) if k != "len")
    force_rows = tuple(sorted((r for r, k in enumerate(kinds) if k == "len"), key=lambda r: links[r]))
    G_inv = np.linalg.inv(G)
    G_inv.flags.writeable = False  # cached per mechanism and shared: nobody may change it (a view of it
    G_inv = G_inv.view()  # cannot be made writeable again, the owner could)
    G_inv.flags.writeable = False
    return JointBasis(tuple(pm.joint_names), tuple(labels), tuple(links), tuple(kinds), G_inv, moment_rows, force_rows)


def joint_quantities(mech: Mechanism, tau: np.ndarray) -> np.ndarray:
    """``tau_joint = G^-T tau``: the joint moments and rod forces, ``(S, dof)`` in the rows of
    :attr:`JointBasis.names`, from generalised forces ``(S, dof)`` of the absolute angles."""
    with np.errstate(invalid="ignore"):  # inf * 0 in a non-finite tau: NaN, reported by nonfinite_notes
        return np.asarray(tau, dtype=float) @ joint_basis(mech).G_inv


def moments_and_forces(mech: Mechanism, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The joint moments ``(S, revolute joints)`` (N·m) and rod forces ``(S, n)`` (N) of ``tau``."""
    jb = joint_basis(mech)
    tj = joint_quantities(mech, tau)
    return tj[:, list(jb.moment_rows)], tj[:, list(jb.force_rows)]


def moment_labels(mech: Mechanism) -> list[str]:
    jb = joint_basis(mech)
    return [jb.labels[r] for r in jb.moment_rows]


def force_labels(mech: Mechanism) -> list[str]:
    jb = joint_basis(mech)
    return [jb.labels[r] for r in jb.force_rows]


def generalised_moment_labels(mech: Mechanism) -> list[str]:
    """Labels of the paper's generalised moments (the angle rows of ``tau``), e.g. ``Mφ1 (abs.) stance_shin``."""
    n = mech.nlinks
    kinds = ["Mφ", "Mψ"] if mech.dim == 3 else ["Mφ"]
    return [f"{k}{i + 1} (abs.) {mech.names[i]}" for k in kinds for i in range(n)]


def generalised_moments(mech: Mechanism, tau: np.ndarray) -> np.ndarray:
    """The angle rows ``[M_phi..., M_psi...]`` of the paper's generalised forces, ``(S, (dim-1) n)``."""
    return np.asarray(tau, dtype=float)[:, : (mech.dim - 1) * mech.nlinks]
