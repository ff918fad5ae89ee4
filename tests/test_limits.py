"""Every resource count a user sets has a bound, and the memory of what it creates is predicted first
(issue 34: C1, L3); numba's environment variables are checked at the edge (U6, T4).

Counts (pinocchio's ``threads``, ``--workers``, NUMBA_NUM_THREADS) are held to
:func:`exo_bench.models.machine.memory.max_count` (4 per usable CPU); within it, the threads' stacks
and Data must fit in the address space left under ``ulimit -v``. The processes that test those
limits set ``RLIMIT_AS`` themselves, in a fresh interpreter, so nothing here can exhaust the machine.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from cli_runs import cli_process
from hypothesis import given, settings
from hypothesis import strategies as st

from conftest import assert_forces_agree
from exo_bench.models.machine import memory
from exo_bench.models.mechanism.presets import exo5


def _python(code: str, env: dict | None = None, timeout: float = 600) -> subprocess.CompletedProcess:
    full = {**os.environ, **(env or {})}
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, timeout=timeout, env=full
    )


# A process that leaves itself ROOM bytes of address space (RLIMIT_AS) after its imports, then
# prepares pinocchio with THREADS threads and runs a batch: it prints the error's line, or "ran".
_UNDER_ULIMIT = """
import resource, numpy as np
from exo_bench.models.mechanism.presets import exo5
from exo_bench.api.preparation import prepare
from exo_bench.models.engines import pinocchio_backend
mech = exo5(3)
q = np.full((200, mech.dof), 0.3)
prepare(mech, "pinocchio").inverse_dynamics(q, q, q)  # every import and first touch before the limit
size = int(open("/proc/self/statm").read().split()[0]) * resource.getpagesize()
resource.setrlimit(resource.RLIMIT_AS, (size + {room}, resource.getrlimit(resource.RLIMIT_AS)[1]))
try:
    {call}
    print("ran")
except (ValueError, MemoryError) as e:
    print(type(e).__name__, "|", e)
"""


@pytest.mark.case("C1", "L3")
@pytest.mark.parametrize(
    "call",
    [
        'prepare(mech, "pinocchio", threads=1000).inverse_dynamics(q, q, q)',
        "pinocchio_backend.inverse_dynamics_parallel(mech, q, q, q, threads=1000)",
    ],
    ids=["prepare", "inverse_dynamics_parallel"],
)
def test_a_thousand_pinocchio_threads_are_refused_naming_the_option(call):
    """A thousand Pinocchio threads are refused with a ValueError naming the option, its bound and the
    value, before any thread starts (they exited the process through libgomp under ``ulimit -v``)."""
    r = _python(_UNDER_ULIMIT.format(room=512 * 2**20, call=call))
    assert "libgomp" not in r.stderr and r.returncode == 0, r.stderr[-2000:]
    line = r.stdout.strip().splitlines()[-1]
    bound = memory.max_count()
    assert line.startswith("ValueError |"), line
    assert "'threads'" in line and f"at most {bound}" in line and "1000" in line, line


@pytest.mark.case("C1")
def test_threads_within_the_bound_whose_stacks_do_not_fit_the_address_space_are_refused():
    """Threads within the bound whose stacks and Data exceed the address space left under ``ulimit -v``
    are refused beforehand, naming the option and how many fit."""
    bound = memory.max_count()
    room = bound * memory.thread_stack_bytes() // 2
    r = _python(_UNDER_ULIMIT.format(room=room, call=f'prepare(mech, "pinocchio", threads={bound})'))
    assert "libgomp" not in r.stderr and r.returncode == 0, r.stderr[-2000:]
    line = r.stdout.strip().splitlines()[-1]
    assert line.startswith("ValueError |") and "'threads'" in line and "address space" in line, line
    assert f"got {bound}" in line, line


@pytest.mark.case("L3")
@settings(max_examples=25, deadline=None)
@given(extra=st.one_of(st.integers(1, 10), st.integers(10, 10**30)))
def test_pinocchio_threads_over_the_bound_are_refused_before_any_data(extra):
    """Any ``threads`` over the bound is refused by the class itself and by ``prepare``, naming the
    option, the bound and the value."""
    from exo_bench.api.preparation import prepare
    from exo_bench.models.engines.pinocchio_backend import PinocchioRNEA

    threads = memory.max_count() + extra
    for make in (
        lambda: PinocchioRNEA(exo5(3), threads=threads),
        lambda: prepare(exo5(3), "pinocchio", threads=threads),
    ):
        with pytest.raises(ValueError) as e:
            make()
        assert "'threads'" in str(e.value) and f"got {threads}" in str(e.value), e.value


@pytest.mark.case("C1")
def test_a_data_per_thread_over_the_memory_is_refused_by_the_cost_model(monkeypatch):
    """Threads within the bound whose Data (one per thread, and the pool's copy) exceed the memory are
    refused by ``prepare`` with the cost model's one line (a ValueError naming the Data, the count and
    a method that fits) before any Data is made."""
    from exo_bench.api import cost_model
    from exo_bench.api.preparation import prepare

    mech, bound = exo5(3), memory.max_count()
    one = cost_model.estimate(mech, "pinocchio", 1, {"threads": 1}).memory
    many = cost_model.estimate(mech, "pinocchio", 1, {"threads": bound}).memory
    monkeypatch.setattr(cost_model, "usable_memory", lambda: int((one + many) / 2))
    with pytest.raises(cost_model.ResourceLimit) as e:
        prepare(mech, "pinocchio", threads=bound)
    msg = str(e.value)
    assert "pinocchio" in msg and f"x {bound + 2}" in msg and "memory limit" in msg and "fits" in msg, msg
    prepare(mech, "pinocchio")  # one thread's Data fits


@pytest.mark.case("L3")
def test_pinocchio_threads_within_the_bound_agree_with_one_thread():
    """Threads up to the bound still run, and give one thread's forces exactly."""
    from exo_bench.api.preparation import prepare

    mech = exo5(3)
    rng = np.random.default_rng(1)
    q, qd, qdd = (rng.uniform(0.2, 1.0, (50, mech.dof)) for _ in range(3))
    one = prepare(mech, "pinocchio").inverse_dynamics(q, qd, qdd)
    many = prepare(mech, "pinocchio", threads=memory.max_count()).inverse_dynamics(q, qd, qdd)
    assert np.array_equal(one, many)


