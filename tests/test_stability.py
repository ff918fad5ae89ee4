"""The stability suite's verdicts (bench/studies/stability/): one representative of each family, the
warnings, the bookkeeping of missing/skipped/failing methods, and the report end to end on a tiny
profile. Physics, not timing: every verdict is checked against what the configuration implies."""

import contextlib
import dataclasses
import io
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from exo_bench.bench.studies import study
from exo_bench.bench.studies.stability import cases as st_cases, evaluation as st_eval, report as st_report
from exo_bench.api import METHODS, MethodSpec, method_names, prepare
from exo_bench.models.runtime.prepared import PreparedModel
from exo_bench.models.engines import pinocchio_backend as pb

TINY = dataclasses.replace(
    st_cases.QUICK,
    name="test",
    samples=1,
    distances=(1e-6, 0.0),
    lengths=(0.0, 1.0),
    one_length=(0.0,),
    ratios=(1.0, 1e6),
    large_n=(8,),
    periods=(0.1,),
    lagrange_budget=2.0,
    wp_rtols=(1e-6, 1e-8),
    rt_rtols=(1e-6, 1e-8),
    rt_integrators=("DOP853",),
    method_rtol=1e-6,
    energy_rtols=(1e-6,),
    stiff_k=(1e6,),
    stiff_mass_scales=(),
    stiff_budget=3000,
    method_seconds=600.0,  # a safety net (issue 34, F1): the tiny runs end on their own, 30 s raced a loaded machine
    rt_cases=("exo5-2d planar gait",),
    method_cases=("exo5-2d planar gait",),
    energy_cases=("exo5-2d passive fall",),
    stiff_reference_rtol=1e-7,
)


def _case(cases, label):
    return next(c for c in cases if c.label == label)


def test_at_a_removable_singularity_matrix_is_exact_and_the_printed_eq18_yields_nan():
    """sin phi_i = 0 exactly (phi_i = 0): eq. (18) as printed divides 0/0; the corrected closed forms
    have no division and stay at round-off from Pinocchio and the 50-digit reference."""
    case = _case(st_cases.family_removable(st_cases.QUICK), "sin phi_i = 0, d = 0")
    assert (case.q[:, : case.mechanism.nlinks] == 0).all()
    with pytest.warns(study.UnusableMethodWarning, match="matrix-paper"):
        fam = st_eval.evaluate_family(
            "removable singularities of eq. (18)", [case], ["pinocchio", "matrix", "matrix-paper"]
        )
    rows = fam.results[0].rows
    tau = prepare(case.mechanism, "matrix").inverse_dynamics(case.q, case.qd, case.qdd)
    assert np.isfinite(tau).all()
    ref = pb.inverse_dynamics(case.mechanism, case.q, case.qd, case.qdd)
    assert np.abs(tau - ref).max() < 1e-13 * np.abs(ref).max()
    assert rows["matrix"].verdict == "ok" and rows["matrix"].rel_err < 1e-13
    assert rows["matrix-paper"].nonfinite > 0 and rows["matrix-paper"].verdict == "unusable"
    assert "matrix-paper" in fam.warnings and "matrix" not in fam.warnings


def test_the_vertical_rod_is_detected_as_singular_for_forward_dynamics():
    cases = st_cases.family_near_vertical(TINY)
    with pytest.warns(st_cases.IllConditionedWarning, match="singular"):
        fam = st_eval.evaluate_family("near-vertical rods", cases, ["pinocchio"])
    at, near = (next(cr for cr in fam.results if cr.case.x == x) for x in (0.0, 1e-6))
    assert at.fd_verdict == "singular" and "vertical rod" in at.singular[0]
    # 1e-6 from vertical M is regular, but cond(M) ~ 1/cos^2 psi: numerically singular
    assert near.singular_samples == 0 and near.fd_verdict == "numerically singular"
    # inverse dynamics is still defined there, and right
    assert at.rows["pinocchio"].verdict == "ok" and at.rows["pinocchio"].rel_err < 1e-13


def test_large_mass_ratios_give_a_condition_number_that_is_flagged():
    cases = [c for c in st_cases.family_masses(TINY) if c.series != "special"]
    with pytest.warns(st_cases.IllConditionedWarning, match="ill-conditioned"):
        fam = st_eval.evaluate_family("mass ratios", cases, ["pinocchio"])
    one, big = (next(cr for cr in fam.results if cr.case.x == r) for r in (1.0, 1e6))
    assert one.fd_verdict == "ok" and one.cond_raw < st_cases.COND_ILL
    assert big.fd_verdict == "ill-conditioned" and big.cond_raw >= st_cases.COND_ILL
    # the heavier swing leg spreads the inertias: cond grows by orders of magnitude with r
    assert big.cond_raw > 1e4 * one.cond_raw
    assert "mass ratios" in fam.mass_warning


