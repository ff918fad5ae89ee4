"""Rows of the benchmark sweep: what one distributed task runs, how results merge, and the one-host rule.

A **row** is every benchmark of one test file at one (dimension, n, model/topology) in one profile:
e.g. all methods of ``bench/test_inverse_dynamics.py`` on the 3D chain of 100 links in the full
profile, batched and per call. A row is the unit of work of the distributed sweep
(:mod:`exo_bench.bench.cluster.cluster`): it runs in one pytest process on one worker, so every ratio
the reports take *within* a row (method against method at equal n) compares timings of one host.

The row of a collected test item is read from its parameters (:func:`row_fields`):

* a tuple parameter ``(method, n, dim, topology)`` (``test_inverse_dynamics.py``'s ``case`` and
  ``single_case``, ``test_compose.py``'s ``compose_case``);
* otherwise named parameters ``n``, ``dim`` and one of ``topology``/``topo``/``model``/``mechanism``;
* otherwise (no n or no dim among the parameters, e.g. ``test_wrapper_overhead[matrix-call]``) the
  row is the test function: the node id without its ``[...]`` parametrization, so all its
  parametrizations run together.

The key is ``"<profile>:<file>:<dim>d-<topology>-n<n>"`` (``"full:bench/test_compose.py:3d-chain-n5"``)
or ``"<profile>:<file>:<function>"``. Select rows with ``pytest ... --row KEY`` (repeatable); list
them with ``pytest ... --collect-only --rows-json PATH``. Both options are added by
:func:`add_options` and applied by :func:`select` (bench/conftest.py calls them).
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterable
from pathlib import Path

#: Parameter names that may carry the model or topology of a row.
TOPOLOGY_NAMES = ("topology", "topo", "model", "mechanism")


def row_fields(item) -> dict:
    """``{"file", "dim", "n", "topology"}`` of a collected pytest item, or ``{"file", "function"}``
    when its parameters do not name a dimension and an n (see the module docstring)."""
    nodeid = item.nodeid
    file = nodeid.split("::", 1)[0]
    params = dict(getattr(getattr(item, "callspec", None), "params", {}) or {})
    for value in params.values():
        if (
            isinstance(value, tuple)
            and len(value) == 4
            and isinstance(value[0], str)
            and isinstance(value[1], int)
            and isinstance(value[2], int)
            and isinstance(value[3], str)
        ):
            _method, n, dim, topology = value
            return {"file": file, "dim": dim, "n": n, "topology": topology}
    if isinstance(params.get("n"), int) and isinstance(params.get("dim"), int):
        topology = next((str(params[k]) for k in TOPOLOGY_NAMES if k in params), "")
        return {"file": file, "dim": params["dim"], "n": params["n"], "topology": topology}
    return {"file": file, "function": re.sub(r"\[.*\]$", "", nodeid.split("::", 1)[-1])}


def row_key(item, profile: str) -> str:
    """The row key of a collected item in a profile (module docstring)."""
    f = row_fields(item)
    if "function" in f:
        return f"{profile}:{f['file']}:{f['function']}"
    return f"{profile}:{f['file']}:{f['dim']}d-{f['topology'] or 'model'}-n{f['n']}"


def add_options(parser) -> None:
    parser.addoption(
        "--row",
        action="append",
        default=None,
        metavar="KEY",
        help="run only the benchmarks of this row (repeatable; keys from --rows-json)",
    )
    parser.addoption(
        "--rows-json",
        default=None,
        metavar="PATH",
        help="write the rows of the collected benchmarks (key, file, node ids) to PATH",
    )
    parser.addoption(
        "--prior-skips",
        default=None,
        metavar="PATH",
        help="skips of the rows before this one in its chain (a JSON list as --skips-json writes): "
        "methods over budget at a smaller n are skipped here without trying",
    )


#: The user property by which a benchmark says it was skipped over budget, as
#: ``[method, n, dim, topology, reason]``, so a larger n of the same kind can skip without trying.
OVER_BUDGET = "over_budget"


def prior_over_budget(config) -> dict[tuple, tuple]:
    """``{(method, dim, topology): (n, reason)}`` from ``--prior-skips``: what the rows before this
    one in its chain (smaller n, bench/cluster/cluster.py) found over budget."""
    path = config.getoption("--prior-skips")
    if not path:
        return {}
    out: dict[tuple, tuple] = {}
    for s in json.loads(Path(path).read_text()):
        for name, value in s.get("params") or []:
            if name == OVER_BUDGET:
                method, n, dim, topology, reason = value
                if (method, dim, topology) not in out or n < out[(method, dim, topology)][0]:
                    out[(method, dim, topology)] = (n, reason)
    return out


def select(config, items: list, profile: str) -> None:
    """``pytest_collection_modifyitems``: write ``--rows-json``, keep only the items of ``--row``."""
    keys = [row_key(it, profile) for it in items]
    path = config.getoption("--rows-json")
    if path:
        from exo_bench.models.files import atomic_write

        atomic_write(path, json.dumps(enumerate_rows(items, keys), indent=1))
    wanted = config.getoption("--row")
    if not wanted:
        return
    unknown = sorted(set(wanted) - set(keys))
    if unknown:
        import pytest

        raise pytest.UsageError(f"--row: no collected benchmark belongs to row {unknown[0]!r}")
    keep = [it for it, k in zip(items, keys) if k in wanted]
    drop = [it for it, k in zip(items, keys) if k not in wanted]
    if drop:
        config.hook.pytest_deselected(items=drop)
    items[:] = keep


def record_peak_memory(config, output_json: dict) -> None:
    """``pytest_benchmark_update_json``: in a row's run (``--row``), its process's peak resident
    memory in MB (``peak_rss_mb``), which :func:`merge` keeps per row: a worker's peak for that row."""
    if not config.getoption("--row"):
        return
    try:
        import resource
    except ImportError:  # not POSIX
        return
    import sys

    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux, bytes on macOS
    output_json["peak_rss_mb"] = peak / 1e6 if sys.platform == "darwin" else peak * 1024 / 1e6


