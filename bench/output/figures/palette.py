"""The colours and text sizes of every figure and recording: one colour per link, one per method
(the method's :class:`~exo_bench.api.methods.MethodSpec`), and spare colours for methods not in the table."""

from __future__ import annotations

from typing import TYPE_CHECKING


from exo_bench.api.methods import method_colour

if TYPE_CHECKING:
    pass

LINK_COLORS = (
    "#1f77b4",
    "#d62728",
    "#2ca02c",
    "#ff7f0e",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#17becf",
    "#bcbd22",
    "#7f7f7f",
)


#: Colours of methods not in the method table (its MethodSpec.colour), in order of appearance.
_SPARE_METHOD_COLORS = ("#6a3d9a", "#882255", "#999933")


#: Smallest text in any figure (points): 9 pt at 150 dpi is 19 px high.
TEXT_PT = 9.0


TITLE_PT = 10.0


def link_color(i: int) -> str:
    """The colour of link ``i`` (0-based) in every figure and recording."""
    return LINK_COLORS[i % len(LINK_COLORS)]


def method_color(method: str, others: list[str] | tuple[str, ...] = ()) -> str:
    """The colour of ``method`` in every figure: its :class:`~exo_bench.api.methods.MethodSpec`'s, or
    for a method not in the table the spare colour of its place among the unlisted ``others``."""
    listed = method_colour(method)
    if listed is not None:
        return listed
    unlisted = [m for m in others if method_colour(m) is None]
    k = unlisted.index(method) if method in unlisted else 0
    return _SPARE_METHOD_COLORS[k % len(_SPARE_METHOD_COLORS)]
