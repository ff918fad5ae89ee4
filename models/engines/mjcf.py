"""MJCF (MuJoCo's XML) export of any mechanism, and the linear map ``G`` to MuJoCo's joints.

**Bodies and joints.** Every link ``k`` (1-based, prefix ``Lk`` as in the URDF,
:func:`exo_bench.models.engines.urdf.link_prefix`) becomes three bodies:

* ``Lk`` at the parent's end (the origin for a root), carrying the start mass ``m_k0``, with the
  hinges, applied in this order (MuJoCo composes the joints of one body in the order written,
  each about its axis in the frame the previous ones left):

  - 3D, non-root only: ``Lk_undo`` about ``-y``, value ``-psi_parent``: it levels the parent's
    frame again, so that the next hinge measures an *absolute* azimuth as the paper does;
  - ``Lk_phi`` about ``z``, value ``phi_k - phi_parent`` (``phi_k`` for a root);
  - 3D only: ``Lk_psi`` about ``-y``, value ``psi_k`` (the elevation of eq. 7);

* ``Lk_end``, child of ``Lk``: a slide ``Lk_len`` along ``sign_k x``, value ``l_k``, carrying the
  end mass ``m_k2``; the children's bodies hang from it;
* ``Lk_mid``, child of ``Lk``: a slide ``Lk_mid`` along ``sign_k x``, value ``n_k l_k``, carrying
  the sliding middle mass ``m_k1`` (omitted when ``m_k1 = 0``).

**Why no mimic, and no constraint, in the dynamics.** MuJoCo has no mimic joint. The middle mass's
slide and the 3D undo hinge are joints of their own, so MuJoCo's model has ``nv = dof + (number of
middle masses) + (3D: non-root links)`` coordinates, and every one of them is a *linear* function of
the paper's: ``q_mj = G q_paper`` with a constant ``G`` (``nv x dof``; rows of ``1``, ``-1`` and
``n_k``). The paper's motions are the motions of MuJoCo's model that stay in the image of ``G``,
a linear holonomic constraint. By virtual work, on such a motion (``qd_mj = G qd``, ``qdd_mj = G
qdd``) the generalised forces of the paper's coordinates are ``tau_paper = G^T tau_mj``, where
``tau_mj`` is MuJoCo's *unconstrained* inverse dynamics (its RNE): the constraint forces that keep
the motion in the image of ``G`` lie in the null space of ``G^T`` and drop out exactly. Likewise
``M_paper = G^T M_mj G``. So the backends (models/engines/mujoco_backend.py) run RNE with every constraint
disabled and map by ``G``: no solver, no softness, no constraint force enters the result.

An ``<equality><joint joint1= joint2= polycoef=...>`` tie (MuJoCo's nearest thing to a mimic)
would instead make ``mj_inverse`` return forces that include the *soft* constraint's reaction
(computed from ``solref``/``solimp`` and the acceleration): not the exact rigid model. The file
still carries those ties, for a user who *simulates* it in MuJoCo (``mj_step``): there they keep
the middle mass at ``n_k l_k`` and the undo hinge at ``-psi_parent`` (softly, as MuJoCo does every
constraint); the backends disable them (``mjDSBL_EQUALITY`` and ``mjDSBL_CONSTRAINT``).

**Point masses and MuJoCo's minimum-inertia rule.** Each point mass is a body's ``<inertial>``
with the exact mass at the body's origin and ``diaginertia="0 0 0"``; a frame without a point
mass (a zero mass) has ``mass="0"``. MuJoCo refuses, at compile time, a moving body whose mass or
rotational inertia is below ``mjMINVAL`` ("mass and inertia of moving bodies must be larger than
mjMINVAL", checked with MuJoCo 4.0): the ``<compiler boundmass= boundinertia=>`` of the file
raise only those values to :data:`BOUND` (1e-12 kg, 1e-12 kg m^2) when it compiles. A user's
simulation sees these 1e-12 floors; :func:`load_model` puts the exact values back after
compiling (``body_mass`` of the zero masses and every ``body_inertia`` set to 0), so the backends
compute with exactly the point masses of the paper. (MuJoCo's RNE never divides by a mass; only
its forward dynamics factorises ``M``, which zero masses can make singular.)

**Names.** The file's elements are named by link number only (``L<k>``...). The mechanism's name is
the ``model`` attribute (:func:`exo_bench.models.files.xml_attr`) and each link's name sits in
a comment as a JSON string (:func:`exo_bench.models.files.xml_comment`): no name can end the
comment or the attribute, so none can add an element (a body, an ``<include>``) or break the XML.

**Size.** The text, ``G``'s rows and the keyframe are built in O(n) (``G`` itself is ``nv x dof``:
a flat tree of 100,000 links would need 447 GiB); what MuJoCo allocates to compile the file grows
as ``nv^2`` and is predicted by :func:`compile_bytes` (``exo-bench mjcf`` refuses beyond the memory).

**Planar models** live in the x-y plane with gravity along ``-y``, as everywhere in the suite
(the file's ``<option gravity>`` says so). Contacts, limits, armature, damping, stiffness and
friction loss are zero or disabled in the file; geoms (spheres at the point masses, a
telescopic pair of capsules per rod) are visual only (``contype = conaffinity = 0``, and
``inertiafromgeom="false"``: they add no mass).

**For a user's simulation and viewer.** MuJoCo's reference configuration ``qpos0`` (where the viewer
opens, and where the compiler evaluates the model) has every rod :data:`REST_LENGTH` long: each
slide has ``ref`` = its rest value and its body sits there, so the joint's value is still the length
(MuJoCo moves a slide's body by ``qpos - ref`` from its place). With zero lengths every mass would
sit on the hinges' axes and the mass matrix be singular (MuJoCo then warns, and writes
MUJOCO_LOG.TXT into the working directory). In 3D a child's undo hinge and its elevation hinge turn
about one axis wherever the two azimuths are equal (``qpos0`` among them), which makes MuJoCo's
joint-space mass matrix singular for its forward dynamics; the file gives the undo hinges an
armature of :data:`UNDO_ARMATURE` (1e-6 kg m^2, a millionth of a 1 kg mass at 1 m) so that
``mj_step`` can run, and the backends set every armature to zero. A keyframe ``rest`` has the
rods at 0.5 m and, in 3D, raised by 0.3 rad.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from exo_bench.models.engines.urdf import link_prefix
from exo_bench.models.files import xml_attr, xml_comment
from exo_bench.models.mechanism.mechanism import Mechanism

#: The compiler's ``boundmass`` and ``boundinertia`` (see the module docstring).
BOUND = 1e-12
#: Length of every rod in MuJoCo's reference configuration ``qpos0`` (m): each slide's ``ref``, with
#: its body placed there, so that the joint's value is still the length itself.
REST_LENGTH = 0.5
#: Armature of the 3D undo hinges in the file (kg m^2), for simulation only (the backends set every
#: armature to 0): see the module docstring.
UNDO_ARMATURE = 1e-6

#: The deepest element MuJoCo's XML parser (tinyxml2, TINYXML2_MAX_ELEMENT_DEPTH) reads: deeper, it
#: refuses the file ("Element nesting is too deep"). Each link nests two bodies inside its parent's
#: end body, so a chain of more than 248 links cannot be read from MJCF (measured with MuJoCo 4.0).
MJCF_MAX_DEPTH = 500


def _tree_depths(mech: Mechanism) -> list[int]:
    """Each link's depth in the tree (roots 0), in O(n): a parent comes before its children."""
    depth = [0] * mech.nlinks
    for i in range(mech.nlinks):
        p = mech.parent[i]
        depth[i] = 0 if p < 0 else depth[p] + 1
    return depth


