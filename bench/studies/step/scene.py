"""The scene motion ``kind = "step"``: the stored predicted step of the scene's mechanism, walked.

In a scene file::

    mechanism = "exo5-3d"
    [motion]
    kind = "step"          # the stored step bench/studies/step/data/<file_stem(mechanism)>-step.npz
    steps = 2              # how many steps to walk (default 2): each one after the first mirrored

The stored step is looked up by the mechanism's name (through the file-name encoder, inside the data
folder) and walked only if it was solved for this very mechanism (equal dimension, g, tree, signs,
masses, fractions and link names: :mod:`exo_bench.bench.studies.step.identity`); any other mechanism,
whatever its name, is refused in one line saying how to solve a step for it.

The motion is :func:`exo_bench.bench.studies.step.data.walking_motion`: the collocation points of the stored step, and for
each further step the same points again (the leg swap relabels the links, so link 1 is always the stance
shin; in 3D the other leg is the mirror image) with the support point O moved to the new foot.
"""

from __future__ import annotations

from pathlib import Path

from exo_bench.bench.studies.step import data
from exo_bench.models.mechanism.mechanism import Mechanism


def load_motion(path: Path, m: dict, mech: Mechanism) -> dict:
    """The ``[motion]`` table of a step scene, checked: ``{"kind", "steps", "stored"}``."""
    steps = m.get("steps", 2)
    if not isinstance(steps, int) or isinstance(steps, bool) or steps < 1:
        raise ValueError(f"{path}: field 'motion.steps': expected an integer >= 1, got {steps!r}")
    try:
        stored = data.load(mech)  # looked up by name in the data folder, reused only for an equal mechanism
    except ValueError as e:
        raise ValueError(f"{path}: field 'mechanism': {e}") from None
    return {"kind": "step", "steps": steps, "stored": stored}


def samples(motion: dict) -> int:
    K = len(motion["stored"].t)
    return K + (motion["steps"] - 1) * (K - 1)


def label(motion: dict) -> str:
    st = motion["stored"]
    return (
        f"predicted step (direct collocation, bench/studies/step/data/{st.file_name}): {motion['steps']} step(s) "
        f"of {st.duration:.3f} s and {st.step_length:.3f} m at {st.settings.speed:g} m/s, "
        f"{len(st.t)} collocation points each"
    )


def build(motion: dict, mech: Mechanism):
    return data.walking_motion(motion["stored"], mech, motion["steps"])


__all__ = ["build", "label", "load_motion", "samples"]
