"""The main job, ``exo-bench run [SCENE...]``: run scenes, write their reports, print a summary.

**Nothing half-written, nothing mixed unannounced.** Every output of a run (scene reports and
figures, and the suite's errata, benchmark and stability reports) is written into a staging
folder inside ``reports/`` and published only when the whole run has finished, by atomic renames
with SIGINT/SIGTERM held back. An error or Ctrl-C before that leaves the folder exactly as it was
(all old); the staging folder is removed on every exit path. Publishing writes ``runs.json`` and a
``summary.md`` that say "being published" first, then the files, then the final ones, so even a
``kill -9`` in that window leaves each file marked by its run and the summary saying so.

**Runs never overwrite results of a wider run.** Each run has an identifier
(:func:`bench.reporting.current_run_id`) that every report carries. ``runs.json`` keeps, per scene,
the summary rows of the run that last ran it and, per file, the run that wrote it; ``summary.md``
is made from it, so ``exo-bench run SCENE`` replaces that scene's rows and keeps every other
scene's, and lists which run produced each report file. A method that fails is recorded (one
line) and the other methods and scenes go on; a scene that fails or is refused keeps its earlier
rows and files, says why in one line on stderr, and the run exits 2.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import sys
import tempfile
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from exo_bench.bench.reporting import (REPORTS, atomic_write, current_run_id, new_run_id, provenance, run_id_of,
                                       set_run_id)
from exo_bench.bench.scenes import Scene, load_scene, shipped_scene_names
from exo_bench.bench.study import Study, finite_max, one_line, run_methods


@dataclass
class SceneOutcome:
    scene: Scene
    study: Study | None = None
    files: list[Path] = field(default_factory=list)
    power_balance: dict[str, float] = field(default_factory=dict)
    reference_error: dict[str, tuple[float, float]] = field(default_factory=dict)  # method -> (abs, rel)
    notes: list[str] = field(default_factory=list)
    error: str | None = None
    seconds: float = 0.0




def power_balance(scene: Scene, study: Study) -> dict[str, float]:
    """max |tau . qd - d(T+Pi)/dt| / max |d(T+Pi)/dt| per method, along an analytic motion."""
    from exo_bench.models.kinematics import energy_rate

    f = scene.motion_function()
    if f is None:
        return {}
    mo = study.motion
    rate = energy_rate(scene.mechanism, f, mo.t)
    scale = max(float(np.abs(rate).max()), 1e-300)
    return {m: finite_max(np.abs((study.results[m].tau * mo.qd).sum(1) - rate)) / scale
            for m in study.ok_methods()}


REFERENCE_SUBSAMPLE = 16


def reference_errors(study: Study, subsample: int = REFERENCE_SUBSAMPLE) -> dict[str, tuple[float, float]]:
    """Largest absolute and relative error of each method against the 50-digit reference
    (``bench.reference``: Lagrange in mpmath, or d'Alembert in mpmath beyond sympy's reach) on an
    evenly spaced subsample."""
    from exo_bench.bench.reference import reference

    mo = study.motion
    idx = np.unique(np.linspace(0, mo.q.shape[0] - 1, subsample).round().astype(int))
    ref, label = reference(study.mechanism, mo.q[idx], mo.qd[idx], mo.qdd[idx])
    study.reference_label = label
    scale = max(float(np.abs(ref).max()), 1e-300)
    out = {}
    for m in study.ok_methods():
        err = finite_max(np.abs(study.results[m].tau[idx] - ref))
        out[m] = (err, err / scale)
    return out


AGREEMENT = 1e-9  # methods are expected to agree to this, relative to the largest |tau|
WHY = {"matrix-paper": "it evaluates eq. (18) exactly as printed, misprints included: see reports/errata.md "
                       "(3D g^l and k^l) and reports/stability.md"}


def disagreement_notes(study: Study) -> list[str]:
    """Where a method departs from the reference by more than AGREEMENT: by how much, where, and why."""
    notes = []
    for m, rel in study.agreement().items():
        if not rel > AGREEMENT:
            continue
        d = np.abs(study.difference(m))
        d[~np.isfinite(d)] = -1.0
        s_, c = np.unravel_index(int(np.argmax(d)), d.shape)
        notes.append(f"**{m} disagrees with {study.reference}** by {rel:.1e} of the largest |tau| (largest at "
                     f"t = {study.motion.t[s_]:.4g} s, {study.force_names[c]})"
                     + (f": {WHY[m]}." if m in WHY else "."))
    return notes


def _scene_table(o: SceneOutcome) -> str:
    sc, st = o.scene, o.study
    mech = sc.mechanism
    lines = [f"# Scene `{sc.name}`", "", provenance(f"exo-bench run {sc.name}"), "",
             sc.description, "",
             f"- **mechanism**: `{mech.name}`, {mech.dim}D, {mech.nlinks} link(s), parents {list(mech.parent)}, "
             f"signs {list(mech.sign)}, total mass {mech.total_mass:.4g} kg",
             f"- **motion**: {sc.motion_label()}",
             f"- **methods**: {', '.join(sc.methods)}; agreement is measured against `{sc.reference}`",
             "- **quantities**: generalised forces of the paper's absolute coordinates "
             "(`M_phi`, `M_psi` in N·m, `F` in N), not joint moments", ""]
    lines += ["| method | status | setup s | us/sample | max rel. diff vs " + sc.reference +
              " | power balance | abs. error vs 50-digit | rel. error vs 50-digit |", "|---|---|---|---|---|---|---|---|"]
    agree = st.agreement()
    for m in sc.methods:
        r = st.results[m]
        if not r.ok:
            status = f"skipped: {r.skipped}" if r.skipped else f"failed: {r.error}"
            lines.append(f"| {m} | {status} | | | | | | |")
            continue
        nan = st.nonfinite(m)
        status = "ok" if nan == 0 else f"**{nan} NaN/Inf values** (errors over the finite entries)"
        pb = o.power_balance.get(m)
        ae, re_ = o.reference_error.get(m, (None, None))
        fmt = lambda x: "" if x is None else f"{x:.2e}"
        lines.append(f"| {m} | {status} | {r.setup_seconds:.3g} | {r.seconds_per_sample * 1e6:.2f} | {fmt(agree.get(m))} | {fmt(pb)} | "
                     f"{fmt(ae)} | {fmt(re_)} |")
    lines += ["", "`setup s`: the first call (building the model, deriving, compiling), timed apart from the batch. "
              "`power balance`: max |tau . qd - d(T+Pi)/dt| / max |d(T+Pi)/dt|, with T and Pi summed over the "
              "point masses (models/kinematics.py) and differentiated by a sixth-order central difference.", ""]
    ref = st.results.get(sc.reference)
    if ref is not None and ref.ok:
        lines += [f"Peak values along the motion ({sc.reference}):", "",
                  "| quantity | min | max | max abs |", "|---|---|---|---|"]
        for k, name in enumerate(st.force_names):
            col = ref.tau[:, k]
            lines.append(f"| {name} | {col.min():.4g} | {col.max():.4g} | {np.abs(col).max():.4g} |")
    if o.notes:
        lines += ["", "Notes:", ""] + [f"- {n}" for n in o.notes]
    if sc.motion["kind"] in ("gait", "planar-gait") and st.ok_methods():
        from exo_bench.bench.plausibility import markdown, plausibility

        lines += ["", markdown(plausibility(st)).rstrip("\n")]
    if sc.motion["kind"] == "step" and st.ok_methods():
        from exo_bench.bench.step.report import markdown as step_markdown  # the predicted step's own section
        lines += ["", step_markdown(sc, st).rstrip("\n")]
    return "\n".join(lines) + "\n"


def run_scene(scene: Scene, staging: Path, limits=None) -> SceneOutcome:
    """Run one scene, writing its outputs into ``staging``; never raises for a method's failure.
    ``limits`` (:class:`bench.resources.Limits`): a method estimated beyond them is skipped."""
    from exo_bench.bench.resources import check_samples

    o = SceneOutcome(scene)
    t0 = time.perf_counter()
    check_samples(scene.mechanism, scene.samples(), limits, f"scene {scene.name!r}")  # before the motion is built
    motion = scene.build_motion()
    o.study = run_methods(scene.name, scene.mechanism, motion, scene.motion_label(), list(scene.methods),
                          reference=scene.reference, limits=limits)
    for m, r in o.study.results.items():
        if r.ok and not np.isfinite(r.tau).all():
            o.notes.append(f"{m}: {int(np.count_nonzero(~np.isfinite(r.tau)))} NaN/Inf values in tau "
                           "(see the stability report for where this method is unusable)")
    o.notes += disagreement_notes(o.study)
    o.power_balance = power_balance(scene, o.study)
    if scene.wants("reference-error"):
        try:
            o.reference_error = reference_errors(o.study)
            o.notes.append(f"50-digit reference: {o.study.reference_label}, on {REFERENCE_SUBSAMPLE} evenly spaced samples")
        except Exception as e:  # noqa: BLE001
            reason = getattr(e, "skip_reason", None) or one_line(e)
            o.notes.append(f"50-digit reference skipped: {reason}")
    if scene.wants("table"):
        p = staging / f"{scene.name}.md"
        atomic_write(p, _scene_table(o))
        o.files.append(p)
    figures = [k for k in ("moments", "forces", "kinogram", "differences", "overview") if scene.wants(k)]
    if figures and o.study.ok_methods():
        from exo_bench.bench import plots  # matplotlib only for scenes that ask for figures
        for kind in figures:
            if kind == "kinogram" and getattr(o.study.motion, "origin", None) is not None:   # a walking motion
                from exo_bench.bench.step.figures import walking_kinogram
                fig = walking_kinogram(o.study)
            else:
                fig = plots.scene_figure(o.study, kind)
            if fig is None:  # differences need two methods that ran
                o.notes.append(f"no {kind} figure: fewer than two methods ran")
                continue
            o.files.append(plots.save_figure(fig, staging / f"{scene.name}-{kind}.png"))
    if scene.wants("equations"):
        from exo_bench.bench.equation_pages import scene_pages  # only for scenes that ask for it
        o.files += scene_pages(scene, staging)
    if scene.wants("recording"):
        from exo_bench.bench import recording  # rerun only for scenes that ask for a recording
        p = recording.write_recording(o.study, staging / f"{scene.name}.rrd")
        if recording.rerun_executable() is not None:
            recording.verify_recording(p)
        o.files.append(p)
    o.seconds = time.perf_counter() - t0
    return o


@contextmanager
def staging_dir(out: Path):
    from exo_bench.bench.output_files import clean_stale_staging, mark_owner

    out.mkdir(parents=True, exist_ok=True)
    clean_stale_staging(out)   # what a killed run left (bench/output_files.py)
    d = Path(tempfile.mkdtemp(prefix=".staging-", dir=out))
    try:
        mark_owner(d)
        yield d
    finally:
        shutil.rmtree(d, ignore_errors=True)


def publish(files: list[Path], out: Path) -> list[Path]:
    """Move finished files from staging into ``out`` (an atomic rename each); each target is
    checked first (nothing but a regular file is ever replaced: bench/output_files.py)."""
    from exo_bench.bench.output_files import output_target

    for f in files:
        output_target(out / f.name)
    done = []
    for f in files:
        target = out / f.name
        os.replace(f, target)
        done.append(target)
    return done


SUMMARY_HEADER = ("| scene | method | largest error | us/sample | power balance |", "|---|---|---|---|---|")


def scene_rows(o: SceneOutcome) -> list[list[str]]:
    """The summary rows of one scene's outcome: ``[scene, method, largest error, us/sample, power balance]``."""
    if o.error:
        return [[o.scene.name, "(scene failed)", o.error, "", ""]]
    rows = []
    agree = o.study.agreement()
    for m in o.scene.methods:
        r = o.study.results[m]
        if not r.ok:
            rows.append([o.scene.name, m, "skipped: " + r.skipped if r.skipped else "failed: " + r.error, "", ""])
            continue
        if m in o.reference_error:
            err = f"{o.reference_error[m][1]:.1e} (ref50)"
        else:
            err = f"{agree.get(m, float('nan')):.1e} (vs {o.scene.reference})"
        if o.study.nonfinite(m):
            err += f"; **{o.study.nonfinite(m)} NaN/Inf**"
        pb = o.power_balance.get(m)
        rows.append([o.scene.name, m, err, f"{r.seconds_per_sample * 1e6:.2f}", "" if pb is None else f"{pb:.1e}"])
    return rows


