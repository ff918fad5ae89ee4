"""``exo-bench run [SCENE...] [--full] [--reports DIR] [--max-memory SIZE]``: the main job.

Runs every shipped scene (or the named ones: then only those), writes their reports
(:mod:`exo_bench.bench.studies.scene_run`), then the suite's reports (errata, benchmarks,
stability), publishes them together (:mod:`exo_bench.bench.output.publish`) and prints a summary.
A scene or a suite job that fails is recorded in one line and the others go on.
"""

from __future__ import annotations

import argparse
import os
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager, nullcontext
from pathlib import Path
from typing import Any, TextIO

from exo_bench.bench.cli.arguments import add_max_memory, add_reports, reports_folder, subcommand
from exo_bench.bench.output.interrupts import check as check_interrupt
from exo_bench.bench.output.provenance import new_run_id, set_run_id
from exo_bench.bench.output.publish import publish_run, staging_dir
from exo_bench.bench.output.publish import check_lock_file
from exo_bench.bench.studies.options import BenchOptions
from exo_bench.bench.studies.options import ReportOptions, RunOptions, StabilityOptions
from exo_bench.bench.studies.scene_run import SceneOutcome, check_scene_files, run_scene, scene_files, scene_rows
from exo_bench.bench.studies.scenes import Scene, load_scene, shipped_scene_names
from exo_bench.bench.studies.study import one_line


def add_parser(sub: argparse._SubParsersAction) -> None:
    shipped = shipped_scene_names()  # as the loader finds them (bench/studies/scenes/*.toml), never typed
    s = subcommand(
        sub,
        "run",
        cmd_run,
        "the main job: run every scene and write the reports",
        "exo-bench run",
        f"exo-bench run {shipped[0]} --reports my-reports" if shipped else "exo-bench run --reports my-reports",
    )
    s.epilog = f"{s.epilog}\n\nshipped scenes:\n" + "\n".join(f"  {n}" for n in shipped)
    s.add_argument(
        "scenes",
        nargs="*",
        help=f"shipped scene names ({', '.join(shipped)}) or scene TOML files (default: every shipped scene)",
    )
    add_reports(s)
    s.add_argument("--full", action="store_true", help="the whole sweep in the benchmark and stability reports")
    add_max_memory(
        s,
        "skip (with the reason in the reports) a scene's method whose estimated memory exceeds SIZE "
        "(default: 80%% of the machine's available memory)",
    )


def cmd_run(args: argparse.Namespace) -> int:
    return run_main_job(
        RunOptions(
            scenes=tuple(args.scenes), reports=reports_folder(args.reports), full=args.full, max_memory=args.max_memory
        )
    )


def print_summary(outcomes: list[SceneOutcome], console: Any = None) -> None:
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    table = Table(title="exo-bench: scene x method")
    for col in ("scene", "method", "largest error", "us/sample", "power balance"):
        table.add_column(col, no_wrap=col != "largest error", overflow="fold")
    for o in outcomes:
        for row in scene_rows(o):
            table.add_row(*(escape(str(c)) for c in row))  # a reason's "[peers]" is text, not rich markup
    console = console or Console()
    if not console.is_terminal:
        console = Console(file=console.file, width=140)
    console.print(table)


def _suite_jobs() -> list[tuple[str, Callable[[Path, Path, bool], int]]]:
    """Suite-wide reports the main job writes after the scenes: (label, job(staging, out, full)).
    Every suite job is part of the main job: a missing module is an installation error, raised
    here, never a report that silently goes missing."""
    from exo_bench.bench.perf.reports import benchmark_reports
    from exo_bench.bench.studies import errata
    from exo_bench.bench.studies.stability import report as stability

    return [
        (
            "errata (exo-bench errata)",
            lambda st, out, full: errata.run(ReportOptions(reports=st, full=full, published_to=out)),
        ),
        (
            "benchmarks (exo-bench bench)",
            lambda st, out, full: benchmark_reports.run(BenchOptions(reports=st, full=full, published_to=out)),
        ),
        (
            "stability (exo-bench stability)",
            lambda st, out, full: stability.run(StabilityOptions(reports=st, full=full, published_to=out)),
        ),
    ]


class _StagingPaths:
    """A stdout that shows the final path of files the suite's jobs announce from the staging folder."""

    def __init__(self, stream: TextIO, staging: Path, out: Path) -> None:
        self.stream, self.staging, self.out = stream, str(staging), str(out)

    def write(self, text: str) -> int:
        return self.stream.write(text.replace(self.staging + os.sep, self.out + os.sep).replace(self.staging, self.out))

    def flush(self) -> None:
        self.stream.flush()

    def __getattr__(self, name: str) -> Any:
        return getattr(self.stream, name)


