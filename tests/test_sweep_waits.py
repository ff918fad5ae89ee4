"""Every wait of a sweep on a Dask cluster has a timeout (issue 34: "every network wait has a
timeout"). The sweep's rows and the stability study's parts were collected with ``as_completed``
and no limit: a scheduler or worker that stopped answering held the command forever.

:func:`exo_bench.bench.cluster.waits.completed` yields each future as it finishes and raises a
TimeoutError (one line from the CLI, exit 2) when none finishes within its ``silence`` seconds. The
tests give it a stand-in for ``distributed.wait`` (no cluster, no clock): it answers from a script.
"""

from __future__ import annotations

import inspect

import pytest

from exo_bench.bench.cluster import waits


def _scripted(*answers):
    """A stand-in for ``distributed.wait``: each call returns the next ``done`` set (or raises
    TimeoutError for None) and records the timeout it was given."""
    calls = []

    def wait(pending, timeout=None, return_when=None):
        calls.append((set(pending), timeout, return_when))
        done = answers[len(calls) - 1]
        if done is None:
            raise TimeoutError
        return set(done), set(pending) - set(done)

    return wait, calls


def test_each_future_is_yielded_as_it_finishes_with_the_timeout_on_every_wait():
    """The futures come back as the stand-in finishes them; every wait is given the silence bound
    and asks for the first completed."""
    wait, calls = _scripted({"b"}, {"a", "c"})
    got = list(waits.completed(["a", "b", "c"], 7.5, wait=wait))
    assert got[0] == "b" and sorted(got[1:]) == ["a", "c"]
    assert [(t, r) for _, t, r in calls] == [(7.5, "FIRST_COMPLETED")] * 2


def test_a_silence_longer_than_the_bound_is_one_timeout_error_naming_the_wait():
    """When nothing finishes within the bound, one TimeoutError says what was waited for, how
    long, how many are left and which option raises it (it waited forever)."""
    wait, _ = _scripted({"a"}, None)
    it = waits.completed(["a", "b", "c"], 90.0, wait=wait, what="sweep rows", option="wait_timeout")
    assert next(it) == "a"
    with pytest.raises(TimeoutError) as e:
        next(it)
    text = str(e.value)
    assert "sweep rows: none of the 2 still running finished within 90 s" in text and "wait_timeout" in text
    assert isinstance(e.value, OSError)  # the CLI's one-line, exit-2 branch


@pytest.mark.parametrize("bad", [0, -1.0, float("nan"), float("inf"), "60"])
def test_a_bad_bound_is_refused_naming_it(bad):
    """The bound is a finite number of seconds > 0."""
    with pytest.raises(ValueError, match="wait_timeout: expected a finite number of seconds > 0"):
        list(waits.completed(["a"], bad, wait=_scripted({"a"})[0], option="wait_timeout"))


def test_the_sweep_and_the_stability_parts_take_a_typed_timeout_with_a_default():
    """run_sweep's ``wait_timeout`` defaults from the row budget (every row ends within its budget,
    per try); the stability parts' from ClusterOptions.wait_timeout."""
    from exo_bench.bench.cluster import cluster
    from exo_bench.bench.studies.options import ClusterOptions

    p = inspect.signature(cluster.run_sweep).parameters["wait_timeout"]
    assert p.default is None and "float" in str(p.annotation)
    assert waits.sweep_silence(1800.0, retries=1) == 2 * 1800.0 + waits.START_SLACK
    assert ClusterOptions().wait_timeout == waits.PART_SILENCE > 0


def test_collecting_the_rows_has_a_timeout(monkeypatch, tmp_path):
    """Listing the rows (``pytest --collect-only``) runs under a timeout; when it expires, one
    TimeoutError says what did not finish and the bound (it had none). A stand-in for subprocess.run."""
    import subprocess

    from exo_bench.bench.cluster import cluster

    seen = {}

    def run(cmd, **kw):
        seen.update(kw)
        raise subprocess.TimeoutExpired(cmd, kw.get("timeout"))

    monkeypatch.setattr(cluster.subprocess, "run", run)
    with pytest.raises(TimeoutError, match=r"collecting the benchmark rows .* did not finish within 600 s"):
        cluster.enumerate_rows(["bench/test_compose.py"], "quick", repo=tmp_path)
    assert seen["timeout"] == cluster.COLLECT_SECONDS
