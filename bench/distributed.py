"""The benchmark sweep and the stability study as tasks on a Dask cluster.

``exo-bench bench --full`` (and ``exo-bench stability --full``) split their work into tasks:

* **bench**: one task per *row* (:mod:`exo_bench.bench.rows`: one test file at one dimension, n and
  model, every method of it). A task runs ``python -m pytest <file> --row KEY --benchmark-enable
  --benchmark-json=... --sweep=...`` in a subprocess on its worker, so every method of a row is
  timed back to back on one host, and returns the pytest-benchmark JSON with the worker's host and
  CPU. The rows merge into ``reports/benchmarks-<profile>.json`` (:func:`rows.merge`).
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
* a row whose pytest fails or that exceeds its budget (:attr:`Sweep.row_budget`, the subprocess is
  killed) is recorded with its reason (in ``rows`` of the merged JSON and as skips in the reports),
  and the sweep goes on;
* every finished row is checkpointed (:func:`checkpoint_dir`: a folder per code commit, a file per
  row, written atomically), so a sweep run again after an interruption runs only the missing rows;
* Ctrl-C cancels the cluster's tasks and closes it (no worker process is left) before anything is
  written into the reports folder.
"""

from __future__ import annotations

import contextlib
import json
import logging
import os
import pickle
import re
import signal
import subprocess
import sys
import tempfile
import time
import uuid
import warnings
from dataclasses import dataclass, field
from pathlib import Path

from exo_bench.bench import rows as _rows
from exo_bench.bench.reporting import REPO, atomic_write

#: Event topic of the workers' "row started" messages (the progress bar's "running" count).
TOPIC = "exo-bench-rows"
#: Seconds to reach a scheduler given with ``--scheduler``.
SCHEDULER_TIMEOUT = 10
#: Task retries after an exception in the task itself (a worker's death is counted by the
#: scheduler's ``allowed-failures`` instead).
RETRIES = 1
#: Benchmark files whose rows form chains: the rows of one (file, dim, topology) run in increasing
#: n, each after the one before, whose skips it receives (``--prior-skips``): a sympy peer over its
#: budget at n is skipped at every larger n without spending its budget again.
CHAINED = ("bench/test_compose.py",)
#: Methods whose composition stays far inside its budget at every n of the sweep (3D n = 50 in about
#: a minute): a row that runs only these needs no chain, so it starts at once (a chain's tail would
#: otherwise run alone on one worker at the end of the sweep).
UNCHAINED_METHODS = frozenset({"matrix", "recurrence"})
#: Row statuses whose record is final and checkpointed: pytest ran the row to its end (its tests
#: passed or failed), or the row exceeded its budget (running it again would exceed it again).
FINAL = ("ok", "failed", "over budget")


# ----------------------------------------------------------------------------- code identity
def code_key(repo: Path = REPO) -> str:
    """The code a sweep measures: the commit, plus a hash of the uncommitted changes to tracked
    files if any (generated reports and README.md excepted); the package version outside git."""
    import hashlib

    try:
        head = subprocess.run(["git", "-C", str(repo), "rev-parse", "HEAD"], capture_output=True, text=True,
                              timeout=10)
        if head.returncode == 0 and head.stdout.strip():
            diff = subprocess.run(["git", "-C", str(repo), "diff", "HEAD", "--", ".", ":!reports", ":!README.md"],
                                  capture_output=True, timeout=30).stdout
            return head.stdout.strip()[:12] + (f"-dirty-{hashlib.sha256(diff).hexdigest()[:8]}" if diff else "")
    except (OSError, subprocess.SubprocessError):
        pass
    from importlib import metadata

    try:
        return "v" + metadata.version("exo-bench")
    except metadata.PackageNotFoundError:
        return "unknown"


def checkpoint_dir(base: Path, code: str) -> Path:
    """Checkpoints of the rows measured with code ``code`` (:func:`code_key`)."""
    return Path(base) / code


def default_checkpoints(reports: Path) -> Path:
    """The checkpoint folder of a reports folder: ``.exo-bench-sweep`` beside it (never inside it,
    so an interrupted sweep leaves nothing in the reports folder)."""
    return Path(reports).resolve().parent / ".exo-bench-sweep"


