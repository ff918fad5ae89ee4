"""Nothing is left in the system's temporary folder (issue 38: empty ``/tmp/exo-bench-row-*`` folders were
left behind). A benchmark row runs in a folder of its own on a Dask worker; a worker killed while the row
runs (the cluster closing, Ctrl-C, a row over its budget killing its worker) cannot remove it. The row's
folder now goes inside the sweep's own temporary folder, which the sweep's process removes at its end
(bench/cluster/cluster.py ``run_sweep``; bench/cluster/tasks.py ``run_row``)."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

#: A worker running one row, killed while the row's pytest runs (``os._exit``: no cleanup runs, as
#: under SIGKILL or a nanny closing its worker).
WORKER = """
import subprocess, sys
from exo_bench.bench.cluster import tasks

class Killed:
    def __init__(self, cmd, **kw):
        import os
        os._exit(9)

subprocess.Popen = Killed
scratch = sys.argv[1] or None
tasks.run_row({"key": "k", "file": "bench/test_x.py", "nodeids": []}, "quick", 10.0, scratch=scratch)
"""


def _killed_worker(tmp_path: Path, scratch: str) -> Path:
    system_tmp = tmp_path / "system-tmp"
    system_tmp.mkdir(exist_ok=True)
    r = subprocess.run(
        [sys.executable, "-c", WORKER, scratch],
        env={**os.environ, "TMPDIR": str(system_tmp)},
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 9, r.stderr  # killed mid-row, as the stub says
    return system_tmp


def _rows(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("exo-bench-row-"))


def test_a_killed_workers_row_folder_is_inside_the_sweeps_folder_and_goes_with_it(tmp_path):
    with tempfile.TemporaryDirectory(prefix="exo-bench-sweep-", dir=tmp_path) as scratch:  # as run_sweep makes it
        system_tmp = _killed_worker(tmp_path, scratch)
        assert _rows(system_tmp) == []  # nothing in the system's temporary folder
        assert len(_rows(Path(scratch))) == 1  # the killed row's folder, left where the sweep removes it
    assert not Path(scratch).exists()


def test_without_the_sweeps_folder_the_killed_row_leaves_its_folder_behind(tmp_path):
    """The leak the sweep's folder closes: a row run with no scratch (or on a host without it) leaves
    its folder in the system's temporary folder when its worker is killed."""
    assert len(_rows(_killed_worker(tmp_path, ""))) == 1


def test_the_sweep_puts_its_rows_in_a_folder_it_removes():
    """run_sweep hands every row its temporary folder (the argument after ``prior``), made by a
    ``TemporaryDirectory`` that encloses the cluster: removed after the workers are gone."""
    import inspect

    from exo_bench.bench.cluster import cluster, tasks

    params = list(inspect.signature(tasks.run_row).parameters)
    assert params[params.index("prior") + 1] == "scratch"
    src = inspect.getsource(cluster.run_sweep)
    assert 'TemporaryDirectory(prefix="exo-bench-sweep-") as scratch, cluster(' in src
    assert "prior,\n                        scratch,\n" in src
