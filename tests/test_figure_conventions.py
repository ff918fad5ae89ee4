"""What the figures say (issue 38): the joint moments figure plots NET joint moments, the numbers of
the scene report (the stance ankle read 8.8 N·m/kg in the figure and 15.95 in the report: the figure
drew the elevation row of ``tau_joint = G^-T tau``, the joint's moment minus its children's); every
figure states its units and sign convention; no two legend labels differ in one Greek letter only
(φ vs ψ cannot be told apart at the printed size); and the predicted step's figures keep their titles
inside the figure and their legends off the data. Figures are read as matplotlib objects, never pixels.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

from exo_bench.bench.output.figures import scene_figures as plots
from exo_bench.bench.output.figures.curves import moments_figure
from exo_bench.bench.studies.plausibility import plausibility
from exo_bench.bench.studies.scene_run import FIGURES
from exo_bench.bench.studies.scenes import load_scene
from exo_bench.bench.studies.study import run_methods
from exo_bench.models.engines.joint_coordinates import joint_quantities
from exo_bench.models.states.states import split
from exo_bench.models.gait.motion import GaitParams, gait, planar_gait
from exo_bench.models.mechanism.presets import exo5, fig5

METHODS = ["pinocchio", "newton-euler"]


def _gait_study(mech, motion, samples=150):
    t = np.linspace(0.0, GaitParams().T, samples, endpoint=False)
    return run_methods(mech.name, mech, motion(mech, t), "the gait of eq. (26)", METHODS)


@pytest.fixture(scope="module")
def studies():
    return {"exo5-3d": _gait_study(exo5(3), gait), "fig5-2d": _gait_study(fig5(2), planar_gait)}


@pytest.fixture(scope="module")
def step():
    """The predicted step's scene (the stored step: no solve), with two methods."""
    sc = load_scene("exo5-3d-step")
    study = run_methods(sc.name, sc.mechanism, sc.build_motion(), sc.motion_label(), METHODS)
    from exo_bench.bench.studies.step.scene import walking_kinogram

    figs = {k: plots.scene_figure(study, k) for k in FIGURES if k != "kinogram"}
    figs["kinogram"] = walking_kinogram(study)
    return study, figs


def _panel_lines(fig, component: str) -> dict[int, np.ndarray]:
    return {
        int(ln.get_gid().rsplit(":", 1)[1]): np.asarray(ln.get_ydata())
        for ax in fig.axes
        for ln in ax.get_lines()
        if (ln.get_gid() or "").startswith(f"net:{component}:")
    }


@pytest.mark.parametrize("name", ["exo5-3d", "fig5-2d"])
def test_the_moments_figure_draws_the_reports_net_joint_moments(studies, name):
    """The figure's peak per joint is the report's Plausibility number (same computation), sagittal and
    over all axes; and in 3D it is not the elevation row of tau_joint the figure drew before."""
    study = studies[name]
    fig = moments_figure(study)
    report = plausibility(study)
    assert report is not None
    sag = _panel_lines(fig, "sagittal")
    assert sorted(sag) == list(range(study.mechanism.nlinks))
    comps = [sag] + ([_panel_lines(fig, "frontal"), _panel_lines(fig, "transverse")] if name == "exo5-3d" else [])
    for row in report.joints:
        k = row.link
        assert np.abs(sag[k]).max() == pytest.approx(row.sagittal, rel=1e-12)
        magnitude = np.sqrt(sum(c[k] ** 2 for c in comps)).max()
        assert magnitude == pytest.approx(row.magnitude, rel=1e-12)
    if name == "exo5-3d":  # the stance ankle: the old curve (tau_joint's psi_1 row per kg) is far from it
        _, psi_rows, _ = split(study.mechanism, joint_quantities(study.mechanism, study.tau("pinocchio")))
        old = np.abs(psi_rows[:, 0]).max() / study.mechanism.total_mass
        assert abs(old - report.joints[0].sagittal) > 0.2 * report.joints[0].sagittal


def _texts(fig) -> str:
    parts = [fig._suptitle.get_text() if fig._suptitle else ""]
    for ax in fig.axes:
        parts += [ax.get_title(loc=loc) for loc in ("left", "center", "right")]
        parts += [ax.get_ylabel()] + [t.get_text() for t in ax.texts]
    return "\n".join(parts)


#: Per figure kind: the words that state its sign convention.
SIGNS = {
    "moments": ("Winter's sign", "right-handed"),
    "forces": ("positive where the rod is pushed",),
    "differences": ("no sign",),
    "overview": ("Winter's sign", "positive pushes the rod longer"),
}
UNITS = {"moments": ("N·m/kg",), "forces": ("(N)",), "differences": ("(N·m)", "(N)"), "overview": ("N·m/kg", "(N)")}


@pytest.mark.parametrize("kind", sorted(SIGNS))
def test_every_figure_states_its_units_and_sign_convention(studies, kind):
    for name, study in studies.items():
        text = _texts(plots.scene_figure(study, kind))
        for words in SIGNS[kind]:
            if words == "right-handed" and name == "fig5-2d":
                continue  # 2D: the sagittal component only
            assert words in text, (name, kind, words)
        for unit in UNITS[kind]:
            assert unit in text, (name, kind, unit)


def _legend_labels(fig) -> list[str]:
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend()] + list(fig.legends)
    return [t.get_text() for leg in legends for t in leg.get_texts()]


def _one_greek_letter_apart(a: str, b: str) -> bool:
    return len(a) == len(b) and [(x, y) for x, y in zip(a, b) if x != y] in ([("φ", "ψ")], [("ψ", "φ")])


def test_no_two_legend_labels_differ_in_one_greek_letter(studies, step):
    figs = [plots.scene_figure(s, k) for s in studies.values() for k in FIGURES] + list(step[1].values())
    for fig in filter(None, figs):
        labels = _legend_labels(fig)
        pairs = [(a, b) for a, b in itertools.combinations(labels, 2) if _one_greek_letter_apart(a, b)]
        assert not pairs, pairs


@pytest.mark.parametrize("kind", [*(k for k in FIGURES if k != "kinogram"), "kinogram"])
def test_the_steps_figures_keep_titles_inside_and_legends_off_the_data(step, kind):
    fig = step[1][kind]
    assert fig is not None
    FigureCanvasAgg(fig).draw()
    renderer = fig.canvas.get_renderer()
    page = fig.bbox
    titles = [fig._suptitle] + [t for sub in fig.subfigs for t in [sub._suptitle]] if fig._suptitle else []
    titles += [ax.title for ax in fig.axes if ax.get_title()] + [
        ax._left_title for ax in fig.axes if ax.get_title("left")
    ]
    assert titles
    for t in filter(None, titles):
        box = t.get_window_extent(renderer)
        assert page.x0 - 1 <= box.x0 and box.x1 <= page.x1 + 1 and box.y1 <= page.y1 + 1, (kind, t.get_text()[:50])
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend()] + list(fig.legends)
    legends += [leg for sub in fig.subfigs for leg in sub.legends]
    assert legends, kind
    plotted = [ax for ax in fig.axes if ax.axison and (ax.get_lines() or ax.collections)]
    for leg in legends:
        box = leg.get_window_extent(renderer)
        for ax in plotted:
            assert not box.overlaps(ax.get_window_extent(renderer)), (kind, [t.get_text() for t in leg.get_texts()][:2])