# ----------------------------------------------------------------------------- one row (on a worker)
def _death_signal():
    """A ``preexec_fn`` by which the row's pytest process gets SIGKILL when its worker dies (Linux
    ``PR_SET_PDEATHSIG``), so a killed worker leaves no orphan timing on its host while the
    scheduler runs the row again elsewhere; ``None`` where prctl is not available. libc is loaded
    here, in the parent, so the child between fork and exec only calls it."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        import ctypes

        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    return lambda: prctl(1, signal.SIGKILL)   # PR_SET_PDEATHSIG = 1


def host_and_cpu() -> tuple[str, str]:
    """This host's name and CPU, as ``bench.reporting.machine_info`` says them."""
    import platform

    from exo_bench.bench.reporting import _cpu_model

    return platform.node(), f"{_cpu_model()}, {os.cpu_count()} logical cores"


def _failure_lines(output: str) -> str:
    lines = [ln.strip() for ln in output.splitlines() if ln.startswith(("FAILED ", "ERROR "))]
    if lines:
        return "; ".join(lines[:3]) + (f" (+{len(lines) - 3} more)" if len(lines) > 3 else "")
    tail = [ln.strip() for ln in output.splitlines() if ln.strip()]
    return tail[-1] if tail else "no output"


def run_row(row: dict, sweep: str, budget: float, code: str | None = None, pytest_args: tuple = (),
            repo: str | None = None, prior: dict | None = None) -> dict:
    """Run one row (every benchmark of it) in a pytest subprocess; its record (see :func:`rows.merge`).

    Runs on a worker. ``code`` is the client's :func:`code_key`: a worker running other code refuses
    the row (timings of other code would be merged silently otherwise). ``prior``: the record of the
    row before this one in its chain (:data:`CHAINED`), whose skips (and those it inherited) reach
    pytest as ``--prior-skips``, so a method over budget at a smaller n is not tried again."""
    t0 = time.perf_counter()
    host, cpu = host_and_cpu()
    inherited = ((prior.get("skips") or []) + (prior.get("inherited") or [])) if prior else []
    rec = {"key": row["key"], "nodeids": row.get("nodeids", []), "host": host, "cpu": cpu, "status": "error",
           "reason": "", "seconds": 0.0, "benchmark_json": None, "skips": [], "machine_info": None,
           "inherited": [s for s in inherited if any(p[0] == _rows.OVER_BUDGET for p in s.get("params") or [])]}
    try:
        from distributed import get_worker

        get_worker().log_event(TOPIC, {"row": row["key"], "event": "start", "host": host})
    except (ImportError, ValueError):   # not on a Dask worker (a direct call)
        pass
    where = Path(repo) if repo else REPO
    if code is not None:
        mine = code_key(where)
        if mine != code:
            rec["reason"] = f"worker {host} runs code {mine}, the sweep measures {code}; install the same commit"
            return rec
    with tempfile.TemporaryDirectory(prefix="exo-bench-row-") as d:
        bjson, sjson, pjson = Path(d) / "benchmarks.json", Path(d) / "skips.json", Path(d) / "prior-skips.json"
        cmd = [sys.executable, "-m", "pytest", row["file"], "--row", row["key"], "-q", "-rfE", "-p", "no:cacheprovider",
               "--benchmark-enable", f"--benchmark-json={bjson}", f"--skips-json={sjson}", f"--sweep={sweep}",
               *pytest_args]
        if rec["inherited"]:
            pjson.write_text(json.dumps(rec["inherited"]))
            cmd.append(f"--prior-skips={pjson}")
        proc = subprocess.Popen(cmd, cwd=where, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                stdin=subprocess.DEVNULL, start_new_session=True,
                                env={**os.environ, "COLUMNS": "400"},   # failure lines in full in the summary
                                preexec_fn=_death_signal())
        try:
            output, _ = proc.communicate(timeout=budget)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
            rec.update(status="over budget", reason=f"over the row budget of {budget:g} s (killed)",
                       seconds=time.perf_counter() - t0)
            return rec
        except BaseException:   # the task is cancelled or the worker closes: no orphan keeps running
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            raise
        rec["seconds"] = time.perf_counter() - t0
        if bjson.exists():
            data = json.loads(bjson.read_text())
            for b in data.get("benchmarks", []):
                b.get("stats", {}).pop("data", None)   # the per-round lists: megabytes; the statistics stay
            rec["benchmark_json"] = data
            rec["machine_info"] = data.get("machine_info")
        if sjson.exists():
            rec["skips"] = json.loads(sjson.read_text())
        if proc.returncode == 0:
            rec["status"] = "ok"
        elif proc.returncode == 1:   # pytest ran the row to its end; some of its tests failed
            rec.update(status="failed", reason=_failure_lines(output))
        else:
            rec.update(status="error", reason=f"pytest exit code {proc.returncode}: {_failure_lines(output)}")
    return rec


