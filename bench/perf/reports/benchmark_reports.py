"""``exo-bench bench``: run the benchmark suite and write its reports (the reports themselves are
:mod:`~exo_bench.bench.perf.reports.paper_table`, :mod:`~exo_bench.bench.perf.reports.error_vs_runtime`
and :mod:`~exo_bench.bench.perf.reports.scaling`, from the frames of
:mod:`~exo_bench.bench.perf.reports.loading`).

Reports (each says what produced it, on what machine and when):

* ``reports/paper_table.md``: the paper's Mathematica timings beside ours, our extra rows, ratios,
  and a verdict on the claim that the gap grows with n and with 3D;
* ``reports/error_vs_runtime.md`` and ``.png``: seconds per sample against error, per method and n;
* ``reports/derivatives.md`` and ``.png``: issue 36's derivatives, ours and the peers', error against
  run time, and its goals met or not (:mod:`~exo_bench.bench.perf.reports.derivatives`);
* ``reports/scaling.md`` and ``.png``: issue 12's goals met or not, the per-call and batched tables
  (compiled and numpy kernels, Pinocchio bare and parallel, PyDy's Cython code), fitted growth
  exponents, the crossover n against Pinocchio, the kernels' compile time, and where the limit is
  (the factored kernel's counted arithmetic at this CPU's measured rates).

The raw pytest-benchmark JSON is kept beside them (``reports/benchmarks-<sweep>.json``).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path


from exo_bench.bench.studies.options import BenchOptions

from exo_bench.bench.output.provenance import REPO
from exo_bench.models.files import atomic_write

# The reports, one module each.
from exo_bench.bench.perf.reports.error_vs_runtime import error_vs_runtime
from exo_bench.bench.perf.reports.loading import _inverse, load
from exo_bench.bench.perf.rows import check_rows_ran
from exo_bench.bench.perf.reports.paper_table import (
    goals,
    paper_table,
    readme_with_table,
)
from exo_bench.bench.perf.reports.scaling import scaling, speed_goals
from exo_bench.bench.output.publish import publish, staging_dir
from exo_bench.bench.output.publish import BENCHMARK_REPORTS, benchmark_json


def _strip_raw_timings(path: Path) -> None:
    """Drop the per-round timing lists (megabytes for the per-call rows); the statistics stay."""
    data = json.loads(path.read_text())
    for b in data.get("benchmarks", []):
        b.get("stats", {}).pop("data", None)
    atomic_write(path, json.dumps(data, indent=1))


REPORT_FILES = BENCHMARK_REPORTS  # the names: bench/output/publish.py


def report_names(out: Path, sweep: str) -> dict[str, str]:
    """The file name each report takes in ``out``. A quick run never replaces what a full run
    wrote: when ``out``'s runs.json says a report came from ``exo-bench bench --full`` (or ``run
    --full``), a quick run writes its reports beside them as ``<name>-quick.<ext>`` instead."""
    from exo_bench.bench.output.files import narrower_names

    return narrower_names(out, REPORT_FILES, sweep == "full")


def write_reports(
    bjson: Path,
    sjson: Path,
    staging: Path,
    out: Path,
    sweep: str,
    command: str,
    update_readme: bool = False,
    published_to: Path | None = None,
) -> list[Path]:
    """Every report of the benchmark suite from its pytest-benchmark JSON ``bjson`` and the skip
    reasons ``sjson`` (both in ``staging``), published into ``out`` together; the README's paper
    table only with ``update_readme``. Used by the serial run and by the Dask sweep alike.
    ``published_to``: the folder these files finally land in when ``out`` is itself a staging
    folder (the main job's), whose runs.json decides :func:`report_names`."""
    check_rows_ran(json.loads(bjson.read_text()))  # a sweep with refused rows publishes nothing
    df, skips, _ = load(bjson, sjson)
    _strip_raw_timings(bjson)
    names = report_names(Path(published_to) if published_to else out, sweep)
    if names["scaling.md"] != "scaling.md":
        print(
            f"{out}: the benchmark reports there come from a full run; this {sweep} run writes "
            f"{', '.join(v for v in names.values() if v.endswith('.md'))} beside them",
            flush=True,
        )
    st = {n: staging / v for n, v in names.items()}
    text = paper_table(df, skips, command)
    atomic_write(st["paper_table.md"], text)
    inv = _inverse(df)
    g12 = speed_goals(inv, skips) if not inv.empty and "topology" in inv else []
    atomic_write(
        st["error_vs_runtime.md"],
        error_vs_runtime(df, skips, command, st["error_vs_runtime.png"])
        + "\n"
        + "\n".join(goals(df))
        + "\n\n"
        + "\n".join(g12)
        + "\n",
    )
    atomic_write(st["scaling.md"], scaling(df, skips, command, st["scaling.png"]))
    from exo_bench.bench.perf.reports.derivatives import derivatives_report, rows as derivative_rows

    png = st["derivatives.png"] if not derivative_rows(df).empty else None
    atomic_write(st["derivatives.md"], derivatives_report(df, skips, command, png))
    # a figure is drawn only where its report has rows (a selection of rows may have none): publish what exists
    published = publish([f for f in [*st.values(), bjson] if f.exists()], out)
    for p in published:
        print(f"wrote {p}")
    if update_readme and names["paper_table.md"] == "paper_table.md":
        from exo_bench.bench.perf.reports.readme_blocks import rewrite_highlights
        from exo_bench.bench.perf.reports.simd_goals import readme_with_goals, report_lines

        simd = report_lines(df)
        with_table = lambda readme: readme_with_table(readme, text, command)  # noqa: E731
        # issue 23's figures of this run are in its scaling.md, beside the highlights page (reports/simd-goals.md
        # is simd_goals' own run)
        page = rewrite_highlights(lambda readme: readme_with_goals(with_table(readme), simd, command, "scaling.md"))
        if page is not None:
            print(f"updated the paper table and issue 23's figures in {page}")
    return published


#: Seconds of the serial suite on the reference machine (2-core AMD EPYC, load 0.4-1.3): quick measured
#: (reports/main-job.log: 479 s); full predicted from its benchmarks' timed total (3026 s in
#: reports/full/benchmarks-full.json) times the quick suite's ratio of wall time to timed total (479 / 169).
SUITE_SECONDS = {"quick": 479.0, "full": 3026.0 * 479.0 / 169.0}
#: The default limit is this many times the prediction: a loaded machine finishes, a hung suite ends.
SUITE_ALLOWANCE = 10.0


def suite_timeout(sweep: str, option: float | None = None) -> float:
    """The suite's time limit: ``option`` (BenchOptions.suite_timeout) or :data:`SUITE_ALLOWANCE` times
    the profile's :data:`SUITE_SECONDS`; a ValueError names a bad option."""
    if option is None:
        return SUITE_ALLOWANCE * SUITE_SECONDS[sweep]
    ok = isinstance(option, int | float) and not isinstance(option, bool) and 0 < float(option) < float("inf")
    if not ok:
        raise ValueError(f"BenchOptions.suite_timeout: expected a finite number of seconds > 0, got {option!r}")
    return float(option)


def run_suite(cmd: list[str], cwd: Path, timeout: float, sweep: str, runner=subprocess.run) -> int:
    """Run the suite's pytest ``cmd``; its exit code, or a TimeoutError (an OSError: one line, exit 2)
    naming the suite and the limit when it runs longer than ``timeout`` seconds (the child is killed)."""
    try:
        return runner(cmd, cwd=cwd, timeout=timeout).returncode
    except subprocess.TimeoutExpired:
        raise TimeoutError(
            f"the benchmark suite (pytest bench --sweep={sweep}) did not finish within its limit of {timeout:g} s "
            "(BenchOptions.suite_timeout; default: the profile's predicted time x "
            f"{SUITE_ALLOWANCE:g}); no report written"
        ) from None


def run(options: BenchOptions) -> int:
    """``exo-bench bench`` in this process: the benchmark suite under pytest, then its reports."""
    full = options.full
    sweep = "full" if full else "quick"
    out = options.folder.resolve()
    limit = suite_timeout(sweep, options.suite_timeout)  # checked before any work
    command = "exo-bench bench" + (" --full" if full else "")
    with staging_dir(out) as st:
        bjson, sjson = st / benchmark_json(sweep), st / "skips.json"
        cmd = [
            sys.executable,
            "-m",
            "pytest",
            str(REPO / "bench"),
            "-q",
            "-p",
            "no:cacheprovider",
            "--benchmark-enable",
            f"--benchmark-json={bjson}",
            f"--skips-json={sjson}",
            f"--sweep={sweep}",
            "--benchmark-columns=min,median,rounds",
        ]
        print("running:", " ".join(cmd[2:]), flush=True)
        code = run_suite(cmd, REPO, limit, sweep)
        if code != 0 or not bjson.exists():
            raise ValueError(f"benchmark suite failed (pytest exit code {code}); no report written")
        write_reports(bjson, sjson, st, out, sweep, command, options.update_readme, options.published_to)
    return 0
