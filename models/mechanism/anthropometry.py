"""Winter's anthropometric table, scaled to a body mass and a stature, as point masses on rods.

**Source.** D. A. Winter, *Biomechanics and Motor Control of Human Movement*, Table 4.1
(segment mass / body mass, centre of mass / segment length from the proximal end, radius of
gyration about the centre of mass / segment length; Dempster's cadaver data as Winter adapts
them) and Fig. 4.1 (segment lengths as fractions of the stature H, after Drillis and Contini).
We did not open the book; every number below is checked against public transcriptions of it:

* Table 4.1: the file ``data/BSP_DempsterWinter.txt`` of the repository BMClab/BMC (Marcos
  Duarte's biomechanics notebooks, commit bb70ec694c7d7db237eb2a131a8cf37183d7e1f4), whose rows read
  (mass, centre of mass from the proximal end and from the distal end, radius of gyration about the
  centre of mass, the proximal end and the distal end): foot 0.0145, 0.5, 0.5, 0.475, 0.69, 0.69;
  leg 0.0465, 0.433, 0.567, 0.302, 0.528, 0.643; thigh 0.1, 0.433, 0.567, 0.323, 0.54, 0.653; HAT
  (greater trochanter to glenohumeral joint) 0.678, 0.626, 0.374, 0.496, 0.798, 0.621. A course
  handout that reprints Table 4.1 ("adapted from Winter, 3rd ed.", University of Rhode Island BME
  207, 2016) gives the same foot, leg and thigh masses and centres of mass.
* Fig. 4.1: ``pyexphys/anthropometry.py`` of dpfens/PyExPhys (commit
  89d19374d31d44a59e86e253731ea0d48ea25666, "Winter, ... 2009"): hips 0.530 H, knees 0.285 H,
  ankles 0.039 H, shoulders 0.818 H, foot length 0.152 H.

Every value used here is the transcriptions' (tests/test_anthropometry_source.py holds them with
their sources); none had to change. The radii about the ends obey the parallel-axis theorem with
those about the centre of mass to 0.001 (the table's rounding). HAT = 0.678 is the fraction
:mod:`exo_bench.models.gait.normative` already uses to find the 56.7 kg subject; the fractions sum to
one (0.678 + 2 (0.100 + 0.0465 + 0.0145) = 1.000).

Lengths (Fig. 4.1, the fractions :mod:`exo_bench.models.gait.gait_fit` already uses): greater
trochanter 0.530 H above the floor, knee 0.285 H, ankle 0.039 H, so thigh 0.245 H and leg 0.246 H;
glenohumeral joint 0.818 H; foot length (heel to toe tip) 0.152 H. Where along the foot the ankle
lies is not in Fig. 4.1: **our assumption** puts the heel's contact point 0.20 of the foot length
behind the ankle and the head of metatarsal II (the toe's contact point, the distal end of
Winter's foot segment) 0.55 of it ahead, both on the floor. Winter's foot segment is then the rod
from the ankle to that toe point (0.092 H long).

Three point masses per rod. A segment of mass ``m`` and length ``L`` whose centre of mass lies at
``c L`` from its proximal end and whose radius of gyration about that centre is ``rho L`` is
represented by masses ``a0 m, a1 m, a2 m`` at fractions ``0, n, 1`` with ``n = c`` and

    a0 = rho^2 / c,    a2 = rho^2 / (1 - c),    a1 = 1 - rho^2 / (c (1 - c))

(:func:`point_masses`): the three have the segment's mass, centre of mass and moment of inertia
about any axis across the rod (a rod has none about its own axis). This needs ``rho^2 <= c (1 -
c)``, which Winter's foot, leg and thigh satisfy. HAT's radius of gyration is too large for its
own length (0.496^2 > 0.626 x 0.374), so the HAT rod runs from the greater trochanter to the top
of the head (0.470 H), which also makes the model's standing height the stature: there HAT's
centre of mass is at 0.626 x 0.288 / 0.470 = 0.384 and its radius of gyration 0.496 x 0.288 /
0.470 = 0.304 of the rod, and the three masses exist.
"""

from __future__ import annotations

from dataclasses import dataclass

from exo_bench.models.states.validation import _finite, _is_number