# ----------------------------------------------------------------------------- the cluster
@contextlib.contextmanager
def cluster(scheduler: str | None = None, workers: int | None = None):
    """A Dask client: on the cluster at ``scheduler``, or on a :class:`LocalCluster` of ``workers``
    single-threaded worker processes (default: one per core) that is closed on exit, Ctrl-C included."""
    from distributed import Client, LocalCluster

    if workers is not None and workers < 1:
        raise ValueError(f"--workers: expected at least 1 worker, got {workers}")
    if scheduler:
        try:
            client = Client(scheduler, timeout=SCHEDULER_TIMEOUT)
        except (OSError, ValueError, TimeoutError) as e:
            text = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
            raise ValueError(f"--scheduler {scheduler!r}: no Dask scheduler reachable there ({text})") from None
        try:
            yield client
        finally:
            client.close()
        return
    n = workers or os.cpu_count() or 1
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # "port 8787 in use" and the like: we start no dashboard anyway
        lc = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                          silence_logs=logging.CRITICAL)
    try:
        client = Client(lc)
        try:
            yield client
        finally:
            client.close()
    finally:
        lc.close()


def check_scheduler(scheduler: str | None) -> None:
    """Refuse (one line, before any work) a ``--scheduler`` address where no scheduler answers."""
    if scheduler:
        with cluster(scheduler):
            pass


def _cancel(client, futures) -> None:
    with contextlib.suppress(Exception):
        client.cancel(futures, force=True)


# ----------------------------------------------------------------------------- the sweep
@dataclass
class SweepOutcome:
    merged: dict                                  # the pytest-benchmark JSON of the whole sweep
    skips: list[dict]                             # skipped or failed benchmarks with reasons
    rows: list[dict]                              # every row's record, in collection order
    ran: list[str] = field(default_factory=list)  # rows run now
    resumed: list[str] = field(default_factory=list)   # rows read from checkpoints
    seconds: float = 0.0
    workers: int = 0


def enumerate_rows(files: list[str], sweep: str, repo: Path = REPO, pytest_args: tuple = ()) -> list[dict]:
    """The rows of the benchmark files (``pytest --collect-only --rows-json``), in collection order."""
    with tempfile.TemporaryDirectory(prefix="exo-bench-rows-") as d:
        path = Path(d) / "rows.json"
        cmd = [sys.executable, "-m", "pytest", *files, "--collect-only", "-q", "-p", "no:cacheprovider",
               f"--rows-json={path}", f"--sweep={sweep}", *pytest_args]
        r = subprocess.run(cmd, cwd=repo, capture_output=True, text=True, stdin=subprocess.DEVNULL)
        if r.returncode != 0 or not path.exists():
            raise ValueError(f"collecting the benchmark rows failed (pytest exit code {r.returncode}): "
                             f"{_failure_lines(r.stdout + r.stderr)}")
        return _rows.read_rows_json(path)


def _load_checkpoint(folder: Path, key: str) -> dict | None:
    p = folder / f"{_rows.safe_name(key)}.json"
    try:
        rec = json.loads(p.read_text())
    except (OSError, ValueError):
        return None
    return rec if rec.get("key") == key and rec.get("status") in FINAL else None


def _progress(total: int, enabled: bool):
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    console = Console()
    return Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                    console=console, disable=not enabled, transient=False)


def _chains(rows: list[dict], chained) -> dict[str, str]:
    """``{row key: key of the row before it in its chain}`` for the rows of the ``chained`` files."""
    groups: dict[tuple, list[dict]] = {}
    for r in rows:
        if r["file"] in chained and r.get("n") is not None and not _methods(r) <= UNCHAINED_METHODS:
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
    """Larger rows first (n, then 3D before 2D: :func:`rows.schedule_order`)."""
    return 10 * (row.get("n") or 0) + (row.get("dim") or 0)


