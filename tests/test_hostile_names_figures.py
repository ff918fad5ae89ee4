"""Hostile names in the scene figures (issue 34, S2's family: a name is text, never code).

matplotlib reads ``$...$`` in any text as mathtext: a link name such as ``a$\\x$b`` stopped the
scene's figures with a parse error. Every figure is drawn with the names' texts taken literally
(:func:`exo_bench.bench.output.provenance.literal_texts`); the axes keep mathtext for their ticks.
"""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.text import Text

from exo_bench.bench.output.figures import scene_figures as plots
from exo_bench.bench.output.figures.scene_figures import FIGURES
from exo_bench.bench.output.provenance import save_figure
from exo_bench.bench.studies.study import run_methods
from exo_bench.models.gait.motion import smooth_random_motion
from exo_bench.models.mechanism.presets import chain


@pytest.mark.case("S2")
def test_every_scene_figure_of_hostile_names_is_drawn_with_the_names_as_written(tmp_path):
    """Link names with matplotlib's math delimiters ($\\x$, $\\frac{$) are drawn as written in
    every scene figure (they stopped the figure with a mathtext parse error)."""
    names = ("a$\\x$b", "x$\\frac{$", "\\input{/etc/hostname} $$ --> <b>")
    mech = chain(3, dim=3).replace(names=names, name="$\\x$ arm")
    motion = smooth_random_motion(mech, np.linspace(0.0, 1.0, 30), seed=1)
    study = run_methods("$\\x$ scene", mech, motion, "a reach", ["pinocchio", "matrix-factored"])
    drawn = 0
    for kind in FIGURES:
        fig = plots.scene_figure(study, kind)
        save_figure(fig, tmp_path / f"{kind}.png")  # raised ValueError (ParseFatalException) before
        shown = [t for t in fig.findobj(Text) if any(n in t.get_text() for n in names)]
        assert all(not t.get_parse_math() for t in shown), kind
        drawn += len(shown)
    assert drawn > 0  # the names are in the figures' legends
