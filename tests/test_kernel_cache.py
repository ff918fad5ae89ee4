"""numba's cache of the newton-euler kernels is keyed on their whole folder (models/numba_cache.py,
registered by models/numba_threads.py): an edit to an element function in models/newton_euler/elements.py,
which the kernels of compiled.py inline, recompiles them instead of loading the stale machine code."""

from __future__ import annotations


import numpy as np
from conftest import package_copy_prober

_PROBE = """
import json

import numpy as np
from exo_bench import prepare, presets
from exo_bench.models.newton_euler import compiled, elements
m = prepare(presets.exo5(dim=3), "newton-euler")
q = np.linspace(0.1, 0.9, m.dof)
tau = m.inverse_dynamics(q, q, q, check=False)
ref = prepare(presets.exo5(dim=3), "newton-euler", kernel="numpy").inverse_dynamics(q, q, q)
k = compiled.newton_euler
print(json.dumps({"file": elements.__file__, "tau": tau.tolist(), "numpy": ref.tolist(),
                  "hits": int(sum(k.stats.cache_hits.values())), "misses": int(sum(k.stats.cache_misses.values()))}))
"""


def test_an_edit_to_a_newton_euler_element_recompiles_its_kernel(tmp_path):
    """In a copy of the package: run the compiled newton-euler kernel (cached), edit ``project_3d``
    (elements.py, not the kernel's file), run again: a cache miss, and the forces of the edited numpy
    reference, not the stale machine code's."""
    pkg, probe = package_copy_prober(tmp_path, _PROBE)

    probe()  # compiles (or loads) into the copy's cache
    before = probe()
    assert before["hits"] >= 1 and before["misses"] == 0, before
    elements_py = pkg / "models" / "newton_euler" / "elements.py"
    text = elements_py.read_text()
    old = "    return l * cp * (cf * fy - sf * fx), l * (cp * fz - sp * radial), cp * radial + sp * fz\n"
    assert text.count(old) == 1
    elements_py.write_text(text.replace(old, old.replace("cp * radial + sp * fz", "2.0 * (cp * radial + sp * fz)")))
    after = probe()
    assert after["misses"] >= 1, after  # recompiled, not served from the stale cache
    tau_before, tau_after, edited = map(np.asarray, (before["tau"], after["tau"], after["numpy"]))
    assert np.abs(tau_after - tau_before).max() > 1e-3 * np.abs(tau_before).max()
    assert np.abs(tau_after - edited).max() <= 1e-12 * np.abs(edited).max()