def run_sweep(files: list[str], sweep: str, *, checkpoints: Path, scheduler: str | None = None,
              workers: int | None = None, budget: float | None = None, pytest_args: tuple = (),
              repo: Path = REPO, only=None, chained=CHAINED, progress: bool = True, on_result=None,
              log=print) -> SweepOutcome:
    """Run every row of the benchmark ``files`` on a Dask cluster (see the module docstring).

    ``checkpoints``: the base folder of the checkpoints (a subfolder per :func:`code_key`);
    ``budget``: seconds per row (default: the profile's :attr:`Sweep.row_budget`); ``pytest_args``:
    appended to every pytest command; ``repo``: the folder pytest runs in (the checkout, on every
    worker too: each resolves its own copy unless it is given); ``only``: row keys to keep (the
    others are left out, as if not collected); ``chained``: files whose rows run as chains
    (:data:`CHAINED`); ``on_result(record)``: called in this process as each row
    finishes (after its checkpoint is written)."""
    from distributed import as_completed

    from exo_bench.bench.sweep import current

    t0 = time.perf_counter()
    if workers is not None and workers < 1:
        raise ValueError(f"--workers: expected at least 1 worker, got {workers}")
    if budget is None:
        budget = float(getattr(current(sweep), "row_budget", 3600.0))
    code = code_key(repo)
    folder = checkpoint_dir(checkpoints, code)
    rows = enumerate_rows(list(files), sweep, repo=repo, pytest_args=pytest_args)
    if only is not None:
        rows = [r for r in rows if r["key"] in set(only)]
    where = None if Path(repo).resolve() == REPO.resolve() else str(repo)
    records: dict[str, dict] = {}
    resumed = []
    for r in rows:
        rec = _load_checkpoint(folder, r["key"])
        if rec is not None:
            records[r["key"]] = rec
            resumed.append(r["key"])
    todo = _rows.schedule_order([r for r in rows if r["key"] not in records])
    log(f"sweep {sweep}: {len(rows)} rows, {len(resumed)} already done at code {code} "
        f"(checkpoints in {folder}), {len(todo)} to run")
    ran, nworkers = [], 0
    if todo:
        folder.mkdir(parents=True, exist_ok=True)
        with cluster(scheduler, workers) as client:
            nworkers = len(client.scheduler_info().get("workers", {})) or (workers or 0)
            running: set[str] = set()
            counts = {"done": 0, "failed": 0}
            with _progress(len(todo), progress) as bar:
                task = bar.add_task("", total=len(todo))

                def describe():
                    bar.update(task, description=f"rows: {counts['done']} done, {len(running)} running, "
                                                 f"{counts['failed']} failed")

                def started(event):
                    msg = event[1] if isinstance(event, tuple) else event
                    if isinstance(msg, dict) and msg.get("event") == "start":
                        running.add(msg["row"])
                        describe()

                client.subscribe_topic(TOPIC, started)
                describe()
                futures, submitted = {}, {}
                prior_of = _chains(rows, chained)
                # chains in increasing n first (a row's prior is submitted before it); the scheduler
                # runs the largest rows first anyway (priority)
                for r in sorted(todo, key=lambda r: (r["key"] not in prior_of, r.get("n") or 0)):
                    p = prior_of.get(r["key"])
                    prior = submitted[p] if p in submitted else (
                        {k: records[p].get(k) for k in ("skips", "inherited")} if p in records else None)
                    f = client.submit(run_row, r, sweep, budget, code, tuple(pytest_args), where, prior,
                                      key=f"exo-bench-row-{_rows.safe_name(r['key'])}-{uuid.uuid4().hex[:8]}",
                                      pure=False, retries=RETRIES, priority=_priority(r))
                    futures[f] = r
                    submitted[r["key"]] = f
                try:
                    for f in as_completed(list(futures)):
                        r = futures[f]
                        try:
                            rec = f.result()
                        except Exception as e:  # noqa: BLE001 - KilledWorker after repeated deaths, ...
                            rec = {"key": r["key"], "nodeids": r["nodeids"], "status": "error",
                                   "reason": f"{type(e).__name__}: {str(e).strip().splitlines()[0] if str(e).strip() else ''}",
                                   "host": None, "cpu": None, "seconds": 0.0, "benchmark_json": None, "skips": []}
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
                except BaseException:   # Ctrl-C (or a failing callback): cancel every task, then close
                    _cancel(client, list(futures))
                    raise
                finally:
                    with contextlib.suppress(Exception):
                        client.unsubscribe_topic(TOPIC)
    ordered = [records[r["key"]] for r in rows if r["key"] in records]
    merged, skips = _rows.merge(ordered)
    merged["sweep"] = {"profile": sweep, "code": code, "workers": nworkers, "scheduler": scheduler or "local",
                       "seconds": time.perf_counter() - t0, "ran": len(ran), "resumed": len(resumed)}
    return SweepOutcome(merged, skips, ordered, ran, resumed, time.perf_counter() - t0, nworkers)