def main_job_folder(options: RunOptions) -> Path:
    """Where the main job publishes: the reports folder itself for the default run, its ``full/``
    folder for ``--full`` (:data:`~exo_bench.bench.output.publish.FULL_FOLDER`). A wider run has
    its own place, so the default run on a fresh clone rewrites every committed report of the folder
    (a narrower run still never overwrites a wider one: :func:`_beside_wider`)."""
    from exo_bench.bench.output.publish import FULL_FOLDER

    out = options.folder
    if not options.full:
        return out
    place = out / FULL_FOLDER
    if place.is_symlink() or (place.exists() and not place.is_dir()):
        raise ValueError(f"{place}: expected the folder of the --full run's reports, got a link or a file there")
    return place


def default_install_scene(scene: Scene) -> Scene:
    """The scene as the default run measures it: without the methods that need an optional extra
    (MuJoCo, Drake: ``MethodSpec.extra``), which only ``--full`` measures; its reference is kept."""
    from dataclasses import replace

    from exo_bench.api.methods import METHODS

    methods = tuple(m for m in scene.methods if not METHODS[m].extra or m == scene.reference)
    return scene if methods == scene.methods else replace(scene, methods=methods)


def _console(stream: TextIO) -> TextIO:
    """A stream to the terminal that stays there while fd 1 goes to the log (:func:`_raw_output_to`)."""
    try:
        real = stream.fileno() == 1
    except (AttributeError, OSError, ValueError):  # a StringIO (tests), a closed stream
        real = False
    return os.fdopen(os.dup(1), "w", buffering=1, encoding="utf-8", errors="replace") if real else stream


@contextmanager
def _raw_output_to(log: Path, staging: Path, out: Path) -> Iterator[None]:
    """Within the block everything the suite's jobs print (their own lines and their subprocesses',
    pytest-benchmark's raw tables) goes to ``log``, with the staging folder's paths shown as the
    published ones; the console keeps progress and the final summary."""
    from contextlib import redirect_stdout

    sys.stdout.flush()
    fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_APPEND | os.O_NOFOLLOW | os.O_CLOEXEC, 0o644)
    saved = os.dup(1)
    try:
        with os.fdopen(fd, "w", buffering=1, encoding="utf-8", errors="replace") as f:
            os.dup2(f.fileno(), 1)  # the subprocesses' output too (bench/perf/reports/benchmark_reports.py)
            try:
                with redirect_stdout(_StagingPaths(f, staging, out)):
                    yield
            finally:
                f.flush()
                os.dup2(saved, 1)
    finally:
        os.close(saved)


def run_main_job(options: RunOptions) -> int:
    """The main job: every scene (or the named ones), then, when no scene is named, the suite's
    reports; all published together (:mod:`exo_bench.bench.output.publish`) into
    :func:`main_job_folder`. The console shows one line per phase and a summary of what was
    written where; the raw output goes to ``main-job.log`` beside the reports."""
    import time

    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from exo_bench.api.cost_model import Limits
    from exo_bench.bench.output.files import output_target
    from exo_bench.bench.output.publish import MANIFEST, SUMMARY
    from exo_bench.bench.output.publish import MAIN_JOB_LOG

    full = options.full
    out = main_job_folder(options)
    names = list(options.scenes) or shipped_scene_names()
    scenes = [load_scene(n) for n in names]  # every scene is validated before anything runs
    if not full:
        scenes = [default_install_scene(sc) for sc in scenes]
    check_scene_files(scenes)  # no scene's reports land on the suite's or on another scene's
    jobs = _suite_jobs() if not options.scenes else []  # naming scenes runs just those scenes
    limits = Limits(memory=options.max_memory)
    for name in (SUMMARY, MANIFEST, *([MAIN_JOB_LOG] if jobs else []), *(f for sc in scenes for f in scene_files(sc))):
        output_target(out / name)  # before any work: no FIFO there
    check_lock_file(out)  # a link or FIFO planted at the folder's lock file is refused now, not after the work
    set_run_id(new_run_id())
    command = (
        "exo-bench run" + (" --full" if full else "") + ("" if not options.scenes else " " + " ".join(options.scenes))
    )
    _warn_known_wrong(scenes)
    outcomes: list[SceneOutcome] = []
    written: list[Path] = []
    job_errors: list[str] = []
    console = Console(file=_console(sys.stdout), highlight=False, soft_wrap=True)
    total = len(scenes) + len(jobs)
    console.print(f"exo-bench run: {total} phases ({len(scenes)} scenes, {len(jobs)} reports) into {out}")
    with (
        staging_dir(out) as staging,
        Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            TextColumn("{task.completed}/{task.total}"),
            TimeElapsedColumn(),
            console=console,
            transient=True,
        ) as progress,
        _raw_output_to(staging / MAIN_JOB_LOG, staging, out) if jobs else nullcontext(),
    ):
        task = progress.add_task("scenes", total=total)

        def done(label: str, t0: float, error: str | None) -> None:
            n = int(progress.tasks[0].completed) + 1
            what = f"failed: {error}" if error else "done"
            progress.console.print(f"[{n}/{total}] {label}: {what} ({time.perf_counter() - t0:.0f} s)", markup=False)
            progress.advance(task)

        for sc in scenes:
            check_interrupt()  # a signal swallowed where it landed (a finaliser) still stops the run
            progress.update(task, description=f"scene {sc.name}")
            staged = {f.name for f in staging.iterdir()}
            t0 = time.perf_counter()
            try:
                o = run_scene(sc, staging, limits)
            except Exception as e:  # noqa: BLE001 - one scene's failure must not lose the others
                o = SceneOutcome(sc, error=getattr(e, "skip_reason", None) or one_line(e))
                for f in staging.iterdir():  # its partial files never replace the earlier run's
                    if f.name not in staged and f.is_file() and f.name != MAIN_JOB_LOG:
                        f.unlink(missing_ok=True)
            outcomes.append(o)
            done(f"scene {sc.name}", t0, o.error)
        for label, fn in jobs:
            check_interrupt()
            progress.update(task, description=label)
            t0 = time.perf_counter()
            error = None
            try:
                fn(staging, out, full)
            except Exception as e:  # noqa: BLE001 - a failing report must not lose the others
                error = one_line(e)
                job_errors.append(f"{label} failed: {error}")
            done(label, t0, error)
        check_interrupt()  # nothing is published after a signal
        if jobs or any(not o.error for o in outcomes):  # nothing ran: the folder is left exactly as it was
            rows = {o.scene.name: scene_rows(o) for o in outcomes}
            written = publish_run(  # under the folder's lock: concurrent runs publish in turn, losing nothing
                staging,
                out,
                rows,
                command,
                failed=frozenset(o.scene.name for o in outcomes if o.error),
                narrower=lambda manifest: _beside_wider(outcomes, manifest, staging, out),
            )
    if written:  # nothing ran (every scene refused or failed): the error lines below say it all
        print_summary(outcomes, console)
        print_written(written, out, console)
    failed = [o for o in outcomes if o.error]
    for o in failed:  # one line each on stderr; summary.md keeps the scene's earlier rows
        print(
            f"exo-bench: error: scene {o.scene.name!r} failed: {o.error} (its earlier rows and files in "
            f"{str(out)!r} are kept)",
            file=sys.stderr,
        )
    for line in job_errors:
        print(f"exo-bench: error: {line}", file=sys.stderr)
    return 2 if failed else 1 if job_errors else 0


