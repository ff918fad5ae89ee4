"""
MuJoCo: the exported MJCF and the ``mujoco`` method
===================================================

``exo-bench mjcf exo5-3d -o exo5.xml`` (or ``exo_bench.to_mjcf``) writes a mechanism as MuJoCo's
XML: each rod a body with its hinges and slides, point masses with their exact masses. The method ``mujoco``
runs MuJoCo's recursive Newton-Euler (``mj_rne``) on it and maps the joints to the paper's coordinates. MuJoCo is
optional (``pip install -e '.[peers]'``); without it this example says so and stops.
"""

import numpy as np

from exo_bench import prepare, presets, random_states, to_mjcf

try:
    import mujoco
except ImportError:
    mujoco = None
    print("skipped: mujoco is not installed (pip install -e '.[peers]')")

# %%
# The MJCF text, compiled by MuJoCo: one body per rod and per sliding mass.
if mujoco is not None:
    mech = presets.exo5(dim=3)
    xml = to_mjcf(mech)
    m = mujoco.MjModel.from_xml_string(xml)
    print(f"MuJoCo {mujoco.__version__}: {m.nbody} bodies, {m.nv} joints, {len(xml.splitlines())} lines of XML")

# %%
# The ``mujoco`` method agrees with the matrix method to rounding (MuJoCo computes in a frame at each tree's
# centre of mass, so its rounding is a little larger: the tests' error model has a term for it).
if mujoco is not None:
    q, qd, qdd = random_states(mech, 20, seed=0)
    tau_mj = prepare(mech, "mujoco").inverse_dynamics(q, qd, qdd)
    tau = prepare(mech, "matrix-factored").inverse_dynamics(q, qd, qdd)
    relative = np.abs(tau_mj - tau).max() / np.abs(tau).max()
    print(f"mujoco vs matrix-factored: {relative:.1e} (relative to the largest force)")
    assert relative < 1e-10