# ----------------------------------------------------------------------------- exo-bench bench
def bench_run(args) -> int:
    """``exo-bench bench`` on the cluster: the sweep as row tasks, then the reports of
    :mod:`exo_bench.bench.bench_reports` from the merged JSON (written only once every row is in)."""
    from exo_bench.bench.reporting import REPORTS

    full = bool(getattr(args, "full", False))
    sweep = "full" if full else "quick"
    out = (Path(args.reports) if getattr(args, "reports", None) else REPORTS).resolve()
    command = "exo-bench bench" + (" --full" if full else "")
    check_scheduler(args.scheduler)
    only = None
    if getattr(args, "rows", None):       # a selection: its own report folder, the same checkpoints
        only = selected_rows(sweep, args.rows)
        command += "".join(f" --rows '{p}'" for p in args.rows)
    outcome = run_sweep(["bench"], sweep, checkpoints=default_checkpoints(out), scheduler=args.scheduler,
                        workers=args.workers, only=only)
    if only is not None:
        out = out / "selected-rows"
    print(f"sweep {sweep}: {len(outcome.ran)} rows run on {outcome.workers} worker(s), {len(outcome.resumed)} "
          f"from checkpoints, {outcome.seconds:.0f} s", flush=True)
    _write_reports(outcome.merged, outcome.skips, out, sweep, command, bool(getattr(args, "update_readme", False)))
    return 0


def selected_rows(sweep: str, patterns: list[str]) -> list[str]:
    """The keys of the benchmark rows that match any of the shell-style ``patterns``; a ValueError
    naming some keys when none does."""
    from fnmatch import fnmatchcase

    keys = [r["key"] for r in enumerate_rows(["bench"], sweep)]
    only = [k for k in keys if any(fnmatchcase(k, p) for p in patterns)]
    if not only:
        raise ValueError(f"--rows: no row of the {sweep} sweep matches {', '.join(map(repr, patterns))}; "
                         f"rows look like {', '.join(keys[:3])} ({len(keys)} rows)")
    return only


def _write_reports(merged: dict, skips: list, out: Path, sweep: str, command: str, update_readme: bool) -> list[Path]:
    """The merged JSON and skips of a sweep into a staging folder, then every benchmark report from
    them (:func:`bench_reports.write_reports`), published into ``out`` together."""
    from exo_bench.bench import bench_reports as br
    from exo_bench.bench.runner import staging_dir

    with staging_dir(out) as st:
        bjson, sjson = st / f"benchmarks-{sweep}.json", st / "skips.json"
        atomic_write(bjson, json.dumps(merged, indent=1))
        atomic_write(sjson, json.dumps(skips, indent=1))
        return br.write_reports(bjson, sjson, st, out, sweep, command, update_readme)


def render_checkpoints(code: str, out: Path, sweep: str = "full", checkpoints: Path | None = None,
                       repo: Path = REPO, update_readme: bool = False) -> list[Path]:
    """The benchmark reports again, from the rows a sweep measured at ``code`` (its checkpoints),
    with this process's report code: for a change to how the reports are drawn, without measuring
    again. Every row of the profile must be there (a ValueError names the missing ones); the reports
    say at which code the rows were measured and that they were rendered again."""
    out = Path(out).resolve()
    folder = checkpoint_dir(checkpoints or default_checkpoints(out), code)
    rows = enumerate_rows(["bench"], sweep, repo=repo)
    records = {r["key"]: _load_checkpoint(folder, r["key"]) for r in rows}
    missing = [k for k, v in records.items() if v is None]
    if missing:
        raise ValueError(f"render: {len(missing)} of {len(rows)} rows have no checkpoint at code {code} in {folder} "
                         f"(first: {missing[0]}); run the sweep at that code first")
    merged, skips = _rows.merge([records[r["key"]] for r in rows])
    merged["sweep"] = {"profile": sweep, "code": code, "rendered_at": code_key(repo), "resumed": len(rows)}
    command = (f"exo-bench bench {'--full' if sweep == 'full' else ''}".strip()
               + f" (rows measured at {code}, reports rendered again at {code_key(repo)})")
    from exo_bench.bench.runner import record_files, snapshot

    before = snapshot(out)
    written = _write_reports(merged, skips, out, sweep, command, update_readme)
    record_files(out, before, command)   # runs.json and summary.md say which run made each file
    return written


