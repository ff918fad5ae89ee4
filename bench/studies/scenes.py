"""Scenes: a mechanism, a motion, the methods to run and the outputs wanted, declared in TOML.

Shipped scenes live in ``bench/studies/scenes/*.toml``; users pass their own file to ``exo-bench run``.
Format (every key is checked; an error names the file and the field)::

    name = "my-gait"                      # optional; the file's stem by default. It names the scene's
                                          # reports (models/files.py file_stem), so it is refused when
                                          # models/files.py check_name refuses it, and by exo-bench run
                                          # when it is a suite report's name or another scene's of the run
    description = "the five-link exoskeleton along the gait of eq. (26)"
    mechanism = "exo5-3d"                 # a preset, or a JSON file relative to the scene file
    methods = ["pinocchio", "matrix", "recurrence"]   # each at most once (so are the outputs)
    reference = "pinocchio"               # optional; the first method by default
    outputs = ["table", "reference-error", "moments", "forces", "kinogram", "differences", "overview",
               "recording", "equations"]   # equations: equations-<scene>.md and .tex (bench/cli/equations.py)

    [motion]
    kind = "gait"                         # gait | planar-gait | smooth-random | states | step | stride
    periods = 1.0                         # gait, planar-gait
    samples_per_period = 1000             # gait, planar-gait
    # duration = 2.0, samples = 400, seed = 0   (smooth-random)
    # steps = 2                           (step: the stored predicted step of the mechanism, bench/studies/step/scene.py)
    # variant = "human", speed = 1.41     (stride: the stored stride of the 2D human, bench/studies/stride/scene.py)
    # file = "states.json"                (states: {"t": [...], "q": [[...]], "qd": ..., "qdd": ...};
    #                                      t strictly increasing, at least 2 samples)

    gait = "paper-assumed-v1"             # optional: a named gait of models.motion.GAITS
                                          # (default "winter-fit-v1", the fitted one), or a table:
    # [motion.gait]                       # overrides of models.motion.GaitParams, and
    # base = "paper-assumed-v1"           # optionally the named gait they change
    # T = 1.1

Every motion has at least :data:`~exo_bench.bench.studies.scene_motion.MIN_SAMPLES` samples (power
balance differentiates along it, the figures draw it) and strictly increasing times; the checks name the
file and the field (the motion's: :mod:`exo_bench.bench.studies.scene_motion`).

The runner builds only what a scene declares: a scene without ``lagrange`` never derives, a
scene without ``recording`` never imports rerun, a 2D scene has no psi anywhere.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from exo_bench.bench.studies.scene_motion import MIN_SAMPLES, MOTIONS, _err, _load_motion
from exo_bench.models.mechanism.presets import load_mechanism, read_toml
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.files import check_name
from exo_bench.models.gait.motion import Motion, from_arrays, gait, planar_gait, smooth_random_motion

__all__ = ["MIN_SAMPLES", "MOTIONS", "OUTPUTS", "SHIPPED", "Scene", "load_scene", "shipped_scene_names"]

SHIPPED = Path(__file__).resolve().parent / "scenes"
OUTPUTS = (
    "table",
    "reference-error",
    "moments",
    "forces",
    "kinogram",
    "differences",
    "overview",
    "recording",
    "equations",
)
_TOP = {"description", "mechanism", "methods", "reference", "outputs", "motion", "name"}


@dataclass(frozen=True)
class Scene:
    name: str
    path: Path
    description: str
    mechanism: Mechanism
    methods: tuple[str, ...]
    reference: str
    outputs: tuple[str, ...]
    motion: dict = field(hash=False, compare=False)

    def wants(self, output: str) -> bool:
        return output in self.outputs

    def motion_label(self) -> str:
        k = self.motion["kind"]
        if k == "gait":
            return (
                f"gait of eq. (26), {self.motion['gait_name']}, {self.motion['periods']:g} period(s) x "
                f"{self.motion['samples_per_period']} samples"
            )
        if k == "planar-gait":
            return (
                f"planar gait (eq. 26, sagittal), {self.motion['gait_name']}, {self.motion['periods']:g} period(s) x "
                f"{self.motion['samples_per_period']} samples"
            )
        if k == "smooth-random":
            return f"smooth random motion (seed {self.motion['seed']}), {self.motion['samples']} samples"
        if k == "step":
            from exo_bench.bench.studies.step.scene import label

            return label(self.motion)
        if k == "stride":
            from exo_bench.bench.studies.stride.scene import label as stride_label

            return stride_label(self.motion)
        return f"states from {self.motion['file']}"

    def motion_function(self):
        """``t -> Motion`` for analytic motions (used for power balance), None for sampled ones."""
        k, m = self.motion["kind"], self.mechanism
        if k == "gait":
            return lambda t: gait(m, t, self.motion["params"])
        if k == "planar-gait":
            return lambda t: planar_gait(m, t, self.motion["params"])
        if k == "smooth-random":
            return lambda t: smooth_random_motion(m, t, seed=self.motion["seed"])
        return None

    def external_forces(self):
        """The forces from outside the mechanism along the motion, ``f_ext`` per sample, or None
        (:func:`exo_bench.bench.studies.scene_motion.scene_forces`: the stride's floor contact)."""
        from exo_bench.bench.studies.scene_motion import scene_forces

        return scene_forces(self.motion, self.mechanism)

    def samples(self) -> int:
        """How many samples :meth:`build_motion` makes (known before building it)."""
        k = self.motion["kind"]
        if k in ("gait", "planar-gait"):
            return int(round(self.motion["samples_per_period"] * self.motion["periods"]))
        if k == "smooth-random":
            return int(self.motion["samples"])
        if k == "step":
            from exo_bench.bench.studies.step.scene import samples

            return samples(self.motion)
        if k == "stride":
            from exo_bench.bench.studies.stride.scene import samples as stride_samples

            return stride_samples(self.motion)
        return len(self.motion["data"]["t"])

    def build_motion(self) -> Motion:
        k = self.motion["kind"]
        if k in ("gait", "planar-gait"):
            p = self.motion["params"]
            S = int(round(self.motion["samples_per_period"] * self.motion["periods"]))
            t = np.arange(S) * (p.T / self.motion["samples_per_period"])
            return self.motion_function()(t)
        if k == "smooth-random":
            t = np.linspace(0.0, self.motion["duration"], self.motion["samples"])
            return self.motion_function()(t)
        if k == "step":
            from exo_bench.bench.studies.step.scene import build

            return build(self.motion, self.mechanism)
        if k == "stride":
            from exo_bench.bench.studies.stride.scene import build as stride_build

            return stride_build(self.motion, self.mechanism)
        data = self.motion["data"]
        return from_arrays(
            self.mechanism,
            data["t"],
            data["q"],
            data["qd"],
            data["qdd"],
            source=f"{self.path}: motion.file {self.motion['file']!r}",
        )


def load_scene(spec: str | Path) -> Scene:
    """A shipped scene name (``bench/studies/scenes/<name>.toml``) or the path of a TOML file."""
    from exo_bench.api import METHODS

    path = Path(spec)
    if not path.suffix and (SHIPPED / f"{spec}.toml").exists():
        path = SHIPPED / f"{spec}.toml"
    if not path.exists():
        known = ", ".join(shipped_scene_names())
        raise ValueError(f"scene {str(spec)!r}: not a shipped scene ({known}) and no such file")
    data = read_toml(path, str(path))
    extra = data.keys() - _TOP
    if extra:
        raise _err(path, sorted(extra)[0], f"one of {sorted(_TOP)}", sorted(extra)[0])
    for key in ("mechanism", "methods", "motion"):
        if key not in data:
            raise ValueError(f"{path}: field '{key}': missing (expected keys mechanism, methods, motion)")
    mech_spec = data["mechanism"]
    if not isinstance(mech_spec, str):
        raise _err(path, "mechanism", "a preset name or a JSON file path", mech_spec)
    from exo_bench.models.mechanism.presets import PRESETS

    try:
        mech = load_mechanism(mech_spec if mech_spec in PRESETS else path.parent / mech_spec)
    except ValueError as e:
        raise ValueError(f"{path}: field 'mechanism': {e}") from None
    methods = data["methods"]
    if not isinstance(methods, list) or not methods or not all(isinstance(m, str) for m in methods):
        raise _err(path, "methods", "a non-empty list of method names", methods)
    for m in methods:
        if m not in METHODS:
            raise _err(path, "methods", f"names among {', '.join(METHODS)}", m)
    _once(path, "methods", methods)
    reference = data.get("reference", methods[0])
    if not isinstance(reference, str) or reference not in methods:
        raise _err(path, "reference", f"one of the scene's methods {methods}", reference)
    outputs = data.get("outputs", ["table"])
    if not isinstance(outputs, list) or not all(isinstance(o, str) for o in outputs):
        raise _err(path, "outputs", f"a list of {', '.join(OUTPUTS)}", outputs)
    for o in outputs:
        if o not in OUTPUTS:
            raise _err(path, "outputs", f"names among {', '.join(OUTPUTS)}", o)
    _once(path, "outputs", outputs)
    motion = _load_motion(path, data["motion"], mech)
    desc = data.get("description", "")
    if not isinstance(desc, str):
        raise _err(path, "description", "a string", desc)
    name = data.get("name", path.stem)
    if not isinstance(name, str) or not name:
        raise _err(path, "name", "a non-empty string", name)
    check_name(name, f"{path}: field 'name'" + ("" if "name" in data else " (the file's name)"))
    if name.startswith(".") or any(ch in "/\\" or ord(ch) < 32 or ord(ch) == 127 for ch in name):
        raise _err(
            path,
            "name",
            "a name usable as a file name (it names the scene's reports: no '/', '\\', control "
            "characters or leading '.')",
            name,
        )
    return Scene(name, path, desc, mech, tuple(methods), reference, tuple(outputs), motion)


def _once(path: Path, field_: str, names: list[str]) -> None:
    """Each name of a list at most once (a method or output named twice gave its rows twice)."""
    twice = next((n for k, n in enumerate(names) if n in names[:k]), None)
    if twice is not None:
        raise ValueError(f"{path}: field '{field_}': expected each name once, got {twice!r} twice")


def shipped_scene_names() -> list[str]:
    return sorted(p.stem for p in SHIPPED.glob("*.toml"))
