"""
The library: prepare once, inverse and forward dynamics, one sample and a batch
===============================================================================

``prepare(mechanism, method)`` does every per-mechanism step once (here: load the compiled kernels), and the
prepared model's calls are cheap. Arrays are batch-first, ``(samples, dof)``, in block order
``[phi_1..phi_n, psi_1..psi_n, l_1..l_n]``; one sample may be a ``(dof,)`` array.
"""

import numpy as np

from exo_bench import joint_torques, net_joint_loads, pinocchio_model, prepare, presets, random_states

mech = presets.exo5(dim=3)  # the paper's five-link 3D exoskeleton: 15 coordinates
model = prepare(mech, "matrix-factored")
print(f"{mech.nlinks} links, dof = {mech.dof}, total mass {mech.total_mass:.2f} kg")

# %%
# A batch of 1000 random states, and the generalised forces ``tau`` (N·m for the angles, N for the rods).
q, qd, qdd = random_states(mech, 1000, seed=0)
tau = model.inverse_dynamics(q, qd, qdd)
print("tau:", tau.shape)

# %%
# One sample: validated by default; ``check=False`` and ``out=`` are the fast path of a controller's loop
# (no checks of values, no allocation).
tau0 = model.inverse_dynamics(q[0], qd[0], qdd[0])
out = np.empty(mech.dof)
model.inverse_dynamics(q[0], qd[0], qdd[0], check=False, out=out)
assert np.array_equal(out, tau0) and np.allclose(tau0, tau[0], rtol=0, atol=1e-12 * np.abs(tau0).max())

# %%
# The mass matrix and the bias forces, ``M(q) qdd + h(q, qd) = tau``, and forward dynamics, which
# recovers the accelerations from the forces.
M = model.mass_matrix(q[0])
h = model.bias_forces(q[0], qd[0])
print("M:", M.shape, " symmetric:", np.allclose(M, M.T))
qdd_back = model.forward_dynamics(q, qd, tau)
print(f"forward(inverse(qdd)) - qdd: {np.abs(qdd_back - qdd).max():.1e}")
assert np.allclose(M @ qdd[0] + h, tau0)

# %%
# Every method agrees: Pinocchio's RNEA on the generated URDF gives the same forces, to the error model of
# the tests (a few machine epsilons of the size of the terms).
reference = prepare(mech, "pinocchio").inverse_dynamics(q, qd, qdd)
print(f"matrix-factored vs pinocchio: {np.abs(tau - reference).max() / np.abs(reference).max():.1e} (relative)")
assert np.allclose(tau, reference, rtol=0, atol=1e-12 * np.abs(reference).max())

# %%
# ``tau`` holds the generalised forces of the *absolute* angles, not joint moments. The joint torques of
# Pinocchio's relative joints are ``G^-T tau``; the net joint moments of gait analysis come from the point
# masses directly (``net_joint_loads``). In 2D the two agree on every joint:
planar = presets.exo5(dim=2)
q2, qd2, qdd2 = random_states(planar, 1, seed=1)
tau2 = prepare(planar, "matrix-factored").inverse_dynamics(q2, qd2, qdd2)
moments, forces = net_joint_loads(planar, q2, qd2, qdd2)
torques = joint_torques(planar, q2, qd2, qdd2)  # rows in Pinocchio's joint order: L1_phi, L1_len, L2_phi...
angle_rows = [i for i, name in enumerate(pinocchio_model(planar).joint_names) if name.endswith("_phi")]
n = planar.nlinks
print("tau (absolute angles):", np.round(tau2[0, :n], 2))
print("net joint moments:    ", np.round(moments[0], 2))
print("joint torques (G^-T):  ", np.round(torques[0, angle_rows], 2))
assert np.allclose(moments[0], torques[0, angle_rows])
