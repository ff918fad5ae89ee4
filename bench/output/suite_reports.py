"""The files the suite's own reports take in a reports folder, named once.

Their writers take their names from here (publish.py: ``summary.md``, ``runs.json``; the errata,
benchmark, stability and equations-size reports), and the main job refuses, before any work, a
scene whose name would take one of them (:func:`exo_bench.bench.studies.scene_run.check_scene_files`):
a scene named ``summary`` or ``errata`` would otherwise replace that report or lose its own page.
"""

from __future__ import annotations

#: The main job's summary of every scene, and the manifest it is made from (bench/output/publish.py).
SUMMARY = "summary.md"
MANIFEST = "runs.json"
#: The folder, inside the reports folder, of the wider runs: ``exo-bench run --full`` (the whole sweep
#: and the methods of the optional extras, MuJoCo and Drake) publishes there, so the default run
#: (``exo-bench run``, the README's first command) always rewrites the reports folder itself and
#: never meets a wider run's files there (bench/cli/run.py).
FULL_FOLDER = "full"
#: The main job's raw output (pytest-benchmark's tables, the stability study's log), kept out of the
#: console and published with the reports.
MAIN_JOB_LOG = "main-job.log"
#: ``exo-bench errata`` (bench/studies/errata.py).
ERRATA = "errata.md"
#: ``exo-bench bench`` (bench/perf/reports/benchmark_reports.py), and its rows per sweep.
BENCHMARK_REPORTS = (
    "paper_table.md",
    "error_vs_runtime.md",
    "error_vs_runtime.png",
    "scaling.md",
    "scaling.png",
    "derivatives.md",  # issue 36's derivatives benchmark (bench/perf/reports/derivatives.py)
    "derivatives.png",
)
SWEEPS = ("quick", "full")
#: ``exo-bench stability`` (bench/studies/stability/report.py and forward_figures.py).
STABILITY_REPORT = "stability.md"
STABILITY_FIGURES = ("stability-families.png", "stability-conditioning.png")
STABILITY_FORWARD_FIGURES = ("stability-work-precision.png", "stability-stiff.png")
#: ``exo-bench equations --size-report`` (bench/studies/equations_size.py).
EQUATIONS_SIZE = ("equations_size.md", "equations_size.png")


def benchmark_json(sweep: str) -> str:
    """The benchmark rows of a sweep (``quick`` or ``full``), published beside the reports."""
    return f"benchmarks-{sweep}.json"


def suite_files() -> frozenset[str]:
    """Every file name the suite's reports may take in a reports folder, with the
    ``<name>-quick.<ext>`` a narrower run writes beside a wider one's (bench/output/files.py)."""
    from exo_bench.bench.output.files import quick_name

    names = {
        SUMMARY,
        MANIFEST,
        MAIN_JOB_LOG,
        ERRATA,
        *BENCHMARK_REPORTS,
        *(benchmark_json(s) for s in SWEEPS),
        STABILITY_REPORT,
        *STABILITY_FIGURES,
        *STABILITY_FORWARD_FIGURES,
        *EQUATIONS_SIZE,
    }
    return frozenset(names | {quick_name(n) for n in names})
