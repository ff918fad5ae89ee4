"""The benchmark sweep and the stability study as tasks on a Dask cluster.

``exo-bench bench --full`` (and ``exo-bench stability --full``) split their work into tasks:

* **bench**: one task per *row* (:mod:`exo_bench.bench.perf.rows`: one test file at one dimension, n and
  model, every method of it). A task runs ``python -m pytest <file> --row KEY --benchmark-enable
  --benchmark-json=... --sweep=...`` in a subprocess on its worker, so every method of a row is
  timed back to back on one host, and returns the pytest-benchmark JSON with the worker's host and
  CPU. The rows merge into ``reports/benchmarks-<profile>.json`` (:func:`exo_bench.bench.perf.rows.merge`).
* **stability**: one task per family of extreme cases and one for the forward-dynamics part.

The cluster is, by default, a :class:`distributed.LocalCluster` of single-threaded worker
processes, one per core, started and stopped by the command (``--workers N`` sizes it;
``--workers 1`` is a serial run); ``--scheduler ADDRESS`` uses a running cluster instead
(``dask scheduler``, then ``dask worker ADDRESS --nthreads 1`` on each machine, each with this
package installed at the same commit: a worker at another commit refuses its rows).

Faults:

* a worker that dies mid-task (killed, out of memory) is restarted by its nanny and the scheduler
  runs the task again elsewhere (up to ``distributed.scheduler.allowed-failures`` times); the
  task's pytest subprocess dies with its worker (``PR_SET_PDEATHSIG``), so no orphan keeps timing;
* a row whose pytest fails or that exceeds its budget (:attr:`exo_bench.bench.perf.profiles.Sweep.row_budget`, the subprocess is
  killed) is recorded with its reason (in ``rows`` of the merged JSON and as skips in the reports),
  and the sweep goes on;
* every finished row is checkpointed (:func:`checkpoint_dir`: a folder per code commit, a file per
  row, written atomically), so a sweep run again after an interruption runs only the missing rows;
* a row refused by its worker (a worker at another commit) or that could not run (its worker died
  too often, its pytest stopped early) has status "error": it is not checkpointed, and the sweep writes
  no report (:func:`exo_bench.bench.perf.rows.check_rows_ran`: one line naming how many rows and the
  first one's reason, exit 2), so the published reports stay; run again, only those rows run;
* Ctrl-C cancels the cluster's tasks and closes it (no worker process is left) before anything is
  written into the reports folder.
"""

from __future__ import annotations

import contextlib
import json
import logging
import re
import subprocess
import sys
import tempfile
import time
import uuid
import warnings
from dataclasses import dataclass, field
from pathlib import Path

from exo_bench.api.methods import composes_within_budget
from exo_bench.models.machine import memory
from exo_bench.models.machine.memory import check_count, check_workers, usable_cpus
from exo_bench.bench.perf import rows as _rows
from exo_bench.bench.output.interrupts import check as check_interrupt
from exo_bench.bench.output.provenance import REPO
from exo_bench.models.files import atomic_write
from exo_bench.bench.cluster.waits import _first_line, probe_scheduler
from exo_bench.bench.cluster.checkpoints import FINAL, checkpoint_dir, code_key, load_checkpoint
from exo_bench.bench.cluster.tasks import TOPIC, failure_lines, run_row

#: Seconds, at most, to reach a scheduler given with ``--scheduler`` and hear it answer (less when
#: dask's ``distributed.comm.timeouts.connect`` is less: :func:`scheduler_timeout`).
SCHEDULER_TIMEOUT = 10.0
#: Task retries after an exception in the task itself (a worker's death is counted by the
#: scheduler's ``allowed-failures`` instead).
RETRIES = 1
#: Seconds ``pytest --collect-only`` may take to list the rows (it takes about 10 s: imports only).
COLLECT_SECONDS = 600.0
#: Benchmark files whose rows form chains: the rows of one (file, dim, topology) run in increasing
#: n, each after the one before, whose skips it receives (``--prior-skips``): a sympy peer over its
#: budget at n is skipped at every larger n without spending its budget again.
CHAINED = ("bench/test_compose.py",)