def _cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def summary_markdown(outcomes: list[SceneOutcome], command: str, manifest: dict | None = None,
                     folder: Path | None = None) -> str:
    """``summary.md``: every scene's rows (this run's ``outcomes`` and, from ``manifest``, the
    scenes of earlier runs, each with its run), and which run produced each report file."""
    manifest = manifest if manifest is not None else new_manifest()
    run_id = current_run_id()
    scenes = {k: dict(v) for k, v in manifest.get("scenes", {}).items()}
    for o in outcomes:
        scenes[o.scene.name] = {"run": run_id, "rows": scene_rows(o)}
    lines = ["# Summary: every scene, every method", "", provenance(command), "",
             "Largest error: against the 50-digit reference (Lagrange in mpmath; d'Alembert in mpmath beyond sympy's "
             "reach; each scene report names it) on a subsample where the scene asks for it "
             "(`ref50`), otherwise the largest difference relative to the scene's reference method (`vs <method>`). "
             "Quantities are generalised forces of the paper's absolute coordinates. `run`: the run that produced "
             "the row (a run of some scenes replaces only their rows).", ""]
    pending = [(rid, r) for rid, r in manifest.get("runs", {}).items() if r.get("status") in ("publishing", "interrupted")]
    for rid, r in pending:
        lines += [f"**Run `{rid}` (`{r.get('command', '?')}`) was interrupted while its files were being published**: "
                  f"the files marked `{rid}` below are from it, the others from earlier runs.", ""]
    lines += [SUMMARY_HEADER[0] + " run |", SUMMARY_HEADER[1] + "---|"]
    for name in sorted(scenes):
        for row in scenes[name]["rows"]:
            rid = scenes[name]["run"]
            lines.append("| " + " | ".join(_cell(c) for c in row) + " | "
                         + (f"`{rid}`" if rid != "unknown" else "unknown (before run identifiers)") + " |")
    files = manifest.get("files", {})
    names = sorted(set(files) | ({f.name for f in Path(folder).iterdir() if _is_report(f)} if folder else set()))
    names = [n for n in names if n not in (SUMMARY, MANIFEST)]
    if names:
        lines += ["", "## Report files", "",
                  "Which run produced each file of this folder (`runs.json` holds the same, machine-readable).", "",
                  "| file | run | command |", "|---|---|---|"]
        runs = manifest.get("runs", {})
        for n in names:
            own = run_id_of(Path(folder) / n) if folder and (Path(folder) / n).exists() else None
            planned = files.get(n, {}).get("run")
            rid = own or planned
            if planned and planned != own and runs.get(planned, {}).get("status") in ("publishing", "interrupted"):
                earlier = f"`{own}`" if own else "an earlier run"
                shown = (f"`{planned}` if published before the interruption, else {earlier}"
                         + (" (the file's own mark says which)" if own or n.endswith((".md", ".png")) else ""))
                rid = planned
            elif rid is None:
                shown = "unknown (written before run identifiers)"
            else:
                shown = f"`{rid}`"
            cmd = runs.get(rid, {}).get("command", "") if rid else ""
            lines.append(f"| {n} | {shown} | {f'`{cmd}`' if cmd else ''} |")
    return "\n".join(lines) + "\n"


