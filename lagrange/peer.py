"""A peer derivation with ``sympy.physics.mechanics``: the same mechanism, built independently from
reference frames, points and particles, run through ``LagrangesMethod`` or ``KanesMethod``.

Nothing here shares code with :mod:`exo_bench.lagrange.derivation` except the output symbols. Each rod gets
its own frame: in 2D ``A_i`` is ``N`` turned by ``phi_i`` about ``N.z``; in 3D ``B_i`` is ``N``
turned by the azimuth ``phi_i`` about ``N.z`` and ``A_i`` is ``B_i`` turned by ``-psi_i`` about
``B_i.y``, so that ``A_i.x = (cos psi cos phi, cos psi sin phi, sin psi)`` (eq. 7). Rod ``i``
starts at the end point of its parent (or at ``O``) and ends at ``sign_i l_i A_i.x`` from there;
its particles sit at fractions ``0, n_i, 1`` (the middle one slides as the rod stretches).
Gravity is ``-g`` along ``N.y`` (2D) or ``N.z`` (3D).

The peer uses our absolute coordinates as its generalised coordinates, so with no applied
loads its left-hand side *is* our ``tau``: ``LagrangesMethod`` gives
``d/dt dL/dqd - dL/dq = tau``; ``KanesMethod`` (with ``u = qd``) gives ``Fr + Fr* = 0`` for the
free system, and with gravity as the only load ``tau = -(Fr + Fr*)``.
"""

from __future__ import annotations

import time

import sympy as sp
from sympy.physics import mechanics as me

from exo_bench.lagrange.budget import time_budget
from exo_bench.lagrange.derivation import parameter_values
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.mechanism.symbols import symbols_for

KINDS = ("lagrange", "kane")


def _build(mech: Mechanism, S):
    """Frames, points and particles of the mechanism, with dynamicsymbols for the coordinates."""
    n, dim = mech.nlinks, mech.dim
    t = me.dynamicsymbols._t
    q = me.dynamicsymbols(" ".join(f"q_{x}" for x in S.q))
    q = list(q) if isinstance(q, (list, tuple)) else [q]
    phi, psi, lens = q[:n], (q[n : 2 * n] if dim == 3 else []), q[-n:]
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    up = N.z if dim == 3 else N.y
    ends: list = []
    particles: list = []
    for i in range(n):
        if dim == 2:
            A = N.orientnew(f"A{i + 1}", "Axis", [phi[i], N.z])
        else:
            B = N.orientnew(f"B{i + 1}", "Axis", [phi[i], N.z])
            A = B.orientnew(f"A{i + 1}", "Axis", [-psi[i], B.y])
        start = ends[mech.parent[i]] if mech.parent[i] >= 0 else O
        rod = mech.sign[i] * lens[i] * A.x
        end = start.locatenew(f"E{i + 1}", rod)
        ends.append(end)
        for b, frac in enumerate((0, S.n[i], 1)):
            P = start.locatenew(f"P{i + 1}_{b}", frac * rod)
            P.set_vel(N, P.pos_from(O).dt(N))
            part = me.Particle(f"m{i + 1}_{b}", P, S.m[i][b])
            part.potential_energy = S.m[i][b] * S.g * P.pos_from(O).dot(up)
            particles.append((part, -S.m[i][b] * S.g * up))
    return t, q, N, particles


def _to_our_symbols(exprs, t, q, S):
    """Replace q(t), q'(t), q''(t) by our plain symbols (second derivatives first)."""
    rep = {}
    for x, sym, d, dd in zip(q, S.q, S.qd, S.qdd):
        rep[x.diff(t, 2)] = dd
        rep[x.diff(t)] = d
        rep[x] = sym
    return tuple(sp.expand(me.msubs(e, rep)) for e in exprs)


def peer_equations(
    mech: Mechanism, kind: str = "lagrange", symbolic_parameters: bool = False, budget: float = 600.0
) -> tuple[sp.Expr, ...]:
    """The peer's generalised forces of ``mech`` in our symbols and block order (len dof).

    ``kind`` is ``"lagrange"`` (``LagrangesMethod``) or ``"kane"`` (``KanesMethod``). Parameters
    stay symbols with ``symbolic_parameters=True``; otherwise the mechanism's values are
    substituted as the same exact Rationals :func:`exo_bench.lagrange.derive` uses. Particles of zero mass
    are kept (their terms vanish). Raises :class:`exo_bench.lagrange.BudgetExceeded` past ``budget`` s.
    """
    if kind not in KINDS:
        raise ValueError(f"peer_equations: field 'kind': expected one of {', '.join(KINDS)}, got {kind!r}")
    S = symbols_for(mech.nlinks, mech.dim)
    with time_budget(budget, f"sympy.physics.mechanics {kind} peer", mech.nlinks, mech.dim):
        t, q, N, parts = _build(mech, S)
        particles = [p for p, _ in parts]
        if kind == "lagrange":
            L = me.Lagrangian(N, *particles)
            lm = me.LagrangesMethod(L, q)
            lhs = list(lm.form_lagranges_equations())
        else:
            u = me.dynamicsymbols(" ".join(f"u_{x}" for x in S.q))
            u = list(u) if isinstance(u, (list, tuple)) else [u]
            kd = [qi.diff(t) - ui for qi, ui in zip(q, u)]
            km = me.KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=kd)
            loads = [(p.point, F) for p, F in parts]
            fr, frstar = km.kanes_equations(particles, loads)
            back = {ui: qi.diff(t) for qi, ui in zip(q, u)}
            back.update({ui.diff(t): qi.diff(t, 2) for qi, ui in zip(q, u)})
            lhs = [-me.msubs(e, back) for e in (fr + frstar)]
        eqs = _to_our_symbols(lhs, t, q, S)
    if not symbolic_parameters:
        vals = parameter_values(mech, S)
        eqs = tuple(sp.expand(e.xreplace(vals)) for e in eqs)
    return eqs


def timed_peer_equations(
    mech: Mechanism, kind: str = "lagrange", budget: float = 600.0
) -> tuple[tuple[sp.Expr, ...], float]:
    """:func:`peer_equations` with symbolic parameters and its wall time in seconds (for benchmarks)."""
    t0 = time.perf_counter()
    eqs = peer_equations(mech, kind, symbolic_parameters=True, budget=budget)
    return eqs, time.perf_counter() - t0
