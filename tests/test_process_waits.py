"""Every wait for a process the package starts has a limit (issue 34: "every network wait has a timeout";
the guide: "Budgets and memory are predicted before the work"). Stand-in processes, no real waiting."""

from __future__ import annotations

import subprocess
import sys
import threading

import numpy as np
import pytest

from exo_bench.bench.perf.reports import benchmark_reports as br


def test_the_suite_is_stopped_at_its_limit_naming_it(tmp_path):
    """A stand-in suite (a child that sleeps 60 s) with a 0.2 s limit: a TimeoutError naming the suite,
    the limit and the option, and the child is gone."""
    cmd = [sys.executable, "-c", "import time; time.sleep(60)"]
    with pytest.raises(TimeoutError, match=r"benchmark suite .*--sweep=quick.* limit of 0\.2 s .*suite_timeout"):
        br.run_suite(cmd, tmp_path, 0.2, "quick")


def test_the_suite_gets_a_limit_from_its_prediction():
    """The default is the profile's predicted seconds times the allowance; the limit reaches the runner."""
    seen = {}

    def runner(cmd, cwd, timeout):
        seen["timeout"] = timeout
        return subprocess.CompletedProcess(cmd, 0)

    assert br.run_suite(["pytest"], br.REPO, br.suite_timeout("quick"), "quick", runner=runner) == 0
    assert seen["timeout"] == pytest.approx(br.SUITE_ALLOWANCE * br.SUITE_SECONDS["quick"])
    assert br.suite_timeout("full") > br.suite_timeout("quick") > 600
    assert br.suite_timeout("quick", 5) == 5.0


@pytest.mark.parametrize("bad", [0, -1, float("nan"), float("inf"), True, "60"])
def test_a_bad_suite_timeout_is_named(bad):
    with pytest.raises(ValueError, match=r"BenchOptions.suite_timeout: expected a finite number of seconds > 0"):
        br.suite_timeout("quick", bad)


def test_the_bench_command_passes_the_option():
    from exo_bench.bench.cli.app import build_parser
    from exo_bench.bench.cli.bench import options

    args = build_parser().parse_args(["bench", "--suite-timeout", "90"])
    assert options(args).suite_timeout == 90.0


def _split_batch(kernel, wait_limit):
    """models.simd_blocks.run over 2 threads with a stand-in kernel (a Python function: run takes any)."""
    from exo_bench.models.machine import simd_blocks

    samples = simd_blocks.parallel_min_samples(1)
    q = np.zeros(samples)
    o = np.zeros(samples)
    simd_blocks.run(kernel, None, q, q, q, o, samples, threads=2, wait_limit=wait_limit)
    return o


def test_a_stuck_pool_share_is_a_named_timeout():
    """A pool thread stuck in its share (a stand-in kernel waiting on an event): the calling thread
    computes every other share, then waits 0.2 s, not forever, and names the batch and the limit. The
    calling thread's first share waits until a pool thread has taken one (an observed event): under load
    the calling thread pulled every share before the pool thread ran (8 of 30 runs, load 6-8), and
    nothing was stuck."""
    main, taken, release = threading.get_ident(), threading.Event(), threading.Event()

    def kernel(params, q, qd, qdd, o, s0, s1):
        if threading.get_ident() != main:
            taken.set()
            release.wait(30)
        else:
            taken.wait(600)  # a hang guard only: the pool thread takes a share once it runs
        o[s0:s1] = 1.0

    try:
        with pytest.raises(
            TimeoutError, match=r"SIMD batch of \d+ samples on 2 threads: 1 share\(s\).*limit of 0\.2 s"
        ):
            _split_batch(kernel, 0.2)
    finally:
        release.set()


def test_the_default_wait_is_bounded_and_a_split_batch_completes():
    """Without a stuck thread every share is computed; the default limit is WAIT_FLOOR at least."""
    from exo_bench.models.machine import simd_blocks

    def kernel(params, q, qd, qdd, o, s0, s1):
        o[s0:s1] = 1.0

    assert np.all(_split_batch(kernel, None) == 1.0)
    assert 0 < simd_blocks.WAIT_FLOOR < float("inf") and simd_blocks.WAIT_ALLOWANCE > 1
