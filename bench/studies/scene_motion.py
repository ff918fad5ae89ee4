"""The motion table of a scene (``[motion]`` in the TOML of :mod:`exo_bench.bench.studies.scenes`) and the
external forces that motion supplies (``f_ext`` per sample, :func:`scene_forces`),
parsed and checked: its kind and its keys, a gait and its overrides (probed for finite rates and
forces before the run), a smooth random motion, or the sampled states of a JSON file (times strictly
increasing). Every error names the file and the field (:func:`_err`); the format is documented in
:mod:`exo_bench.bench.studies.scenes`. The stored step and stride motions are parsed by
``bench/studies/step/scene.py`` and ``bench/studies/stride/scene.py``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from exo_bench.models.mechanism.presets import read_json
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.gait.motion import DEFAULT_GAIT, GAITS, GaitParams, from_arrays, gait, planar_gait


MOTIONS = ("gait", "planar-gait", "smooth-random", "states", "step", "stride")  # step, stride: bench/studies/*/scene.py
_MOTION_KEYS = {"kind", "periods", "samples_per_period", "duration", "samples", "seed", "file", "gait", "steps"}
_MOTION_KEYS |= {"variant", "speed"}  # stride: bench/studies/stride/scene.py
#: Fewest samples of a motion: derivatives (power balance) and plots need at least two.
MIN_SAMPLES = 2


def _err(path: Path, field_: str, expected: str, got: Any) -> ValueError:
    return ValueError(f"{path}: field '{field_}': expected {expected}, got {got!r}")


def _number(path, key, value, lo=None, integer=False):
    ok = isinstance(value, int if integer else (int, float)) and not isinstance(value, bool)
    if ok and not integer:
        ok = math.isfinite(value)
    if not ok or (lo is not None and value <= lo):
        kind = "an integer" if integer else "a number"
        raise _err(path, key, f"{kind}" + (f" > {lo}" if lo is not None else ""), value)
    return value


def _load_motion(path: Path, m: Any, mech: Mechanism) -> dict:
    if not isinstance(m, dict):
        raise _err(path, "motion", "a table with a 'kind'", m)
    extra = m.keys() - _MOTION_KEYS
    if extra:
        raise _err(path, f"motion.{sorted(extra)[0]}", f"one of {sorted(_MOTION_KEYS)}", sorted(extra)[0])
    kind = m.get("kind")
    if kind not in MOTIONS:
        raise _err(path, "motion.kind", f"one of {', '.join(MOTIONS)}", kind)
    out: dict[str, Any] = {"kind": kind}
    if kind == "step":
        from exo_bench.bench.studies.step.scene import load_motion

        return load_motion(path, m, mech)
    if kind == "stride":
        from exo_bench.bench.studies.stride.scene import load_motion as stride_motion

        return stride_motion(path, m, mech)
    if kind in ("gait", "planar-gait"):
        if kind == "gait" and (mech.dim != 3 or mech.nlinks != 5):
            raise _err(
                path,
                "motion.kind",
                "'gait' only for a 3D five-link mechanism (eq. 26)",
                f"{kind} with a {mech.dim}D {mech.nlinks}-link mechanism",
            )
        if kind == "planar-gait" and (mech.dim != 2 or mech.nlinks > 5):
            raise _err(
                path,
                "motion.kind",
                "'planar-gait' only for a 2D mechanism of at most five links",
                f"{kind} with a {mech.dim}D {mech.nlinks}-link mechanism",
            )
        out["periods"] = _number(path, "motion.periods", m.get("periods", 1.0), lo=0)
        out["samples_per_period"] = _number(
            path, "motion.samples_per_period", m.get("samples_per_period", 1000), lo=1, integer=True
        )
        spec = m.get("gait", {})
        named = isinstance(spec, str)
        spec = {"base": spec} if named else spec
        if not isinstance(spec, dict):
            raise _err(path, "motion.gait", "a gait name or a table of GaitParams fields", spec)
        overrides = {k: v for k, v in spec.items() if k != "base"}
        base = spec.get("base", DEFAULT_GAIT)
        if not isinstance(base, str) or base not in GAITS:
            raise _err(path, "motion.gait" if named else "motion.gait.base", f"a gait among {', '.join(GAITS)}", base)
        names = {f.name for f in fields(GaitParams)}
        for k, v in overrides.items():
            if k not in names:
                raise _err(path, f"motion.gait.{k}", f"one of {sorted(names | {'base'})}", k)
            if isinstance(v, list):
                default = getattr(GAITS[base], k)
                if len(v) != len(default) or not all(
                    isinstance(x, (int, float)) and not isinstance(x, bool) for x in v
                ):
                    raise _err(path, f"motion.gait.{k}", f"a list of {len(default)} numbers", v)
                overrides = {**overrides, k: tuple(float(x) for x in v)}
            else:
                _number(path, f"motion.gait.{k}", v, lo=0 if k == "T" else None)
        out["params"] = replace(GAITS[base], **overrides)
        _probe_gait(path, kind, mech, out["params"], "T" in overrides)
        out["gait_name"] = base + (f" with {', '.join(sorted(overrides))} changed" if overrides else "")
        S = int(round(out["samples_per_period"] * out["periods"]))
        if S < MIN_SAMPLES:
            raise _err(
                path,
                "motion.periods",
                f"periods x samples_per_period >= {MIN_SAMPLES} samples (derivatives and plots need at least two)",
                f"{out['periods']} x {out['samples_per_period']} = {S} sample(s)",
            )
    elif kind == "smooth-random":
        out["duration"] = _number(path, "motion.duration", m.get("duration", 2.0), lo=0)
        out["samples"] = _number(path, "motion.samples", m.get("samples", 400), lo=1, integer=True)
        out["seed"] = _number(path, "motion.seed", m.get("seed", 0), lo=-1, integer=True)
    else:
        f = m.get("file")
        if not isinstance(f, str):
            raise _err(path, "motion.file", "a JSON file with t, q, qd, qdd", f)
        p = path.parent / f
        if not p.exists():
            raise _err(path, "motion.file", "an existing file", str(p))
        data = read_json(p, f"{path}: field 'motion.file' ({p})")
        if not isinstance(data, dict) or not {"t", "q", "qd", "qdd"} <= data.keys():
            raise _err(
                path,
                "motion.file",
                "an object with keys t, q, qd, qdd",
                sorted(data) if isinstance(data, dict) else type(data).__name__,
            )
        out["file"], out["data"] = f, data
        source = f"{path}: motion.file {f!r}"
        motion = from_arrays(mech, _times(source, data["t"]), data["q"], data["qd"], data["qdd"], source=source)
        if motion.q.shape[0] < MIN_SAMPLES:
            raise ValueError(
                f"{source}: expected at least {MIN_SAMPLES} samples (derivatives and plots need two), "
                f"got {motion.q.shape[0]}"
            )
    return out


def _probe_gait(path: Path, kind: str, mech: Mechanism, params, period_given: bool) -> None:
    """Refuse, before the run, a gait whose rates or accelerations are not finite float64 or whose
    forces would overflow (a period T of 1e-300 s): 16 samples of one period, numpy's warnings off."""
    from exo_bench.models.states.states import as_states

    fn = gait if kind == "gait" else planar_gait
    with np.errstate(all="ignore"):
        mo = fn(mech, np.linspace(0.0, params.T, 16), params)
    key = "motion.gait.T" if period_given else "motion.gait"
    for label in ("q", "qd", "qdd"):
        a = np.asarray(getattr(mo, label), dtype=float)
        if not np.isfinite(a).all():
            raise _err(
                path,
                key,
                f"a gait whose {label} is finite in float64 (a period T this short makes the rates overflow)",
                params.T,
            )
    try:
        as_states(mech, mo.q, mo.qd, mo.qdd, source=str(path))
    except ValueError as e:
        raise _err(
            path, key, f"a gait whose forces stay within float64 ({str(e).split(': ', 1)[-1]})", params.T
        ) from None


def _times(source: str, t: Any) -> np.ndarray:
    """The times of a sampled motion: a list of finite numbers, strictly increasing."""
    if not isinstance(t, list):
        raise ValueError(f"{source}: field 't': expected a list of numbers (seconds), got {type(t).__name__}")
    for k, x in enumerate(t):
        if not isinstance(x, (int, float)) or isinstance(x, bool):
            raise ValueError(f"{source}: field 't' sample {k}: expected a number (seconds), got {x!r}")
    a = np.asarray(t, dtype=float)
    bad = np.flatnonzero(~np.isfinite(a))
    if bad.size:
        raise ValueError(f"{source}: field 't' sample {int(bad[0])}: expected a finite time, got {a[bad[0]]}")
    steps = np.flatnonzero(np.diff(a) <= 0)
    if steps.size:
        k = int(steps[0]) + 1
        raise ValueError(
            f"{source}: field 't': expected strictly increasing times, got t[{k - 1}] = {float(a[k - 1])!r} "
            f"then t[{k}] = {float(a[k])!r}"
        )
    return a


# The external forces a scene's motion supplies (``f_ext`` per sample, issue 37), and what the scene runner says
# of them.

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
