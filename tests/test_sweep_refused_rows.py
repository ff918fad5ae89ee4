"""A sweep whose workers refused rows publishes nothing (issue 34: no wider result is overwritten by a
narrower run; the CLI prints one line and exits 2).

``exo-bench bench --workers N`` runs the sweep's rows on a Dask cluster (bench/cluster/). A worker at
another commit than the scheduler refuses every row it is given (status "error"); so does a row whose
worker died too often. Such a sweep published paper_table.md and the other reports from error rows,
exit 0, replacing the good reports of an earlier run. Here the cluster is an in-process stand-in
(:class:`InProcess`: each task runs in this process when it is submitted, no worker is started), and the
rows are a fixed list (no pytest collection); the tasks are the real :func:`run_row`, whose code check
refuses the row before any pytest runs, or a stand-in that returns a finished row.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import io

import pytest

from exo_bench.bench.cli import app as cli
from exo_bench.bench.cluster import cluster as cluster_module
from exo_bench.bench.cluster import tasks, waits
from exo_bench.bench.cluster.checkpoints import CHECKPOINTS

ROWS = [
    {
        "key": f"bench/test_inverse_dynamics.py:{d}d-chain-n{n}",
        "file": "bench/test_inverse_dynamics.py",
        "dim": d,
        "n": n,
        "topology": "chain",
        "nodeids": [f"bench/test_inverse_dynamics.py::test_inverse[newton-euler-chain{n}-{d}d]"],
    }
    for d in (2, 3)
    for n in (1, 2)
]
GOOD = "# paper table\n\nthe good rows of an earlier, whole run\n"


class InProcess:
    """A Dask client's stand-in: a task runs in this process when it is submitted."""

    def scheduler_info(self) -> dict:
        return {"workers": {"in-process": {}}}

    def subscribe_topic(self, topic, handler) -> None:
        pass

    def unsubscribe_topic(self, topic) -> None:
        pass

    def cancel(self, futures, force=False) -> None:
        pass

    def submit(self, fn, *args, **kw) -> concurrent.futures.Future:
        f: concurrent.futures.Future = concurrent.futures.Future()
        try:
            f.set_result(fn(*args))
        except Exception as e:  # noqa: BLE001 - as a worker's task: the future holds it
            f.set_exception(e)
        return f


def finished(row: dict, *args) -> dict:
    """A row that ran to its end on a worker of the sweep's code (no benchmark in it)."""
    return {"key": row["key"], "nodeids": row["nodeids"], "status": "ok", "reason": "", "host": "h", "cpu": "c"}


@pytest.fixture
def stand_ins(monkeypatch):
    """The sweep's cluster, row list and code as stand-ins; ``runs[key]`` says how a row's task runs
    (default: the real :func:`run_row`, which refuses it: this checkout's code is not ``c0de``)."""
    runs: dict = {}
    monkeypatch.setattr(cluster_module, "cluster", lambda *a, **k: contextlib.nullcontext(InProcess()))
    monkeypatch.setattr(cluster_module, "enumerate_rows", lambda *a, **k: [dict(r) for r in ROWS])
    monkeypatch.setattr(cluster_module, "code_key", lambda repo=None: "c0de")  # the scheduler's code
    monkeypatch.setattr(cluster_module, "run_row", lambda row, *a: runs.get(row["key"], tasks.run_row)(row, *a))
    monkeypatch.setattr(waits, "completed", lambda futures, silence, **kw: iter(futures))
    monkeypatch.setattr(tasks, "code_key", lambda repo=None: "another-commit")  # the workers' code
    return runs


def bench(reports) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli.main(["bench", "--workers", "1", "--reports", str(reports)])
    return code, out.getvalue(), err.getvalue()


def published(reports) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in reports.iterdir() if p.is_file()}


@pytest.mark.case("D9")
def test_a_sweep_whose_workers_refused_every_row_publishes_nothing(stand_ins, tmp_path):
    """A sweep whose workers refused every row (a worker at another commit) publishes nothing: exit 2, one
    line naming how many rows were refused and the first one's reason; the earlier reports stay byte for
    byte. Before, paper_table.md and the other reports were replaced by error rows, exit 0."""
    reports = tmp_path / "reports"
    reports.mkdir()
    (reports / "paper_table.md").write_text(GOOD)
    before = published(reports)
    code, out, err = bench(reports)
    assert code == 2, (code, out, err)
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "4 of 4 rows" in lines[0] and "refused" in lines[0], lines[0]
    assert "runs code another-commit, the sweep measures c0de" in lines[0], lines[0]  # the first row's reason
    assert published(reports) == before
    assert sorted(p.name for p in reports.iterdir() if p.name != CHECKPOINTS) == ["paper_table.md"]


