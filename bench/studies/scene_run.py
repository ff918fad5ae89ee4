"""One scene of the main job: its study (every method along the motion), its report, figures,
equations pages and recording, written into the run's staging folder; and its rows of the summary.

The main job that runs the scenes and publishes their files is :mod:`exo_bench.bench.cli.run`;
publishing is :mod:`exo_bench.bench.output.publish`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from exo_bench.bench.output.provenance import provenance
from exo_bench.models.files import atomic_write
from exo_bench.bench.studies.scene_motion import note as forces_note
from exo_bench.bench.studies.scenes import Scene
from exo_bench.bench.studies.study import Study, finite_max, one_line, run_methods
from exo_bench.models.files import markdown_code
from exo_bench.models.files import file_stem

if TYPE_CHECKING:
    from matplotlib.figure import Figure


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
    external: bool = False  # its methods were given the motion's external forces (bench/studies/scene_motion.py)

    def ran(self) -> Study:
        """The scene's study; a scene that failed before its methods ran has none (ValueError)."""
        if self.study is None:
            raise ValueError(f"scene {self.scene.name!r}: no study ({self.error or 'its methods did not run'})")
        return self.study


def _us(seconds: float | None) -> str:
    """Seconds per sample as microseconds, ``.2f``; empty when not measured."""
    return "" if seconds is None else f"{seconds * 1e6:.2f}"


def power_balance(scene: Scene, study: Study) -> dict[str, float]:
    """``max |tau . qd - d(T+Pi)/dt| / max |d(T+Pi)/dt|`` per method, along an analytic motion."""
    from exo_bench.models.mechanism.kinematics import energy_rate

    f = scene.motion_function()
    if f is None:
        return {}
    mo = study.motion
    rate = energy_rate(scene.mechanism, f, mo.t)
    scale = max(float(np.abs(rate).max()), 1e-300)
    return {m: finite_max(np.abs((study.tau(m) * mo.qd).sum(1) - rate)) / scale for m in study.ok_methods()}


REFERENCE_SUBSAMPLE = 16


def reference_errors(study: Study, subsample: int = REFERENCE_SUBSAMPLE) -> dict[str, tuple[float, float]]:
    """Largest absolute and relative error of each method against the 50-digit reference
    (``bench.reference``: Lagrange in mpmath, or d'Alembert in mpmath beyond sympy's reach) on an
    evenly spaced subsample."""
    from exo_bench.bench.studies.study import reference

    mo = study.motion
    idx = np.unique(np.linspace(0, mo.q.shape[0] - 1, subsample).round().astype(int))
    ref, label = reference(study.mechanism, mo.q[idx], mo.qd[idx], mo.qdd[idx])
    study.reference_label = label
    scale = max(float(np.abs(ref).max()), 1e-300)
    out = {}
    for m in study.ok_methods():
        err = finite_max(np.abs(study.tau(m)[idx] - ref))
        out[m] = (err, err / scale)
    return out


AGREEMENT = 1e-9  # methods are expected to agree to this, relative to the largest |tau|


def _why_it_disagrees(method: str) -> str | None:
    from exo_bench.api import METHODS

    return METHODS[method].why_it_disagrees if method in METHODS else None


def disagreement_notes(study: Study) -> list[str]:
    """Where a method departs from the reference by more than AGREEMENT: by how much, where, and why."""
    notes = []
    for m, rel in study.agreement().items():
        if not rel > AGREEMENT:
            continue
        d = np.abs(study.difference(m))
        d[~np.isfinite(d)] = -1.0
        s_, c = np.unravel_index(int(np.argmax(d)), d.shape)
        notes.append(
            f"**{m} disagrees with {study.reference}** by {rel:.1e} of the largest |tau| (largest at "
            f"t = {study.motion.t[s_]:.4g} s, {study.force_names[c]})"
            + (f": {why}." if (why := _why_it_disagrees(m)) else ".")
        )
    return notes


