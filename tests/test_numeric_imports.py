"""Preparing or calling a numeric method imports no sympy (issue 35), and no CasADi unless its derivatives
are asked for; ``import exo_bench`` alone imports neither them nor numba (exo_bench/__init__.py's promise).

Each method runs in a fresh process of its own: a module imported once stays in ``sys.modules``, so one
method's imports would hide another's. The numeric methods are read from the method table: every method
whose text does not say it is derived with sympy (a new method is covered without editing this test).
"""

from __future__ import annotations

import json
import subprocess
import sys
from typing import Any

import pytest

from exo_bench.api.methods import METHODS

#: Every method of the table that computes numerically (its text does not name sympy).
NUMERIC = [name for name, spec in METHODS.items() if "sympy" not in spec.text]

_PROBE = """
import json, sys
from exo_bench import prepare, presets
from exo_bench.api.methods import METHODS
from exo_bench.models.gait.motion import random_states
from exo_bench.models.runtime.prepared import MissingExtra

name = sys.argv[1]
ran = []
for kernel in METHODS[name].kernel_options or (None,):
    for dim in (2, 3):
        mech = presets.exo5(dim=dim)
        try:
            model = prepare(mech, name, **({} if kernel is None else {"kernel": kernel}))
        except MissingExtra as e:
            print(json.dumps({"missing": str(e)}))
            raise SystemExit(0)
        q, qd, qdd = random_states(mech, 40, 0)  # a batch (the SIMD kernels' blocks) and one sample
        tau = model.inverse_dynamics(q, qd, qdd)
        model.inverse_dynamics(q, qd, qdd, check=False)
        model.inverse_dynamics(q[0], qd[0], qdd[0])
        model.forward_dynamics(q, qd, tau)
        model.forward_dynamics(q[0], qd[0], tau[0])
        model.mass_matrix(q)
        model.bias_forces(q, qd)
        model.mass_matrix_and_bias(q, qd)
        ran.append([kernel, dim])
loaded = sorted(m for m in ("sympy", "casadi") if m in sys.modules)
print(json.dumps({"ran": ran, "loaded": loaded}))
"""


def _probe(code: str, *args: str) -> Any:
    r = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_the_numeric_methods_are_read_from_the_table():
    """The selection keeps the matrix family, newton-euler and the engines, and leaves out lagrange."""
    assert "lagrange" not in NUMERIC
    assert {"matrix", "matrix-factored", "matrix-paper", "recurrence", "newton-euler", "pinocchio"} <= set(NUMERIC)


@pytest.mark.parametrize("name", NUMERIC)
def test_a_numeric_method_imports_no_sympy(name):
    """In a fresh process: prepare ``name`` with each of its kernels, 2D and 3D, and call its inverse
    dynamics (batch, unchecked, one sample), forward dynamics, mass matrix and bias forces: neither
    sympy nor CasADi is in ``sys.modules``."""
    out = _probe(_PROBE, name)
    if "missing" in out:
        pytest.skip(out["missing"])
    assert len(out["ran"]) == 2 * max(1, len(METHODS[name].kernel_options)), out
    assert out["loaded"] == [], f"{name}: preparing and calling it imported {out['loaded']}"


def test_importing_the_package_imports_no_numba_sympy_or_casadi():
    """``import exo_bench`` and its lazy names for building a model (not the model itself) load none of
    the heavy libraries: numba's runtime set-up happens where kernels are compiled, not on import."""
    out = _probe(
        "import json, sys\n"
        "import exo_bench\n"
        "from exo_bench import Mechanism, MethodSpec, method_names, prepare, presets\n"
        "presets.exo5(dim=3)\n"
        "print(json.dumps(sorted(m for m in ('numba', 'llvmlite', 'sympy', 'casadi') if m in sys.modules)))"
    )
    assert out == [], f"import exo_bench loaded {out}"
