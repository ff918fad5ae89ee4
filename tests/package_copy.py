"""A copy of the package to edit a source file of, run in fresh processes (the stale-cache tests:
tests/test_compiled.py, tests/test_kernel_cache.py).

The copy is made from the checkout's sources, never from its ``__pycache__`` (another process may
be writing numba's cache there while it is copied). A test that is not about a cold compile starts
from :func:`warm_package` instead: one copy per session whose numba cache the kernels of the stale-cache
probes were compiled into once, in a process of its own, then copied whole (the cache is keyed on
the sources' contents, models/machine/numba_cache.py, so a copy of it is valid in the copy of the sources).
Each test edits its own copy; nothing is shared between tests but the untouched template.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

from exo_bench.models.machine.numba_cache import INSTALLED_CACHE_SUFFIX

ROOT = Path(__file__).resolve().parent.parent

#: The kernels the probes of the stale-cache tests run before their edit, compiled into the template:
#: exo5-3d by ``matrix`` (one sample) and ``newton-euler`` (one sample and a batch: its SIMD kernel),
#: unchecked, and the numpy references, checked.
WARM_UP = """
import json

import numpy as np
from exo_bench import prepare, presets
from exo_bench.models.machine import numba_runtime
mech = presets.exo5(dim=3)
for method, batches in (("matrix", [None]), ("newton-euler", [None, 40])):
    m, ref = prepare(mech, method), prepare(mech, method, kernel="numpy")
    for S in batches:
        q = np.linspace(0.1, 0.9, m.dof) if S is None else np.linspace(0.1, 0.9, S * m.dof).reshape(S, m.dof)
        m.inverse_dynamics(q, q, q, check=False)
        ref.inverse_dynamics(q, q, q)
print(json.dumps({"file": numba_runtime.__file__}))
"""


def copy_sources(dest: Path) -> Path:
    """The package's sources (its folders as installed: exo_bench with models, matrix_method and
    lagrange inside) copied to ``dest/exo_bench``, without any ``__pycache__``."""
    pkg = dest / "exo_bench"
    skip = shutil.ignore_patterns("__pycache__")
    shutil.copytree(ROOT / "exo_bench", pkg, ignore=skip)
    for sub in ("models", "matrix_method", "lagrange"):
        shutil.copytree(ROOT / sub, pkg / sub, ignore=skip)
    return pkg


def package_copy_prober(tmp_path: Path, probe: str, template: Path | None = None) -> tuple[Path, Callable[[], dict]]:
    """A copy of the package under ``tmp_path`` (to edit a source file of) and ``run()``, which runs the
    script ``probe`` on that copy in a fresh process and returns the JSON of its last line; the probe's
    ``"file"`` must be a path inside the copy (the copy ran, not the installed package). ``template``:
    a package folder to copy whole, its numba cache included (:func:`warm_package`); else the
    checkout's sources, with an empty cache."""
    if template is None:
        pkg = copy_sources(tmp_path)
    else:
        pkg = tmp_path / "exo_bench"
        shutil.copytree(template, pkg)
        # a copy laid out as installed keeps its compiled kernels beside the package (models/machine/numba_cache.py)
        cache = template.parent / f"{template.name}{INSTALLED_CACHE_SUFFIX}"
        if cache.is_dir():
            shutil.copytree(cache, tmp_path / cache.name)
    env = {**{k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}, "PYTHONPATH": str(tmp_path)}

    def run() -> dict:
        r = subprocess.run(
            [sys.executable, "-c", probe], env=env, cwd=tmp_path, capture_output=True, text=True, timeout=900
        )
        assert r.returncode == 0, r.stderr[-3000:]
        out = json.loads(r.stdout.strip().splitlines()[-1])
        assert out["file"].startswith(str(tmp_path)), out["file"]  # the copy, not the installed package
        return out

    return pkg, run


def warm_package(folder: Path) -> Path:
    """A copy of the package in ``folder`` whose numba cache holds the kernels of :data:`WARM_UP`
    (compiled there in a fresh process); the template of :func:`package_copy_prober`."""
    pkg, run = package_copy_prober(folder, WARM_UP)
    run()
    return pkg


def edit_probe(method: str, imports: str, edited: str, kernel: str) -> str:
    """A probe (a script for :func:`package_copy_prober`) that prints exo5-3d's forces at one sample by
    ``method``'s compiled kernel and by its numpy kernel, the compiled kernel's numba cache hits and misses
    (``kernel``: an expression of the kernel, in which ``m`` is the prepared model) and, as ``"file"``,
    the file of ``edited`` (a module the test edits); ``imports``: the lines that import what they name."""
    return f"""
import json

import numpy as np
from exo_bench import prepare, presets
{imports}
m = prepare(presets.exo5(dim=3), {method!r})
q = np.linspace(0.1, 0.9, m.dof)
tau = m.inverse_dynamics(q, q, q, check=False)
ref = prepare(presets.exo5(dim=3), {method!r}, kernel="numpy").inverse_dynamics(q, q, q)
k = {kernel}
print(json.dumps({{"file": {edited}.__file__, "tau": tau.tolist(), "numpy": ref.tolist(),
                  "hits": int(sum(k.stats.cache_hits.values())), "misses": int(sum(k.stats.cache_misses.values()))}}))
"""


def assert_edit_recompiles(tmp_path: Path, template: Path, probe: str, source: str, old: str, new: str) -> None:
    """In a copy of ``template`` (:func:`warm_package`): run ``probe`` (:func:`edit_probe`), whose kernel
    loads from the copy's cache; replace the one ``old`` of the copy's ``source`` (a path inside the
    package) by ``new``; run it again. The kernel recompiles (a cache miss, not the stale machine code),
    its forces move by more than 1e-3 of their size, and they are the edited numpy kernel's, to 1e-12 of
    their size, as the unedited ones are."""
    pkg, run = package_copy_prober(tmp_path, probe, template=template)
    before = run()  # loads from the copy's cache
    assert before["hits"] >= 1 and before["misses"] == 0, before
    path = pkg / source
    text = path.read_text()
    assert text.count(old) == 1
    path.write_text(text.replace(old, new))
    after = run()
    assert after["misses"] >= 1, after  # recompiled, not served from the stale cache
    tau_before, tau_after, edited = map(np.asarray, (before["tau"], after["tau"], after["numpy"]))
    assert np.abs(tau_after - tau_before).max() > 1e-3 * np.abs(tau_before).max()
    # the compiled kernel agrees with the edited numpy kernel as it does with the unedited one
    assert np.abs(tau_after - edited).max() <= 1e-12 * np.abs(edited).max()
