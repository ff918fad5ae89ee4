"""Publishing a run's reports: staging, atomic renames, ``runs.json`` and ``summary.md``, and the names the
suite's own reports take in a reports folder (named once: the main job refuses a scene that would take one).

**Nothing half-written, nothing mixed unannounced.** Every output of a run is written into a
staging folder inside the reports folder (:func:`staging_dir`) and published only when the whole
run has finished, by atomic renames with SIGINT/SIGTERM held back (:func:`publish_run`). An error or
Ctrl-C before that leaves the folder exactly as it was (all old); the staging folder is removed on
every exit path. Publishing writes ``runs.json`` and a ``summary.md`` that say "being published"
first, then the files, then the final ones, so even a ``kill -9`` in that window leaves each file
marked by its run and the summary saying so.

**Runs never overwrite results of a wider run.** Each run has an identifier
(:func:`exo_bench.bench.output.provenance.current_run_id`) that every report carries. ``runs.json``
keeps, per scene, the summary rows of the run that last ran it and, per file, the run that wrote it;
``summary.md`` is made from it, so ``exo-bench run SCENE`` replaces that scene's rows and keeps
every other scene's, and lists which run produced each report file. A report command run on its
own marks its files the same way (:func:`record_files`).

**Concurrent runs lose nothing.** Both hold the reports folder's lock while they read, merge and
write ``runs.json`` and ``summary.md`` and move their files in (one lock per reports folder,
:func:`reports_lock`, here); the work before runs unlocked, in parallel.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import shutil
import signal
import stat
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from exo_bench.bench.output.provenance import current_run_id, provenance, run_id_of
from exo_bench.models.files import atomic_write


# The files the suite's own reports take in a reports folder, named once.

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


# One lock per reports folder: runs that publish into one folder do it one after the other.

#: The lock file in every reports folder (hidden: it is not a report).
LOCK_NAME = ".exo-bench.lock"
#: A run that has waited this long for the lock says so, once.
NOTICE_AFTER_S = 5.0
#: How often a waiting run tries the lock again.
POLL_S = 0.05


def _stderr(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def _refused(path: Path, mode: int) -> ValueError:
    from exo_bench.models.files import kind_of

    if stat.S_ISLNK(mode):
        return ValueError(
            f"{path}: is a symlink (to {os.path.realpath(path)!r}); the reports folder's lock file is never "
            "opened through a link (remove it)"
        )
    return ValueError(f"{path}: is {kind_of(mode)}; the reports folder's lock file must be a regular file (remove it)")


def check_lock_file(folder: Path) -> None:
    """Refuse, before any work, what :func:`open_lock_file` would refuse (without making the file)."""
    path = Path(folder) / LOCK_NAME
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return
    except OSError as e:
        if e.errno == errno.ENOTDIR:  # the folder is made later, or refused as a folder
            return
        raise ValueError(f"{path}: cannot check the reports folder's lock file ({e.strerror or e})") from None
    if not stat.S_ISREG(mode):
        raise _refused(path, mode)


def open_lock_file(folder: Path) -> int:
    """The descriptor of ``folder``'s lock file, made if missing; never through a link, never a
    FIFO, a device or a folder (a ValueError line names what is there)."""
    path = Path(folder) / LOCK_NAME
    flags = os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC
    try:
        fd = os.open(path, flags, 0o666)
    except OSError as e:
        try:
            mode = os.lstat(path).st_mode
        except OSError:
            mode = stat.S_IFREG
        if e.errno in (errno.ELOOP, errno.EISDIR) and not stat.S_ISREG(mode):
            raise _refused(path, mode) from None
        raise ValueError(f"{path}: cannot open the reports folder's lock file ({e.strerror or e})") from None
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        raise _refused(path, mode)
    return fd


def _holder(fd: int) -> str:
    """What the lock file says about its holder ("process 123 on host (exo-bench run a)"), or ""."""
    try:
        text = os.pread(fd, 4096, 0).decode("utf-8", errors="replace").strip()
    except OSError:
        return ""
    return text.splitlines()[0] if text else ""


def _mark_holder(fd: int, command: str) -> None:
    import socket

    line = f"process {os.getpid()} on {socket.gethostname()} ({command})\n".encode("utf-8", errors="replace")
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, line, 0)
    except OSError:  # the mark is informative only; the lock is what counts
        pass


@contextmanager
def reports_lock(
    folder: Path,
    command: str = "",
    *,
    notice_after: float = NOTICE_AFTER_S,
    clock: Callable[[], float] = time.monotonic,
    pause: Callable[[float], None] = time.sleep,
    say: Callable[[str], None] = _stderr,
) -> Iterator[None]:
    """Hold ``folder``'s lock for the block. Waits while another process holds it (Ctrl-C and
    SIGTERM still end the wait) and says so in one line once it has waited ``notice_after``
    seconds of ``clock``; ``pause`` sleeps between tries. Not reentrant: a process takes it once."""
    folder = Path(folder)
    fd = open_lock_file(folder)
    try:
        start, told = clock(), False
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                pass
            if not told and clock() - start >= notice_after:
                holder = _holder(fd) or "another process"
                say(
                    f"exo-bench: waiting for {str(folder / LOCK_NAME)!r}: {holder} is publishing into the same "
                    "reports folder; this run publishes when it is done"
                )
                told = True
            pause(POLL_S)
        _mark_holder(fd, command)
        yield
    finally:
        os.close(fd)  # releases the lock


@contextmanager
def staging_dir(out: Path) -> Iterator[Path]:
    from exo_bench.bench.output.files import clean_stale_staging, mark_owner

    out.mkdir(parents=True, exist_ok=True)
    clean_stale_staging(out)  # what a killed run left (bench/output/files.py)
    d = Path(tempfile.mkdtemp(prefix=".staging-", dir=out))
    try:
        mark_owner(d)
        yield d
    finally:
        shutil.rmtree(d, ignore_errors=True)


def publish(files: list[Path], out: Path) -> list[Path]:
    """Move finished files from staging into ``out`` (an atomic rename each); each target is
    checked first (nothing but a regular file is ever replaced: bench/output/files.py)."""
    from exo_bench.bench.output.files import move_into, output_target

    for f in files:
        output_target(out / f.name)
    return [move_into(f, out / f.name) for f in files]  # never through a link; a replaced file keeps its mode


SUMMARY_HEADER = ("| scene | method | largest error | us/sample | power balance |", "|---|---|---|---|---|")


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def summary_markdown(command: str, manifest: dict | None = None, folder: Path | None = None) -> str:
    """``summary.md``: every scene's rows (from ``manifest``: this run's and earlier runs' scenes,
    each with its run), and which run produced each report file."""
    manifest = manifest if manifest is not None else new_manifest()
    scenes = {k: dict(v) for k, v in manifest.get("scenes", {}).items()}
    lines = [
        "# Summary: every scene, every method",
        "",
        provenance(command),
        "",
        "Largest error: against the 50-digit reference (Lagrange in mpmath; d'Alembert in mpmath beyond sympy's "
        "reach; each scene report names it) on a subsample where the scene asks for it "
        "(`ref50`), otherwise the largest difference relative to the scene's reference method (`vs <method>`). "
        "Quantities are generalised forces of the paper's absolute coordinates. `run`: the run that produced "
        "the row (a run of some scenes replaces only their rows).",
        "",
    ]
    pending = [
        (rid, r) for rid, r in manifest.get("runs", {}).items() if r.get("status") in ("publishing", "interrupted")
    ]
    for rid, r in pending:
        lines += [
            f"**Run `{rid}` (`{r.get('command', '?')}`) was interrupted while its files were being published**: "
            f"the files marked `{rid}` below are from it, the others from earlier runs.",
            "",
        ]
    lines += [SUMMARY_HEADER[0] + " run |", SUMMARY_HEADER[1] + "---|"]
    for name in sorted(scenes):
        for row in scenes[name]["rows"]:
            rid = scenes[name]["run"]
            lines.append(
                "| "
                + " | ".join(_cell(c) for c in row)
                + " | "
                + (f"`{rid}`" if rid != "unknown" else "unknown (before run identifiers)")
                + " |"
            )
    files = manifest.get("files", {})
    names = sorted(set(files) | ({f.name for f in Path(folder).iterdir() if _is_report(f)} if folder else set()))
    names = [n for n in names if n not in (SUMMARY, MANIFEST)]
    if names:
        lines += [
            "",
            "## Report files",
            "",
            "Which run produced each file of this folder (`runs.json` holds the same, machine-readable).",
            "",
            "| file | run | command |",
            "|---|---|---|",
        ]
        runs = manifest.get("runs", {})
        for n in names:
            own = run_id_of(Path(folder) / n) if folder and (Path(folder) / n).exists() else None
            planned = files.get(n, {}).get("run")
            rid = own or planned
            if planned and planned != own and runs.get(planned, {}).get("status") in ("publishing", "interrupted"):
                earlier = f"`{own}`" if own else "an earlier run"
                shown = f"`{planned}` if published before the interruption, else {earlier}" + (
                    " (the file's own mark says which)" if own or n.endswith((".md", ".png")) else ""
                )
                rid = planned
            elif rid is None:
                shown = "unknown (written before run identifiers)"
            else:
                shown = f"`{rid}`"
            cmd = runs.get(rid, {}).get("command", "") if rid else ""
            lines.append(f"| {n} | {shown} | {f'`{cmd}`' if cmd else ''} |")
    return "\n".join(lines) + "\n"


def _is_report(p: Path) -> bool:
    return p.is_file() and not p.name.startswith(".")


def new_manifest() -> dict:
    return {"format": 1, "runs": {}, "scenes": {}, "files": {}}


def read_manifest(out: Path) -> dict:
    """``runs.json`` of a reports folder; for a folder written before run identifiers, the scene
    rows of its ``summary.md`` (marked as of an unknown run)."""
    p = Path(out) / MANIFEST
    if p.is_file():  # never open a FIFO or a device (it would block or never end)
        try:
            data = json.loads(p.read_text())
        except (OSError, ValueError):
            data = None
        if isinstance(data, dict) and data.get("format") == 1:
            from exo_bench.bench.output.json_shape import check_manifest

            return check_manifest(data, p)  # every field it reads has its type, or one line names it
        print(
            f"exo-bench: warning: {p} is not a manifest this version can read; its runs are listed as unknown",
            file=sys.stderr,
        )
    m = new_manifest()
    old = Path(out) / SUMMARY
    if old.is_file():
        try:
            text = old.read_text(errors="replace")
        except OSError:
            return m
        for line in text.splitlines():
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if (
                line.startswith("| ")
                and len(cells) >= 5
                and cells[0] not in ("scene", "")
                and not cells[0].startswith("-")
            ):
                m["scenes"].setdefault(cells[0], {"run": "unknown", "rows": []})["rows"].append(cells[:5])
        if m["scenes"]:
            m["runs"]["unknown"] = {"command": "a run before run identifiers", "status": "complete"}
    return m


@contextmanager
def _signals_held() -> Iterator[None]:
    """SIGINT and SIGTERM wait until the block ends (publishing is a few renames)."""
    sigs = {signal.SIGINT, signal.SIGTERM}
    try:
        old = signal.pthread_sigmask(signal.SIG_BLOCK, sigs)
    except (AttributeError, ValueError, OSError):
        old = None
    try:
        yield
    finally:
        if old is not None:
            signal.pthread_sigmask(signal.SIG_SETMASK, old)


def publish_run(
    staging: Path,
    out: Path,
    scene_rows: dict[str, list[list[str]]],
    command: str,
    failed: frozenset[str] = frozenset(),
    narrower: Callable[[dict], frozenset[str]] | None = None,
) -> list[Path]:
    """Publish every finished file of the run from ``staging`` into ``out``, with ``runs.json`` and
    ``summary.md``: first both saying the run is being published, then the files (atomic renames),
    then the final ``runs.json`` and ``summary.md``; signals are held back meanwhile.

    All of it under the folder's lock (:func:`exo_bench.bench.output.publish.reports_lock`):
    runs publishing into one folder at once go one after the other, and each reads ``runs.json``
    as the one before left it and merges its own rows and files into it, so none is lost.
    ``failed`` scenes keep their earlier rows; so do the scenes ``narrower(manifest)`` returns
    (called under the lock with the folder's current manifest: bench/cli/run.py renames their
    staged files to go beside the wider run's)."""
    with reports_lock(out, command):
        manifest = read_manifest(out)
        kept = narrower(manifest) if narrower is not None else frozenset()
        return _publish_locked(staging, out, scene_rows, command, manifest, failed | kept)


def _publish_locked(
    staging: Path, out: Path, scene_rows: dict[str, list[list[str]]], command: str, manifest: dict, keep: frozenset[str]
) -> list[Path]:
    run_id = current_run_id()
    files = sorted(f for f in staging.iterdir() if _is_report(f))
    manifest = json.loads(json.dumps(manifest))
    for r in manifest.setdefault("runs", {}).values():  # an earlier run killed while publishing
        if r.get("status") == "publishing":
            r["status"] = "interrupted"
    manifest.setdefault("runs", {})[run_id] = {
        "command": command,
        "status": "publishing",
        "finished": time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime()),
    }
    for f in files:
        manifest.setdefault("files", {})[f.name] = {"run": run_id}
    for name, rows in scene_rows.items():
        if name in keep and manifest.get("scenes", {}).get(name, {}).get("rows"):
            continue  # a refused, failed or narrower scene keeps the rows of the run that last ran it
        manifest.setdefault("scenes", {})[name] = {"run": run_id, "rows": rows}
    _prune(manifest, out)
    done = []
    with _signals_held():
        atomic_write(out / MANIFEST, json.dumps(manifest, indent=1))
        atomic_write(out / SUMMARY, summary_markdown(command, manifest, out))
        done = publish(files, out)
        manifest["runs"][run_id]["status"] = "complete"
        atomic_write(out / SUMMARY, summary_markdown(command, manifest, out))
        atomic_write(out / MANIFEST, json.dumps(manifest, indent=1))
    return done + [out / SUMMARY, out / MANIFEST]


