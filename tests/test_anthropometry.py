"""Winter's anthropometric table (models/mechanism/anthropometry.py): the fractions, and the three point masses
that stand for a segment.

Oracles: the table's own numbers (each checked against a reprint or stated unchecked in the module),
and the mass, first and second moments of three point masses computed here by hand. Error model: the
masses are closed forms of a few table numbers (a handful of roundings), so sums agree to ~1e-15
relative; 1e-12 leaves a margin and fails on any formula error in the table's third digit.
"""

from __future__ import annotations

import math

import pytest

from exo_bench.models.mechanism import anthropometry as a

SEGMENTS = [a.FOOT, a.LEG, a.THIGH, a.hat_to_vertex()]


def test_the_mass_fractions_are_winters_and_sum_to_the_body():
    assert (a.FOOT.mass, a.LEG.mass, a.THIGH.mass, a.HAT.mass) == (0.0145, 0.0465, 0.100, 0.678)
    assert (a.FOOT.com, a.LEG.com, a.THIGH.com, a.HAT.com) == (0.5, 0.433, 0.433, 0.626)
    assert math.isclose(a.HAT.mass + 2 * (a.THIGH.mass + a.LEG.mass + a.FOOT.mass), 1.0, rel_tol=1e-12)


def test_the_lengths_stack_to_the_stature():
    assert math.isclose(a.ANKLE_HEIGHT + a.LEG.length + a.THIGH.length + a.hat_to_vertex().length, 1.0)
    assert math.isclose(a.THIGH.length, 0.245) and math.isclose(a.LEG.length, 0.246)


def test_hat_on_the_vertex_rod_keeps_its_centre_of_mass_and_inertia_in_metres():
    v, h = a.hat_to_vertex(), a.HAT
    assert math.isclose(v.com * v.length, h.com * h.length, rel_tol=1e-12)
    assert math.isclose(v.gyration * v.length, h.gyration * h.length, rel_tol=1e-12)


@pytest.mark.parametrize("seg", SEGMENTS, ids=lambda s: s.name)
@pytest.mark.parametrize("body_mass", [56.7, 91.3])
def test_three_masses_have_the_segments_mass_centre_and_inertia(seg, body_mass):
    (m0, m1, m2), n = a.point_masses(seg, body_mass)
    assert min(m0, m1, m2) >= 0
    m = seg.mass * body_mass
    assert math.isclose(m0 + m1 + m2, m, rel_tol=1e-12)
    com = (m1 * n + m2) / m  # fractions of the rod's length from its proximal end
    assert math.isclose(com, seg.com, rel_tol=1e-12)
    inertia_about_com = m0 * com**2 + m1 * (n - com) ** 2 + m2 * (1 - com) ** 2
    assert math.isclose(inertia_about_com, m * seg.gyration**2, rel_tol=1e-12)


def test_hat_on_its_own_length_cannot_be_three_masses_and_says_why():
    with pytest.raises(ValueError, match=r"segment 'HAT': field 'gyration': expected rho\^2 <= c \(1 - c\) = 0.2341"):
        a.point_masses(a.HAT, 56.7)


@pytest.mark.parametrize(
    ("mass", "stature", "field"),
    [(0.0, 1.75, "body_mass"), (float("nan"), 1.75, "body_mass"), (56.7, -1.0, "stature"), (56.7, True, "stature")],
)
def test_a_bad_body_is_named(mass, stature, field):
    with pytest.raises(ValueError, match=f"human model: field '{field}': expected a number in"):
        a.check_body(mass, stature)
