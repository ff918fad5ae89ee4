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
  (:func:`exo_bench.models.numba_cache.index_locked`, tests/test_numba_cache_lock.py): without it, two
  processes compiling two signatures of one kernel at once could both take data file 1, and the index
  left could name the other signature's code (numba issues 4807, 10128), hence one folder per worker
  before. And ``PYTEST_XDIST_*``, which xdist sets in the worker's environment, is removed: a pytest
  its tests start (the benchmark rows of ``exo-bench bench``) would read it and take itself for a
  worker, and pytest-benchmark would time nothing.

* :func:`pytest_xdist_make_scheduler`: each file on one worker, and the files of
  :data:`SHARED_WORKER` on one worker together.
"""

from __future__ import annotations

import os
import sys
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
        def _split_scope(self, nodeid: str) -> str:
            file = nodeid.split("::", 1)[0]
            return SHARED_WORKER.get(file, file)

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
