"""The external forces a scene's motion supplies (``f_ext`` per sample, issue 37), and what the scene
runner says of them.

A motion made with forces from outside the mechanism (the predicted stride stands on the floor) is only
reproduced by inverse dynamics given those forces: without them a method's generalised forces carry
the floor's load on the rows that hold the body up (the root's). :meth:`Scene.external_forces
<exo_bench.bench.studies.scenes.Scene.external_forces>` returns them (:func:`scene_forces`), the scene
runner passes them to every method (:func:`exo_bench.bench.studies.study.run_methods`, ``f_ext``) and
notes how far each method's loads are from the ones the motion was made with (:func:`note`).

Only the stride supplies any: its stored contact forces (read through its loader,
:func:`exo_bench.bench.studies.stride.data.load`, when the scene was loaded), at the end points of the
heel and foot rods named by :data:`exo_bench.bench.studies.stride.data.CONTACTS`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from exo_bench.models.mechanism.mechanism import Mechanism

if TYPE_CHECKING:
    from exo_bench.bench.studies.study import Study


@dataclass(frozen=True)
class SceneForces:
    """``f_ext (S, links, 3, dim)`` in newtons along a scene's motion; ``what``: where they come from (one
    line); ``expected``: the generalised forces the motion was made with, ``(S, dof)``, and ``whose``."""

    f_ext: np.ndarray
    what: str
    expected: np.ndarray | None = None
    whose: str = ""


def scene_forces(motion: dict, mech: Mechanism) -> SceneForces | None:
    """The external forces of a scene's ``motion`` table (as loaded), None for a motion without any."""
    if motion.get("kind") == "stride":
        return stride_forces(motion["stored"], mech)
    return None


def stride_forces(stored: Any, mech: Mechanism) -> SceneForces:
    """A stored stride's contact forces as ``f_ext``: each named contact point's force ``(K, dim)`` at the
    end point of its link (:data:`~exo_bench.bench.studies.stride.data.CONTACTS`); the optimiser's loads
    (the stored ``tau``) as what each method should reproduce. A stored contact array of another shape,
    or a contact name the mechanism lacks, is a ValueError naming it."""
    from exo_bench.bench.studies.stride.data import CONTACTS

    links = dict(CONTACTS)
    names, contact = tuple(stored.contact_names), np.asarray(stored.contact, dtype=float)
    K = len(stored.t)
    where = f"stored stride {stored.path}"
    if contact.shape != (K, len(names), mech.dim):
        raise ValueError(
            f"{where}: field 'contact': expected forces of shape {(K, len(names), mech.dim)} (nodes, contact "
            f"points {', '.join(names)}, {mech.dim}D), got {contact.shape}"
        )
    f = np.zeros((K, mech.nlinks, 3, mech.dim))
    for j, name in enumerate(names):
        link = links.get(name)
        if link not in mech.names:
            raise ValueError(
                f"{where}: field 'contact_names': expected names among {', '.join(links)} whose links "
                f"{mech.name!r} has, got {name!r}"
            )
        f[:, mech.names.index(link), 2] += contact[:, j]
    what = (
        "the stored stride's floor contact forces (heel and toe of each foot, at the end points of the heel "
        "and foot rods), one per node"
    )
    return SceneForces(f, what, np.asarray(stored.tau, dtype=float), "the optimiser's loads (the stored tau)")


def note(forces: SceneForces, study: Study) -> str:
    """One line for the scene's notes: which forces every method was given, and each method's largest
    difference from the loads the motion was made with, relative to their largest magnitude."""
    line = f"External forces: every method's inverse dynamics includes {forces.what} (f_ext)"
    if forces.expected is None or not study.ok_methods():
        return line + "."
    scale = max(float(np.abs(forces.expected).max()), 1e-300)
    diffs = {m: float(np.abs(study.tau(m) - forces.expected).max()) / scale for m in study.ok_methods()}
    worst = max(diffs, key=lambda m: diffs[m] if np.isfinite(diffs[m]) else np.inf)
    each = ", ".join(f"{m} {d:.1e}" for m, d in diffs.items())
    return (
        f"{line}. Against {forces.whose}: largest difference {diffs[worst]:.1e} of their largest magnitude "
        f"({worst}; each: {each})."
    )