SUMMARY, MANIFEST = "summary.md", "runs.json"


def _is_report(p: Path) -> bool:
    return p.is_file() and not p.name.startswith(".")


def new_manifest() -> dict:
    return {"format": 1, "runs": {}, "scenes": {}, "files": {}}


def read_manifest(out: Path) -> dict:
    """``runs.json`` of a reports folder; for a folder written before run identifiers, the scene
    rows of its ``summary.md`` (marked as of an unknown run)."""
    p = Path(out) / MANIFEST
    if p.is_file():   # never open a FIFO or a device (it would block or never end)
        try:
            data = json.loads(p.read_text())
            if isinstance(data, dict) and data.get("format") == 1:
                return data
        except (OSError, ValueError):
            pass
        print(f"exo-bench: warning: {p} is not a manifest this version can read; its runs are listed as unknown",
              file=sys.stderr)
    m = new_manifest()
    old = Path(out) / SUMMARY
    if old.is_file():
        try:
            text = old.read_text(errors="replace")
        except OSError:
            return m
        for line in text.splitlines():
            cells = [c.strip() for c in line.strip().strip("|").split("|")]
            if line.startswith("| ") and len(cells) >= 5 and cells[0] not in ("scene", "") and not cells[0].startswith("-"):
                m["scenes"].setdefault(cells[0], {"run": "unknown", "rows": []})["rows"].append(cells[:5])
        if m["scenes"]:
            m["runs"]["unknown"] = {"command": "a run before run identifiers", "status": "complete"}
    return m