def _scene_table(o: SceneOutcome) -> str:
    sc, st = o.scene, o.ran()
    mech = sc.mechanism
    lines = [
        f"# Scene `{sc.name}`",
        "",
        provenance(f"exo-bench run {sc.name}"),
        "",
        sc.description,
        "",
        f"- **mechanism**: {markdown_code(mech.name)}, {mech.dim}D, {mech.nlinks} link(s), parents {list(mech.parent)}, "
        f"signs {list(mech.sign)}, total mass {mech.total_mass:.4g} kg",
        f"- **motion**: {sc.motion_label()}",
        f"- **methods**: {', '.join(sc.methods)}; agreement is measured against `{sc.reference}`",
        "- **quantities**: generalised forces of the paper's absolute coordinates "
        "(`M_phi`, `M_psi` in N·m, `F` in N), not joint moments"
        + ("; with the motion's external forces (notes)" if o.external else ""),
        "",
    ]
    lines += [
        "| method | status | setup s | us/sample | max rel. diff vs "
        + sc.reference
        + " | power balance | abs. error vs 50-digit | rel. error vs 50-digit |",
        "|---|---|---|---|---|---|---|---|",
    ]
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
        setup = "" if r.setup_seconds is None else f"{r.setup_seconds:.3g}"
        lines.append(
            f"| {m} | {status} | {setup} | {_us(r.seconds_per_sample)} | {fmt(agree.get(m))} | {fmt(pb)} | "
            f"{fmt(ae)} | {fmt(re_)} |"
        )
    lines += [
        "",
        "`setup s`: the first call (building the model, deriving, compiling), timed apart from the batch. "
        "`power balance`: max |tau . qd - d(T+Pi)/dt| / max |d(T+Pi)/dt|, with T and Pi summed over the "
        "point masses (models/mechanism/kinematics.py) and differentiated by a sixth-order central difference.",
        "",
    ]
    ref = st.results.get(sc.reference)
    if ref is not None and ref.tau is not None:
        lines += [
            f"Peak values along the motion ({sc.reference}):",
            "",
            "| quantity | min | max | max abs |",
            "|---|---|---|---|",
        ]
        for k, name in enumerate(st.force_names):
            col = ref.tau[:, k]
            lines.append(f"| {name} | {col.min():.4g} | {col.max():.4g} | {np.abs(col).max():.4g} |")
    if o.notes:
        lines += ["", "Notes:", ""] + [f"- {n}" for n in o.notes]
    if sc.motion["kind"] in ("gait", "planar-gait"):
        from exo_bench.bench.studies.plausibility import markdown, plausibility

        loads = plausibility(st)
        if loads is not None:  # None when no method produced tau
            lines += ["", markdown(loads).rstrip("\n")]
    if sc.motion["kind"] == "step" and st.ok_methods():
        from exo_bench.bench.studies.step.report import markdown as step_markdown  # the predicted step's own section

        lines += ["", step_markdown(sc, st).rstrip("\n")]
    if sc.motion["kind"] == "stride":  # the stride against Winter's, its verdicts and actuator sizing
        from exo_bench.bench.studies.stride import report as stride_report, scene as stride_scene

        figure = stride_scene.extra_files(sc)
        # without the floor (no external forces) the report says what the table shows instead
        tau = st.tau(sc.reference) if st.results[sc.reference].ok and not o.external else None
        section = stride_report.markdown(mech, sc.motion["stored"], figure[0] if figure else None, tau=tau)
        lines += ["", section.rstrip("\n")]
    return "\n".join(lines) + "\n"


#: The outputs drawn as figures, one PNG each.
FIGURES = ("moments", "forces", "kinogram", "differences", "overview")


def scene_file(scene: Scene, output: str) -> str:
    """The file of one output of a scene (``table``, a figure, ``recording``), named by the
    file-name encoder (models/files.py ``file_stem``) from the scene's name."""
    stem = file_stem(scene.name)
    if output == "table":
        return f"{stem}.md"
    if output == "recording":
        return f"{stem}.rrd"
    if output in FIGURES:
        return f"{stem}-{output}.png"
    raise ValueError(f"scene {scene.name!r}: output {output!r} writes no file of its own")


def scene_files(scene: Scene) -> list[str]:
    """Every file the scene's outputs write into the reports folder (its ``equations`` pages:
    :func:`exo_bench.bench.output.equation_pages.page_names`)."""
    from exo_bench.bench.output.equation_pages import page_names

    names = [scene_file(scene, k) for k in ("table", *FIGURES, "recording") if scene.wants(k)]
    if scene.motion["kind"] == "stride":
        from exo_bench.bench.studies.stride.scene import extra_files

        names += extra_files(scene)
    return names + (list(page_names(file_stem(scene.name))) if scene.wants("equations") else [])