def nesting_depth(mech: Mechanism) -> int:
    """The depth of the deepest element in :func:`to_mjcf`'s text: ``mujoco > worldbody`` (2), then
    per link of tree depth d (roots 0) its body at 3 + 2d, its end body at 4 + 2d and what that
    holds at 5 + 2d."""
    return 5 + 2 * max(_tree_depths(mech), default=0)


class MjcfTooDeep(ValueError):
    """The MJCF of a mechanism nests deeper than MuJoCo's parser reads (:data:`MJCF_MAX_DEPTH`);
    ``skip_reason`` is the same line, so the benchmark rows skip with it."""

    def __init__(self, mech: Mechanism, depth: int):
        self.skip_reason = (
            f"the MJCF of {mech.name!r} nests {depth} elements deep; MuJoCo's XML parser (tinyxml2) reads at most "
            f"{MJCF_MAX_DEPTH}: each link nests two bodies deeper, so at most {(MJCF_MAX_DEPTH - 5) // 2 + 1} "
            "links in a chain from the support point"
        )
        super().__init__(self.skip_reason)


def check_nesting(mech: Mechanism) -> None:
    """:class:`MjcfTooDeep` where MuJoCo would refuse the MJCF of ``mech`` for its depth."""
    depth = nesting_depth(mech)
    if depth > MJCF_MAX_DEPTH:
        raise MjcfTooDeep(mech, depth)