@contextmanager
def _signals_held():
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


def publish_run(staging: Path, out: Path, outcomes: list[SceneOutcome], command: str, manifest: dict) -> list[Path]:
    """Publish every finished file of the run from ``staging`` into ``out``, with ``runs.json`` and
    ``summary.md``: first both saying the run is being published, then the files (atomic renames),
    then the final ``runs.json`` and ``summary.md``; signals are held back meanwhile."""
    run_id = current_run_id()
    files = sorted(f for f in staging.iterdir() if _is_report(f))
    manifest = json.loads(json.dumps(manifest))
    for r in manifest.setdefault("runs", {}).values():   # an earlier run killed while publishing
        if r.get("status") == "publishing":
            r["status"] = "interrupted"
    manifest.setdefault("runs", {})[run_id] = {"command": command, "status": "publishing",
                                               "finished": time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime())}
    for f in files:
        manifest.setdefault("files", {})[f.name] = {"run": run_id}
    for o in outcomes:
        if o.error and manifest.get("scenes", {}).get(o.scene.name, {}).get("rows"):
            continue   # a refused or failed scene keeps the rows of the run that last ran it
        manifest.setdefault("scenes", {})[o.scene.name] = {"run": run_id, "rows": scene_rows(o)}
    _prune(manifest, out)
    done = []
    with _signals_held():
        atomic_write(out / MANIFEST, json.dumps(manifest, indent=1))
        atomic_write(out / SUMMARY, summary_markdown([], command, manifest, out))
        done = publish(files, out)
        manifest["runs"][run_id]["status"] = "complete"
        atomic_write(out / SUMMARY, summary_markdown([], command, manifest, out))
        atomic_write(out / MANIFEST, json.dumps(manifest, indent=1))
    return done + [out / SUMMARY, out / MANIFEST]


