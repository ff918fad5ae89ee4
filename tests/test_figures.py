"""The scene figures as a reader gets them: PNGs at 150 dpi or more, text of 9 pt or more, legends
outside the plots, every axis with its unit, one colour per method never used for anything else,
and names that come from the mechanism.

Checked with matplotlib on the figures the runner saves (drawn with the Agg renderer, so every
bounding box is the one in the PNG) and with Pillow on the PNG files themselves.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.text import Text
from PIL import Image

from exo_bench.bench.output.figures import scene_figures as plots
from exo_bench.bench.studies import scene_run as runner
from exo_bench.api import METHODS
from exo_bench.bench.output.figures.palette import TEXT_PT, link_color
from exo_bench.bench.output.figures.scene_figures import FIGURES
from exo_bench.bench.output.provenance import PNG_DPI
from exo_bench.bench.studies.scenes import load_scene, shipped_scene_names
from exo_bench.bench.studies.study import run_methods
from exo_bench.models.gait.motion import smooth_random_motion
from exo_bench.models.mechanism.presets import chain

METHOD_COLORS = {name: spec.colour for name, spec in METHODS.items()}

REPORTS = Path(__file__).resolve().parents[1] / "reports"
#: Every method, as in the shipped scenes: the notes are as long as theirs (matrix-paper's NaN at
#: t = 0 in 3D adds a warning line, expected).
METHODS = '["pinocchio", "matrix", "matrix-factored", "matrix-paper", "recurrence", "lagrange"]'
pytestmark = pytest.mark.filterwarnings("ignore:matrix-paper. eq. .18. as printed divides 0/0:RuntimeWarning")
UNIT = re.compile(r"\([^()]*[A-Za-z·/]+[^()]*\)")


def _scene(tmp_path, mechanism: str, kind: str) -> Path:
    p = tmp_path / f"{mechanism}.toml"
    p.write_text(
        f'mechanism = "{mechanism}"\nmethods = {METHODS}\n'
        f'outputs = ["table", {", ".join(repr(k).replace(chr(39), chr(34)) for k in FIGURES)}]\n'
        f'[motion]\nkind = "{kind}"\nsamples_per_period = 120\n'
    )
    return p


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    """Two scenes run by the runner (its PNGs) and their figures (matplotlib objects)."""
    out = {}
    for mech, kind in (("exo5-3d", "gait"), ("fig5-2d", "planar-gait")):
        d = tmp_path_factory.mktemp(mech)
        o = runner.run_scene(load_scene(_scene(d, mech, kind)), d)
        out[mech] = (o, {k: plots.scene_figure(o.study, k) for k in FIGURES})
    return out


def _arm_study():
    """A user's 3-link arm: no stance leg, no swing leg, no walking."""
    mech = chain(3, dim=3)
    t = np.linspace(0.0, 1.0, 60)
    return run_methods("arm", mech, smooth_random_motion(mech, t, seed=1), "a reach", ["pinocchio", "matrix"])


def _drawn(fig):
    FigureCanvasAgg(fig).draw()
    return fig.canvas.get_renderer()


def _all_legends(fig):
    out = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    stack = [fig]
    while stack:
        f = stack.pop()
        out += list(f.legends)
        stack += list(f.subfigs)
    return out


def _plots(fig):
    """The axes that show data (the note strips are axes with their axis turned off)."""
    return [ax for ax in fig.axes if ax.axison]


def test_every_png_the_runner_writes_is_150_dpi_or_more(scenes):
    for o, _ in scenes.values():
        pngs = [f for f in o.files if f.suffix == ".png"]
        assert len(pngs) == len(FIGURES)
        for f in pngs:
            dpi = Image.open(f).info["dpi"]
            assert min(dpi) >= 150 - 0.5, f"{f.name}: {dpi}"


@pytest.mark.parametrize("scene", sorted(n for n in shipped_scene_names()))
def test_the_shipped_reports_figures_are_150_dpi_or_more(scene):
    sc = load_scene(scene)
    for kind in FIGURES:
        if not sc.wants(kind):
            continue
        png = REPORTS / f"{scene}-{kind}.png"
        assert png.exists(), png
        assert min(Image.open(png).info["dpi"]) >= 150 - 0.5, png.name
    assert PNG_DPI >= 150