def print_written(written: list[Path], out: Path, console: Any) -> None:
    """What the run wrote and where, in a few lines: the reports by name, the rest counted."""
    from exo_bench.bench.output.publish import MAIN_JOB_LOG, SUMMARY

    reports = sorted(p.name for p in written if p.suffix == ".md" and p.name != SUMMARY)
    others = [p for p in written if p.suffix != ".md" and p.name != MAIN_JOB_LOG]
    console.print(f"wrote {len(written)} files into {out}:", markup=False)
    console.print(f"  open first: {out / SUMMARY}", markup=False)
    console.print(f"  reports: {', '.join(reports)}", markup=False)
    kinds = sorted({p.suffix for p in others})
    console.print(f"  beside them: {len(others)} figures, recordings and data ({', '.join(kinds)})", markup=False)
    if any(p.name == MAIN_JOB_LOG for p in written):
        console.print(f"  the raw output (benchmark tables, logs): {out / MAIN_JOB_LOG}", markup=False)


def _beside_wider(outcomes: list[SceneOutcome], manifest: dict, staging: Path, out: Path) -> frozenset[str]:
    """The scenes whose published rows measured a method that this run skipped because its engine is not
    installed here (the README's first command has no extra ``[peers]``): their staged files are renamed
    ``<name>-quick.<ext>``, to be published beside the wider run's, and their summary rows stay the wider
    run's; one stdout line each says so."""
    from exo_bench.bench.output.files import announce_narrower, quick_name
    from exo_bench.bench.studies.scene_run import lacking_here

    narrower = []
    for o in outcomes:
        lacking = lacking_here(o, manifest.get("scenes", {}).get(o.scene.name, {}).get("rows", []))
        if not lacking:
            continue
        names = {p.name: quick_name(p.name) for p in o.files}
        for p in o.files:
            p.rename(p.with_name(names[p.name]))
        o.files = [p.with_name(names[p.name]) for p in o.files]
        narrower.append(o.scene.name)
        announce_narrower(
            out,
            names,
            f"reports of scene {o.scene.name!r}",
            f"have rows of {', '.join(lacking)}, not installed here",
        )
    return frozenset(narrower)


def _warn_known_wrong(scenes: list[Scene]) -> None:
    """One stderr line when a scene runs a method known to be wrong (its results are in the reports)."""
    from exo_bench.api.methods import known_wrong_warning

    hits = sorted({(m, sc.mechanism.dim) for sc in scenes for m in sc.methods}, key=lambda h: (-h[1], h[0]))
    for m, dim in hits:
        line = known_wrong_warning(m, dim)
        if line:
            print(line, file=sys.stderr)
            return