def _prune(manifest: dict, out: Path) -> None:
    """Forget files that are no longer in the folder (and are not being published) and runs that
    no scene row and no file refers to any more."""
    files = manifest.get("files", {})
    for name in [n for n, f in files.items() if not (Path(out) / n).exists()
                 and manifest.get("runs", {}).get(f.get("run"), {}).get("status") != "publishing"]:
        del files[name]
    used = {v.get("run") for v in manifest.get("scenes", {}).values()} | {f.get("run") for f in files.values()}
    runs = manifest.get("runs", {})
    for rid in [r for r, v in runs.items() if r not in used and v.get("status") != "publishing"]:
        del runs[rid]


def record_files(out: Path, before: dict[str, int], command: str) -> None:
    """After a standalone report command (``exo-bench errata``/``bench``/``stability``) wrote into
    ``out``: mark the files it changed (``before``: name -> mtime from :func:`snapshot`) with this
    process's run in ``runs.json`` and rewrite ``summary.md``, keeping every scene's rows."""
    out = Path(out)
    if not out.is_dir():
        return
    now = snapshot(out)
    changed = [n for n, t in now.items() if before.get(n) != t and n not in (SUMMARY, MANIFEST)]
    if not changed:
        return
    manifest = read_manifest(out)
    run_id = current_run_id()
    manifest.setdefault("runs", {})[run_id] = {"command": command, "status": "complete",
                                               "finished": time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime())}
    for n in changed:
        manifest.setdefault("files", {})[n] = {"run": run_id}
    _prune(manifest, out)
    with _signals_held():
        atomic_write(out / MANIFEST, json.dumps(manifest, indent=1))
        atomic_write(out / SUMMARY, summary_markdown([], command, manifest, out))


def snapshot(out: Path) -> dict[str, int]:
    """``name -> mtime_ns`` of the report files in ``out`` (empty when it does not exist)."""
    out = Path(out)
    if not out.is_dir():
        return {}
    return {f.name: f.stat().st_mtime_ns for f in out.iterdir() if _is_report(f)}


def print_summary(outcomes: list[SceneOutcome]) -> None:
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    table = Table(title="exo-bench: scene x method")
    for col in ("scene", "method", "largest error", "us/sample", "power balance"):
        table.add_column(col, no_wrap=col != "largest error", overflow="fold")
    for o in outcomes:
        for row in scene_rows(o):
            table.add_row(*(escape(str(c)) for c in row))   # a reason's "[peers]" is text, not rich markup
    console = Console()
    if not console.is_terminal:
        console = Console(width=140)
    console.print(table)


#: Suite-wide reports the main job writes after the scenes: (label, module, function).
SUITE_JOBS = (
    ("errata (exo-bench errata)", "exo_bench.bench.errata", "run"),
    ("benchmarks (exo-bench bench)", "exo_bench.bench.bench_reports", "run"),
    ("stability (exo-bench stability)", "exo_bench.bench.stability", "run"),
)


def _suite_jobs() -> list[tuple[str, object]]:
    import importlib

    # Every suite job is part of the main job: a missing module is an installation error, raised
    # here, never a report that silently goes missing.
    return [(label, getattr(importlib.import_module(module), func)) for label, module, func in SUITE_JOBS]


