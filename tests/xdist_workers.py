"""The README's test command on two pytest-xdist workers, each a test process of its own.

Hooks of tests/conftest.py (imported there, so they are conftest hooks):

* :func:`pytest_cmdline_main`: a run that names no paths (the README's ``python -m pytest``: pyproject's
  testpaths) gets ``-n 2 --dist loadfile`` unless it chose ``-n``, ``--dist`` or ``--tx`` itself, asks
  for ``--pdb`` or only collects. A run that names files stays in one process (``-s`` and ``--pdb``
  work; ``-n 2`` makes it parallel). Not in pyproject's addopts: ``exo-bench run`` and ``exo-bench
  bench`` run pytest on bench/ with that ini, and an ``-n`` there fails with "unrecognized arguments"
  where the [test] extra (pytest-xdist) is not installed, and disables every benchmark where it is
  (pytest-benchmark refuses to time under xdist). tests/conftest.py is not loaded by those runs.
* :func:`pytest_configure`, in a worker: numba's cache folder (``NUMBA_CACHE_DIR``, inherited by the
  CLI processes its tests start) is one folder for both workers, so a kernel one worker compiled is
  loaded, not compiled again, by the other (numba's compiles were about two thirds of a cold run's
  time). Safe since numba's index of a function's machine code is read and rewritten under a lock
  (:func:`exo_bench.models.machine.numba_cache.index_locked`, tests/test_numba_cache_lock.py): without it, two
  processes compiling two signatures of one kernel at once could both take data file 1, and the index
  left could name the other signature's code (numba issues 4807, 10128), hence one folder per worker
  before. And ``PYTEST_XDIST_*``, which xdist sets in the worker's environment, is removed: a pytest
  its tests start (the benchmark rows of ``exo-bench bench``) would read it and take itself for a
  worker, and pytest-benchmark would time nothing.

* :func:`pytest_xdist_make_scheduler`: each file on one worker, and the files of
  :data:`SHARED_WORKER` on one worker together; the costliest (:data:`COSTLY_FIRST`) handed out first.
* :func:`pytest_sessionstart`, in the controller of a run on workers: the kernels are compiled into
  the workers' numba cache before the workers start (tests/warm_kernels.py, its parts at once), so
  that the workers and the CLI processes their tests start load them instead of each compiling
  them on a fresh clone (a process that misses the cache compiles; the lock only orders the saving).
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

#: Workers of the whole suite: the cores of the 2-core machine CI runs on.
WORKERS = 2
#: xdist's variables in a worker's environment (xdist/remote.py, ``setup_config``'s caller).
XDIST_VARIABLES = ("PYTEST_XDIST_WORKER", "PYTEST_XDIST_TESTRUNUID", "PYTEST_XDIST_WORKER_COUNT")


def whole_suite_in_workers(config: pytest.Config) -> bool:
    """Whether this run is the whole suite, to be run on :data:`WORKERS` workers (module docstring)."""
    o = config.option
    return (
        config.pluginmanager.hasplugin("xdist")
        and not hasattr(config, "workerinput")
        and config.args_source is pytest.Config.ArgsSource.TESTPATHS
        and getattr(o, "numprocesses", None) is None
        and getattr(o, "dist", "no") == "no"
        and not getattr(o, "tx", None)
        and not o.usepdb
        and not o.collectonly
    )


@pytest.hookimpl(wrapper=True)
def pytest_cmdline_main(config: pytest.Config):
    if whole_suite_in_workers(config):
        config.option.numprocesses = WORKERS
        config.option.dist = "loadfile"
    return (yield)


#: Test files that run on one worker together: they share a session fixture too costly to build in
#: both (the warm package copy, tests/package_copy.py).
SHARED_WORKER = {"tests/test_compiled.py": "warm_package", "tests/test_kernel_cache.py": "warm_package"}

#: The costliest files (or :data:`SHARED_WORKER` groups), costliest first: handed out before every
#: other file, so that none of them starts last and keeps one worker busy while the other idles
#: (xdist's own order is by the number of tests in a file, which put test_errata.py, one test of two
#: minutes, among the last). Ranked by the worker seconds each took in a run with ``--durations=0``
#: (a fresh clone of 1cdc5cb, 2026-11-27, loaded: /tmp/s7dur.log), after the cuts of that session;
#: a file not listed keeps xdist's order after these. tests/test_xdist_order.py checks each exists.
COSTLY_FIRST = (
    "warm_package",
    "tests/test_distributed.py",
    "tests/test_stability.py",
    "tests/test_errata.py",
    "bench/test_compose.py",
    "tests/test_analytic_jacobian.py",
    "tests/test_reports_lock.py",
    "tests/test_lagrange_reference.py",
    "bench/test_inverse_dynamics.py",
    "tests/test_runner.py",
    "tests/test_figures.py",
    "tests/test_forward_conditioning.py",
    "tests/test_interrupts.py",
    "tests/test_numeric_imports.py",
    "tests/test_equations_export.py",
    "tests/test_lagrange_peer.py",
    "tests/test_fuzz_cli.py",
    "tests/test_row_selection.py",
    "bench/test_derivatives.py",
    "tests/test_symbolic.py",
    "tests/test_limits.py",
    "tests/test_run_ids.py",
)


def costly_first(scopes: list[str]) -> list[str]:
    """``scopes`` (xdist's order) with those of :data:`COSTLY_FIRST` first, in its order."""
    rank = {scope: k for k, scope in enumerate(COSTLY_FIRST)}
    return sorted(scopes, key=lambda scope: rank.get(scope, len(rank)))  # stable: the rest keep their order


@pytest.hookimpl(tryfirst=True, optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log):
    """``--dist loadfile`` with :data:`SHARED_WORKER`: a file runs on one worker, so its module's
    fixtures and caches and the first compiles of its kernels are paid once, not in both workers
    (``load`` splits a file; xdist's ``loadgroup`` cannot group here: it renames ``item._nodeid``,
    which pytest 9 no longer reads)."""
    if config.getvalue("dist") != "loadfile":
        return None
    from xdist.scheduler import LoadFileScheduling

    class FilesTogether(LoadFileScheduling):
        _ordered = False

        def _split_scope(self, nodeid: str) -> str:
            file = nodeid.split("::", 1)[0]
            return SHARED_WORKER.get(file, file)

        def _assign_work_unit(self, node) -> None:
            if not self._ordered:  # the first hand-out: the queue is complete, nothing is assigned yet
                self._ordered = True
                queue = {scope: self.workqueue[scope] for scope in costly_first(list(self.workqueue))}
                self.workqueue.clear()
                self.workqueue.update(queue)
            super()._assign_work_unit(node)

    return FilesTogether(config, log)


def numba_cache_folder(config: pytest.Config) -> Path:
    """The workers' numba cache, one for both: the user's ``NUMBA_CACHE_DIR`` if set, else in pytest's
    cache folder (kept between runs, like numba's ``__pycache__``), else (``-p no:cacheprovider``) in
    the run's temporary folder (the parent of each worker's ``basetemp``; pytest keeps the last three
    runs')."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"])
    cache = getattr(config, "cache", None)
    if cache is not None:
        return cache.mkdir("numba")
    folder = Path(config.option.basetemp).parent / "numba-cache"
    folder.mkdir(exist_ok=True)
    return folder


def pytest_configure(config: pytest.Config) -> None:
    worker = getattr(config, "workerinput", {}).get("workerid")
    if worker is None:
        return
    os.environ["NUMBA_CACHE_DIR"] = str(numba_cache_folder(config))
    for name in XDIST_VARIABLES:
        os.environ.pop(name, None)
    if "numba" in sys.modules:  # numba reads its environment when imported
        from numba.core import config as numba_config

        numba_config.reload_config()


#: The warm-up script (its parts: ``PARTS`` there) and how long a part may take before the run goes on
#: without it (its kernels are then compiled by the tests that need them, as without a warm-up).
WARM_KERNELS = Path(__file__).resolve().parent / "warm_kernels.py"
WARM_PARTS = ("matrix", "newton-euler")
WARM_TIMEOUT = 1800


def warm_numba_cache(folder: Path, timeout: float = WARM_TIMEOUT) -> list[str]:
    """Run the parts of tests/warm_kernels.py at once with ``NUMBA_CACHE_DIR=folder``; one line per
    part: its own last line, or why it did not finish (a failed part only costs the time it took)."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(folder)}
    procs = [
        subprocess.Popen(
            [sys.executable, str(WARM_KERNELS), part],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
        )
        for part in WARM_PARTS
    ]
    lines = []
    for part, proc in zip(WARM_PARTS, procs):
        try:
            out, _ = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, _ = proc.communicate()
            lines.append(f"warm_kernels {part}: stopped after {timeout} s; its kernels compile in the tests")
            continue
        tail = out.strip().splitlines()[-1:] or [""]
        if proc.returncode != 0:
            lines.append(f"warm_kernels {part}: exit {proc.returncode}: {tail[0]}; its kernels compile in the tests")
        else:
            lines.append(tail[0])
    return lines


def pytest_sessionstart(session: pytest.Session) -> None:
    """In the controller of a run on workers (module docstring), before xdist starts them."""
    config = session.config
    if (
        hasattr(config, "workerinput")
        or not config.pluginmanager.hasplugin("xdist")
        or not getattr(config.option, "numprocesses", None)
        or config.option.collectonly
        or (getattr(config, "cache", None) is None and not os.environ.get("NUMBA_CACHE_DIR"))
    ):
        return
    start = time.monotonic()
    lines = warm_numba_cache(numba_cache_folder(config))
    reporter = config.pluginmanager.get_plugin("terminalreporter")
    if reporter is not None:
        reporter.write_line(
            f"numba cache {numba_cache_folder(config)} warmed in {time.monotonic() - start:.0f} s: " + "; ".join(lines)
        )
