"""The joint moments figure (the paper's Fig. 7): NET joint moments, the numbers of the scene report.

A study's ``tau`` are generalised forces of the absolute angles; ``tau_joint = G^-T tau`` are those of
the joint coordinates, whose elevation rows are, for a link with children, its joint's moment minus its
children's (:mod:`exo_bench.models.mechanism.joint_loads`). Neither is the moment in a joint. The **net joint
moment** at the start of link k is the moment the parent side exerts on everything beyond the joint,
about the joint: :func:`exo_bench.models.mechanism.joint_loads.net_joint_loads`, from the motion's point masses,
the computation the report's Plausibility table reads (issue 38: the figure read 8.8 N·m/kg at the
stance ankle where the report said 15.95). It depends on the motion alone; how far each method's
``tau`` is from the others is the differences figure's.

Every panel is one component (:func:`exo_bench.models.mechanism.joint_loads.moment_components`) with its sign
convention in its title, in N·m per kg of the model's mass, as the report gives them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from matplotlib.figure import Figure

from exo_bench.bench.output.figures.curves import (
    _check_ok,
    _header,
    _not_run_line,
    _panels,
    _wrap_notes,
    _write_notes,
    nonfinite_notes,
)
from exo_bench.bench.output.figures.palette import TEXT_PT, TITLE_PT, link_color
from exo_bench.models.mechanism.joint_loads import moment_components, net_joint_loads

if TYPE_CHECKING:
    from exo_bench.bench.studies.study import Study

#: The unit of every net-moment curve: N·m per kg of the model's total mass (as the report's table).
UNIT = "N·m/kg"


def net_moment_curves(study: Study) -> list[tuple[str, str, np.ndarray]]:
    """``(component, sign convention, (S, n) array in N·m/kg)`` of the study's motion."""
    mech, mo = study.mechanism, study.motion
    M, _ = net_joint_loads(mech, mo.q, mo.qd, mo.qdd)
    return [(name, sign, values / mech.total_mass) for name, sign, values in moment_components(mech, M)]


def joint_labels(study: Study) -> list[str]:
    """One legend label per joint: the link whose start it is (``"joint 1: start of stance_shin"``)."""
    return [f"joint {k + 1}: start of {name}" for k, name in enumerate(study.mechanism.names)]


def draw_net_moments(ax, study: Study, component: tuple[str, str, np.ndarray], labels: list[str]) -> None:
    """One component's curves on ``ax``, one colour per joint (its link's), titled with its sign."""
    name, sign, values = component
    t = study.motion.t
    for k in range(values.shape[1]):
        ax.plot(t, values[:, k], color=link_color(k), lw=1.5, label=labels[k], gid=f"net:{name}:{k}")
    ax.set_title(f"{name} component ({sign})", loc="left", fontsize=TEXT_PT)
    ax.set_ylabel(f"M / m ({UNIT})", fontsize=TEXT_PT)
    ax.axhline(0.0, color="k", lw=0.6, alpha=0.5)
    ax.grid(True, alpha=0.3)
    ax.set_xlim(t[0], t[-1])
    ax.tick_params(labelsize=TEXT_PT)


def moments_figure(study: Study, ratio: float | None = None) -> Figure:
    """Net joint moments along the motion, one panel per component (``ratio``: unused, kept for the
    figures' common signature)."""
    _check_ok(study)  # a study without any tau has nothing to show (its motion alone is no scene result)
    curves = net_moment_curves(study)
    labels = joint_labels(study)
    mech = study.mechanism
    notes = [
        f"per kg of the model's {mech.total_mass:.4g} kg; from the motion's point masses (models/mechanism/joint_loads.py), "
        "the numbers of the scene report's Plausibility table; the methods' differences: the differences figure"
    ] + (["not run: " + _not_run_line(study)] if _not_run_line(study) else [])
    notes = _wrap_notes(notes + nonfinite_notes(study))
    fig = Figure(figsize=(11.5, 1.9 + 2.35 * len(curves) + 0.2 * len(notes)), layout="constrained")
    axes, note_ax = _panels(fig, len(curves), len(notes))
    for ax, component in zip(axes, curves):
        draw_net_moments(ax, study, component, labels)
    axes[-1].set_xlabel("time t (s)", fontsize=TEXT_PT)
    fig.legend(
        *axes[0].get_legend_handles_labels(),
        loc="outside right upper",
        fontsize=TEXT_PT,
        title="joint (link colour)",
        title_fontsize=TEXT_PT,
        frameon=False,
    )
    what = (
        "Net joint moments (the paper's Fig. 7) in N·m/kg: the moment the parent side exerts on everything\n"
        "beyond the joint, about the joint; not the generalised forces τ of the absolute angles"
    )
    fig.suptitle(_header(study, what), fontsize=TITLE_PT)
    _write_notes(note_ax, notes)
    return fig
