"""``simulate``'s right-hand side with external forces ``f_ext(t, q, qd)`` (issue 37): the controls plus
``Q(q, f_ext)`` (:class:`ControlsWithForces`), with the Jacobian of the sum for ``jacobian="analytic"``
(:class:`ControlsWithForcesJacobian`); the forces themselves, their checks and ``Q`` are
:mod:`exo_bench.models.runtime.external_forces`'."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from exo_bench.models.runtime.external_forces import check_f_ext, dQ_dq, generalized_forces, refuse_overflow
from exo_bench.models.mechanism.mechanism import Mechanism


class ControlsWithForces:
    """``controls(t, q, qd) + Q(q, f_ext(t, q, qd))``: what ``simulate`` integrates with ``f_ext``
    (ground contact, interaction forces that depend on the state). ``f_ext`` is called as the controls
    are, with ``q, qd`` of shape ``(k, dof)``, and returns forces ``(k, links, 3, dim)`` (``(links, 3,
    dim)`` is taken for ``k = 1``); a force that is not finite is a ValueError naming the link and the
    point."""

    def __init__(self, model: Any, controls: Callable[..., Any], f_ext: Callable[..., Any]):
        self.model, self.controls, self.f_ext = model, controls, f_ext

    def __call__(self, t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        f = self.forces(t, q, qd)
        Q = self.model._external_forces(q, f)
        refuse_overflow(self.model.mechanism, f"simulate at t = {t:.6g} s", f, Q, "Q")
        return self.controls(t, q, qd) + Q

    def forces(self, t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """``f_ext(t, q, qd)``, checked, ``(k, links, 3, dim)``."""
        f = self.f_ext(t, q, qd)  # read by check_f_ext: real numbers only, as the calls read f_ext
        mech = self.model.mechanism
        if q.shape[0] == 1 and _shape(f) == (mech.nlinks, 3, mech.dim):
            f = np.asarray(f)[None]
        return check_f_ext(mech, f, q.shape, True, f"simulate at t = {t:.6g} s")


def _shape(a: Any) -> tuple | None:
    try:
        return np.shape(a)
    except ValueError:  # ragged: check_f_ext names it
        return None


class ControlsWithForcesJacobian(ControlsWithForces):
    """:class:`ControlsWithForces` whose controls and ``f_ext`` both have a ``jacobian(t, q, qd)``, with
    the Jacobian of the sum for ``simulate(jacobian="analytic")``: ``dQ/dq = dQ/dq|_f + J^T df/dq`` (the
    geometry, :func:`dQ_dq`, and the forces' own change, ``Q`` being linear in ``f``), ``dQ/dqd = J^T
    df/dqd``. ``f_ext.jacobian`` returns ``(df/dq, df/dqd)``, each ``(k, links, 3, dim, dof)``."""

    def jacobian(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        mech = self.model.mechanism
        cq, cqd = self.controls.jacobian(t, q, qd)  # type: ignore[attr-defined]  # checked by with_external_forces
        want = (q.shape[0], mech.nlinks, 3, mech.dim, mech.dof)
        fq, fqd = (np.broadcast_to(np.asarray(a, dtype=float), want) for a in self.f_ext.jacobian(t, q, qd))  # type: ignore[attr-defined]
        return cq + dQ_dq(mech, q, self.forces(t, q, qd)) + _through(mech, q, fq), cqd + _through(mech, q, fqd)


def _through(mech: Mechanism, q: np.ndarray, G: np.ndarray) -> np.ndarray:
    """``J^T G``, ``(k, dof, dof)``: column ``j`` the generalised forces of the forces' derivative ``G[..., j]``."""
    k, d = q.shape
    cols = np.moveaxis(G, -1, 1).reshape(k * d, *G.shape[1:-1])
    return generalized_forces(mech, np.repeat(q, d, axis=0), cols).reshape(k, d, d).transpose(0, 2, 1)


def with_external_forces(model: Any, controls: Callable[..., Any], f_ext: Any, jacobian: str) -> ControlsWithForces:
    """``simulate``'s controls with the external forces ``f_ext(t, q, qd)`` added (:class:`ControlsWithForces`),
    after checking that ``f_ext`` is a function. The analytic Jacobian needs ``f_ext.jacobian(t, q, qd) ->
    (df/dq, df/dqd)`` (:class:`ControlsWithForcesJacobian`, when the controls have theirs too); without it
    it is refused by name."""
    if not callable(f_ext):
        raise ValueError(
            f"simulate: field 'f_ext': expected a function (t, q, qd) -> forces (samples, links, 3, dim) in "
            f"newtons, got {type(f_ext).__name__}"
        )
    if jacobian == "analytic" and not callable(getattr(f_ext, "jacobian", None)):
        raise ValueError(
            "simulate: field 'jacobian': expected 'finite-difference' with f_ext (the analytic Jacobian has no "
            "derivative of f_ext(t, q, qd): give f_ext a jacobian(t, q, qd) -> (df/dq, df/dqd) attribute, each "
            "(samples, links, 3, dim, dof)), got 'analytic'"
        )
    if jacobian == "analytic" and callable(getattr(controls, "jacobian", None)):
        return ControlsWithForcesJacobian(model, controls, f_ext)
    return ControlsWithForces(model, controls, f_ext)
