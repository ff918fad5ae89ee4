"""The whole suite runs on two pytest-xdist workers, sharing one numba cache, with no xdist
variables for the processes its tests start (tests/xdist_workers.py); a run that names files stays
in one process.

Each test runs pytest on two probe files in a temporary folder, whose conftest uses tests/xdist_workers.py
as tests/conftest.py does, and whose pyproject's ``testpaths`` point at the probe files,
so that "no paths named" is the README's command in miniature. Every probe test writes what its
process sees to a JSON file of its own.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("xdist")

HERE = Path(__file__).resolve().parent

PROBE = """
import json, os, subprocess, sys
from pathlib import Path

import pytest


@pytest.mark.parametrize("k", range(6))
def test_record(k):
    child = subprocess.run(
        [sys.executable, "-c", "import json, os; print(json.dumps(sorted(k for k in os.environ if k.startswith('PYTEST_XDIST'))))"],
        capture_output=True, text=True, check=True,
    )
    Path(f"seen-{Path(__file__).stem}-{k}.json").write_text(json.dumps({
        "pid": os.getpid(),
        "file": Path(__file__).stem,
        "numba_cache": os.environ.get("NUMBA_CACHE_DIR"),
        "child_xdist_variables": json.loads(child.stdout),
    }))
"""


#: The probe folder's conftest: tests/conftest.py's use of tests/xdist_workers.py.
CONFTEST = """
from xdist_workers import pytest_cmdline_main, pytest_configure, pytest_xdist_make_scheduler
"""


def _run_probe(folder: Path, *args: str) -> list[dict]:
    (folder / "conftest.py").write_text(CONFTEST)
    (folder / "pyproject.toml").write_text('[tool.pytest.ini_options]\ntestpaths = ["a_test.py", "b_test.py"]\n')
    for name in ("a_test.py", "b_test.py"):
        (folder / name).write_text(PROBE)
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "PYTEST_ADDOPTS")}
    env["PYTHONPATH"] = os.pathsep.join([str(HERE), env.get("PYTHONPATH", "")])
    r = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", *args],
        cwd=folder,
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    return [json.loads(p.read_text()) for p in sorted(folder.glob("seen-*.json"))]


def test_the_whole_suite_runs_on_two_workers_sharing_one_numba_cache(tmp_path):
    seen = _run_probe(tmp_path, "-p", "no:cacheprovider")
    assert len(seen) == 12
    pids = {s["pid"] for s in seen}
    assert len(pids) == 2, pids  # both workers ran tests
    for f in ("a_test", "b_test"):  # each file on one worker (pytest_xdist_make_scheduler)
        assert len({s["pid"] for s in seen if s["file"] == f}) == 1, seen
    caches = {s["pid"]: s["numba_cache"] for s in seen}
    assert len(set(caches.values())) == 1 and None not in caches.values(), caches  # locked: test_numba_cache_lock
    assert all(s["child_xdist_variables"] == [] for s in seen), seen


def test_a_run_that_names_files_stays_in_one_process(tmp_path):
    seen = _run_probe(tmp_path, "a_test.py", "b_test.py", "-p", "no:cacheprovider")
    assert len(seen) == 12
    assert {s["pid"] for s in seen} == {seen[0]["pid"]}
    assert all(s["numba_cache"] is None for s in seen), seen