SOURCE = (
    "Winter, Biomechanics and Motor Control of Human Movement, Table 4.1 and Fig. 4.1, as transcribed in "
    "BMClab/BMC data/BSP_DempsterWinter.txt (Table 4.1) and dpfens/PyExPhys pyexphys/anthropometry.py (Fig. 4.1)"
)

#: The normative subject of :mod:`exo_bench.models.gait.normative` (kg).
BODY_MASS = 56.7
#: The stature the suite's rest lengths use (:data:`exo_bench.models.gait.gait_fit.STATURE`), m.
STATURE = 1.75

#: Heights above the floor as fractions of the stature (Winter, Fig. 4.1).
HIP_HEIGHT = 0.530
KNEE_HEIGHT = 0.285
ANKLE_HEIGHT = 0.039
SHOULDER_HEIGHT = 0.818
FOOT_LENGTH = 0.152


@dataclass(frozen=True)
class Segment:
    """One row of Table 4.1 with its length from Fig. 4.1 (fractions of body mass and stature)."""

    name: str
    mass: float  # segment mass / body mass
    length: float  # segment length / stature
    com: float  # centre of mass from the proximal end / segment length
    gyration: float  # radius of gyration about the centre of mass / segment length
    proximal: str
    distal: str


#: Heel and toe contact points, forward of the ankle, as fractions of the stature (our assumption).
HEEL_FORWARD = -0.20 * FOOT_LENGTH
TOE_FORWARD = 0.55 * FOOT_LENGTH

FOOT = Segment(
    "foot",
    0.0145,
    (TOE_FORWARD**2 + ANKLE_HEIGHT**2) ** 0.5,
    0.500,
    0.475,
    "lateral malleolus",
    "head of metatarsal II",
)
LEG = Segment("leg", 0.0465, KNEE_HEIGHT - ANKLE_HEIGHT, 0.433, 0.302, "femoral condyles", "medial malleolus")
THIGH = Segment("thigh", 0.100, HIP_HEIGHT - KNEE_HEIGHT, 0.433, 0.323, "greater trochanter", "femoral condyles")
#: Table 4.1's HAT row, on its own length (greater trochanter to glenohumeral joint).
HAT = Segment("HAT", 0.678, SHOULDER_HEIGHT - HIP_HEIGHT, 0.626, 0.496, "greater trochanter", "glenohumeral joint")


def hat_to_vertex() -> Segment:
    """HAT on the rod from the greater trochanter to the top of the head (see the module text)."""
    length = 1.0 - HIP_HEIGHT
    scale = HAT.length / length
    return Segment("HAT", HAT.mass, length, HAT.com * scale, HAT.gyration * scale, "greater trochanter", "vertex")


def point_masses(seg: Segment, body_mass: float) -> tuple[tuple[float, float, float], float]:
    """``((m0, m1, m2), n)``: three masses on the segment's rod with its mass, centre of mass and
    moment of inertia across the rod (module text). Raises ValueError where no such masses exist."""
    c, rho2 = seg.com, seg.gyration**2
    if not 0.0 < c < 1.0 or rho2 > c * (1.0 - c):
        raise ValueError(
            f"segment {seg.name!r}: field 'gyration': expected rho^2 <= c (1 - c) = {c * (1 - c):.4g} "
            f"(three masses on the rod), got rho = {seg.gyration:.4g}, rho^2 = {rho2:.4g}"
        )
    m = seg.mass * body_mass
    a0, a2 = rho2 / c, rho2 / (1.0 - c)
    return (a0 * m, (1.0 - a0 - a2) * m, a2 * m), c


def check_body(body_mass: float, stature: float) -> None:
    """A ValueError naming the field unless both are finite and positive, within human-like bounds
    wide enough for any person (1-1000 kg, 0.3-3 m)."""
    for name, x, lo, hi, unit in (("body_mass", body_mass, 1.0, 1000.0, "kg"), ("stature", stature, 0.3, 3.0, "m")):
        if not (_is_number(x) and _finite(x)) or not lo <= float(x) <= hi:
            raise ValueError(f"human model: field {name!r}: expected a number in [{lo:g}, {hi:g}] {unit}, got {x!r}")