def enumerate_rows(items: Iterable, keys: list[str]) -> list[dict]:
    """``[{"key", "file", "nodeids", "dim", "n", ...}]`` in collection order, one per row."""
    rows: dict[str, dict] = {}
    for it, k in zip(items, keys):
        r = rows.setdefault(k, {"key": k, **row_fields(it), "nodeids": []})
        r["nodeids"].append(it.nodeid)
    return list(rows.values())


def schedule_order(rows: list[dict]) -> list[dict]:
    """Largest rows first (n, then 3D before 2D), so that the longest tasks do not start last and
    leave the other workers idle at the end; the order among equals is the collection order."""
    return sorted(rows, key=lambda r: (-(r.get("n") or 0), -(r.get("dim") or 0)))


def safe_name(key: str) -> str:
    """A file name for a row key (checkpoints): readable, and unique by a short hash."""
    import hashlib

    from exo_bench.models.files import file_stem

    stem = file_stem(key)[-80:].lstrip("-")  # the one file-name encoder; the tail never an option
    return f"{stem}-{hashlib.sha256(key.encode()).hexdigest()[:10]}"


# ----------------------------------------------------------------------------- merging
def merge(results: list[dict]) -> tuple[dict, list[dict]]:
    """The pytest-benchmark JSON of a whole sweep from its row results (:func:`exo_bench.bench.cluster.tasks.run_row`
    records) and the list of skipped or failed benchmarks with their reasons.

    Each benchmark keeps its row's host and CPU in ``extra_info`` (``host``, ``cpu``, ``row``); the
    top level has the usual ``machine_info``/``commit_info``/``datetime``/``version`` (of the first
    row that ran; ``machine_info["hosts"]`` lists every host) so ``py.test-benchmark compare`` reads
    it, and ``rows`` records each row's status, reason, host, CPU, seconds and peak memory."""
    benchmarks: list = []
    skips: list = []
    rows: dict = {}
    top = None
    hosts: list[str] = []
    for r in results:
        data = r.get("benchmark_json") or {}
        rows[r["key"]] = {k: r.get(k) for k in ("status", "reason", "host", "cpu", "seconds", "machine_info")}
        rows[r["key"]]["peak_rss_mb"] = data.get("peak_rss_mb")
        if data and top is None:
            top = data
        if r.get("host") and r["host"] not in hosts:
            hosts.append(r["host"])
        for b in data.get("benchmarks", []):
            b = dict(b)
            b["extra_info"] = {**b.get("extra_info", {}), "host": r.get("host"), "cpu": r.get("cpu"), "row": r["key"]}
            benchmarks.append(b)
        skips += r.get("skips") or []
        if r.get("status") not in ("ok", None):
            done = {b["fullname"] for b in data.get("benchmarks", [])} | {s["nodeid"] for s in r.get("skips") or []}
            skips += [
                {"nodeid": nid, "reason": f"row {r['status']}: {r.get('reason')}", "params": []}
                for nid in r.get("nodeids", [])
                if nid not in done
            ]
    merged = {k: v for k, v in (top or {}).items() if k not in ("benchmarks", "peak_rss_mb")}
    merged.setdefault("machine_info", {})
    merged["machine_info"] = {**merged["machine_info"], "hosts": hosts}
    merged["benchmarks"] = benchmarks
    merged["rows"] = rows
    return merged, skips