def check_scene_files(scenes: list[Scene]) -> None:
    """Refuse, before any work, scenes whose reports would land on another's: a scene named like
    one of the suite's own reports (bench/output/publish.py: ``summary``, ``errata``, ...,
    with their ``-quick`` names), or like a file that other scenes write (their ``-quick`` and
    ``equations-`` pages), and two scenes of one run with one file name. Names are compared as
    the file-name encoder writes them, ignoring case (file systems may fold it)."""
    from exo_bench.bench.output.equation_pages import page_names
    from exo_bench.bench.output.files import quick_name
    from exo_bench.bench.output.publish import suite_files

    reserved = {Path(n).stem.casefold(): n for n in sorted(suite_files())}
    pages_prefix = Path(page_names("x")[0]).stem.removesuffix("x").casefold()  # "equations-"
    quick_suffix = Path(quick_name("x.md")).stem.removeprefix("x").casefold()  # "-quick"
    taken: dict[str, Scene] = {}
    for sc in scenes:
        stem = file_stem(sc.name)
        what = f"{sc.path}: field 'name': expected a scene name"
        if stem.casefold() in reserved:
            raise ValueError(
                f"{what} other than the suite's own reports, got {sc.name!r}, which would take the name of the "
                f"suite's own report {reserved[stem.casefold()]}"
            )
        if stem.casefold().startswith(pages_prefix) or stem.casefold().endswith(quick_suffix):
            kind = "equations pages" if stem.casefold().startswith(pages_prefix) else "narrower runs' reports"
            raise ValueError(
                f"{what} that does not start with {pages_prefix!r} or end with {quick_suffix!r}, got {sc.name!r}, "
                f"which would take the name of other scenes' {kind}"
            )
        for f in [f"{stem}.md", *scene_files(sc)]:  # its summary rows and page go by its name, output or not
            other = taken.get(f.casefold())
            if other is not None and other is not sc:
                if Path(other.path).resolve() == Path(sc.path).resolve():
                    raise ValueError(f"{sc.path}: named twice in this run; expected each scene once")
                raise ValueError(
                    f"{what} of its own in this run, got {sc.name!r}, which writes {f} as scene {other.name!r} "
                    f"({other.path}) does (file names compared as written, ignoring case)"
                )
            taken[f.casefold()] = sc


