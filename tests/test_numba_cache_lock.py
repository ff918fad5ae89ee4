"""Two processes that compile into one numba cache at once keep both kernels (models/machine/numba_cache.py).

numba's index of a cached function is read, extended and replaced without a lock
(numba/core/caching.py, ``IndexDataCacheFile.save``): two processes saving two signatures of one
function at once both read the same index, both take data file 1, and the index left names one
signature, possibly with the other's machine code in its data file (numba issues 4807, 10128). It
happens wherever processes share a cache: two ``exo-bench`` commands or a Dask local cluster in one
checkout (its ``__pycache__``), the two xdist workers of the README's test command (one
``NUMBA_CACHE_DIR``, tests/xdist_workers.py). :func:`exo_bench.models.machine.numba_runtime.ensure` makes the
index's save and load hold a lock on the index (``<index>.lock``), so they take turns.

The test forces the interleaving: each process, having read the index inside a save, waits until the
other has begun its save and either read the index too or stands blocked on the index's lock (a
waiter, ``->``, in /proc/locks on the lock file); without the lock both read the empty index before
either writes. With it the second waits on the lock, the first sees it waiting, and the saves follow
one another. No clock: each outcome is observed, whatever the machine's speed. A third process then
loads both signatures from the cache, compiling nothing, and computes with each. About 5 s: three
processes importing numba.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

KERNEL = """
from numba import njit


@njit(cache=True)
def twice(x):
    return 2 * x
"""

SAVER = """
import os, sys, threading, time
from pathlib import Path

import numpy as np

from exo_bench.models.machine import numba_runtime

numba_runtime.ensure()
from numba.core import caching

me, other, kind = sys.argv[1], sys.argv[2], sys.argv[3]
here = Path.cwd()
saving = threading.local()
read_index = caching.IndexDataCacheFile._load_index
save = caching.IndexDataCacheFile.save


def blocked_on(lock):  # whether a process waits for an flock on the file lock (a -> line of /proc/locks)
    try:
        inode = f":{os.stat(lock).st_ino} "
    except FileNotFoundError:  # no lock file: nobody locks this index
        return False
    return any("->" in line and "FLOCK" in line and inode in line for line in open("/proc/locks"))


def load_index_meeting_the_other(self):
    index = read_index(self)
    if getattr(saving, "now", False):
        (here / f"read-{me}").touch()
        while not (here / f"saving-{other}").exists():  # the other process is still compiling
            time.sleep(0.01)
        lock = f"{self._index_path}.lock"  # it has begun its save: has it read the index, or is it locked out?
        while not (here / f"read-{other}").exists() and not blocked_on(lock):
            time.sleep(0.01)
    return index


def save_marked(self, key, data):
    (here / f"saving-{me}").touch()
    saving.now = True
    try:
        return save(self, key, data)
    finally:
        saving.now = False


caching.IndexDataCacheFile._load_index = load_index_meeting_the_other
caching.IndexDataCacheFile.save = save_marked
(here / f"ready-{me}").touch()
while not (here / f"ready-{other}").exists():  # both compile together
    time.sleep(0.01)
import kernel

print(kernel.twice(np.arange(3, dtype=kind)).tolist())
"""

LOADER = """
import json

import numpy as np

from exo_bench.models.machine import numba_runtime

numba_runtime.ensure()
import kernel

out = {k: kernel.twice(np.arange(3, dtype=k)).tolist() for k in ("int64", "float64")}
out["compiled"] = sum(kernel.twice.stats.cache_misses.values())
out["loaded"] = sum(kernel.twice.stats.cache_hits.values())
print(json.dumps(out))
"""


def _env(tmp_path: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env["NUMBA_CACHE_DIR"] = str(tmp_path / "cache")
    env["PYTHONPATH"] = os.pathsep.join([str(tmp_path), env.get("PYTHONPATH", "")])
    return env


def test_two_processes_saving_one_kernels_signatures_at_once_keep_both(tmp_path):
    (tmp_path / "kernel.py").write_text(KERNEL)
    (tmp_path / "saver.py").write_text(SAVER)
    (tmp_path / "loader.py").write_text(LOADER)
    env = _env(tmp_path)
    savers = [
        subprocess.Popen(
            [sys.executable, "saver.py", me, other, kind],
            cwd=tmp_path,
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for me, other, kind in (("a", "b", "int64"), ("b", "a", "float64"))
    ]
    for p in savers:
        out, err = p.communicate(timeout=300)
        assert p.returncode == 0, err[-3000:]
    assert {(tmp_path / f"read-{k}").exists() for k in "ab"} == {True}, "a save did not run"
    r = subprocess.run(
        [sys.executable, "loader.py"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300
    )
    assert r.returncode == 0, r.stderr[-3000:]
    seen = json.loads(r.stdout)
    assert seen["int64"] == [0, 2, 4] and seen["float64"] == [0.0, 2.0, 4.0], seen
    assert seen["compiled"] == 0 and seen["loaded"] == 2, f"the index lost a signature: {seen}"
