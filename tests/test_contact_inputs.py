"""Ground contact and the human model's body at the edge, probed as a careless user would call them
(issue 34's classes of input applied to issue 37's contact and anthropometry): each bad input is a
one-line ValueError naming the field, the expected and the actual value, never a raw numpy or
Python error, and never read as something else (a mask of the strings "False" as True).

No solve and no kernel: numpy on a few points."""

from __future__ import annotations

from decimal import Decimal

import numpy as np
import pytest

from exo_bench.models.simulation import contact
from exo_bench.models.mechanism.presets import human

POINTS_2D = np.array([[0.0, -0.01], [0.2, 0.003]])
RATES_2D = np.array([[0.1, -0.2], [0.0, 0.0]])

BAD_POINTS = {
    "str array": lambda: POINTS_2D.astype(str),
    "str list": lambda: POINTS_2D.astype(str).tolist(),
    "bool": lambda: POINTS_2D != 0,
    "Decimal": lambda: np.array([[Decimal(float(x)) for x in row] for row in POINTS_2D], dtype=object),
}


@pytest.mark.case("P4")
@pytest.mark.parametrize("kind", sorted(BAD_POINTS))
def test_contact_points_that_are_not_real_numbers_are_named(kind):
    """contact_force of positions or velocities of strings, booleans or Decimals is a ValueError naming
    the field (it was numpy's raw TypeError: "ufunc 'isfinite' not supported", "boolean negative")."""
    with pytest.raises(ValueError, match=r"contact: field 'position': expected"):
        contact.contact_force(BAD_POINTS[kind](), RATES_2D)
    with pytest.raises(ValueError, match=r"contact: field 'velocity': expected"):
        contact.contact_force(POINTS_2D, BAD_POINTS[kind]())


@pytest.mark.case("P4")
def test_body_and_contact_numbers_of_any_size_or_numpy_type():
    """A body mass, stature or contact parameter given as a huge Python int is a ValueError naming the
    field (it was "OverflowError: int too large to convert to float"), and numpy's real scalars within
    the bounds are numbers (np.int64(70) kg was refused as "expected a number in [1, 1000] kg")."""
    for field, value in (("body_mass", 10**400), ("stature", -(10**400))):
        with pytest.raises(ValueError, match=f"human model: field '{field}': expected"):
            human(2, **{field: value})
    with pytest.raises(ValueError, match="contact: field 'stiffness': expected"):
        contact.ContactParameters(stiffness=10**400)
    assert human(2, body_mass=np.int64(70)).masses == human(2, body_mass=70).masses
    assert human(2, stature=np.float32(1.5)).masses == human(2, stature=float(np.float32(1.5))).masses
    assert contact.ContactParameters(stiffness=np.float32(1e6)).hertz == contact.ContactParameters(stiffness=1e6).hertz


@pytest.mark.case("P5")
def test_the_ground_mask_is_booleans_and_the_states_agree():
    """ground_forces' mask of points must be booleans of shape (links, 3): a mask of the strings "False" was
    read as True everywhere (every point in contact) and one of 2s as True; velocities of another
    sample count than the positions were broadcast silently."""
    mech = human(2)
    p = np.zeros((1, mech.nlinks, 3, 2))
    p[..., 1] = -0.01
    v = np.zeros_like(p)
    mask = np.zeros((mech.nlinks, 3), bool)
    mask[4, 2] = True
    for bad in (np.full(mask.shape, "False"), np.where(mask, 2, 0), mask.astype(float)):
        with pytest.raises(ValueError, match=r"contact: field 'points': .*expected booleans, got dtype"):
            contact.ground_forces(p, v, bad)
    with pytest.raises(ValueError, match=r"contact: field 'velocities': expected .*\(1, 10, 3, 2\).*\(3, 10, 3, 2\)"):
        contact.ground_forces(p, np.zeros((3, mech.nlinks, 3, 2)), mask)
    f = contact.ground_forces(p, v, mask.tolist())
    assert f[0, 4, 2, 1] > 0  # the one point in contact pushes up; no other point has a force
    f[0, 4, 2] = 0.0
    assert not f.any()
