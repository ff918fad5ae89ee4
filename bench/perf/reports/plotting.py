"""What the benchmark figures share: log-log panels by dimension, and a row's colour (its method's) and line style (its kernel's)."""

from __future__ import annotations

from pathlib import Path


from exo_bench.bench.perf.reports.loading import _base, _kernel


def _log_log_by_dim(
    png: Path, draw, xlabel: str, ylabel: str, title: str, panel_title: str = "{dim}D", note: str = ""
) -> None:
    """One log-log panel per dimension (2D, 3D) sharing the y axis; ``draw(ax, dim)`` plots a panel.
    One legend for both panels, outside the data (right of them), and ``note`` under the panels."""
    from matplotlib.figure import Figure
    from matplotlib.layout_engine import ConstrainedLayoutEngine

    from exo_bench.bench.output.figures.palette import TEXT_PT, TITLE_PT

    from exo_bench.bench.output.provenance import save_figure

    layout = ConstrainedLayoutEngine()
    fig = Figure(figsize=(15, 6.5), layout=layout)
    axes = fig.subplots(1, 2, sharey=True)
    for ax, dim in zip(axes, (2, 3)):
        draw(ax, dim)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(xlabel, fontsize=TEXT_PT)
        ax.set_title(panel_title.format(dim=dim), fontsize=TITLE_PT)
        ax.tick_params(labelsize=TEXT_PT)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel(ylabel, fontsize=TEXT_PT)
    handles: dict = {}
    for ax in axes:
        for h, label in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(label, h)
    fig.legend(list(handles.values()), list(handles), loc="outside right upper", fontsize=TEXT_PT)
    if note:
        fig.text(0.01, 0.0, note, fontsize=TEXT_PT, ha="left", va="bottom", wrap=True)
        layout.set(rect=(0, 0.06, 1, 0.94))
    fig.suptitle(title, fontsize=TITLE_PT + 1)
    save_figure(fig, png)


def _style(method: str, methods) -> dict:
    """Colour from the base method (the same as in every scene figure), line style from the kernel:
    ``matrix (numba)`` solid, ``matrix (numpy)`` dashed; other rows (pin.rnea, PyDy) dash-dot."""
    from exo_bench.bench.output.figures.palette import method_color

    bases = sorted({_base(m) for m in methods})
    return {
        "color": method_color(_base(method), bases),
        "ls": {"numba": "-", "numpy": "--", "": "-"}.get(_kernel(method), "-."),
    }