@pytest.mark.case("D9")
def test_a_sweep_with_one_refused_row_publishes_nothing_and_a_rerun_runs_only_that_row(stand_ins, tmp_path):
    """One row refused among finished ones: nothing published (exit 2, the count and that row's reason);
    the finished rows are checkpointed, so the run again measures only the refused row."""
    refused = ROWS[2]["key"]
    stand_ins.update({r["key"]: finished for r in ROWS if r["key"] != refused})
    reports = tmp_path / "reports"
    reports.mkdir()
    (reports / "paper_table.md").write_text(GOOD)
    before = published(reports)
    code, out, err = bench(reports)
    assert code == 2, (code, out, err)
    assert len(err.strip().splitlines()) == 1, err
    assert "1 of 4 rows" in err and refused in err, err
    assert published(reports) == before
    ran = []
    stand_ins.clear()
    stand_ins.update({r["key"]: (lambda row, *a: ran.append(row["key"]) or finished(row)) for r in ROWS})
    code, out, err = bench(reports)
    assert ran == [refused], (ran, out, err)
    assert "1 rows run" in out and "3 from checkpoints" in out, out
    assert code == 0, (code, out, err)
    assert published(reports)["paper_table.md"] != before["paper_table.md"]  # every row in: the reports are new


def failing_suite(code: int):
    """The serial suite's pytest as a stand-in: it wrote part of its JSON, then exited with ``code``."""

    def run_suite(cmd, cwd, timeout, sweep, runner=None):
        bjson = next(a.split("=", 1)[1] for a in cmd if a.startswith("--benchmark-json="))
        with open(bjson, "w") as f:
            f.write('{"benchmarks": []}')
        return code

    return run_suite


@pytest.mark.parametrize("code", [1, 2, -9])
def test_the_serial_suite_that_failed_publishes_nothing(code, tmp_path, monkeypatch):
    """The serial path (``exo-bench bench`` without a cluster) has no rows: its pytest's exit code is the
    refusal. A suite that failed, stopped or was killed publishes nothing: one line, exit 2, the earlier
    reports kept."""
    from exo_bench.bench.perf.reports import benchmark_reports as br

    monkeypatch.setattr(br, "run_suite", failing_suite(code))
    reports = tmp_path / "reports"
    reports.mkdir()
    (reports / "paper_table.md").write_text(GOOD)
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = cli.main(["bench", "--reports", str(reports)])
    assert rc == 2 and len(err.getvalue().strip().splitlines()) == 1, (rc, err.getvalue())
    assert f"pytest exit code {code}" in err.getvalue() and "no report written" in err.getvalue()
    assert published(reports) == {"paper_table.md": GOOD.encode()}


def test_the_main_jobs_benchmarks_that_failed_keep_the_published_reports(tmp_path, monkeypatch):
    """``exo-bench run``'s benchmarks job is the serial path: when its suite fails the job fails (exit 1, its
    line on stderr), and the benchmark reports published before are kept byte for byte."""
    from exo_bench.bench.cli import run as main_job
    from exo_bench.bench.perf.reports import benchmark_reports as br
    from exo_bench.bench.studies.options import RunOptions

    monkeypatch.setattr(br, "run_suite", failing_suite(1))
    monkeypatch.setattr(main_job, "shipped_scene_names", lambda: [])  # no scene: the suite's jobs only
    jobs = [j for j in main_job._suite_jobs() if j[0].startswith("benchmarks")]
    monkeypatch.setattr(main_job, "_suite_jobs", lambda: jobs)
    reports = tmp_path / "reports"
    reports.mkdir()
    (reports / "paper_table.md").write_text(GOOD)
    err = io.StringIO()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
        rc = main_job.run_main_job(RunOptions(scenes=(), reports=reports, full=False))
    assert rc == 1, (rc, err.getvalue())
    assert "benchmarks (exo-bench bench) failed" in err.getvalue(), err.getvalue()
    assert "benchmark suite failed (pytest exit code 1); no report written" in err.getvalue(), err.getvalue()
    assert (reports / "paper_table.md").read_text() == GOOD
