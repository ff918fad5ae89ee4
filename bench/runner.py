"""The main job, ``exo-bench run [SCENE...]``: run scenes, write their reports, print a summary.

Every output is first written into a staging folder inside ``reports/`` and moved into place
with an atomic rename when its scene has finished, so an error or Ctrl-C never leaves a
half-written report; the staging folder is removed on every exit path. A scene or method that
fails is recorded (one line) and the other scenes go on.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from exo_bench.bench.reporting import REPORTS, atomic_write, provenance
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
    return "\n".join(lines) + "\n"


def run_scene(scene: Scene, staging: Path) -> SceneOutcome:
    """Run one scene, writing its outputs into ``staging``; never raises for a method's failure."""
    o = SceneOutcome(scene)
    t0 = time.perf_counter()
    motion = scene.build_motion()
    o.study = run_methods(scene.name, scene.mechanism, motion, scene.motion_label(), list(scene.methods),
                          reference=scene.reference)
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
        make = {"moments": plots.moments_figure, "forces": plots.forces_figure, "kinogram": plots.kinogram_figure,
                "differences": plots.differences_figure, "overview": plots.overview_figure}
        for kind in figures:
            fig = make[kind](o.study)
            if fig is None:  # differences need two methods that ran
                o.notes.append(f"no {kind} figure: fewer than two methods ran")
                continue
            o.files.append(plots.save_figure(fig, staging / f"{scene.name}-{kind}.png"))
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
    out.mkdir(parents=True, exist_ok=True)
    d = Path(tempfile.mkdtemp(prefix=".staging-", dir=out))
    try:
        yield d
    finally:
        shutil.rmtree(d, ignore_errors=True)


def publish(files: list[Path], out: Path) -> list[Path]:
    """Move finished files from staging into ``out`` (an atomic rename each)."""
    done = []
    for f in files:
        target = out / f.name
        os.replace(f, target)
        done.append(target)
    return done


def summary_markdown(outcomes: list[SceneOutcome], command: str) -> str:
    lines = ["# Summary: every scene, every method", "", provenance(command), "",
             "Largest error: against the 50-digit reference (Lagrange in mpmath; d'Alembert in mpmath beyond sympy's "
             "reach; each scene report names it) on a subsample where the scene asks for it "
             "(`ref50`), otherwise the largest difference relative to the scene's reference method (`vs <method>`). "
             "Quantities are generalised forces of the paper's absolute coordinates.", "",
             "| scene | method | largest error | us/sample | power balance |", "|---|---|---|---|---|"]
    for o in outcomes:
        if o.error:
            lines.append(f"| {o.scene.name} | (scene failed) | {o.error} | | |")
            continue
        agree = o.study.agreement()
        for m in o.scene.methods:
            r = o.study.results[m]
            if not r.ok:
                lines.append(f"| {o.scene.name} | {m} | {'skipped: ' + r.skipped if r.skipped else 'failed: ' + r.error} | | |")
                continue
            if m in o.reference_error:
                err = f"{o.reference_error[m][1]:.1e} (ref50)"
            else:
                err = f"{agree.get(m, float('nan')):.1e} (vs {o.scene.reference})"
            if o.study.nonfinite(m):
                err += f"; **{o.study.nonfinite(m)} NaN/Inf**"
            pb = o.power_balance.get(m)
            lines.append(f"| {o.scene.name} | {m} | {err} | {r.seconds_per_sample * 1e6:.2f} | "
                         f"{'' if pb is None else f'{pb:.1e}'} |")
    return "\n".join(lines) + "\n"


def print_summary(outcomes: list[SceneOutcome]) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(title="exo-bench: scene x method")
    for col in ("scene", "method", "largest error", "us/sample", "power balance"):
        table.add_column(col, no_wrap=col != "largest error", overflow="fold")
    for row in summary_markdown(outcomes, "").splitlines():
        if row.startswith("| ") and not row.startswith("| scene |"):
            table.add_row(*[c.strip() for c in row.strip("|").split("|")])
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
    import importlib.util

    jobs = []
    for label, module, func in SUITE_JOBS:
        if importlib.util.find_spec(module) is not None:
            jobs.append((label, getattr(importlib.import_module(module), func)))
    return jobs


def run(args) -> int:
    import argparse as _argparse

    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    out = Path(args.reports) if getattr(args, "reports", None) else REPORTS
    full = bool(getattr(args, "full", False))
    names = list(args.scenes) or shipped_scene_names()
    scenes = [load_scene(n) for n in names]  # every scene is validated before anything runs
    jobs = _suite_jobs() if not args.scenes else []  # naming scenes runs just those scenes
    outcomes: list[SceneOutcome] = []
    written: list[Path] = []
    job_errors: list[str] = []
    with staging_dir(out) as staging, Progress(TextColumn("{task.description}"), BarColumn(),
                                               TextColumn("{task.completed}/{task.total}"), TimeElapsedColumn(),
                                               transient=False) as progress:
        task = progress.add_task("scenes", total=len(scenes) + len(jobs))
        for sc in scenes:
            progress.update(task, description=f"scene {sc.name}")
            try:
                o = run_scene(sc, staging)
                written += publish(o.files, out)
            except Exception as e:  # noqa: BLE001 - one scene's failure must not lose the others
                o = SceneOutcome(sc, error=one_line(e))
            outcomes.append(o)
            progress.advance(task)
        command = "exo-bench run" + (" --full" if full else "") + ("" if not args.scenes else " " + " ".join(args.scenes))
        atomic_write(staging / "summary.md", summary_markdown(outcomes, command))
        written += publish([staging / "summary.md"], out)
        for label, fn in jobs:
            progress.update(task, description=label)
            try:
                fn(_argparse.Namespace(full=full, reports=str(out)))
            except Exception as e:  # noqa: BLE001 - a failing report must not lose the others
                job_errors.append(f"{label} failed: {one_line(e)}")
            progress.advance(task)
    print_summary(outcomes)
    for p in written:
        print(f"wrote {p}")
    failed = [o for o in outcomes if o.error]
    for o in failed:
        print(f"scene {o.scene.name} failed: {o.error}")
    for line in job_errors:
        print(line)
    return 1 if failed or job_errors else 0