@dataclass(frozen=True)
class JointMap:
    """MuJoCo's joint coordinates as a linear map of the paper's: ``q_mj = G q_paper``.

    ``joints[r]`` is the name of the joint of row ``r`` of ``G`` in MuJoCo's order (the order the
    joints are written, which is MuJoCo's ``qpos``/``qvel`` order: one coordinate per hinge or
    slide). ``bodies[i]`` are the names of link ``i``'s start, middle (``None`` when ``m_i1 = 0``)
    and end bodies."""

    G: np.ndarray  # (nv, dof)
    joints: tuple[str, ...]
    bodies: tuple[tuple[str, str | None, str], ...]


#: MuJoCo's arena (``mjModel.narena``, what ``mjData`` allocates, once while compiling), fitted as
#: ``ARENA[0] + ARENA[1] nv + ARENA[2] nv^2 + ARENA[3] neq nv`` bytes (MuJoCo 4.0's default ``memory``:
#: ``nv`` coordinates, ``neq`` ties). Measured on 2D and 3D chains, flat trees and random trees of 1 to
#: 600 links (nv up to 2400), the fit is 1.19 to 1.35 times MuJoCo's value: an upper bound.
ARENA = (16 * 2**20, 80_000, 40, 150)


def mujoco_sizes(mech: Mechanism) -> tuple[int, int]:
    """``(nv, neq)`` of the compiled MJCF, without building it: ``nv = dof`` plus a slide per middle
    mass and, in 3D, an undo hinge per non-root link; one tie (``neq``) for each of those."""
    extra = sum(1 for m in mech.masses if m[1] > 0.0)
    if mech.dim == 3:
        extra += sum(1 for p in mech.parent if p >= 0)
    return mech.dof + extra, extra


def compile_bytes(mech: Mechanism) -> int:
    """Bytes MuJoCo allocates to compile the MJCF of ``mech`` (its arena, :data:`ARENA`, plus the
    text and the model, ``4 kB`` a link), predicted before any work."""
    nv, neq = mujoco_sizes(mech)
    a0, a1, a2, a3 = ARENA
    return a0 + a1 * nv + a2 * nv * nv + a3 * neq * nv + 4096 * mech.nlinks


def _depth_first(mech: Mechanism):
    """``(link, entering)`` events of a depth-first walk of the tree, roots in order: each link is
    entered before its children and left after them. Iterative, so a chain of thousands of links
    (whose MJCF nests as deep) needs no recursion."""
    stack = [(i, True) for i in reversed(range(mech.nlinks)) if mech.parent[i] < 0]
    while stack:
        i, entering = stack.pop()
        yield i, entering
        if entering:
            stack.append((i, False))
            stack.extend((c, True) for c in reversed(mech.children[i]))