@pytest.mark.parametrize("mech", ["exo5-3d", "fig5-2d"])
@pytest.mark.parametrize("kind", FIGURES)
def test_no_legend_covers_a_plot(scenes, mech, kind):
    fig = scenes[mech][1][kind]
    renderer = _drawn(fig)
    legends = _all_legends(fig)
    assert legends, "every scene figure has a legend"
    for leg in legends:
        box = leg.get_window_extent(renderer)
        for ax in _plots(fig):
            assert not box.overlaps(ax.get_window_extent(renderer)), (kind, [t.get_text() for t in leg.get_texts()][:3])


@pytest.mark.parametrize("mech", ["exo5-3d", "fig5-2d"])
@pytest.mark.parametrize("kind", FIGURES)
def test_all_text_is_9_pt_or_more(scenes, mech, kind):
    fig = scenes[mech][1][kind]
    _drawn(fig)
    small = [
        (t.get_text()[:30], t.get_fontsize())
        for t in fig.findobj(Text)
        if t.get_visible() and t.get_text().strip() and t.get_fontsize() < TEXT_PT
    ]
    assert not small


@pytest.mark.parametrize("mech", ["exo5-3d", "fig5-2d"])
@pytest.mark.parametrize("kind", FIGURES)
def test_every_axis_with_tick_labels_names_its_unit(scenes, mech, kind):
    fig = scenes[mech][1][kind]
    _drawn(fig)
    for ax in _plots(fig):
        axes = [("x", ax.get_xticklabels(), ax.get_xlabel()), ("y", ax.get_yticklabels(), ax.get_ylabel())]
        if hasattr(ax, "get_zlabel"):
            axes.append(("z", ax.get_zticklabels(), ax.get_zlabel()))
        for name, ticks, label in axes:
            if any(t.get_visible() and t.get_text() for t in ticks):
                assert UNIT.search(label), (kind, name, label)


@pytest.mark.parametrize("kind", ["differences", "overview"])
def test_each_method_has_its_colour_and_nothing_else_uses_a_method_colour(scenes, kind):
    fig = scenes["exo5-3d"][1][kind]
    method_lines = [ln for ax in fig.axes for ln in ax.get_lines() if (ln.get_gid() or "").startswith("diff:")]
    assert {ln.get_gid()[5:] for ln in method_lines} == {
        "matrix",
        "matrix-factored",
        "matrix-paper",
        "recurrence",
        "lagrange",
    }
    for ln in method_lines:
        assert ln.get_color() == METHOD_COLORS[ln.get_gid()[5:]]
    reserved = set(METHOD_COLORS.values())
    others = [ln for ax in fig.axes for ln in ax.get_lines() if not (ln.get_gid() or "").startswith("diff:")]
    assert not [ln.get_label() for ln in others if ln.get_color() in reserved]


def test_method_colours_are_not_link_colours_grey_or_black():
    links = {link_color(i) for i in range(10)}
    assert not set(METHOD_COLORS.values()) & (links | {"#000000", "#7f7f7f", "k", "0.45"})
    assert len(set(METHOD_COLORS.values())) == len(METHOD_COLORS)


def test_a_users_arm_gets_names_from_its_links_not_from_walking():
    study = _arm_study()
    assert plots.trail_points(study.mechanism) == {"tip (link3 end)": (2, 2)}
    for kind in ("kinogram", "overview"):
        fig = plots.scene_figure(study, kind)
        _drawn(fig)
        words = " ".join(t.get_text() for t in fig.findobj(Text)).lower()
        for bad in ("walking direction", "foot", "hip", "stance", "swing"):
            assert bad not in words, (kind, bad)
    assert "tip (link3 end)" in " ".join(t.get_text() for t in plots.overview_figure(study).findobj(Text))


WALKING_WORDS = ("walking direction", "walking", "foot", "hip", "stance", "swing", "ankle", "knee")


