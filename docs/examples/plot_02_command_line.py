"""
The command line: example states, inverse and forward dynamics as JSON
======================================================================

``exo-bench states PRESET -o FILE`` writes valid example states (``q``, ``qd``, ``qdd`` and their ``tau``) of
any mechanism; ``inverse`` and ``forward`` read such a file and print JSON on stdout. Bad input is answered by
one line on stderr and exit code 2. In a shell, the same commands are::

    .venv/bin/exo-bench states exo5-3d -o states.json
    .venv/bin/exo-bench inverse exo5-3d states.json --method matrix-factored > tau.json
    .venv/bin/exo-bench forward exo5-3d states.json > qdd.json

Here they run through Python's ``subprocess`` in a temporary folder.
"""

import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np


def exo_bench(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    """``exo-bench ARGS`` with this Python (``python -m exo_bench.bench.cli``), its output captured."""
    cmd = [sys.executable, "-m", "exo_bench.bench.cli", *args]
    return subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=300)


scratch = tempfile.TemporaryDirectory(prefix="exo-bench-example-")  # removed at the end
folder = Path(scratch.name)
print(exo_bench("presets", cwd=folder).stdout.splitlines()[-3:])

# %%
# Example states of the 3D exoskeleton (15 coordinates), 10 samples by default.
assert exo_bench("states", "exo5-3d", "-o", "states.json", cwd=folder).returncode == 0
states = json.loads((folder / "states.json").read_text())
print({k: np.shape(v) for k, v in states.items()})

# %%
# Inverse dynamics prints ``{"method": ..., "tau": [[...]]}``: the generalised forces, one row per sample,
# the same as the file's ``tau`` (which ``states`` computed with the library).
run = exo_bench("inverse", "exo5-3d", "states.json", "--method", "matrix-factored", cwd=folder)
tau = np.array(json.loads(run.stdout)["tau"])
print(json.loads(run.stdout)["method"], tau.shape)
assert np.allclose(tau, states["tau"], rtol=0, atol=1e-12 * np.abs(tau).max())

# %%
# Forward dynamics reads ``q``, ``qd`` and ``tau`` and prints the accelerations: the file's ``qdd`` again.
run = exo_bench("forward", "exo5-3d", "states.json", cwd=folder)
qdd = np.array(json.loads(run.stdout)["qdd"])
print(f"forward - qdd: {np.abs(qdd - states['qdd']).max():.1e}")
assert np.allclose(qdd, states["qdd"], rtol=0, atol=1e-8)

# %%
# States written for one mechanism do not fit another: one line on stderr, exit code 2, no traceback.
run = exo_bench("inverse", "fig2a-2d", "states.json", cwd=folder)
print("exit code", run.returncode, ":", run.stderr.strip())
assert run.returncode == 2 and len(run.stderr.strip().splitlines()) == 1
scratch.cleanup()
