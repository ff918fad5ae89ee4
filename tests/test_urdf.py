"""The generated URDF: the bodies, joints and mimic joints the mechanism implies, and its total mass."""

import math
import xml.etree.ElementTree as ET

import pinocchio as pin
import pytest

from exo_bench.models.mechanism.presets import exo5, fig2b, random_tree
from exo_bench.models.engines.urdf import to_urdf


def _parse(mech):
    root = ET.fromstring(to_urdf(mech))
    joints = root.findall("joint")
    kinds = {}
    for j in joints:
        kind = "mimic" if j.find("mimic") is not None else j.get("type")
        kinds[kind] = kinds.get(kind, 0) + 1
    masses = [float(e.get("value")) for e in root.iter("mass")]
    return root, joints, kinds, masses


TREES = [random_tree(n, d, s) for n, d, s in [(1, 2, 0), (3, 2, 1), (6, 2, 2), (1, 3, 3), (4, 3, 4), (7, 3, 5)]]


@pytest.mark.parametrize("mech", TREES + [exo5(3), exo5(2), fig2b(2)], ids=lambda m: m.name)
def test_joints_and_bodies_follow_the_mechanism(mech):
    root, joints, kinds, masses = _parse(mech)
    n, roots = mech.nlinks, mech.parent.count(-1)
    revolute = sum(1 for j in joints if j.get("type") == "revolute" and j.find("mimic") is None)
    prismatic = sum(1 for j in joints if j.get("type") == "prismatic" and j.find("mimic") is None)
    assert prismatic == n  # one length per rod
    assert revolute == (mech.dim - 1) * n  # phi (and psi in 3D) per rod
    mid_mimics = [j for j in joints if j.find("mimic") is not None and j.get("type") == "prismatic"]
    assert len(mid_mimics) == sum(1 for m in mech.masses if m[1] > 0)
    for j, i in zip(mid_mimics, [i for i in range(n) if mech.masses[i][1] > 0]):
        assert math.isclose(float(j.find("mimic").get("multiplier")), mech.n[i])
    undo = [j for j in joints if j.find("mimic") is not None and j.get("type") == "revolute"]
    assert len(undo) == (n - roots if mech.dim == 3 else 0)
    if mech.dim == 2:  # planar: rotations about z only, translations in the plane
        for j in joints:
            axis = [float(a) for a in j.find("axis").get("xyz").split()]
            assert (axis[:2] == [0, 0]) if j.get("type") == "revolute" else axis[2] == 0


@pytest.mark.parametrize("mech", TREES + [exo5(3)], ids=lambda m: m.name)
def test_total_mass_equals_the_mechanisms(mech):
    _, _, _, masses = _parse(mech)
    assert math.isclose(sum(masses), mech.total_mass, rel_tol=1e-14)
    model = pin.buildModelFromXML(to_urdf(mech), mimic=True)
    assert math.isclose(sum(I.mass for I in model.inertias), mech.total_mass, rel_tol=1e-14)
    assert model.nq == model.nv == mech.dof


def test_zero_mass_adds_no_body():
    m = random_tree(3, 3, 9)
    masses = list(m.masses)
    masses[1] = (0.0, 0.0, masses[1][2])
    zero = m.replace(masses=tuple(masses))
    root, joints, kinds, ms = _parse(zero)
    assert len(ms) == 3 * 3 - 2
    assert "L2_mid" not in {j.get("name") for j in joints}
    assert root.find("link[@name='L2_frame']").find("inertial") is None


@pytest.mark.parametrize("mech", TREES + [exo5(3), exo5(2), fig2b(3)], ids=lambda m: m.name)
@pytest.mark.parametrize("zero_middle", [False, True])
def test_model_size_predicted_without_building_is_pinocchios(mech, zero_middle):
    """pinocchio_model_size (the memory estimate's input) against the model Pinocchio builds from the
    URDF: nv = dof (mimic joints have no velocity), and the joints per link (phi, psi, the 3D undo
    mimic below a root, len, the mid mimic only for a middle mass)."""
    from exo_bench.models.engines.urdf import pinocchio_model_size

    if zero_middle:
        mech = mech.replace(masses=tuple((a, 0.0 if i % 2 == 0 else b, c) for i, (a, b, c) in enumerate(mech.masses)))
    model = pin.buildModelFromXML(to_urdf(mech), mimic=True)
    assert pinocchio_model_size(mech) == (model.nv, model.njoints)
