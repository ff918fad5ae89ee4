"""scipy's implicit integrators with an analytic Jacobian kept current.

scipy's ``Radau`` and ``BDF`` are tuned for a Jacobian estimated by finite differences, which costs
``2 dof`` right-hand-side evaluations (vectorised: one call of ``2 dof`` columns) each time. They
therefore hold a Jacobian as long as they can:

* ``Radau`` re-evaluates it only after a step whose simplified Newton iteration needed more than 2
  iterations with a last contraction rate above 1e-3, or after a Newton failure;
* ``BDF`` only after a Newton failure.

Between those events each Newton iteration works with a Jacobian from an older state: it converges
more slowly (more stage evaluations per step), and Radau's error estimate, which passes through
``(3.638/h I - J)^-1``, differs, so the steps differ too. The stability report measured this: at
rtol 1e-12 on the planar gait, an analytic Jacobian under scipy's rule held a stale Jacobian from
0.18 to 0.27 s and took 4% *more* evaluations than finite differences.

An analytic Jacobian (:func:`exo_bench.models.simulation.forward_dynamics.make_jacobian`) costs no right-hand-side
evaluation, so the rule that fits it is the opposite one: re-evaluate it at the new state after
every accepted step (one Jacobian and, as after most step-size changes anyway, one new LU per step).
:class:`RadauCurrentJacobian` and :class:`BDFCurrentJacobian` do exactly that and nothing else: they
run scipy's own step (``_step_impl``, the extension point of ``scipy.integrate.OdeSolver``) and then
replace the Jacobian held and drop the factorisation built from the old one. ``njev`` counts every
evaluation, the refreshes included. :data:`CURRENT_JACOBIAN` maps the integrator names onto them;
:func:`exo_bench.models.simulation.forward_dynamics.simulate` uses them for ``jacobian="analytic"``.

The attributes replaced (``J``, ``current_jac``, ``LU_real``/``LU_complex`` of Radau, ``J``, ``LU`` of
BDF) are those of scipy 1.11-1.17; ``tests/test_analytic_jacobian.py`` fails if a scipy release
renames them (the count of Jacobians per step).
"""

from __future__ import annotations

from scipy.integrate import BDF, Radau


class RadauCurrentJacobian(Radau):
    """scipy's Radau IIA (order 5), with the Jacobian re-evaluated at the new state after every
    accepted step (scipy holds it until a Newton iteration converges slowly or fails)."""

    def _step_impl(self):
        accepted, message = super()._step_impl()
        if accepted and not self.current_jac:
            self.J = self.jac(self.t, self.y, self.f)
            self.current_jac = True
            self.LU_real = self.LU_complex = None
        return accepted, message


class BDFCurrentJacobian(BDF):
    """scipy's variable-order BDF (NDF), with the Jacobian re-evaluated at the new state after every
    accepted step (scipy holds it until a Newton iteration fails)."""

    def _step_impl(self):
        accepted, message = super()._step_impl()
        if accepted:
            self.J = self.jac(self.t, self.y)
            self.LU = None
        return accepted, message


#: The ``solve_ivp`` method for each implicit integrator when the Jacobian is analytic.
CURRENT_JACOBIAN = {"Radau": RadauCurrentJacobian, "BDF": BDFCurrentJacobian}