# ----------------------------------------------------------------------------- exo-bench stability
def stability_task(part: str, profile_name: str, methods: list[str]):
    """One task of the stability study, run on a worker: a family (``"family:<name>"``) or the
    forward-dynamics part (``"forward"``). Returns ``(result, warnings)``, the warnings it raised
    as ``(category name, message)``, re-issued by the client."""
    from exo_bench.bench.methods import PreparedSet
    from exo_bench.bench.stability import cases, evaluation, forward_evaluation

    profile = cases.FULL if profile_name == "full" else cases.QUICK
    try:
        from distributed import get_worker

        get_worker().log_event(TOPIC, {"row": part, "event": "start"})
    except (ImportError, ValueError):
        pass
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if part == "forward":
            res = forward_evaluation.run_forward(profile, methods, lambda msg: None,
                                                 PreparedSet(evaluation.method_options(profile)))
        else:
            name = part.split(":", 1)[1]
            make = cases.FAMILIES[name]
            doc = " ".join((make.__doc__ or "").split())
            res = evaluation.evaluate_family(name, make(profile), methods, {}, doc, evaluation.method_options(profile))
    return res, [(w.category.__name__, str(w.message)) for w in caught]


def stability_evaluator(args):
    """The ``evaluate(profile, methods, log)`` of :func:`stability.report.run` that runs the
    families and the forward part as tasks on the cluster, checkpointed per part."""
    from exo_bench.bench import study
    from exo_bench.bench.reporting import REPORTS
    from exo_bench.bench.stability import cases

    out = (Path(args.reports) if getattr(args, "reports", None) else REPORTS).resolve()
    check_scheduler(args.scheduler)

    def evaluate(profile, methods, log):
        from distributed import as_completed

        folder = checkpoint_dir(default_checkpoints(out), code_key())
        parts = [f"family:{name}" for name in cases.FAMILIES] + ["forward"]
        tag = lambda part: _rows.safe_name(f"stability:{profile.name}:{','.join(methods)}:{part}")  # noqa: E731
        results = {}
        for part in parts:
            with contextlib.suppress(OSError, pickle.UnpicklingError, EOFError, AttributeError, ImportError):
                results[part] = pickle.loads((folder / f"{tag(part)}.pickle").read_bytes())
        todo = [p for p in parts if p not in results]
        log(f"stability {profile.name}: {len(parts)} parts, {len(parts) - len(todo)} from checkpoints, "
            f"{len(todo)} to run")
        if todo:
            folder.mkdir(parents=True, exist_ok=True)
            with cluster(args.scheduler, args.workers) as client:
                futures = {client.submit(stability_task, p, profile.name, methods, pure=False, retries=RETRIES,
                                         key=f"exo-bench-stability-{tag(p)}-{uuid.uuid4().hex[:8]}"): p for p in todo}
                try:
                    with _progress(len(todo), True) as bar:
                        task = bar.add_task("stability parts", total=len(todo))
                        for f in as_completed(list(futures)):
                            part = futures[f]
                            results[part] = f.result()
                            atomic_write(folder / f"{tag(part)}.pickle", pickle.dumps(results[part]))
                            bar.advance(task)
                except BaseException:
                    _cancel(client, list(futures))
                    raise
        categories = {c.__name__: c for c in (study.StabilityWarning, study.UnusableMethodWarning,
                                              cases.IllConditionedWarning)}
        for part in parts:
            for cat, msg in results[part][1]:
                warnings.warn(msg, categories.get(cat, UserWarning), stacklevel=2)
        families = [results[p][0] for p in parts if p != "forward"]
        return families, results["forward"][0]

    return evaluate