def test_missing_over_budget_and_raising_methods_are_rows_not_crashes(monkeypatch):
    import sys
    import types

    mod = types.ModuleType("fake_methods")

    class Over(Exception):
        skip_reason = "over its time budget (test)"

    class over(PreparedModel):  # over budget while preparing, as lagrange's derivation can be
        def __init__(self, mechanism):
            raise Over()

    class boom(PreparedModel):  # prepares, then fails when called
        def _inverse_dynamics(self, q, qd, qdd):
            raise RuntimeError("boom")

    class nan(PreparedModel):
        def _inverse_dynamics(self, q, qd, qdd):
            return np.full(q.shape, np.nan)

    mod.over, mod.boom, mod.nan = over, boom, nan
    monkeypatch.setitem(sys.modules, "fake_methods", mod)
    for name in ("over", "boom", "nan"):
        monkeypatch.setitem(METHODS, f"fake-{name}", MethodSpec(f"fake-{name}", "fake_methods", name, "test"))
    monkeypatch.setitem(METHODS, "fake-missing", MethodSpec("fake-missing", "no_such_module_xyz", "f", "test"))
    names = ["pinocchio", "fake-over", "fake-boom", "fake-nan", "fake-missing"]
    with pytest.warns(study.UnusableMethodWarning, match="fake-nan"):
        fam = st_eval.evaluate_family(st_cases.BASELINE, st_cases.family_baseline(TINY)[:2], names)
    rows = fam.results[0].rows
    assert [rows[n].status for n in names] == ["ok", "skipped", "failed", "ok", "missing"]
    assert rows["fake-over"].reason.startswith("over its time budget")
    assert "boom" in rows["fake-boom"].reason
    assert rows["fake-nan"].verdict == "unusable" and rows["fake-nan"].nonfinite == fam.results[0].case.q.size
    # a skip is remembered for mechanisms of the same structure (same symbolic work) and not retried
    memo = {}
    case = fam.results[0].case
    st_eval.evaluate_case(case, ["fake-over"], memo)
    heavier = dataclasses.replace(case, mechanism=case.mechanism.replace(g=1.62))
    assert "not retried" in st_eval.evaluate_case(heavier, ["fake-over"], memo).rows["fake-over"].reason


PNGS = ("stability-families.png", "stability-conditioning.png", "stability-work-precision.png", "stability-stiff.png")


@pytest.fixture(scope="module")
def tiny_run(tmp_path_factory):
    """`exo-bench stability` once on the tiny profile: the output folder, the exit code and the
    figures as they were handed to the PNG writer."""
    from exo_bench.bench.output import provenance as reporting
    from exo_bench.bench.cli import main

    out = tmp_path_factory.mktemp("stability")
    figures = {}
    real_save = reporting.save_figure

    def capture(fig, path, *args, **kwargs):
        figures[Path(path).name] = fig
        return real_save(fig, path, *args, **kwargs)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(st_report, "QUICK", TINY)  # where `exo-bench stability` reads its profile
        mp.setattr(reporting, "save_figure", capture)
        err = io.StringIO()
        with contextlib.redirect_stderr(err):
            code = main(["stability", "--reports", str(out)])
    # The command line turns the study's warnings into one line each on stderr (matrix-paper, the
    # printed eq. (18), is unusable in 3D by design).
    lines = err.getvalue().splitlines()
    assert any(ln.startswith("exo-bench: warning: method 'matrix-paper' is unusable") for ln in lines), lines
    assert not any("Traceback" in ln for ln in lines)
    return out, code, figures


def test_the_report_has_rows_for_every_family_and_method(tiny_run):
    """End to end on a tiny profile: `exo-bench stability` writes the report and its plots; every
    family has a summary row for every method registered at run time; the round trip passes."""
    out, code, _ = tiny_run
    assert code == 0
    text = (out / "stability.md").read_text()
    for png in PNGS:
        data = (out / png).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and f"({png})" in text
    summary = text.split("## Summary")[1].split("Mass matrix")[0]
    for fam in st_cases.FAMILIES:
        for m in method_names():
            assert f"| {fam} | {m} |" in summary, (fam, m)
    assert "Generated by `exo-bench stability`" in text
    assert "**Tolerance.**" in text and "FAIL" not in text.split("### Round trip")[1].split("Per method")[0]
    assert "rtol = 1e-k" in text  # the work-precision labels are explained
    assert not list(out.glob(".*.tmp"))  # nothing half-written
    chart_free = text.split("## Chart-free dynamics")[1]  # the gait at psi5 = pi/2, and cond(M) against cond(M_r)
    assert "**Verdict: met.**" in chart_free and "psi5 = 1.5707963267948966" in chart_free
    for fam in st_cases.FAMILIES:
        assert f"| {fam} | " in chart_free.split("cond(M_r), per family")[1], fam


_GREY_OR_BLACK = {"#7f7f7f", "#000000", "#808080"}