# ----------------------------------------------------------------------------- the cluster
@contextlib.contextmanager
def cluster(scheduler: str | None = None, workers: int | None = None, timeout: float | None = None):
    """A Dask client: on the cluster at ``scheduler``, or on a :class:`LocalCluster` of ``workers``
    single-threaded worker processes (default: one per CPU it may use) that is closed on exit, Ctrl-C included.

    ``scheduler`` must answer Dask's handshake within ``timeout`` seconds (default
    :func:`scheduler_timeout`), else a ValueError names it (:func:`probe_scheduler`); ``workers`` is
    bounded, and its processes must fit in memory (:func:`exo_bench.models.machine.memory.check_workers`)."""
    from distributed import Client, LocalCluster

    if scheduler:
        timeout = scheduler_timeout() if timeout is None else timeout
        probe_scheduler(scheduler, timeout)
        try:
            client = Client(scheduler, timeout=timeout)
        except Exception as e:  # noqa: BLE001 - whatever the peer did: one line naming it
            raise ValueError(
                f"--scheduler {scheduler!r}: no Dask scheduler reachable there ({_first_line(e)})"
            ) from None
        try:
            yield client
        finally:
            client.close()
        return
    n = check_workers(workers if workers is not None else usable_cpus(), memory.usable_memory())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "port 8787 in use" and the like: we start no dashboard anyway
        lc = LocalCluster(
            n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None, silence_logs=logging.CRITICAL
        )
    try:
        client = Client(lc)
        try:
            yield client
        finally:
            client.close()
    finally:
        lc.close()


def scheduler_timeout() -> float:
    """Seconds to reach a ``--scheduler`` and hear it answer: :data:`SCHEDULER_TIMEOUT`, or dask's
    ``distributed.comm.timeouts.connect`` when that is less (``DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT``)."""
    import dask
    from dask.utils import parse_timedelta

    theirs = parse_timedelta(dask.config.get("distributed.comm.timeouts.connect"), default="seconds")
    return float(min(SCHEDULER_TIMEOUT, theirs)) if theirs else SCHEDULER_TIMEOUT


def check_scheduler(scheduler: str | None, timeout: float | None = None) -> None:
    """Refuse (one line, before any work) a ``--scheduler`` address where no scheduler answers
    within ``timeout`` seconds (default :func:`scheduler_timeout`)."""
    if scheduler:
        with cluster(scheduler, timeout=timeout):
            pass


def cancel_tasks(client, futures) -> None:
    with contextlib.suppress(Exception):
        client.cancel(futures, force=True)


# ----------------------------------------------------------------------------- the sweep
@dataclass
class SweepOutcome:
    merged: dict  # the pytest-benchmark JSON of the whole sweep
    skips: list[dict]  # skipped or failed benchmarks with reasons
    rows: list[dict]  # every row's record, in collection order
    ran: list[str] = field(default_factory=list)  # rows run now
    resumed: list[str] = field(default_factory=list)  # rows read from checkpoints
    seconds: float = 0.0
    workers: int = 0


def enumerate_rows(files: list[str], sweep: str, repo: Path = REPO, pytest_args: tuple = ()) -> list[dict]:
    """The rows of the benchmark files (``pytest --collect-only --rows-json``), in collection order."""
    with tempfile.TemporaryDirectory(prefix="exo-bench-rows-") as d:
        path = Path(d) / "rows.json"
        cmd = [
            sys.executable,
            "-m",
            "pytest",
            *files,
            "--collect-only",
            "-q",
            "-p",
            "no:cacheprovider",
            f"--rows-json={path}",
            f"--sweep={sweep}",
            *pytest_args,
        ]
        try:
            r = subprocess.run(
                cmd, cwd=repo, capture_output=True, text=True, stdin=subprocess.DEVNULL, timeout=COLLECT_SECONDS
            )
        except subprocess.TimeoutExpired:
            raise TimeoutError(
                f"collecting the benchmark rows (pytest --collect-only in {str(repo)!r}) did not finish within "
                f"{COLLECT_SECONDS:g} s"
            ) from None
        if r.returncode != 0 or not path.exists():
            raise ValueError(
                f"collecting the benchmark rows failed (pytest exit code {r.returncode}): "
                f"{failure_lines(r.stdout + r.stderr)}"
            )
        return _rows.read_rows_json(path)


