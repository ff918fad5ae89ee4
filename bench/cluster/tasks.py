"""The tasks a cluster's workers run: one benchmark row in a pytest subprocess (:func:`run_row`) and one part
of the stability study (:func:`stability_task`)."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

from exo_bench.bench.perf import rows as _rows
from exo_bench.bench.output.provenance import REPO
from exo_bench.bench.cluster.checkpoints import code_key

#: Event topic of the workers' "row started" messages (the progress bar's "running" count).
TOPIC = "exo-bench-rows"


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
    return lambda: prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG = 1


def host_and_cpu() -> tuple[str, str]:
    """This host's name and CPU, as ``bench.reporting.machine_info`` says them."""
    import platform

    from exo_bench.bench.output.provenance import _cpu_model

    return platform.node(), f"{_cpu_model()}, {os.cpu_count()} logical cores"


def failure_lines(output: str) -> str:
    lines = [ln.strip() for ln in output.splitlines() if ln.startswith(("FAILED ", "ERROR "))]
    if lines:
        return "; ".join(lines[:3]) + (f" (+{len(lines) - 3} more)" if len(lines) > 3 else "")
    tail = [ln.strip() for ln in output.splitlines() if ln.strip()]
    return tail[-1] if tail else "no output"


def run_row(
    row: dict,
    sweep: str,
    budget: float,
    code: str | None = None,
    pytest_args: tuple = (),
    repo: str | None = None,
    prior: dict | None = None,
    scratch: str | None = None,
) -> dict:
    """Run one row (every benchmark of it) in a pytest subprocess; its record (see :func:`exo_bench.bench.perf.rows.merge`).

    Runs on a worker. ``code`` is the client's :func:`code_key`: a worker running other code refuses
    the row (timings of other code would be merged silently otherwise). ``prior``: the record of the
    row before this one in its chain (:data:`CHAINED`), whose skips (and those it inherited) reach
    pytest as ``--prior-skips``, so a method over budget at a smaller n is not tried again.
    ``scratch``: the sweep's temporary folder (:func:`exo_bench.bench.cluster.cluster.run_sweep` removes
    it at its end), where the row's own folder goes when this host has it: a worker killed mid-row
    (the cluster closing, Ctrl-C) cannot remove its folder, the sweep does (issue 38: empty
    ``/tmp/exo-bench-row-*`` folders were left behind); elsewhere, the system's temporary folder."""
    t0 = time.perf_counter()
    host, cpu = host_and_cpu()
    inherited = ((prior.get("skips") or []) + (prior.get("inherited") or [])) if prior else []
    rec = {
        "key": row["key"],
        "nodeids": row.get("nodeids", []),
        "host": host,
        "cpu": cpu,
        "status": "error",
        "reason": "",
        "seconds": 0.0,
        "benchmark_json": None,
        "skips": [],
        "machine_info": None,
        "inherited": [s for s in inherited if any(p[0] == _rows.OVER_BUDGET for p in s.get("params") or [])],
    }
    try:
        from distributed import get_worker

        get_worker().log_event(TOPIC, {"row": row["key"], "event": "start", "host": host})
    except (ImportError, ValueError):  # not on a Dask worker (a direct call)
        pass
    where = Path(repo) if repo else REPO
    if code is not None:
        mine = code_key(where)
        if mine != code:
            rec["reason"] = f"worker {host} runs code {mine}, the sweep measures {code}; install the same commit"
            return rec
    parent = scratch if scratch and Path(scratch).is_dir() else None
    with tempfile.TemporaryDirectory(prefix="exo-bench-row-", dir=parent) as d:
        bjson, sjson, pjson = Path(d) / "benchmarks.json", Path(d) / "skips.json", Path(d) / "prior-skips.json"
        cmd = [
            sys.executable,
            "-m",
            "pytest",
            row["file"],
            "--row",
            row["key"],
            "-q",
            "-rfE",
            "-p",
            "no:cacheprovider",
            "--benchmark-enable",
            f"--benchmark-json={bjson}",
            f"--skips-json={sjson}",
            f"--sweep={sweep}",
            *pytest_args,
        ]
        if rec["inherited"]:
            pjson.write_text(json.dumps(rec["inherited"]))
            cmd.append(f"--prior-skips={pjson}")
        proc = subprocess.Popen(
            cmd,
            cwd=where,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
            env={**os.environ, "COLUMNS": "400"},  # failure lines in full in the summary
            preexec_fn=_death_signal(),
        )
        try:
            output, _ = proc.communicate(timeout=budget)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            with contextlib.suppress(subprocess.TimeoutExpired):  # a child in a session of its own may hold the pipe
                proc.communicate(timeout=60)
            rec.update(
                status="over budget",
                reason=f"over the row budget of {budget:g} s (killed)",
                seconds=time.perf_counter() - t0,
            )
            return rec
        except BaseException:  # the task is cancelled or the worker closes: no orphan keeps running
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            raise
        rec["seconds"] = time.perf_counter() - t0
        if bjson.exists():
            data = json.loads(bjson.read_text())
            for b in data.get("benchmarks", []):
                b.get("stats", {}).pop("data", None)  # the per-round lists: megabytes; the statistics stay
            rec["benchmark_json"] = data
            rec["machine_info"] = data.get("machine_info")
        if sjson.exists():
            rec["skips"] = json.loads(sjson.read_text())
        if proc.returncode == 0:
            rec["status"] = "ok"
        elif proc.returncode == 1:  # pytest ran the row to its end; some of its tests failed
            rec.update(status="failed", reason=failure_lines(output))
        else:
            rec.update(status="error", reason=f"pytest exit code {proc.returncode}: {failure_lines(output)}")
    return rec


# ----------------------------------------------------------------------------- exo-bench stability
def stability_task(part: str, profile_name: str, methods: list[str]):
    """One task of the stability study, run on a worker: a family (``"family:<name>"``) or the
    forward-dynamics part (``"forward"``). Returns ``(result, warnings)``, the warnings it raised
    as ``(category name, message)``, re-issued by the client."""
    from exo_bench.api import PreparedSet
    from exo_bench.bench.studies.stability import cases, evaluation, forward_evaluation

    profile = cases.FULL if profile_name == "full" else cases.QUICK
    try:
        from distributed import get_worker

        get_worker().log_event(TOPIC, {"row": part, "event": "start"})
    except (ImportError, ValueError):
        pass
    res: object
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if part == "forward":
            res = forward_evaluation.run_forward(
                profile, methods, lambda msg: None, PreparedSet(evaluation.method_options(profile))
            )
        else:
            name = part.split(":", 1)[1]
            make = cases.FAMILIES[name]
            doc = " ".join((make.__doc__ or "").split())
            res = evaluation.evaluate_family(name, make(profile), methods, {}, doc, evaluation.method_options(profile))
    return res, [(w.category.__name__, str(w.message)) for w in caught]