def run_scene(scene: Scene, staging: Path, limits=None) -> SceneOutcome:
    """Run one scene, writing its outputs into ``staging``; never raises for a method's failure.
    ``limits`` (:class:`exo_bench.api.cost_model.Limits`): a method estimated beyond them is skipped."""
    from exo_bench.api.cost_model import check_samples

    o = SceneOutcome(scene)
    t0 = time.perf_counter()
    check_samples(scene.mechanism, scene.samples(), limits, f"scene {scene.name!r}")  # before the motion is built
    motion = scene.build_motion()
    forces = scene.external_forces()  # the stride's floor: every method's loads include it
    o.study = study = run_methods(
        scene.name,
        scene.mechanism,
        motion,
        scene.motion_label(),
        list(scene.methods),
        reference=scene.reference,
        limits=limits,
        f_ext=None if forces is None else forces.f_ext,
    )
    o.external = forces is not None
    if forces is not None:
        o.notes.append(forces_note(forces, study))
    for m, r in study.results.items():
        if r.tau is not None and not np.isfinite(r.tau).all():
            o.notes.append(
                f"{m}: {int(np.count_nonzero(~np.isfinite(r.tau)))} NaN/Inf values in tau "
                "(see the stability report for where this method is unusable)"
            )
    o.notes += disagreement_notes(study)
    o.power_balance = power_balance(scene, study)
    if scene.wants("reference-error") and forces is not None:
        o.notes.append("50-digit reference skipped: it has no external forces")
    elif scene.wants("reference-error"):
        try:
            o.reference_error = reference_errors(study)
            o.notes.append(
                f"50-digit reference: {study.reference_label}, on {REFERENCE_SUBSAMPLE} evenly spaced samples"
            )
        except Exception as e:  # noqa: BLE001
            reason = getattr(e, "skip_reason", None) or one_line(e)
            o.notes.append(f"50-digit reference skipped: {reason}")
    if scene.wants("table"):
        p = staging / scene_file(scene, "table")
        atomic_write(p, _scene_table(o))
        o.files.append(p)
    figures = [k for k in FIGURES if scene.wants(k)]
    if figures and study.ok_methods():
        # matplotlib only for scenes that ask for figures
        from exo_bench.bench.output.figures import scene_figures as plots
        from exo_bench.bench.output.provenance import save_figure

        for kind in figures:
            fig: Figure | None
            if kind == "kinogram" and getattr(study.motion, "origin", None) is not None:  # a walking motion
                from exo_bench.bench.studies.step.scene import walking_kinogram

                fig = walking_kinogram(study)
            elif kind == "kinogram" and scene.motion["kind"] == "stride":  # the stride walks from O
                from exo_bench.bench.studies.stride.scene import kinogram

                fig = kinogram(scene)
            else:
                fig = plots.scene_figure(study, kind)
            if fig is None:  # differences need two methods that ran
                o.notes.append(f"no {kind} figure: fewer than two methods ran")
                continue
            o.files.append(save_figure(fig, staging / scene_file(scene, kind)))
    if scene.motion["kind"] == "stride":
        from exo_bench.bench.studies.stride.scene import write_figures

        o.files += write_figures(scene, staging)
    if scene.wants("equations"):
        from exo_bench.bench.output.equation_pages import scene_pages  # only for scenes that ask for it

        o.files += scene_pages(scene, staging)
    if scene.wants("recording"):
        from exo_bench.bench.output import recording  # rerun only for scenes that ask for a recording
        from exo_bench.bench.studies.plausibility import plausibility, text

        loads = plausibility(study)
        loads_text: str | None
        extra = None
        if scene.motion["kind"] == "stride":  # the stride's verdicts, and its actuators over time
            from exo_bench.bench.studies.stride import report as stride_report, scene as stride_scene

            loads_text = stride_report.text(scene.mechanism, scene.motion["stored"])
            extra = stride_scene.log_stride(scene)
        elif (
            loads is not None and getattr(study.motion, "origin", None) is not None
        ):  # the predicted step: its own loads text
            from exo_bench.bench.studies.step.report import text as step_text

            loads_text = step_text(study)
        else:
            loads_text = None if loads is None else text(loads)
        p = recording.write_recording(study, staging / scene_file(scene, "recording"), loads=loads_text, extra=extra)
        if recording.rerun_executable() is not None:
            recording.verify_recording(p)
        o.files.append(p)
    o.seconds = time.perf_counter() - t0
    return o


def lacking_here(o: SceneOutcome, earlier: list[list[str]]) -> list[str]:
    """The methods that ``earlier`` (the scene's summary rows of the run published before, from
    ``runs.json``) measured and that this run skipped because their engine is not installed here.
    When there are any, this run is narrower than the published one: it must not replace it."""
    measured = {r[1] for r in earlier if len(r) >= 3 and not r[2].startswith(("skipped:", "failed:", "(scene"))}
    if o.error or o.study is None:
        return []
    return [m for m, r in o.study.results.items() if r.missing_extra and m in measured]


def scene_rows(o: SceneOutcome) -> list[list[str]]:
    """The summary rows of one scene's outcome: ``[scene, method, largest error, us/sample, power balance]``."""
    if o.error:
        return [[o.scene.name, "(scene failed)", o.error, "", ""]]
    rows = []
    study = o.ran()
    agree = study.agreement()
    for m in o.scene.methods:
        r = study.results[m]
        if not r.ok:
            rows.append([o.scene.name, m, f"skipped: {r.skipped}" if r.skipped else f"failed: {r.error}", "", ""])
            continue
        if m in o.reference_error:
            err = f"{o.reference_error[m][1]:.1e} (ref50)"
        else:
            err = f"{agree.get(m, float('nan')):.1e} (vs {o.scene.reference})"
        if study.nonfinite(m):
            err += f"; **{study.nonfinite(m)} NaN/Inf**"
        pb = o.power_balance.get(m)
        rows.append([o.scene.name, m, err, _us(r.seconds_per_sample), "" if pb is None else f"{pb:.1e}"])
    return rows