@pytest.mark.case("L3")
@pytest.mark.parametrize("command", ["bench", "stability"])
def test_workers_over_the_bound_are_refused_in_one_line(command, monkeypatch, capsys, tmp_path):
    """``--workers`` over the bound is refused in one line naming the option, the bound and the value,
    before any worker starts."""
    from exo_bench.bench.cli import app
    from exo_bench.bench.cli import bench as bench_cli
    from exo_bench.bench.cli import stability as stability_cli

    monkeypatch.setattr(bench_cli, "cmd_bench", lambda args: 0)  # never a sweep, whatever happens
    monkeypatch.setattr(stability_cli, "cmd_stability", lambda args: 0)
    n = memory.max_count() + 1
    code = app.main([command, "--workers", str(n), "--reports", str(tmp_path / "rep")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert "--workers" in err and f"at most {memory.max_count()}" in err and f"got {n}" in err, err


@pytest.mark.case("L3")
def test_a_local_cluster_whose_workers_do_not_fit_in_memory_is_refused(monkeypatch):
    """A local cluster whose worker processes would not fit in the memory a run may use is refused
    beforehand, naming ``--workers``, the memory and how many fit; no worker starts."""
    import distributed

    from exo_bench.bench.cluster import cluster as cluster_mod
    from exo_bench.models.machine import memory

    def no_cluster(*a, **k):
        raise AssertionError("a LocalCluster was started")

    monkeypatch.setattr(distributed, "LocalCluster", no_cluster)
    monkeypatch.setattr(memory, "usable_memory", lambda: int(1.5 * memory.WORKER_BYTES))
    with pytest.raises(ValueError) as e:
        with cluster_mod.cluster(None, 2):
            pass
    msg = str(e.value)
    assert "--workers" in msg and "got 2" in msg and "at most 1" in msg and "memory" in msg, msg
    with pytest.raises(ValueError, match="--workers"):
        with cluster_mod.cluster(None, memory.max_count() + 1):
            pass


# ----------------------------------------------------------------------------- numba's environment
_BATCH = """
import numpy as np
from exo_bench.models.mechanism.presets import exo5
from exo_bench.api.preparation import prepare
mech = exo5(3)
try:
    m = prepare(mech, "{method}")
    q = np.full((20000, mech.dof), 0.3)
    m.inverse_dynamics(q, q, q)
    print("ran")
except ValueError as e:
    print("ValueError |", e)
"""


@pytest.mark.case("U6", "L3")
@pytest.mark.parametrize(
    "var,value",
    [
        ("NUMBA_NUM_THREADS", "0"),
        ("NUMBA_NUM_THREADS", "-3"),
        ("NUMBA_NUM_THREADS", "two"),
        ("NUMBA_NUM_THREADS", "100000"),
        ("NUMBA_THREADING_LAYER", "bogus"),
        ("NUMBA_THREADING_LAYER", "tbb"),
    ],
)
@pytest.mark.parametrize("method", ["matrix-factored", "newton-euler"])
def test_numba_variables_are_refused_naming_the_variable(var, value, method):
    """A bad NUMBA_NUM_THREADS or NUMBA_THREADING_LAYER is refused with one ValueError naming the
    variable, its value and what is expected, before numba starts."""
    if value == "tbb":
        import importlib.util

        if importlib.util.find_spec("tbb") is not None:
            pytest.skip("Intel TBB is installed here: the tbb layer loads")
    r = _python(_BATCH.format(method=method), env={**os.environ, var: value})
    assert r.returncode == 0, r.stderr[-2000:]
    line = r.stdout.strip().splitlines()[-1]
    assert line.startswith("ValueError |") and f"{var}={value!r}" in line and "expected" in line, line


@pytest.mark.case("U6")
@pytest.mark.parametrize("var,value", [("NUMBA_NUM_THREADS", "0"), ("NUMBA_THREADING_LAYER", "bogus")])
def test_numba_variables_give_one_cli_line(var, value, tmp_path):
    """The CLI refuses them in one line naming the variable, exit 2."""
    states = tmp_path / "s.npz"
    z = np.full((20000, 15), 0.3)
    np.savez(states, q=z, qd=z, qdd=z)
    r = cli_process("inverse", "exo5-3d", states, "--method", "matrix-factored", env={**os.environ, var: value})
    err = r.stderr.strip()
    assert r.returncode == 2 and len(err.splitlines()) == 1, err
    assert f"{var}={value!r}" in err and "internal error" not in err, err


@pytest.mark.case("T4")
@pytest.mark.parametrize("method", ["matrix-factored", "newton-euler"])
def test_numba_disable_jit_refuses_the_compiled_kernels_in_one_line(method, tmp_path):
    """NUMBA_DISABLE_JIT=1 refuses the compiled kernels in one line naming the variable and why, and
    the numpy kernels still run (they raised "internal error: NotImplementedError: <intrinsic tile_in>")."""
    states = tmp_path / "s.npz"
    z = np.full((200, 15), 0.3)
    np.savez(states, q=z, qd=z, qdd=z)
    r = cli_process("inverse", "exo5-3d", states, "--method", method, env={**os.environ, "NUMBA_DISABLE_JIT": "1"})
    err = r.stderr.strip()
    assert r.returncode == 2 and len(err.splitlines()) == 1, err
    assert "NUMBA_DISABLE_JIT" in err and "kernel" in err and "internal error" not in err, err
    out = tmp_path / "tau.npz"
    code = f"""
    import numpy as np
    from exo_bench.models.mechanism.presets import exo5
    from exo_bench.api.preparation import prepare
    mech = exo5(3)
    q = np.full((200, mech.dof), 0.3)
    a = prepare(mech, "{method}", kernel="numpy").inverse_dynamics(q, q, q)
    b = prepare(mech, "pinocchio").inverse_dynamics(q, q, q)
    np.savez({str(out)!r}, a=a, b=b)
    """
    r = _python(code, env={**os.environ, "NUMBA_DISABLE_JIT": "1"})
    assert r.returncode == 0, r.stderr[-2000:]
    with np.load(out) as f:
        assert_forces_agree(f["a"], f["b"], exo5(3), z, z, z, what=f"{method} (numpy) under NUMBA_DISABLE_JIT")