def _joint_rows(mech: Mechanism) -> list[tuple[str, dict[int, float]]]:
    """``(joint name, {paper column: coefficient})`` in the order of the file (depth first)."""
    n = mech.nlinks
    psi0, l0 = n, (2 if mech.dim == 3 else 1) * n
    rows: list[tuple[str, dict[int, float]]] = []
    for i, entering in _depth_first(mech):
        k, p = link_prefix(mech, i), mech.parent[i]
        if entering:
            if mech.dim == 3 and p >= 0:
                rows.append((f"{k}_undo", {psi0 + p: -1.0}))
            rows.append((f"{k}_phi", {i: 1.0} if p < 0 else {i: 1.0, p: -1.0}))
            if mech.dim == 3:
                rows.append((f"{k}_psi", {psi0 + i: 1.0}))
            rows.append((f"{k}_len", {l0 + i: 1.0}))
        elif mech.masses[i][1] > 0.0:
            rows.append((f"{k}_mid", {l0 + i: float(mech.n[i])}))
    return rows


def joint_map(mech: Mechanism) -> JointMap:
    """``G`` and the names of the joints and bodies of :func:`to_mjcf`, without MuJoCo."""
    rows = _joint_rows(mech)
    G = np.zeros((len(rows), mech.dof))
    for r, (_, coef) in enumerate(rows):
        for c, v in coef.items():
            G[r, c] = v
    bodies = tuple(
        (
            link_prefix(mech, i),
            f"{link_prefix(mech, i)}_mid" if mech.masses[i][1] > 0 else None,
            f"{link_prefix(mech, i)}_end",
        )
        for i in range(mech.nlinks)
    )
    return JointMap(G, tuple(name for name, _ in rows), bodies)


def _inertial(mass: float) -> str:
    return f'<inertial pos="0 0 0" mass="{float(mass)!r}" diaginertia="0 0 0"/>'


def _sphere(mass: float, rgba: str) -> str:
    if mass <= 0.0:
        return ""
    r = 0.02 + 0.015 * float(mass) ** (1 / 3)
    return f'<geom type="sphere" size="{r:.3f}" rgba="{rgba}"/>'