class _StagingPaths:
    """A stdout that shows the final path of files the suite's jobs announce from the staging folder."""

    def __init__(self, stream, staging: Path, out: Path):
        self.stream, self.staging, self.out = stream, str(staging), str(out)

    def write(self, text: str) -> int:
        return self.stream.write(text.replace(self.staging + os.sep, self.out + os.sep).replace(self.staging, self.out))

    def flush(self) -> None:
        self.stream.flush()

    def __getattr__(self, name):
        return getattr(self.stream, name)


def run(args) -> int:
    import argparse as _argparse
    from contextlib import redirect_stdout

    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from exo_bench.bench.resources import Limits

    out = Path(args.reports) if getattr(args, "reports", None) else REPORTS
    full = bool(getattr(args, "full", False))
    names = list(args.scenes) or shipped_scene_names()
    scenes = [load_scene(n) for n in names]  # every scene is validated before anything runs
    jobs = _suite_jobs() if not args.scenes else []  # naming scenes runs just those scenes
    limits = Limits(memory=getattr(args, "max_memory", None))
    from exo_bench.bench.output_files import output_target
    for name in (SUMMARY, MANIFEST, *(f"{sc.name}.md" for sc in scenes)):   # before any work: no FIFO there
        output_target(out / name)
    set_run_id(new_run_id())
    command = "exo-bench run" + (" --full" if full else "") + ("" if not args.scenes else " " + " ".join(args.scenes))
    _warn_known_wrong(scenes)
    outcomes: list[SceneOutcome] = []
    written: list[Path] = []
    job_errors: list[str] = []
    with staging_dir(out) as staging, Progress(TextColumn("{task.description}"), BarColumn(),
                                               TextColumn("{task.completed}/{task.total}"), TimeElapsedColumn(),
                                               transient=False) as progress:
        task = progress.add_task("scenes", total=len(scenes) + len(jobs))
        for sc in scenes:
            progress.update(task, description=f"scene {sc.name}")
            staged = {f.name for f in staging.iterdir()}
            try:
                o = run_scene(sc, staging, limits)
            except Exception as e:  # noqa: BLE001 - one scene's failure must not lose the others
                o = SceneOutcome(sc, error=getattr(e, "skip_reason", None) or one_line(e))
                for f in staging.iterdir():   # its partial files never replace the earlier run's
                    if f.name not in staged and f.is_file():
                        f.unlink(missing_ok=True)
            outcomes.append(o)
            progress.advance(task)
        for label, fn in jobs:
            progress.update(task, description=label)
            try:
                with redirect_stdout(_StagingPaths(sys.stdout, staging, out)):
                    fn(_argparse.Namespace(full=full, reports=str(staging), published_to=str(out)))
            except Exception as e:  # noqa: BLE001 - a failing report must not lose the others
                job_errors.append(f"{label} failed: {one_line(e)}")
            progress.advance(task)
        if jobs or any(not o.error for o in outcomes):   # nothing ran: the folder is left exactly as it was
            written = publish_run(staging, out, outcomes, command, read_manifest(out))
    if written:   # nothing ran (every scene refused or failed): the error lines below say it all
        print_summary(outcomes)
    for p in written:
        print(f"wrote {p}")
    failed = [o for o in outcomes if o.error]
    for o in failed:   # one line each on stderr; summary.md keeps the scene's earlier rows
        print(f"exo-bench: error: scene {o.scene.name!r} failed: {o.error} (its earlier rows and files in "
              f"{str(out)!r} are kept)", file=sys.stderr)
    for line in job_errors:
        print(f"exo-bench: error: {line}", file=sys.stderr)
    return 2 if failed else 1 if job_errors else 0


def _warn_known_wrong(scenes: list[Scene]) -> None:
    """One stderr line when a scene runs a method known to be wrong (its results are in the reports)."""
    from exo_bench.bench.methods import KNOWN_WRONG

    hits = sorted({(m, sc.mechanism.dim) for sc in scenes for m in sc.methods if m in KNOWN_WRONG})
    for m, dim in hits:
        if dim == 3:
            print(f"exo-bench: warning: method {m!r}: {KNOWN_WRONG[m]}", file=sys.stderr)
            return
    if hits:
        m = hits[0][0]
        print(f"exo-bench: warning: method {m!r} is eq. (18) exactly as printed, kept to expose the paper's misprints: "
              "wrong in 3D by design (its 2D results here are the closed forms)", file=sys.stderr)