def progress_bar(total: int, enabled: bool):
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    console = Console()
    return Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
        disable=not enabled,
        transient=False,
    )


def _chains(rows: list[dict], chained) -> dict[str, str]:
    """``{row key: key of the row before it in its chain}`` for the rows of the ``chained`` files."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        if r["file"] in chained and r.get("n") is not None and not _methods(r) <= composes_within_budget():
            groups.setdefault((r["file"], r.get("dim"), r.get("topology")), []).append(r)
    out = {}
    for g in groups.values():
        g = sorted(g, key=lambda r: r["n"])
        out.update({b["key"]: a["key"] for a, b in zip(g, g[1:])})
    return out


def _methods(row: dict) -> set[str]:
    """The methods a row runs, from its test ids (``test_compose[<method>-<topology><n>-<dim>d]``);
    a test id of another shape counts as an unknown method (the row stays chained)."""
    out = set()
    for nid in row.get("nodeids", []):
        m = re.search(r"\[(.+)-[a-z]+\d+-\dd\]$", nid)
        out.add(m.group(1) if m else nid)
    return out


def _priority(row: dict) -> int:
    """Larger rows first (n, then 3D before 2D: :func:`exo_bench.bench.perf.rows.schedule_order`)."""
    return 10 * (row.get("n") or 0) + (row.get("dim") or 0)


def run_sweep(
    files: list[str],
    sweep: str,
    *,
    checkpoints: Path,
    scheduler: str | None = None,
    workers: int | None = None,
    budget: float | None = None,
    pytest_args: tuple = (),
    repo: Path = REPO,
    only=None,
    chained=CHAINED,
    progress: bool = True,
    on_result=None,
    log=print,
    wait_timeout: float | None = None,
) -> SweepOutcome:
    """Run every row of the benchmark ``files`` on a Dask cluster (see the module docstring).

    ``checkpoints``: the base folder of the checkpoints (a subfolder per :func:`code_key`);
    ``budget``: seconds per row (default: the profile's :attr:`exo_bench.bench.perf.profiles.Sweep.row_budget`); ``pytest_args``:
    appended to every pytest command; ``repo``: the folder pytest runs in (the checkout, on every
    worker too: each resolves its own copy unless it is given); ``only``: row keys to keep (the
    others are left out, as if not collected); ``chained``: files whose rows run as chains
    (:data:`CHAINED`); ``on_result(record)``: called in this process as each row
    finishes (after its checkpoint is written); ``wait_timeout``: seconds the running rows may all
    go without one finishing (default :func:`exo_bench.bench.cluster.waits.sweep_silence` of the budget),
    then a TimeoutError (the finished rows' checkpoints are kept)."""
    from exo_bench.bench.cluster.waits import completed, sweep_silence

    from exo_bench.bench.perf.profiles import current

    t0 = time.perf_counter()
    if workers is not None:
        check_count("--workers", workers, "worker processes")
    if budget is None:
        budget = float(getattr(current(sweep), "row_budget", 3600.0))
    silence = sweep_silence(budget, RETRIES) if wait_timeout is None else wait_timeout
    code = code_key(repo)
    folder = checkpoint_dir(checkpoints, code)
    rows = enumerate_rows(list(files), sweep, repo=repo, pytest_args=pytest_args)
    if only is not None:
        rows = [r for r in rows if r["key"] in set(only)]
    where = None if Path(repo).resolve() == REPO.resolve() else str(repo)
    records: dict[str, dict] = {}
    resumed = []
    for r in rows:
        rec = load_checkpoint(folder, r["key"])
        if rec is not None:
            records[r["key"]] = rec
            resumed.append(r["key"])
    todo = _rows.schedule_order([r for r in rows if r["key"] not in records])
    log(
        f"sweep {sweep}: {len(rows)} rows, {len(resumed)} already done at code {code} "
        f"(checkpoints in {folder}), {len(todo)} to run"
    )
    ran, nworkers = [], 0
    if todo:
        folder.mkdir(parents=True, exist_ok=True)
        # the rows' temporary folders go in this one, removed when the sweep ends, whatever the workers did
        with tempfile.TemporaryDirectory(prefix="exo-bench-sweep-") as scratch, cluster(scheduler, workers) as client:
            nworkers = len(client.scheduler_info().get("workers", {})) or (workers or 0)
            running: set[str] = set()
            counts = {"done": 0, "failed": 0}
            with progress_bar(len(todo), progress) as bar:
                task = bar.add_task("", total=len(todo))

                def describe():
                    bar.update(
                        task,
                        description=f"rows: {counts['done']} done, {len(running)} running, {counts['failed']} failed",
                    )

                def started(event):
                    msg = event[1] if isinstance(event, tuple) else event
                    if isinstance(msg, dict) and msg.get("event") == "start":
                        running.add(msg["row"])
                        describe()

                client.subscribe_topic(TOPIC, started)
                describe()
                futures: dict = {}
                submitted: dict[str, object] = {}
                prior_of = _chains(rows, chained)
                # chains in increasing n first (a row's prior is submitted before it); the scheduler
                # runs the largest rows first anyway (priority)
                for r in sorted(todo, key=lambda r: (r["key"] not in prior_of, r.get("n") or 0)):
                    p = prior_of.get(r["key"])
                    prior = (
                        submitted[p]
                        if p in submitted
                        else ({k: records[p].get(k) for k in ("skips", "inherited")} if p in records else None)
                    )
                    f = client.submit(
                        run_row,
                        r,
                        sweep,
                        budget,
                        code,
                        tuple(pytest_args),
                        where,
                        prior,
                        scratch,
                        key=f"exo-bench-row-{_rows.safe_name(r['key'])}-{uuid.uuid4().hex[:8]}",
                        pure=False,
                        retries=RETRIES,
                        priority=_priority(r),
                    )
                    futures[f] = r
                    submitted[r["key"]] = f
                try:
                    for f in completed(list(futures), silence, what=f"sweep {sweep}: rows", option="wait_timeout"):
                        check_interrupt()  # a signal swallowed where it landed still ends the sweep
                        r = futures[f]
                        try:
                            rec = f.result()
                        except Exception as e:  # noqa: BLE001 - KilledWorker after repeated deaths, ...
                            rec = {
                                "key": r["key"],
                                "nodeids": r["nodeids"],
                                "status": "error",
                                "reason": f"{type(e).__name__}: {str(e).strip().splitlines()[0] if str(e).strip() else ''}",
                                "host": None,
                                "cpu": None,
                                "seconds": 0.0,
                                "benchmark_json": None,
                                "skips": [],
                            }
                        if rec["status"] in FINAL:
                            atomic_write(folder / f"{_rows.safe_name(r['key'])}.json", json.dumps(rec))
                        records[r["key"]] = rec
                        ran.append(r["key"])
                        running.discard(r["key"])
                        counts["done" if rec["status"] == "ok" else "failed"] += 1
                        bar.advance(task)
                        describe()
                        if rec["status"] != "ok":
                            log(f"row {r['key']}: {rec['status']}: {rec['reason']}")
                        if on_result is not None:
                            on_result(rec)
                except BaseException:  # Ctrl-C (or a failing callback): cancel every task, then close
                    cancel_tasks(client, list(futures))
                    raise
                finally:
                    with contextlib.suppress(Exception):
                        client.unsubscribe_topic(TOPIC)
    ordered = [records[r["key"]] for r in rows if r["key"] in records]
    merged, skips = _rows.merge(ordered)
    merged["sweep"] = {
        "profile": sweep,
        "code": code,
        "workers": nworkers,
        "scheduler": scheduler or "local",
        "seconds": time.perf_counter() - t0,
        "ran": len(ran),
        "resumed": len(resumed),
    }
    return SweepOutcome(merged, skips, ordered, ran, resumed, time.perf_counter() - t0, nworkers)