def _figure_problems(fig) -> list[str]:
    """What breaks the figure rules (bench/studies/stability/figures.py), measured on the drawn figure."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import to_hex
    from matplotlib.text import Text

    FigureCanvasAgg(fig)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    problems = []
    axes = [ax for ax in fig.axes if ax.get_visible()]
    legends = list(fig.legends) + [ax.get_legend() for ax in axes if ax.get_legend() is not None]
    if not legends:
        problems.append("no legend")
    for lg in legends:
        box = lg.get_window_extent(renderer)
        for ax in axes:  # the axes' extent is its data area
            if box.overlaps(ax.get_window_extent(renderer)):
                problems.append(f"legend {lg.get_title().get_text()!r} overlaps the data of {ax.get_title()!r}")
    for t in fig.findobj(Text):
        if t.get_visible() and t.get_text().strip() and t.get_fontsize() < 9:
            problems.append(f"text {t.get_text()!r} at {t.get_fontsize()} pt")
    for ax in axes:
        for label in (ax.get_xlabel(), ax.get_ylabel()):
            if not (label.endswith(")") and "(" in label.splitlines()[0]):
                problems.append(f"axis label without a unit in parentheses: {label!r}")
        for line in ax.get_lines():
            if not line.get_xydata().size:
                continue
            dashed, colour = line.get_linestyle() == "--", to_hex(line.get_color())
            if dashed != (colour in _GREY_OR_BLACK):  # thresholds, and only they, are grey/black dashed
                problems.append(f"line {line.get_label()!r}: style {line.get_linestyle()!r}, colour {colour}")
            if dashed and line.get_label().startswith("_"):
                problems.append("a threshold without a legend label")
    return problems


@pytest.mark.parametrize("png", PNGS)
def test_every_figure_is_readable_at_150_dpi_with_its_legend_outside_the_data(tiny_run, png):
    from PIL import Image

    out, _, figures = tiny_run
    with Image.open(out / png) as im:
        dpi = im.info.get("dpi")
    assert dpi is not None and min(dpi) >= 149.99, dpi  # pHYs stores pixels per metre: 150 dpi = 5906 /m
    assert _figure_problems(figures[png]) == []


def test_the_figure_check_catches_a_legend_over_the_data():
    """The check above can fail: a legend drawn inside the axes, a small font, a method-coloured
    dashed line and an axis without a unit are each reported."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(4, 3))
    ax = fig.subplots()
    ax.plot([1, 2, 3], [1, 2, 3], label="data")
    ax.axhline(2, color="#d62728", ls="--", label="threshold")
    ax.set_xlabel("time")
    ax.set_ylabel("force (N)", fontsize=6)
    ax.legend(loc="upper left")
    problems = "\n".join(_figure_problems(fig))
    assert "overlaps the data" in problems and "at 6.0 pt" in problems
    assert "without a unit" in problems and "colour #d62728" in problems


class _KnownError(PreparedModel):
    """Pinocchio's forces plus an error of ``RELATIVE`` times the largest force on one entry."""

    RELATIVE = 0.0

    def _inverse_dynamics(self, q, qd, qdd):
        tau = pb.inverse_dynamics(self.mechanism, q, qd, qdd)
        tau[-1, 0] += self.RELATIVE * np.abs(tau).max()
        return tau


@pytest.mark.parametrize(
    "relative,verdict",
    [
        (1e-3 * st_cases.REL_DEGRADED, "ok"),
        (30 * st_cases.REL_DEGRADED, "degraded"),
        (30 * st_cases.REL_UNUSABLE, "unusable"),
    ],
)
def test_a_known_error_is_measured_against_the_reference_and_judged_by_the_thresholds(monkeypatch, relative, verdict):
    """A method off by a known relative error: the study measures that error against the 50-digit
    reference (to the reference's and Pinocchio's rounding) and gives the verdict its size implies;
    only an unusable method warns."""
    fake = type("_Known", (_KnownError,), {"RELATIVE": relative})
    monkeypatch.setattr(sys.modules[__name__], "_Known", fake, raising=False)
    monkeypatch.setitem(
        METHODS, "known-error", MethodSpec("known-error", __name__, "_Known", "pinocchio plus a known error")
    )
    case = st_cases.family_baseline(TINY)[1]  # exo5-2d, benign
    with warnings.catch_warnings():
        warnings.simplefilter("error", study.UnusableMethodWarning)
        if verdict == "unusable":
            with pytest.warns(study.UnusableMethodWarning, match="known-error"):
                fam = st_eval.evaluate_family(st_cases.BASELINE, [case], ["known-error"])
        else:
            fam = st_eval.evaluate_family(st_cases.BASELINE, [case], ["known-error"])
    row = fam.results[0].rows["known-error"]
    # Pinocchio and the reference agree to a few ulps of the largest force (tests/conftest.py), so the
    # measured error is the injected one to 1e-13 of the largest force.
    assert abs(row.rel_err - relative) <= 1e-13 and row.verdict == verdict