class RowsRefused(ValueError):
    """A sweep some of whose rows were refused or could not run (status ``"error"``): its reports are
    not written, so they never replace a published report with error rows."""


def check_rows_ran(merged: dict) -> None:
    """Refuse (:class:`RowsRefused`, one line) the merged JSON of a sweep with a row in status
    ``"error"``: a worker at another commit refused it, its worker died too often, or its pytest
    stopped early (exit code 2 or more). Rows that ran to their end (``"ok"``, ``"failed"``) or past
    their budget are results, reported with their reasons. The line says how many rows and the first
    one's reason; the finished rows are checkpointed, so the command run again measures only the
    others. A serial run's JSON has no rows (its pytest's exit code is checked instead)."""
    rows = merged.get("rows") or {}
    refused = [(k, r) for k, r in rows.items() if isinstance(r, dict) and r.get("status") == "error"]
    if refused:
        key, first = refused[0]
        raise RowsRefused(
            f"{len(refused)} of {len(rows)} rows of the sweep were refused or could not run (first: row {key}: "
            f"{first.get('reason') or 'no reason given'}); no report written, the published ones are kept; "
            "the finished rows are checkpointed: run the command again to measure only the others"
        )


# ----------------------------------------------------------------------------- the one-host rule
class CrossHostRatio(ValueError):
    """A report was about to divide a timing measured on one host by one measured on another."""


def ratio(num: float, den: float, host_num: str | None, host_den: str | None, what: str = "ratio") -> float:
    """``num / den``, refused (:class:`CrossHostRatio`) when the two timings come from different
    hosts; ``None`` hosts (a single-process run, which is one host) are accepted."""
    if host_num is not None and host_den is not None and host_num != host_den:
        raise CrossHostRatio(
            f"{what}: refusing to divide a timing from host {host_num!r} by one from "
            f"host {host_den!r}; ratios compare timings of one row, which runs on one host"
        )
    return num / den


#: The columns that make one comparison group of the reports: every ratio they take (method
#: against method, crossovers at equal n) is between rows of one group.
RATIO_GROUP = ("kind", "dim", "n", "mechanism", "topology", "batched", "within")
#: Kinds whose ratios stay within one method (the wrapper's call against its kernel): ``within``
#: is the method for them, so two methods of such a kind may come from different hosts.
WITHIN_METHOD = ("wrapper",)


def check_ratio_groups(df) -> None:
    """Refuse (:class:`CrossHostRatio`) a benchmark table in which a comparison group of the
    reports (:data:`RATIO_GROUP`; ``kind`` is the group's first word: compose, inverse, wrapper,
    memory) holds timings of more than one host. A table without a ``host`` column (one pytest
    process) is one host and passes."""
    if df is None or len(df) == 0 or "host" not in df or "group" not in df:
        return
    d = df.assign(kind=df["group"].astype(str).str.split("-").str[0])
    within = d["method"].astype(str).where(d["kind"].isin(WITHIN_METHOD), "") if "method" in d else ""
    d = d.assign(within=within)
    cols = [c for c in RATIO_GROUP if c in d]
    d = d[cols + ["host"]].astype(str)  # NaN and mixed types as text, so that groupby keeps every row
    for key, g in d.groupby(cols, dropna=False):
        hosts = sorted(set(g["host"]) - {"None", "nan"})
        if len(hosts) > 1:
            name = ", ".join(f"{c}={v}" for c, v in zip(cols, key if isinstance(key, tuple) else (key,)))
            raise CrossHostRatio(
                f"benchmark group ({name}) has timings from hosts {', '.join(hosts)}: "
                "its ratios would divide timings of different hosts; rerun those rows"
            )


def read_rows_json(path: str | Path) -> list[dict]:
    return json.loads(Path(path).read_text())
