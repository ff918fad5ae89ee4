"""The package's shape: one import name, layers that only go down, no cycles.

* The layer contract and the acyclicity contract live in pyproject.toml ([tool.importlinter]) and
  are checked here with import-linter, function-local imports included. import-linter reads the
  package from the file system, and an editable install maps ``exo_bench.models`` and friends onto
  the top-level folders by an import hook it cannot see, so the check runs on a copy of the tree
  laid out as installed (``exo_bench/models``, ...).
* A user's own ``models.py`` (or ``bench.py``, ``lagrange.py``) beside their script does not shadow
  ours: everything we ship is under ``exo_bench``.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SUBPACKAGES = ("models", "matrix_method", "lagrange", "bench")


def test_layers_only_go_down_and_there_are_no_cycles(tmp_path):
    lint = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    if lint is None:
        pytest.fail("lint-imports is not installed: install the test extra, pip install -e '.[test]'")
    pkg = tmp_path / "exo_bench"
    shutil.copytree(ROOT / "exo_bench", pkg, ignore=shutil.ignore_patterns("__pycache__"))
    for sub in SUBPACKAGES:
        shutil.copytree(ROOT / sub, pkg / sub, ignore=shutil.ignore_patterns("__pycache__", "scenes"))
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    r = subprocess.run(
        [lint, "--config", str(ROOT / "pyproject.toml"), "--no-cache"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=1800,
    )
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-2000:]
    assert "0 broken" in r.stdout


def test_a_users_own_models_module_does_not_shadow_ours(tmp_path):
    for name in ("models", "bench", "lagrange", "matrix_method"):
        (tmp_path / f"{name}.py").write_text(f"raise ImportError('the user\\'s own {name}.py was imported')\n")
    script = tmp_path / "use_it.py"
    script.write_text(
        "import numpy as np\n"
        "from exo_bench import prepare, presets\n"
        "from exo_bench.models.gait.motion import random_states\n"
        "m = presets.exo5(dim=3)\n"
        "q, qd, qdd = random_states(m, 3, seed=0)\n"
        "a = prepare(m, 'matrix').inverse_dynamics(q, qd, qdd)\n"
        "b = prepare(m, 'pinocchio').inverse_dynamics(q, qd, qdd)\n"
        "print(float(np.abs(a - b).max() / np.abs(b).max()))\n"
    )
    r = subprocess.run([sys.executable, str(script)], cwd=tmp_path, capture_output=True, text=True, timeout=1800)
    assert r.returncode == 0, r.stderr
    # Two float64 implementations of the same forces: a few ulps of the largest force (conftest).
    assert float(r.stdout) < 1e-13


def test_every_package_is_installed():
    """pyproject's explicit package list names every folder with an __init__.py (a subpackage left
    out is missing from a regular, non-editable install)."""
    import tomllib

    listed = set(tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {".".join(init.parent.relative_to(ROOT).parts) for init in (ROOT / "exo_bench").rglob("__init__.py")}
    for sub in SUBPACKAGES:
        for init in (ROOT / sub).rglob("__init__.py"):
            rel = init.parent.relative_to(ROOT).parts
            found.add(".".join(("exo_bench",) + rel))
    assert found == listed, (sorted(found - listed), sorted(listed - found))
