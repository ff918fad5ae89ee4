"""
The predicted walking step (stored: no solve)
=============================================

The paper's gait (eq. 26) does not walk, so exo-bench predicts a step by direct collocation (50
Hermite-Simpson intervals, Winter's average speed 1.41 m/s, swing-foot clearance, joint ranges, an effort
objective; solved with CasADi and IPOPT). The solutions are stored with the package, so reading one needs no
CasADi; ``exo-bench gait --dim 2`` describes it and ``exo-bench gait --dim 2 --solve`` solves it again.
"""

import matplotlib.pyplot as plt
import numpy as np

from exo_bench import load_step, prepare, presets, step_violations

mech = presets.exo5(dim=2)
step = load_step(mech)  # stored with the package (exo5-2d-step.npz), reused only for an equal mechanism
print(f"{step.file_name}: {len(step.t)} points, {step.duration:.3f} s, step length {step.step_length:.3f} m")
solver = step.meta["solver"]
print(
    f"solved {step.meta['date']}: IPOPT {solver['status']} in {solver['iterations']} iterations, {solver['solve_seconds']:.0f} s"
)

# %%
# Every constraint re-evaluated in numpy from the stored arrays (nothing of the optimiser is reused).
worst = max(step_violations(step, mech).items(), key=lambda kv: kv[1])
print(f"largest constraint violation: {worst[1]:.1e} ({worst[0]})")
assert worst[1] < 1e-6

# %%
# The stored loads came from the equations' CasADi export; any method recomputes them from the motion.
tau = prepare(mech, "newton-euler").inverse_dynamics(step.q, step.qd, step.qdd)
print(f"stored tau vs newton-euler: {np.abs(tau - step.tau).max() / np.abs(step.tau).max():.1e} (relative)")
assert np.allclose(tau, step.tau, rtol=0, atol=1e-8 * np.abs(step.tau).max())

# %%
# The net joint moments along the step (sagittal plane, Winter's sign: extension of a rod from +x towards
# up is positive), per kilogram of body mass.
fig, ax = plt.subplots(figsize=(6, 3.2), layout="constrained")
for i, name in enumerate(mech.names):
    ax.plot(100 * step.t / step.duration, step.moments[:, i] / mech.total_mass, label=name)
ax.set(xlabel="% of the step", ylabel="net joint moment (N·m/kg)")
ax.set_title("exo5-2d, predicted step: net joint moments")
ax.legend(ncols=3, loc="upper center", bbox_to_anchor=(0.5, -0.25))
plt.show()
