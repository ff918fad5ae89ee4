"""Counts of threads and processes fit under the user's process limit (issue 34: "every resource count has
a bound"; RLIMIT_NPROC counts threads too): refused before the work, naming the option, the limit and how
many fit. The limit is monkeypatched: no process is started."""

from __future__ import annotations

import os
import resource

import pytest

from exo_bench.models.machine import memory

LIMIT, RUNNING = 40, 36  # four more threads or processes may start


@pytest.fixture
def tight(monkeypatch):
    """A non-root user with ``ulimit -u 40`` and 36 threads running."""
    real = resource.getrlimit

    def getrlimit(which):
        return (LIMIT, LIMIT) if which == resource.RLIMIT_NPROC else real(which)

    monkeypatch.setattr(resource, "getrlimit", getrlimit)
    monkeypatch.setattr(os, "getuid", lambda: 1000)
    monkeypatch.setattr(memory, "user_tasks", lambda uid: RUNNING)
    monkeypatch.setattr(memory, "usable_cpus", lambda: 4)  # the CPU bound (16) is not the one hit


def test_a_count_over_the_room_is_refused_naming_the_limit(tight):
    assert memory.check_count("threads", LIMIT - RUNNING) == 4
    with pytest.raises(ValueError) as e:
        memory.check_count("threads", 5)
    msg = str(e.value)
    assert msg.startswith("threads: expected at most 4 threads") and "RLIMIT_NPROC" in msg, msg
    assert "ulimit -u 40" in msg and "got 5" in msg, msg


def test_pinocchio_threads_are_refused_before_the_work(tight):
    pytest.importorskip("pinocchio")
    from exo_bench.api.preparation import prepare
    from exo_bench.models.mechanism.presets import exo5

    with pytest.raises(ValueError, match=r"threads.*RLIMIT_NPROC.*got 6"):
        prepare(exo5(3), "pinocchio", threads=6)


def test_local_workers_are_refused_before_a_cluster_starts(tight, monkeypatch):
    import distributed

    from exo_bench.bench.cluster import cluster as cluster_mod

    def no_cluster(*a, **k):
        raise AssertionError("a LocalCluster was started")

    monkeypatch.setattr(distributed, "LocalCluster", no_cluster)
    with pytest.raises(ValueError, match=r"--workers.*at most 4 worker processes.*RLIMIT_NPROC.*got 5"):
        with cluster_mod.cluster(None, 5):
            pass


def test_no_room_is_checked_when_unlimited_or_root(monkeypatch):
    real = resource.getrlimit
    monkeypatch.setattr(resource, "getrlimit", lambda w: (10, 10) if w == resource.RLIMIT_NPROC else real(w))
    monkeypatch.setattr(os, "getuid", lambda: 0)  # the kernel does not apply it to root
    assert memory.task_room() is None
    monkeypatch.setattr(os, "getuid", lambda: 1000)
    monkeypatch.setattr(resource, "getrlimit", lambda w: (resource.RLIM_INFINITY,) * 2)
    assert memory.task_room() is None


def test_the_users_threads_are_counted():
    """This process's own threads are among its user's (the count read from /proc)."""
    with open("/proc/self/status") as f:
        mine = int(next(line for line in f if line.startswith("Threads:")).split()[1])
    assert memory.user_tasks(os.getuid()) >= mine >= 1


def test_local_workers_count_their_threads(tight, monkeypatch):
    """A local worker adds WORKER_TASKS threads and processes and the cluster CLUSTER_TASKS: with room for
    20, three workers (20) fit and four (24) are refused, naming how many fit."""
    monkeypatch.setattr(memory, "user_tasks", lambda uid: LIMIT - 20)
    assert memory.check_workers(3, None) == 3
    with pytest.raises(ValueError, match=r"--workers: 4 local workers start about 24 .*RLIMIT_NPROC.*at most 3, got 4"):
        memory.check_workers(4, None)