def test_a_users_arm_scene_names_its_tip_and_never_walks(tmp_path):
    """A user's own 3-link arm (a mechanism file with its own link names) in a scene with every
    figure: the trail is the arm's "tip", named after its last link, and no figure, report or
    recording text speaks of walking, feet or hips, or compares its loads with walking."""
    arm = chain(3, dim=3).to_dict()
    arm["name"] = "my-arm"
    for link, name in zip(arm["links"], ("upper_arm", "forearm", "hand")):
        link["name"] = name
    (tmp_path / "arm.json").write_text(json.dumps(arm))
    (tmp_path / "arm.toml").write_text(
        'mechanism = "arm.json"\nmethods = ["pinocchio", "matrix"]\n'
        f'outputs = ["table", {", ".join(chr(34) + k + chr(34) for k in FIGURES)}]\n'
        '[motion]\nkind = "smooth-random"\nduration = 1.0\nsamples = 60\nseed = 3\n'
    )
    o = runner.run_scene(load_scene(tmp_path / "arm.toml"), tmp_path)
    study = o.study
    assert plots.trail_points(study.mechanism) == {"tip (hand end)": (2, 2)}
    assert sorted(f.name for f in o.files if f.suffix == ".png") == sorted(f"arm-{k}.png" for k in FIGURES)
    for kind in FIGURES:
        fig = plots.scene_figure(study, kind)
        _drawn(fig)
        words = " ".join(t.get_text() for t in fig.findobj(Text))
        for bad in WALKING_WORDS:
            assert bad not in words.lower(), (kind, bad)
        if kind == "overview":  # the figure that draws the trails
            assert "tip (hand end)" in words
    report = next(f for f in o.files if f.suffix == ".md").read_text()
    assert "Plausibility" not in report and "Winter" not in report


@pytest.mark.parametrize("mech", ["exo5-3d", "fig5-2d"])
@pytest.mark.parametrize("kind", FIGURES)
def test_all_text_lies_inside_the_figure_and_the_time_plots_use_its_width(scenes, mech, kind):
    """No text runs off the PNG, and a long note does not squeeze the plots: constrained layout once
    shrank the moment and force plots to a sixth of the figure's width to fit an unwrapped note."""
    fig = scenes[mech][1][kind]
    renderer = _drawn(fig)
    page = fig.bbox
    # tick labels are left out: matplotlib keeps (and does not draw) the labels of ticks beyond an
    # axis' limits; the axes themselves must lie inside the figure
    ticks = {
        id(lab)
        for ax in fig.axes
        for axis in (ax.xaxis, ax.yaxis, getattr(ax, "zaxis", None))
        if axis
        for tick in axis.get_major_ticks() + axis.get_minor_ticks()
        for lab in (tick.label1, tick.label2)
    }
    for ax in fig.axes:
        box = ax.get_window_extent(renderer)
        assert page.x0 - 1 <= box.x0 and box.x1 <= page.x1 + 1 and page.y0 - 1 <= box.y0 and box.y1 <= page.y1 + 1
    for t in fig.findobj(Text):
        if id(t) not in ticks and t.get_visible() and t.get_text().strip():
            box = t.get_window_extent(renderer)
            assert box.x0 >= page.x0 - 1 and box.x1 <= page.x1 + 1, (kind, t.get_text()[:40])
            assert box.y0 >= page.y0 - 1 and box.y1 <= page.y1 + 1, (kind, t.get_text()[:40])
    if kind in ("moments", "forces", "differences"):
        for ax in _plots(fig):
            assert ax.get_window_extent(renderer).width >= 0.55 * page.width, kind


def test_the_dashed_line_at_height_0_is_a_floor_only_for_a_model_standing_on_a_stance_leg():
    """fig2b's thigh hangs from its shin's end and reaches below the level of O: that line is no
    floor there. The exoskeleton (and fig5's planar walker) stand on it."""
    from exo_bench.models.mechanism.presets import exo5, fig2b, fig5

    assert plots.ground_label(exo5(3)) == plots.ground_label(fig5(2)) == "floor (height 0)"
    for mech in (fig2b(2), chain(3, dim=3)):
        assert "floor (height" not in plots.ground_label(mech)
        assert "not a floor" in plots.ground_label(mech)
    words = " ".join(t.get_text() for t in plots.kinogram_figure(_arm_study()).findobj(Text))
    assert "floor (height 0)" not in words and "level of O" in words


@pytest.mark.parametrize("mech", ["exo5-3d", "fig5-2d"])
@pytest.mark.parametrize("kind", FIGURES)
def test_no_two_axis_labels_overlap(scenes, mech, kind):
    """The overview's 3D z label once sat on top of the rod-force panel's y label."""
    fig = scenes[mech][1][kind]
    renderer = _drawn(fig)
    labels = [
        a.label
        for ax in fig.axes
        for a in (ax.xaxis, ax.yaxis, getattr(ax, "zaxis", None))
        if a is not None and a.label.get_visible() and a.label.get_text().strip()
    ]
    boxes = [(lab.get_text(), lab.get_window_extent(renderer)) for lab in labels]
    for i, (ta, a) in enumerate(boxes):
        for tb, b in boxes[i + 1 :]:
            assert not a.overlaps(b), (kind, ta, tb)
