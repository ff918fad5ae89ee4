"""Smooth ground contact at a point: a Hunt-Crossley normal force with smoothed Coulomb friction, in numpy
and as CasADi expressions (one model, two forms), and the controls that hold the human model's posture on it.

The kind of contact Moco's ``SmoothSphereHalfSpaceForce`` (Serrancolí, Falisse et al. 2019; Simbody's
``SmoothSphereHalfSpaceForce``, whose documentation gives the units below) and gait2d (Ackermann and
van den Bogert 2010) use in predictive gait: every function is smooth (C-infinity), so a collocation
solver can differentiate it, and vectorised over any leading axes. The floor is the plane through the
origin normal to the last axis (``y`` in 2D, ``z`` in 3D, gravity's axis); a contact point is a
point mass (the heel and toe of :func:`exo_bench.models.mechanism.presets.human`) at the bottom of a sphere of
radius ``radius``, so it touches the floor at height 0.

Normal force, with penetration ``d = -z`` and its rate ``dd = -vz``:

* smoothed penetration ``d_s = s_d * log(1 + exp(d / s_d))`` (softplus, width ``s_d``; it never
  overflows: :func:`softplus`), so the force is positive everywhere and vanishes like
  ``exp(-height / s_d)`` above the floor;
* Hertz: ``f_H = (4/3) k sqrt(R k) d_s^(3/2)`` with ``k = stiffness^(2/3) / 2`` (Simbody's formula, two
  equal materials: ``f_H = (sqrt 2 / 3) E sqrt(R) d_s^(3/2)``);
* Hunt-Crossley dissipation: ``f_n = f_H * softplus(1 + 3/2 c dd)`` (width ``s_c``), which is
  ``f_H (1 + 3/2 c dd)`` and never pulls (Simbody switches with ``tanh`` instead).

Friction, against the tangential velocity ``v_t`` (slip ``s = sqrt(|v_t|^2 + e^2)``, ``e`` small, so the
direction ``v_t / s`` is smooth through zero):

    f_t = -f_n * mu(s) * v_t / s,   mu(s) = mu_d tanh(x) + (mu_s - mu_d) 2x / (1 + x^2) + mu_v s,   x = s / v_tr

The first two terms are Coulomb's with a Stribeck peak: they rise from 0 to at most ``mu_s`` near
``s = v_tr`` and tend to ``mu_d``; ``mu_v`` is viscous. So ``|f_t| <= (mu_s + mu_v |v_t|) f_n``, and ``f_t``
opposes the slip (tested). Simbody's form of the same three coefficients uses ``min(s / v_tr, 1)``,
whose derivative jumps.

Parameters (:class:`ContactParameters`; units as Simbody documents them): ``stiffness`` E, the plain
strain modulus (N/m^2); ``radius`` R (m); ``dissipation`` c (s/m); ``static_friction``,
``dynamic_friction`` (1); ``viscous_friction`` (s/m); ``transition_velocity`` (m/s); and our smoothing
widths ``penetration_smoothing`` (m), ``dissipation_smoothing`` (1), ``slip_smoothing`` (m/s). The
default stiffness and dissipation, 3 067 776 N/m^2 and 2 s/m, we found in a public script's contact
block for the heel and front spheres (``contactHeel``/``contactFront``) of the OpenSim 2D gait model
that Moco's example2DWalking uses; we did not open that model file, so they are that example's values
as quoted, not checked at their source; the friction defaults (0.8, 0.8, 0.5 s/m, 0.2 m/s) and the
radius (0.035 m) are that example's as we remember them, **not checked**. With them, one contact
point carries a quarter of 56.7 kg at 6 mm of penetration.

Derivatives: :func:`contact_force_jacobians` returns ``df/dp`` and ``df/dv`` in closed form (tested
against complex-step derivatives; every function here accepts complex arrays for that).

**As CasADi expressions**, for collocation.

:func:`contact_force_expr` builds the same force as :func:`contact_force` for
one contact point from CasADi column vectors ``p`` and ``v`` (``SX`` or ``MX``, ``dim`` rows), so a
transcription (bench/studies/step/ for the paper's step; the stride to come) can add the floor's forces
at the heels and toes to its dynamics and let CasADi differentiate them; :func:`contact_function` wraps
it as a ``casadi.Function`` ``(p, v) -> f``. The softplus and sigmoid take the branch whose exponent's
argument is not positive, with ``if_else`` (both branches are evaluated; the unused one is discarded,
not multiplied by zero, so its overflow never reaches the result). tests/test_contact_casadi.py holds
it equal to the numpy form and its CasADi Jacobians equal to
:func:`exo_bench.models.simulation.contact.contact_force_jacobians`.

CasADi is an optional extra (``pip install 'exo-bench[casadi]'``): without it these functions raise a
ValueError naming the extra.

**Posture.** Holding the human model's posture, and its ground contact, as controls for ``simulate``.

:func:`exo_bench.models.mechanism.presets.human` floats (a massless root rod places the hips), so it stands only
on its heels and toes (:mod:`exo_bench.models.simulation.contact`) and only if its joints hold. Its angles are
absolute, so a joint moment ``tau`` between a link and the link it turns against (its reference)
is the generalised force ``+tau`` on the link's angle and ``-tau`` on the reference's: internal, it
changes no total momentum. The joints of the 2D model: each hip (thigh against HAT: the pelvis is
part of HAT), knee (leg against thigh), ankle (foot against leg) and arch (heel against foot, the
foot's own stiffness). Every rod but the root's is held at its length by a rod force. The root's
angle and length carry no force: O holds nothing up.

:func:`hold` is a proportional-derivative hold of all of those about a reference posture, the plain
controller a standing test needs (not a model of muscles); :func:`ground_reaction` is the floor's force
at the heels and toes in the layout of ``f_ext``, for ``simulate(..., f_ext=...)`` and every method's
inverse and forward dynamics (:mod:`exo_bench.models.runtime.external_forces`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, fields
from typing import Any

import numpy as np
from exo_bench.models.mechanism.kinematics import point_mass_positions, point_mass_velocities
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.validation import _finite, _is_number

#: Positions and velocities beyond this are refused: the force's powers of them overflow float64
#: (``d^(3/2) * E`` near 1e308) long before, and a NaN must not come out.
MAX_INPUT = 1e50


@dataclass(frozen=True)
class ContactParameters:
    """The contact model's parameters (SI units; see the module text for each one's source)."""

    stiffness: float = 3067776.0  # N/m^2, plain strain modulus
    radius: float = 0.035  # m, the sphere's radius (the sole's curvature at the point)
    dissipation: float = 2.0  # s/m, Hunt-Crossley
    static_friction: float = 0.8  # 1
    dynamic_friction: float = 0.8  # 1
    viscous_friction: float = 0.5  # s/m
    transition_velocity: float = 0.2  # m/s
    penetration_smoothing: float = 1e-3  # m, width of the softplus of the penetration
    dissipation_smoothing: float = 0.05  # 1, width of the softplus of 1 + 3/2 c dd
    slip_smoothing: float = 1e-4  # m/s, e in s = sqrt(|v_t|^2 + e^2)

    def __post_init__(self) -> None:
        for f in fields(self):
            x = getattr(self, f.name)
            zero_ok = f.name in ("dissipation", "static_friction", "dynamic_friction", "viscous_friction")
            ok = _is_number(x) and _finite(x)
            if not ok or not (x == 0 and zero_ok or 1e-9 <= x <= 1e12):
                want = "0 or a number in [1e-9, 1e12]" if zero_ok else "a number in [1e-9, 1e12]"
                raise ValueError(f"contact: field {f.name!r}: expected {want}, got {x!r}")
            object.__setattr__(self, f.name, float(x))  # float64: a numpy float32 would compute in float32
        if self.dynamic_friction > self.static_friction:
            raise ValueError(
                f"contact: field 'dynamic_friction': expected <= static_friction = {self.static_friction!r}, "
                f"got {self.dynamic_friction!r}"
            )

    @property
    def hertz(self) -> float:
        """``K`` of ``f_H = K d_s^(3/2)``, N/m^(3/2)."""
        k = 0.5 * self.stiffness ** (2.0 / 3.0)
        return (4.0 / 3.0) * k * math.sqrt(self.radius * k)


#: The default parameters (an immutable value: safe as a default argument).
DEFAULT_CONTACT = ContactParameters()


def softplus(x: np.ndarray, width: float) -> np.ndarray:
    """``width * log(1 + exp(x / width))`` without overflow (the exponent's real part is never positive);
    analytic, so complex steps pass through it."""
    z = np.asarray(x) / width
    pos = np.real(z) > 0
    return width * (np.where(pos, z, 0) + np.log1p(np.exp(np.where(pos, -z, z))))


def sigmoid(x: np.ndarray, width: float) -> np.ndarray:
    """The derivative of :func:`softplus`, ``1 / (1 + exp(-x / width))``, without overflow."""
    z = np.asarray(x) / width
    e = np.exp(np.where(np.real(z) > 0, -z, z))
    return np.where(np.real(z) > 0, 1 / (1 + e), e / (1 + e))


def _check(name: str, a: np.ndarray) -> np.ndarray:
    a = a if isinstance(a, np.ndarray) else np.asarray(a)
    if a.dtype.kind not in "iufc" or isinstance(a, np.ma.MaskedArray):  # complex: complex-step derivatives
        raise ValueError(f"contact: field {name!r}: expected an array of real numbers in SI units, got {_kind(a)}")
    if a.ndim == 0 or a.shape[-1] not in (2, 3):
        raise ValueError(f"contact: field {name!r}: expected an array (..., dim) with dim 2 or 3, got shape {a.shape}")
    if not np.all(np.isfinite(a)) or np.any(np.abs(a) > MAX_INPUT):
        bad = tuple(
            int(i) for i in np.argwhere(~np.isfinite(a) | (np.abs(np.nan_to_num(a, nan=np.inf)) > MAX_INPUT))[0]
        )
        raise ValueError(
            f"contact: field {name!r}: expected finite values within +-{MAX_INPUT:g}, got {a[bad].item()!r} at {bad}"
        )
    return a


def _kind(a: np.ndarray) -> str:
    """What an array that is not real numbers holds, for a message."""
    return "a masked array" if isinstance(a, np.ma.MaskedArray) else f"dtype {a.dtype}"


def _parts(p: np.ndarray, v: np.ndarray, c: ContactParameters):
    """The intermediate quantities both the force and its Jacobians use."""
    d = -p[..., -1]
    dd = -v[..., -1]
    d_s = softplus(d, c.penetration_smoothing)
    f_h = c.hertz * d_s**1.5
    damp = softplus(1 + 1.5 * c.dissipation * dd, c.dissipation_smoothing)
    f_n = f_h * damp
    vt = v[..., :-1]
    s = np.sqrt(np.sum(vt * vt, axis=-1) + c.slip_smoothing**2)
    x = s / c.transition_velocity
    mu = c.dynamic_friction * np.tanh(x) + (c.static_friction - c.dynamic_friction) * 2 * x / (1 + x * x)
    mu = mu + c.viscous_friction * s
    return d, dd, d_s, f_h, damp, f_n, vt, s, x, mu


def contact_force(p: np.ndarray, v: np.ndarray, params: ContactParameters = ContactParameters()) -> np.ndarray:
    """The floor's force on contact points at positions ``p`` moving at ``v``, both ``(..., dim)``, in
    newtons, same shape (world frame: the last axis is the normal)."""
    p, v = _check("position", p), _check("velocity", v)
    _, _, _, _, _, f_n, vt, s, _, mu = _parts(p, v, params)
    return _force(f_n, mu, s, vt)


def _force(f_n: np.ndarray, mu: np.ndarray, s: np.ndarray, vt: np.ndarray) -> np.ndarray:
    return np.concatenate([-(f_n * mu / s)[..., None] * vt, f_n[..., None]], axis=-1)


def contact_force_jacobians(
    p: np.ndarray, v: np.ndarray, params: ContactParameters = ContactParameters()
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(f, df/dp, df/dv)``: the force of :func:`contact_force` and its derivatives, ``(..., dim, dim)``
    with ``J[..., i, j] = d f_i / d x_j``, in closed form."""
    p, v = _check("position", p), _check("velocity", v)
    c = params
    d, dd, d_s, f_h, damp, f_n, vt, s, x, mu = _parts(p, v, c)
    dim = p.shape[-1]
    # the normal force: d f_n / d z = -f_H'(d) damp; d f_n / d vz = -f_H damp' 3/2 c
    dfn_dz = -1.5 * c.hertz * np.sqrt(d_s) * sigmoid(d, c.penetration_smoothing) * damp
    dfn_dvz = -f_h * sigmoid(1 + 1.5 * c.dissipation * dd, c.dissipation_smoothing) * 1.5 * c.dissipation
    # w = f / f_n = (-mu v_t / s, 1)
    h = mu / s
    w = np.concatenate([-h[..., None] * vt, np.ones_like(h)[..., None]], axis=-1)
    e2 = np.exp(-2 * x)  # x = s / v_tr > 0: sech^2 x = 4 e^-2x / (1 + e^-2x)^2 never overflows
    sech2 = 4 * e2 / (1 + e2) ** 2
    dmu = c.dynamic_friction * sech2 / c.transition_velocity
    dmu = dmu + (c.static_friction - c.dynamic_friction) * 2 * (1 - x * x) / (1 + x * x) ** 2 / c.transition_velocity
    dmu = dmu + c.viscous_friction
    dh = (dmu * s - mu) / (s * s)
    shape = p.shape[:-1] + (dim, dim)
    jp = np.zeros(shape, dtype=np.result_type(p, v, float))
    jp[..., :, -1] = w * dfn_dz[..., None]
    jv = np.zeros_like(jp)
    jv[..., :, -1] = w * dfn_dvz[..., None]
    t = dim - 1
    outer = vt[..., :, None] * vt[..., None, :]
    eye = np.eye(t)
    jv[..., :t, :t] = -f_n[..., None, None] * (
        dh[..., None, None] * outer / s[..., None, None] + h[..., None, None] * eye
    )
    return _force(f_n, mu, s, vt), jp, jv


def ground_forces(
    positions: np.ndarray, velocities: np.ndarray, points: np.ndarray, params: ContactParameters = ContactParameters()
) -> np.ndarray:
    """The floor's forces on the point masses, ``(samples, links, 3, dim)`` (the layout of ``f_ext``):
    :func:`contact_force` at the point masses where the boolean mask ``points (links, 3)`` is set (the
    heels' and toes' end masses of :func:`exo_bench.models.mechanism.presets.human`), zero elsewhere.
    ``positions`` and ``velocities`` are those of :func:`exo_bench.models.mechanism.kinematics.point_mass_positions`
    and ``point_mass_velocities``."""
    positions, velocities = _check("positions", positions), _check("velocities", velocities)
    if velocities.shape != positions.shape:
        raise ValueError(
            f"contact: field 'velocities': expected the shape of the positions, {positions.shape}, got {velocities.shape}"
        )
    points = np.asarray(points)
    if points.dtype.kind != "b" or points.shape != positions.shape[1:3]:
        raise ValueError(
            f"contact: field 'points': expected a mask of shape {positions.shape[1:3]}, got {points.shape} "
            f"(expected booleans, got dtype {points.dtype})"
        )
    out = np.zeros(positions.shape)
    out[:, points] = contact_force(positions[:, points], velocities[:, points], params)
    return out


def _casadi() -> Any:
    try:
        import casadi
    except ImportError as e:  # pragma: no cover - CI installs the extra
        raise ValueError("contact: CasADi expressions need the casadi extra: pip install 'exo-bench[casadi]'") from e
    return casadi


def _softplus(ca: Any, x: Any, width: float) -> Any:
    z = x / width
    return width * ca.if_else(z > 0, z + ca.log1p(ca.exp(-z)), ca.log1p(ca.exp(z)))


def contact_force_expr(p: Any, v: Any, params: ContactParameters = DEFAULT_CONTACT) -> Any:
    """The floor's force (N, world axes, ``dim x 1``) on a contact point at ``p`` moving at ``v``."""
    ca = _casadi()
    c = params
    dim = p.shape[0]
    d_s = _softplus(ca, -p[dim - 1], c.penetration_smoothing)
    damp = _softplus(ca, 1 + 1.5 * c.dissipation * (-v[dim - 1]), c.dissipation_smoothing)
    f_n = c.hertz * d_s**1.5 * damp
    vt = v[: dim - 1]
    s = ca.sqrt(ca.sumsqr(vt) + c.slip_smoothing**2)
    x = s / c.transition_velocity
    mu = c.dynamic_friction * ca.tanh(x) + (c.static_friction - c.dynamic_friction) * 2 * x / (1 + x * x)
    mu = mu + c.viscous_friction * s
    return ca.vertcat(-(f_n * mu / s) * vt, f_n)


def contact_function(dim: int, params: ContactParameters = DEFAULT_CONTACT) -> Any:
    """``casadi.Function('contact', [p, v], [f])`` for one point in ``dim`` (2 or 3) dimensions."""
    if dim not in (2, 3):
        raise ValueError(f"contact: field 'dim': expected 2 or 3, got {dim!r}")
    ca = _casadi()
    p, v = ca.SX.sym("p", dim), ca.SX.sym("v", dim)
    return ca.Function("contact", [p, v], [contact_force_expr(p, v, params)], ["p", "v"], ["f"])


Controls = Callable[[float, np.ndarray, np.ndarray], np.ndarray]


@dataclass(frozen=True)
class Gains:
    """Stiffness and damping of the hold: joints (N·m/rad, N·m·s/rad), the arch (the same units), and
    rods (N/m, N·s/m)."""

    joint: tuple[float, float] = (3000.0, 100.0)
    arch: tuple[float, float] = (1000.0, 5.0)
    rod: tuple[float, float] = (2e5, 2e3)


def joints(mech: Mechanism) -> list[tuple[int, int, str]]:
    """``(link, reference, kind)`` of every joint of :func:`exo_bench.models.mechanism.presets.human`."""
    ix = {name: i for i, name in enumerate(mech.names)}
    if mech.dim != 2 or not {"root", "hat", "right_heel", "left_heel"} <= set(ix):
        raise ValueError(f"posture: mechanism {mech.name!r}: expected the 2D human preset (presets.human(2))")
    out = []
    for side in ("right", "left"):
        out += [(ix[f"{side}_thigh"], ix["hat"], "joint"), (ix[f"{side}_leg"], ix[f"{side}_thigh"], "joint")]
        out += [(ix[f"{side}_foot"], ix[f"{side}_leg"], "joint"), (ix[f"{side}_heel"], ix[f"{side}_foot"], "arch")]
    return out


def contact_points(mech: Mechanism) -> np.ndarray:
    """The mask ``(links, 3)`` of the heels' and toes' contact points (the end masses of the heel and foot rods)."""
    mask = np.zeros((mech.nlinks, 3), dtype=bool)
    for i, name in enumerate(mech.names):
        if name.endswith(("_heel", "_foot")):
            mask[i, 2] = True
    return mask


def hold(mech: Mechanism, q_ref: np.ndarray, gains: Gains = Gains()) -> Controls:
    """Controls holding every joint angle and rod length of the 2D human at those of ``q_ref (1, dof)``."""
    n = mech.nlinks
    js = joints(mech)
    q_ref = np.asarray(q_ref, dtype=float).reshape(1, -1)
    rods = np.array([i for i in range(n) if mech.names[i] != "root"])
    kp_l, kd_l = gains.rod

    def controls(t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        tau = np.zeros_like(q)
        for i, r, kind in js:
            kp, kd = gains.joint if kind == "joint" else gains.arch
            m = -kp * ((q[:, i] - q[:, r]) - (q_ref[:, i] - q_ref[:, r])) - kd * (qd[:, i] - qd[:, r])
            tau[:, i] += m
            tau[:, r] -= m
        tau[:, n + rods] = -kp_l * (q[:, n + rods] - q_ref[:, n + rods]) - kd_l * qd[:, n + rods]
        return tau

    return controls


def ground_reaction(mech: Mechanism, q: np.ndarray, qd: np.ndarray, params: ContactParameters = DEFAULT_CONTACT):
    """The floor's forces on the heels and toes in the layout of ``f_ext``, ``(samples, links, 3, dim)``."""
    return ground_forces(
        point_mass_positions(mech, q), point_mass_velocities(mech, q, qd), contact_points(mech), params
    )


def centre_of_mass(mech: Mechanism, q: np.ndarray) -> np.ndarray:
    """The whole body's centre of mass, ``(samples, dim)``."""
    w = mech.mass_array / mech.total_mass
    return np.einsum("lk,slkd->sd", w, point_mass_positions(mech, q))


def balanced_standing(mech: Mechanism, stature: float = 1.75) -> np.ndarray:
    """:func:`exo_bench.models.mechanism.presets.human_standing` leaning forward about the ankles until the centre of
    mass is above the middle of the heel and toe contact points (upright, it is above the ankles, 5 cm
    from the heels: on soft contact the body then rocks back onto its heels and falls; people stand
    leaning a few degrees forward). Secant iterations on the lean; the centre of mass's horizontal
    position is nearly linear in it, so three suffice to 1e-12 m."""
    from exo_bench.models.mechanism.presets import human_standing

    mask = contact_points(mech)

    def offset(lean: float) -> float:
        q = human_standing(mech, stature, lean)
        feet = point_mass_positions(mech, q)[0][mask][:, 0]
        return float(centre_of_mass(mech, q)[0, 0] - 0.5 * (feet.min() + feet.max()))

    a, b = 0.0, 0.05
    fa, fb = offset(a), offset(b)
    for _ in range(8):
        if fb == fa or abs(fb) < 1e-13:
            break
        a, b, fa = b, b - fb * (b - a) / (fb - fa), fb
        fb = offset(b)
    return human_standing(mech, stature, b)
