"""numba's cache of the kernels is keyed on their whole folder and the shared sources (models/machine/numba_cache.py,
installed by models/machine/numba_runtime.py): an edit to an element function in models/mechanism/rod_elements.py,
which the kernels of compiled.py inline, recompiles them instead of loading the stale machine code."""

from __future__ import annotations


import numpy as np
from package_copy import assert_edit_recompiles, edit_probe, package_copy_prober

_PROBE = edit_probe(
    "newton-euler",
    "from exo_bench.models.mechanism import rod_elements as elements\nfrom exo_bench.models.newton_euler import compiled",
    "elements",
    "compiled.newton_euler",
)


def test_an_edit_to_a_newton_euler_element_recompiles_its_kernel(tmp_path, warm_package):
    """In a copy of the package: run the compiled newton-euler kernel (cached), edit ``project_3d``
    (rod_elements.py, not the kernel's file), run again: a cache miss, and the forces of the edited numpy
    reference, not the stale machine code's. The copy starts from the session's warm template."""
    old = "    return l * cp * (cf * fy - sf * fx), l * (cp * fz - sp * radial), cp * radial + sp * fz\n"
    new = old.replace("cp * radial + sp * fz", "2.0 * (cp * radial + sp * fz)")
    assert_edit_recompiles(tmp_path, warm_package, _PROBE, "models/mechanism/rod_elements.py", old, new)


_PROBE_TRIG = """
import json

import numpy as np
from exo_bench import prepare, presets
from exo_bench.models.machine import fast_trig
from exo_bench.models.newton_euler import simd as ne_simd
mech = presets.exo5(dim=3)
q = np.linspace(0.1, 0.9, 40 * mech.dof).reshape(40, mech.dof)
out = {"file": fast_trig.__file__}
for method, kernel in (("newton-euler", ne_simd.kernel_for(mech.nlinks)),):
    m = prepare(mech, method)
    out[method] = m.inverse_dynamics(q, q, q, check=False).tolist()
    out[method + " numpy"] = prepare(mech, method, kernel="numpy").inverse_dynamics(q, q, q).tolist()
    out[method + " misses"] = int(sum(kernel.stats.cache_misses.values()))
print(json.dumps(out))
"""


def test_an_edit_to_the_shared_sin_cos_recompiles_the_simd_kernel(tmp_path, warm_package):
    """models/machine/fast_trig.py is outside both kernel folders, and the SIMD kernels of ``matrix-factored`` and
    ``newton-euler`` import its ``sincos_reduced`` by name (models/machine/numba_cache.py, SHARED_SOURCES; an edit
    to it once left both families' cached SIMD kernels on the old sin/cos). In a copy of the package:
    run newton-euler's batched kernel (cached), spoil the sine polynomial's first coefficient, run
    again: it recompiles and its forces move away from the numpy reference (which uses numpy's sin/cos)
    by far more than the error model. One family's kernel shows the mechanism; that every cached kernel
    of both families (and of every kernel folder) is keyed on the shared sources is
    tests/test_kernel_cache_keys.py's, without compiling. The copy starts from the session's warm template."""
    pkg, probe = package_copy_prober(tmp_path, _PROBE_TRIG, template=warm_package)
    before = probe()
    methods = ("newton-euler",)
    assert all(before[m + " misses"] == 0 for m in methods), before
    trig_py = pkg / "models" / "machine" / "fast_trig.py"
    text = trig_py.read_text()
    old = "S1 = -1.66666666666666324348e-01"
    assert text.count(old) == 1
    trig_py.write_text(text.replace(old, "S1 = -1.7e-01"))
    after = probe()
    for m in methods:
        assert after[m + " misses"] >= 1, (m, after[m + " misses"])
        tau_before, tau_after, ref = (np.asarray(x[k]) for x, k in ((before, m), (after, m), (after, m + " numpy")))
        scale = np.abs(ref).max()
        assert np.abs(tau_before - ref).max() <= 1e-12 * scale
        assert np.abs(tau_after - ref).max() > 1e-6 * scale, m


_PROBE_LANES = """
import json
import pathlib

import numpy as np
from exo_bench import prepare, presets
from exo_bench.models.machine import numba_runtime
from exo_bench.models.gait.motion import smooth_random_motion
from exo_bench.models.newton_euler import simd

out = {"file": numba_runtime.__file__}
for name in pathlib.Path("which.txt").read_text().split():
    mech = presets.exo5(dim=3) if name == "wide" else presets.chain(900, 3)
    mo = smooth_random_motion(mech, np.linspace(0.0, 3.0, 37), seed=1)
    out[name] = prepare(mech, "newton-euler").inverse_dynamics(mo.q, mo.qd, mo.qdd, check=False).tolist()
    stats = simd.kernel_for(mech.nlinks).stats
    out[name + " hits"], out[name + " misses"] = (int(sum(s.values())) for s in (stats.cache_hits, stats.cache_misses))
print(json.dumps(out))
"""


def test_kernels_of_both_block_sizes_compiled_in_other_processes_load_together(tmp_path, warm_package):
    """newton-euler's SIMD kernel for blocks of 32 (exo5-3d) and of 16 samples (a 3D chain of 900),
    each compiled first in its own process, then both loaded from the cache by a third process: each
    computes its own mechanism's forces (numba names a symbol after the qualified name and a
    per-process counter; without the block size in the name, models/machine/numba_runtime.jit_for, the third
    process segfaulted or LLVM aborted). The blocks of 32 were compiled by the process that built the
    session's warm template (tests/package_copy.py), the blocks of 16 by the first probe here; the
    probes' cache statistics show which process compiled and which loaded."""
    from conftest import assert_forces_agree
    from exo_bench import prepare, presets
    from exo_bench.models.gait.motion import smooth_random_motion
    from exo_bench.models.machine.numba_cache import installed_cache_folder

    pkg, probe = package_copy_prober(tmp_path, _PROBE_LANES, template=warm_package)
    folder = installed_cache_folder(pkg / "models" / "newton_euler" / "simd.py", pkg)  # beside the copy's package
    assert folder is not None
    cached = [f.name for f in folder.glob("simd.*.nbi")]
    assert any("32lanes" in f for f in cached) and not any("16lanes" in f for f in cached), cached
    for which, compiles in (("narrow", "narrow"), ("wide narrow", "")):
        (tmp_path / "which.txt").write_text(which)
        got = probe()
        for name in which.split():  # compiled here if it is this process's to compile, else loaded
            hits, misses = got[name + " hits"], got[name + " misses"]
            expected = (misses >= 1 and hits == 0) if name == compiles else (misses == 0 and hits >= 1)
            assert expected, (which, name, hits, misses)
    for name, mech in (("wide", presets.exo5(dim=3)), ("narrow", presets.chain(900, 3))):
        mo = smooth_random_motion(mech, np.linspace(0.0, 3.0, 37), seed=1)
        q, qd, qdd = mo.q, mo.qd, mo.qdd
        ref = prepare(mech, "newton-euler", kernel="numpy").inverse_dynamics(q, qd, qdd)
        assert_forces_agree(np.asarray(got[name]), ref, mech, q, qd, qdd, what=name)
