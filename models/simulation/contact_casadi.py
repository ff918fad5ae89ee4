"""The ground contact of :mod:`exo_bench.models.simulation.contact` as CasADi expressions, for collocation.

:func:`contact_force_expr` builds the same force as :func:`exo_bench.models.simulation.contact.contact_force` for
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
"""

from __future__ import annotations

from typing import Any

from exo_bench.models.simulation.contact import DEFAULT_CONTACT, ContactParameters


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
