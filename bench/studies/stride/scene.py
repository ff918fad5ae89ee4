"""The scene motion ``kind = "stride"``: the stored full stride of the 2D human, run from its stored solution.

In a scene file::

    mechanism = "human-2d"
    [motion]
    kind = "stride"        # the stored stride bench/studies/stride/data/<human-2d>-<variant>-v<cm/s>.npz
    variant = "human"      # "human" (leg rods held within 1 cm) or "exo" (rods free within their specs)
    speed = 1.41           # m/s: which stored stride

No solve runs: the stride is read (:func:`exo_bench.bench.studies.stride.data.load`, reused only for an
equal mechanism) and every method's inverse dynamics runs along its nodes. Beside the scene's usual
outputs the scene writes the comparison with Winter's curves (``<scene>-winter.png``,
:func:`extra_files`), its own kinogram (the stride walks from O: the root rod carries the hips), its
section of the report (:mod:`~exo_bench.bench.studies.stride.report`) and, in the recording, the actuators' loads and the ground force
over time (:func:`log_stride`).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from exo_bench.bench.studies.stride import data
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.files.names import file_stem

#: The extra figure of a stride scene: our curves against Winter's.
WINTER_FIGURE = "winter"


def load_motion(path: Path, m: dict, mech: Mechanism) -> dict:
    """The ``[motion]`` table of a stride scene, checked: ``{"kind", "variant", "speed", "stored"}``."""
    variant, speed = m.get("variant", "human"), m.get("speed", 1.41)
    if not isinstance(variant, str) or variant not in data.VARIANTS:
        raise ValueError(f"{path}: field 'motion.variant': expected one of {', '.join(data.VARIANTS)}, got {variant!r}")
    if isinstance(speed, bool) or not isinstance(speed, (int, float)) or not (math.isfinite(speed) and 0 < speed < 10):
        raise ValueError(f"{path}: field 'motion.speed': expected a speed in (0, 10) m/s, got {speed!r}")
    try:
        stored = data.load(variant, float(speed), mech)
    except ValueError as e:
        raise ValueError(f"{path}: field 'motion': {e}") from None
    return {"kind": "stride", "variant": variant, "speed": float(speed), "stored": stored}


def samples(motion: dict) -> int:
    return len(motion["stored"].t)


def label(motion: dict) -> str:
    st = motion["stored"]
    return (
        f"predicted stride (direct collocation, bench/studies/stride/data/{Path(st.path).name}): {st.variant} "
        f"variant at {st.speed:g} m/s, {st.period:.3f} s and {st.stride_length:.3f} m, {len(st.t)} nodes"
    )


def build(motion: dict, mech: Mechanism):
    from exo_bench.models.gait.motion import from_arrays

    st = motion["stored"]
    return from_arrays(mech, st.t, st.q, st.qd, st.qdd, source=f"stored stride {Path(st.path).name}")


def extra_files(scene) -> list[str]:
    """The files a stride scene writes beyond the outputs it declares (names by the file-name encoder)."""
    return [f"{file_stem(scene.name)}-{WINTER_FIGURE}.png"] if scene.wants("table") else []


def what(scene) -> str:
    st = scene.motion["stored"]
    return f"{scene.name}: {st.variant} variant at {st.speed:g} m/s ({scene.mechanism.name})"


def write_figures(scene, staging: Path) -> list[Path]:
    """Write :func:`extra_files` into ``staging``: our curves against Winter's."""
    from exo_bench.bench.output.provenance import save_figure
    from exo_bench.bench.studies.stride.comparison import compare
    from exo_bench.bench.studies.stride.figures import winter_figure

    c = compare(scene.mechanism, scene.motion["stored"])
    return [save_figure(winter_figure(c, what(scene)), staging / name) for name in extra_files(scene)]


def kinogram(scene):
    from exo_bench.bench.studies.stride.figures import stride_kinogram

    st = scene.motion["stored"]
    return stride_kinogram(scene.mechanism, st.t, st.q, what(scene))


def log_stride(scene):
    """A function ``(stream, times)`` that logs the stride's actuators and ground force to a rerun
    recording (``rr.send_columns``): joint moments (N·m) and telescopic rod forces (N) by actuator, and the
    ground force of each foot (N), under ``stride/``."""
    import rerun as rr

    from exo_bench.bench.studies.stride.actuators import actuators

    st = scene.motion["stored"]
    act = actuators(scene.mechanism, st.tau)
    # entity path parts through the file-name encoder: letters, digits, _ and - only
    series = {f"stride/joint_moments/{file_stem(n)}": act.moments[:, k] for k, n in enumerate(act.joint_names)}
    rods = [(k, n) for k, n in enumerate(act.rod_names) if n in st.telescopic]
    series |= {f"stride/rod_forces/{file_stem(n)}": act.forces[:, k] for k, n in rods}
    for f, foot in enumerate(data.FEET):
        for i, ax in enumerate(("fore-aft", "vertical")):
            series[f"stride/ground_force/{file_stem(foot)}_{ax}"] = st.grf[:, f, i]

    def log(stream, times) -> None:
        for entity, values in series.items():
            stream.send_columns(
                entity, indexes=[times], columns=rr.Scalars.columns(scalars=np.asarray(values, dtype=float))
            )

    return log


__all__ = ["WINTER_FIGURE", "build", "extra_files", "kinogram", "label", "load_motion", "log_stride", "samples"]