def to_mjcf(mech: Mechanism) -> str:
    """The MJCF text of a mechanism (see the module docstring)."""
    g = "0 -{0!r} 0".format(float(mech.g)) if mech.dim == 2 else "0 0 -{0!r}".format(float(mech.g))
    out = [
        '<?xml version="1.0"?>',
        f"<!-- {xml_comment(mech.name)}: {mech.dim}D, {mech.nlinks} link(s), generated by exo-bench (models/engines/mjcf.py). "
        "MuJoCo's joint coordinates are q_mj = G q_paper (exo_bench.models.engines.mjcf.joint_map): "
        "*_undo = -psi_parent, *_phi = phi_k - phi_parent, *_psi = psi_k, *_len = l_k, *_mid = n_k l_k; "
        "tau_paper = G^T tau_mj. Point masses: exact masses, zero rotational inertia; the compiler's "
        f"boundmass/boundinertia raise zero values to {BOUND:g} (MuJoCo refuses less on a moving body). -->",
        f"<mujoco model={xml_attr(mech.name)}>",
        f'  <compiler angle="radian" inertiafromgeom="false" boundmass="{BOUND:g}" boundinertia="{BOUND:g}"/>',
        f'  <option gravity="{g}" timestep="0.001" integrator="implicitfast">',
        '    <flag contact="disable" limit="disable" frictionloss="disable"/>',
        "  </option>",
        "  <default>",
        '    <joint limited="false" armature="0" damping="0" stiffness="0" frictionloss="0"/>',
        '    <geom contype="0" conaffinity="0" group="1"/>',
        "  </default>",
        "  <worldbody>",
        '    <light pos="0 0 4" dir="0 0 -1"/>',
        '    <geom type="sphere" size="0.03" rgba="0.2 0.2 0.2 1"/>',
    ]

    depth = _tree_depths(mech)
    for i, entering in _depth_first(mech):
        k, p = link_prefix(mech, i), mech.parent[i]
        pad = "  " * (2 + 2 * depth[i])
        s = mech.sign[i]
        m0, m1, m2 = mech.masses[i]
        half = REST_LENGTH / 2
        if not entering:  # after the children: close the end body, then the middle mass
            out.append(f"{pad}  </body>")
            if m1 > 0.0:
                ref = float(mech.n[i]) * REST_LENGTH
                out.append(f'{pad}  <body name="{k}_mid" pos="{s * ref!r} 0 0">')
                out.append(f'{pad}    <joint name="{k}_mid" type="slide" axis="{s} 0 0" ref="{ref!r}"/>')
                out.append(
                    f"{pad}    {_inertial(m1)}<!-- sliding middle mass m1, at n l -->" + _sphere(m1, "0.1 0.5 0.8 1")
                )
                out.append(f"{pad}  </body>")
            out.append(f"{pad}</body>")
            continue
        out.append(
            f"{pad}<!-- link {i + 1}: {xml_comment(mech.names[i])}, parent {p + 1 if p >= 0 else 'support'}, "
            f"sign {s:+d}, n = {float(mech.n[i])!r} -->"
        )
        out.append(f'{pad}<body name="{k}">')
        if mech.dim == 3 and p >= 0:
            out.append(f'{pad}  <joint name="{k}_undo" type="hinge" axis="0 -1 0" armature="{UNDO_ARMATURE:g}"/>')
        out.append(f'{pad}  <joint name="{k}_phi" type="hinge" axis="0 0 1"/>')
        if mech.dim == 3:
            out.append(f'{pad}  <joint name="{k}_psi" type="hinge" axis="0 -1 0"/>')
        out.append(f"{pad}  {_inertial(m0)}<!-- start mass m0 -->")
        out.append(
            f'{pad}  <geom type="capsule" fromto="0 0 0 {s * half!r} 0 0" size="0.012" rgba="0.5 0.5 0.6 1"/>'
            + _sphere(m0, "0.85 0.4 0.1 1")
        )
        out.append(f'{pad}  <body name="{k}_end" pos="{s * REST_LENGTH!r} 0 0">')
        out.append(f'{pad}    <joint name="{k}_len" type="slide" axis="{s} 0 0" ref="{REST_LENGTH!r}"/>')
        out.append(f"{pad}    {_inertial(m2)}<!-- end mass m2 -->")
        out.append(
            f'{pad}    <geom type="capsule" fromto="0 0 0 {-s * half!r} 0 0" size="0.008" rgba="0.7 0.7 0.8 1"/>'
            + _sphere(m2, "0.85 0.4 0.1 1")
        )

    out.append("  </worldbody>")
    ties = []
    for i in range(mech.nlinks):
        k, p = link_prefix(mech, i), mech.parent[i]
        if mech.masses[i][1] > 0.0:
            ties.append(
                f'    <joint name="{k}_mid_tie" joint1="{k}_mid" joint2="{k}_len" '
                f'polycoef="0 {float(mech.n[i])!r} 0 0 0"/>'
            )
        if mech.dim == 3 and p >= 0:
            ties.append(
                f'    <joint name="{k}_undo_tie" joint1="{k}_undo" joint2="{link_prefix(mech, p)}_psi" '
                'polycoef="0 -1 0 0 0"/>'
            )
    if ties:
        out += [
            "  <!-- for simulation in MuJoCo: the middle masses at n l, the undo hinges at -psi_parent "
            "(soft, as every MuJoCo constraint; exo-bench's inverse dynamics disable them and map by G) -->",
            "  <equality>",
            *ties,
            "  </equality>",
        ]
    rest = np.zeros(mech.dof)
    rest[-mech.nlinks :] = REST_LENGTH
    if mech.dim == 3:
        rest[mech.nlinks : 2 * mech.nlinks] = 0.3
    qpos = [sum(c * rest[k] for k, c in coef.items()) for _, coef in _joint_rows(mech)]  # G @ rest, G not formed
    out += [
        "  <keyframe>",
        f'    <key name="rest" qpos="{" ".join(repr(float(x)) for x in qpos)}"/>',
        "  </keyframe>",
        "</mujoco>",
    ]
    return "\n".join(out) + "\n"
