"""
Derivatives and the CasADi export
=================================

Every prepared model has the analytic derivatives of its equations, batch-first (``model.derivatives``):
newton-euler's O(n) passes differentiated, and forward dynamics' by the implicit-function theorem. With the
extra ``casadi`` (``pip install -e '.[casadi]'``) the equations are also ``casadi.Function`` objects, for
optimal control (IPOPT comes in CasADi's wheel); ``exo-bench equations exo5-3d --format casadi -o out/``
saves them as ``.casadi`` files.
"""

import numpy as np

from exo_bench import casadi_functions, prepare, presets, random_states

mech = presets.exo5(dim=3)
model = prepare(mech, "matrix-factored")
q, qd, qdd = random_states(mech, 100, seed=0)

# %%
# Inverse dynamics' derivatives: ``dtau/dq``, ``dtau/dqd`` and ``M = dtau/dqdd``, each ``(100, 15, 15)``.
dtau_dq, dtau_dqd, M = model.derivatives.inverse_dynamics(q, qd, qdd)
print(dtau_dq.shape, "computed by:", model.derivatives.source)
assert np.allclose(M, model.mass_matrix(q))

# %%
# Checked against a central difference of inverse dynamics in one direction (error of order h²).
h, dq = 1e-6, np.random.default_rng(1).standard_normal(mech.dof)
fd = (model.inverse_dynamics(q + h * dq, qd, qdd) - model.inverse_dynamics(q - h * dq, qd, qdd)) / (2 * h)
print(f"dtau/dq @ dq vs central difference: {np.abs(dtau_dq @ dq - fd).max():.1e}")
assert np.allclose(dtau_dq @ dq, fd, rtol=1e-6, atol=1e-6 * np.abs(fd).max())

# %%
# Forward dynamics' derivatives: the accelerations, ``dqdd/dq``, ``dqdd/dqd`` and ``M^-1``.
tau = model.inverse_dynamics(q, qd, qdd)
acc, dqdd_dq, dqdd_dqd, Minv = model.derivatives.forward_dynamics(q, qd, tau)
assert np.allclose(acc, qdd, atol=1e-8) and np.allclose(Minv @ M, np.eye(mech.dof), atol=1e-8)

# %%
# The same equations as ``casadi.Function`` objects: numbers, or symbols inside your own problem. Their
# Jacobian by CasADi's automatic differentiation equals the analytic one.
try:
    import casadi as ca
except ImportError:
    ca = None
    print("skipped: casadi is not installed (pip install -e '.[casadi]')")
if ca is not None:
    eqs = casadi_functions(mech)  # inverse_dynamics, mass_matrix, bias_forces, forward_dynamics, ...
    x = ca.SX.sym("q", mech.dof)
    J = ca.Function("J", [x], [ca.jacobian(eqs.inverse_dynamics(x, qd[0], qdd[0]), x)])
    error = np.abs(np.asarray(J(q[0])) - dtau_dq[0]).max()
    print(f"CasADi's Jacobian vs the analytic one: {error:.1e}")
    assert np.allclose(np.asarray(J(q[0])), dtau_dq[0])
