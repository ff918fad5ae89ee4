"""The equations pages of eq. (5)/(17) (the ``equations`` output of a scene) and the time budget of
``exo-bench equations`` (bench/cli/equations.py, which holds the command): kept apart so that the runner
(bench/cli/run.py) imports only this.

A scene listing ``equations`` in its outputs gets ``equations-<scene>.md`` and ``.tex``
(:func:`scene_pages`), with the aggregates of eq. (6) as symbols; a two-link planar scene's page writes
eq. (4) with both signs.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

#: Seconds that composing and generating may take (``--budget``).
DEFAULT_BUDGET = 120.0


class EquationsBudget(ValueError):
    """The composition and generation would take, or took, longer than the budget."""

    def __init__(self, message: str):
        super().__init__(message)


class _Clock:
    """The budget of one generation: refused up front by the estimate, checked between phases on
    ``clock`` (seconds; ``time.perf_counter``, or a test's deterministic stand-in)."""

    def __init__(self, mech, fmt: str, budget: float, clock: Callable[[], float] = time.perf_counter):
        from exo_bench.api.cost_model import equations_estimate

        self.mech, self.fmt, self.budget, self.clock = mech, fmt, float(budget), clock
        self.start = clock()
        est = equations_estimate(mech, fmt)
        if est > self.budget:
            raise EquationsBudget(self._message(f"needs about {_seconds(est)} (estimated before any work)"))

    def _message(self, what: str) -> str:
        m = self.mech
        return (
            f"equations of {m.name!r} (n={m.nlinks} links, dim={m.dim}) as {self.fmt}: composing and generating "
            f"{what}, over the budget of {self.budget:g} s; raise it with --budget SECONDS"
        )

    def check(self, phase: str) -> None:
        t = self.clock() - self.start
        if t > self.budget:
            raise EquationsBudget(self._message(f"took {t:.1f} s by the end of {phase}"))


def eq4_pair(mech):
    """The serial and branched two-link planar models of ``mech``'s masses (eq. (4)), or None."""
    if mech.dim != 2 or mech.nlinks != 2 or tuple(mech.parent) != (-1, 0):
        return None
    return mech.replace(sign=(1, 1)), mech.replace(sign=(1, -1))


#: Elements a Markdown page lists in full; beyond, it shows A and B (and P), the .tex has everything.
MD_ELEMENTS = 200


def md_matrices(mech):
    from exo_bench.models.states.states import blocks, matrix_names

    count = len(blocks(mech.dim)) * len(matrix_names(mech.dim)) * mech.nlinks**2
    if count <= MD_ELEMENTS:
        return None
    return ("A", "B", "P") if mech.dim == 3 else ("A", "Lambda", "P")


# ------------------------------------------------------------------------------ the scene output
def scene_pages(scene, staging: Path) -> list[Path]:
    """The ``equations`` output of a scene: ``equations-<scene>.md`` and ``.tex`` (:func:`page_names`)
    with the aggregates as symbols (eq. (4) with both signs for a two-link planar model)."""
    import shlex

    from exo_bench.bench.output.provenance import provenance
    from exo_bench.models.files import atomic_write
    from exo_bench.matrix_method.export import latex as export_latex
    from exo_bench.bench.output import latex_document
    from exo_bench.models.files import file_stem

    mech = scene.mechanism
    _Clock(mech, "latex", DEFAULT_BUDGET)
    parts = export_latex.element_parts(mech, True)
    header = provenance(f"exo-bench run {shlex.quote(scene.name)}")
    Name = latex_document.Name
    title = ("Equations of motion of scene ", Name(scene.name), " (", Name(mech.name), ")")
    md = latex_document.document(
        mech, True, "md", header, title=title, parts=parts, eq4=eq4_pair(mech), matrices_shown=md_matrices(mech)
    )
    tex = latex_document.document(
        mech, True, "tex", "", title=("Equations of motion of ", Name(mech.name)), parts=parts, eq4=eq4_pair(mech)
    )
    md_name, tex_name = page_names(file_stem(scene.name))
    return [atomic_write(staging / md_name, md), atomic_write(staging / tex_name, tex)]


def page_names(stem: str) -> tuple[str, str]:
    """The files of a scene's ``equations`` output, for the scene's file stem (the file-name
    encoder's: models/files.py ``file_stem``)."""
    return f"equations-{stem}.md", f"equations-{stem}.tex"


def _seconds(x: float) -> str:
    from exo_bench.api.cost_model import _seconds as fmt

    return fmt(x)