def _prune(manifest: dict, out: Path) -> None:
    """Forget files that are no longer in the folder (and are not being published) and runs that
    no scene row and no file refers to any more."""
    files = manifest.get("files", {})
    for name in [
        n
        for n, f in files.items()
        if not (Path(out) / n).exists() and manifest.get("runs", {}).get(f.get("run"), {}).get("status") != "publishing"
    ]:
        del files[name]
    used = {v.get("run") for v in manifest.get("scenes", {}).values()} | {f.get("run") for f in files.values()}
    runs = manifest.get("runs", {})
    for rid in [r for r, v in runs.items() if r not in used and v.get("status") != "publishing"]:
        del runs[rid]


def record_files(out: Path, before: dict[str, int], command: str) -> None:
    """After a standalone report command (``exo-bench errata``/``bench``/``stability``) wrote into
    ``out``: mark the files it changed (``before``: name -> mtime from :func:`snapshot`) with this
    process's run in ``runs.json`` and rewrite ``summary.md``, keeping every scene's rows. Under the
    folder's lock, like :func:`publish_run`; a changed file whose own mark names another run was
    published meanwhile by that run and stays its."""
    out = Path(out)
    if not out.is_dir():
        return
    run_id = current_run_id()

    def changed_here() -> list[str]:
        return [
            n
            for n, t in snapshot(out).items()
            if before.get(n) != t and n not in (SUMMARY, MANIFEST) and run_id_of(out / n) in (None, run_id)
        ]

    if not changed_here():  # nothing written (an interrupted command): the folder stays as it was, no lock file
        return
    with reports_lock(out, command):
        changed = changed_here()
        if not changed:
            return
        manifest = read_manifest(out)
        manifest.setdefault("runs", {})[run_id] = {
            "command": command,
            "status": "complete",
            "finished": time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime()),
        }
        for n in changed:
            manifest.setdefault("files", {})[n] = {"run": run_id}
        _prune(manifest, out)
        with _signals_held():
            atomic_write(out / MANIFEST, json.dumps(manifest, indent=1))
            atomic_write(out / SUMMARY, summary_markdown(command, manifest, out))


def snapshot(out: Path) -> dict[str, int]:
    """``name -> mtime_ns`` of the report files in ``out`` (empty when it does not exist)."""
    out = Path(out)
    if not out.is_dir():
        return {}
    return {f.name: f.stat().st_mtime_ns for f in out.iterdir() if _is_report(f)}
