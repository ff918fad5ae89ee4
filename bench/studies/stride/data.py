"""The stored stride: writing and reading it (``.npz`` + JSON metadata, no pickle), and what it holds.

A stored stride is ``bench/studies/stride/data/<file_stem(mechanism)>-<variant>-v<speed in cm/s>.npz``
(:func:`path_of`; the key is encoded by :func:`exo_bench.models.files.file_stem`, never used as a path):
one **full** stride of the 2D human (:func:`exo_bench.models.mechanism.presets.human`), from a right heel strike
to the next, sampled at the collocation nodes. The optimiser solves half of it (right heel strike to
left heel strike) with a left/right symmetry constraint; the second half stored here is the first
mirrored (right and left links exchanged, the hips one half stride further on), so every consumer
reads the whole cycle without knowing that (:mod:`exo_bench.bench.studies.stride.problem`).

Arrays (``K`` nodes, ``dof = 20``; SI units; forces in world axes ``(x forward, y up)``):

* ``t (K,)`` s, from 0 to the period; ``q, qd, qdd (K, dof)`` the model's coordinates;
* ``tau (K, dof)``: the actuators' generalised forces the optimiser found, ``ID(q, qd, qdd) - Q(q,
  f_contact)`` (:mod:`exo_bench.models.runtime.external_forces`);
* ``moments (K, joints)`` N·m, the joint moments named by ``meta["joint_names"]`` (hips, knees,
  ankles, arches: :func:`exo_bench.bench.studies.stride.actuators.actuators`; the arch moment is what
  holds the foot's fixed arch, not an actuator);
* ``rod_forces (K, rods)`` N, the rod forces named by ``meta["rod_names"]`` (every rod but the root's;
  the telescopic actuators are ``meta["telescopic"]``, the thigh and leg rods; the others' lengths are
  fixed and their force is structural);
* ``residuals (K, 3)``: HAT's angle, the root's angle (N·m) and length (N): zero up to the solve's
  tolerance (nothing but the actuators and the floor moves the body);
* ``contact (K, points, 2)`` N: the floor's force at each contact point named by
  ``meta["contact_names"]`` (right heel, right toe, left heel, left toe: the end masses of the heel
  and foot rods), as :func:`exo_bench.models.simulation.contact.ground_reaction` computes it from ``q, qd``;
* ``grf (K, 2, 2)`` N: the ground reaction per foot (``meta["feet"]``: right, left), heel plus toe.

``meta`` (JSON): ``variant`` ("human" or "exo"), ``speed`` (m/s), ``period`` (s), ``stride_length``
(m), ``body_weight`` (N), the names above, ``settings`` (the problem's, a dict:
:class:`exo_bench.bench.studies.stride.problem.StrideSettings`), ``solver`` (IPOPT's status,
iterations, solve time in seconds on the host that solved it, objective, tolerances, constraint
violation), ``provenance`` (commit, date, command, CasADi version), and the mechanism's definition and
digest: :func:`load` reuses a stride only for an equal mechanism
(:mod:`exo_bench.bench.studies.step.identity`).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from exo_bench.bench.studies.step import identity
from exo_bench.bench.studies.step.data import read_stored
from exo_bench.bench.studies.stride.passive import check_passive, check_spring
from exo_bench.models.simulation.contact import DEFAULT_CONTACT, ContactParameters
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.files import file_stem
from exo_bench.models.states.validation import _finite, _is_number

DATA = Path(__file__).resolve().parent / "data"
VARIANTS = ("human", "exo")
#: The floor's contact points: (name, link whose end mass it is).
CONTACTS = (
    ("right_heel", "right_heel"),
    ("right_toe", "right_foot"),
    ("left_heel", "left_heel"),
    ("left_toe", "left_foot"),
)
FEET = ("right", "left")
ARRAYS = ("t", "q", "qd", "qdd", "tau", "moments", "rod_forces", "residuals", "contact", "grf")
HOW_TO_SOLVE = "solve one with exo-bench stride --solve --speed V --variant human|exo --store"


@dataclass(frozen=True)
class StoredStride:
    """One full stride and how it was found (module docstring: the arrays and ``meta``)."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    tau: np.ndarray
    moments: np.ndarray
    rod_forces: np.ndarray
    residuals: np.ndarray
    contact: np.ndarray
    grf: np.ndarray
    meta: dict = field(default_factory=dict)
    path: str = ""

    @property
    def variant(self) -> str:
        return str(self.meta["variant"])

    @property
    def speed(self) -> float:
        return float(self.meta["speed"])

    @property
    def period(self) -> float:
        return float(self.t[-1])

    @property
    def stride_length(self) -> float:
        return float(self.meta["stride_length"])

    @property
    def settings(self) -> dict:
        return dict(self.meta["settings"])

    @property
    def solver(self) -> dict:
        return dict(self.meta.get("solver", {}))

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(self.meta["joint_names"])

    @property
    def rod_names(self) -> tuple[str, ...]:
        return tuple(self.meta["rod_names"])

    @property
    def telescopic(self) -> tuple[str, ...]:
        return tuple(self.meta["telescopic"])

    @property
    def contact_names(self) -> tuple[str, ...]:
        return tuple(self.meta["contact_names"])

    @property
    def body_weight(self) -> float:
        return float(self.meta["body_weight"])


def contact_mask_order(mech: Mechanism) -> list[int]:
    """The link index of every contact point of :data:`CONTACTS`, in that order (each the link's end mass)."""
    return [mech.names.index(link) for _, link in CONTACTS]


def contact_of(settings: Any, where: str = "stride: field 'settings.contact'") -> ContactParameters:
    """The floor's contact parameters of a stride problem (its settings, or their stored dict):
    :data:`~exo_bench.models.simulation.contact.DEFAULT_CONTACT` with the fields of its ``contact`` changed (a stride
    stored without the field has the defaults); a one-line ValueError ``where: ...`` naming a bad field
    (unknown, or a value :class:`~exo_bench.models.simulation.contact.ContactParameters` refuses)."""
    over = settings.get("contact", {}) if isinstance(settings, dict) else settings.contact
    names = [f.name for f in fields(ContactParameters)]
    unknown = [k for k in over if k not in names] if isinstance(over, dict) else [over]
    if unknown:
        raise ValueError(f"{where}: expected fields of ContactParameters ({', '.join(names)}), got {unknown[0]!r}")
    try:
        return replace(DEFAULT_CONTACT, **over) if over else DEFAULT_CONTACT
    except ValueError as e:
        raise ValueError(f"{where}: {e}") from None


def check_settings(s: Any, source: str = "stride", prefix: str = "") -> None:
    """Check the settings that price and shape a stride problem where they are made (a
    :class:`~exo_bench.bench.studies.stride.problem.StrideSettings`, or the dict stored with a stride, a
    field it lacks having its default): ``passive`` and ``spring``
    (:mod:`~exo_bench.bench.studies.stride.passive`), ``w_floor`` a finite price >= 0 (a negative one would
    reward the floor's damping), ``contact`` (:func:`contact_of`), ``tol`` and ``constr_viol_tol`` in (0, 1). A one-line ValueError
    ``source: field 'prefix<name>': expected ..., got ...`` otherwise."""
    get = s.get if isinstance(s, dict) else lambda key, default: getattr(s, key, default)
    check_passive(get("passive", "none"), f"{source}: field '{prefix}passive'")
    check_spring(get("spring", (0.0, 0.0, 0.0)), f"{source}: field '{prefix}spring'")
    w = get("w_floor", 0.0)
    if not (_is_number(w) and _finite(w) and w >= 0):
        raise ValueError(
            f"{source}: field '{prefix}w_floor': expected a finite number >= 0 (the floor's absorbed work per metre "
            f"over body weight, priced as the joints'), got {w!r}"
        )
    for key in ("tol", "constr_viol_tol"):
        x = get(key, 1e-10)
        if not (_is_number(x) and _finite(x) and 0 < x < 1):
            raise ValueError(f"{source}: field '{prefix}{key}': expected IPOPT's tolerance in (0, 1), got {x!r}")
    contact_of(s, f"{source}: field '{prefix}contact'")


def contact_forces(mech: Mechanism, q: np.ndarray, qd: np.ndarray, params=None) -> np.ndarray:
    """``(K, 4, 2)``: the floor's force at each contact point of :data:`CONTACTS` from ``q, qd``
    (:func:`exo_bench.models.simulation.contact.ground_reaction`, the default contact parameters unless given)."""
    from exo_bench.models.simulation.contact import ground_reaction

    f = ground_reaction(mech, np.atleast_2d(q), np.atleast_2d(qd), params or DEFAULT_CONTACT)
    return f[:, contact_mask_order(mech), 2, :]


def grf_per_foot(contact: np.ndarray) -> np.ndarray:
    """``(K, 2, 2)``: heel plus toe of the right and the left foot, from ``contact (K, 4, 2)``."""
    return np.stack([contact[:, 0] + contact[:, 1], contact[:, 2] + contact[:, 3]], axis=1)


def speed_key(speed: float) -> str:
    """The speed as the file name writes it: ``v`` and centimetres per second (1.41 m/s: ``v141``)."""
    ok = isinstance(speed, (int, float)) and math.isfinite(speed) and 0 < speed < 10
    if not ok or abs(speed * 100 - round(speed * 100)) > 1e-6:
        raise ValueError(f"stride: field 'speed': expected a speed in (0, 10) m/s in steps of 0.01, got {speed!r}")
    return f"v{round(speed * 100):d}"


def check_variant(variant: str) -> str:
    if variant not in VARIANTS:
        raise ValueError(f"stride: field 'variant': expected one of {', '.join(VARIANTS)}, got {variant!r}")
    return variant


def path_of(mech_name: str, variant: str, speed: float, folder: Path | None = None) -> Path:
    """Where the stride of ``(mechanism, variant, speed)`` is stored; always a file inside ``folder``."""
    stem = file_stem(f"{mech_name}-{check_variant(variant)}-{speed_key(speed)}")
    return (DATA if folder is None else Path(folder)) / f"{stem}.npz"


def save(stride: StoredStride, mech: Mechanism, folder: Path | None = None) -> Path:
    """Write ``stride`` (atomically) under its key, with the mechanism's definition and digest."""
    from exo_bench.bench.output.provenance import atomic_path

    meta = {**stride.meta, **identity.stored_identity(mech)}
    for key in ("variant", "speed", "stride_length", "settings"):
        if key not in meta:
            raise ValueError(f"stride: field 'meta.{key}': expected it, got none")
    check_shapes({k: np.asarray(getattr(stride, k)) for k in ARRAYS}, mech, "stride to save")
    path = path_of(mech.name, meta["variant"], meta["speed"], folder)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = json.dumps(meta, allow_nan=False, sort_keys=True)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            arrays: dict[str, Any] = {k: np.asarray(getattr(stride, k), dtype=float) for k in ARRAYS}
            np.savez_compressed(f, meta=np.array(text), **arrays)
    return path


def check_shapes(arrays: dict[str, np.ndarray], mech: Mechanism, source: str) -> None:
    """A one-line ValueError unless every array has the shape the module docstring states."""
    K = arrays["t"].shape[0] if arrays["t"].ndim == 1 else -1
    want: dict[str, tuple[int, ...]] = {"t": (K,), "residuals": (K, 3), "contact": (K, 4, 2), "grf": (K, 2, 2)}
    want |= {k: (K, mech.dof) for k in ("q", "qd", "qdd", "tau")}
    want |= {"moments": (K, 8), "rod_forces": (K, mech.nlinks - 1)}
    for k, shape in want.items():
        if arrays[k].shape != shape or K < 3:
            raise ValueError(f"stride: {source}: field {k!r}: expected shape {shape} (K >= 3), got {arrays[k].shape}")
        if not np.all(np.isfinite(arrays[k])):
            raise ValueError(f"stride: {source}: field {k!r}: expected finite values, got a NaN or an infinity")
    steps = np.diff(arrays["t"])
    if not np.all(steps > 0):
        at = int(np.argmax(~(steps > 0)))
        raise ValueError(
            f"stride: {source}: field 't': expected increasing times, got t[{at}] = {arrays['t'][at]!r} then "
            f"t[{at + 1}] = {arrays['t'][at + 1]!r}"
        )


def _check_meta(meta: dict[str, Any], variant: str, speed: float, source: str) -> None:
    """A one-line ValueError naming the file unless ``meta`` is the stride of its file's key (its
    variant and speed) and the fields it holds have their types: numbers are real, positive and finite,
    the solver and the provenance objects, the names lists of strings (an edited file is refused, not
    described)."""

    def bad(key: str, want: str) -> ValueError:
        return ValueError(f"stride: {source}: field 'meta.{key}': expected {want}, got {meta.get(key)!r}")

    if meta.get("variant") != variant:
        raise bad("variant", f"{variant!r} (the file's key)")
    for key in ("speed", "stride_length", "body_weight"):
        x = meta.get(key, 1.0 if key == "body_weight" else None)
        if not (isinstance(x, int | float) and not isinstance(x, bool) and np.isfinite(x) and x > 0):
            raise bad(key, "a positive finite number")
    if speed_key(meta["speed"]) != speed_key(speed):
        raise bad("speed", f"{speed:g} m/s (the file's key)")
    for key in ("solver", "provenance", "settings"):
        if not isinstance(meta.get(key, {}), dict):
            raise bad(key, "an object")
    check_settings(meta.get("settings", {}), f"stride: {source}", "meta.settings.")
    for key in ("joint_names", "rod_names", "telescopic", "contact_names", "feet"):
        x = meta.get(key, [])
        if not (isinstance(x, list) and all(isinstance(n, str) for n in x)):
            raise bad(key, "a list of names")


def _check_mechanism(meta: dict[str, Any], mech: Mechanism, source: str) -> None:
    if meta.get("mechanism_digest") == identity.digest(mech):
        return
    stored = meta.get("mechanism_definition")
    why = identity.difference(stored, identity.dynamics(mech)) if isinstance(stored, dict) else "no definition stored"
    raise ValueError(
        f"stride: the stored stride {source} was solved for another mechanism than {mech.name!r} ({why or 'digest differs'}); "
        f"a stored stride is reused only for an equal mechanism: {HOW_TO_SOLVE}"
    )


def load(variant: str, speed: float, mech: Mechanism | None = None, folder: Path | None = None) -> StoredStride:
    """The stored stride of ``variant`` at ``speed`` for ``mech`` (the 2D human preset by default); a
    one-line ValueError when there is none, it cannot be read, or it was solved for another mechanism."""
    if mech is None:
        from exo_bench.models.mechanism.presets import human

        mech = human(2)
    p = path_of(mech.name, variant, speed, folder)
    if not p.is_file():
        known = ", ".join(sorted(x.stem for x in p.parent.glob("*.npz")))
        raise ValueError(f"stride: no stored stride {p.name} in {p.parent} (stored: {known or 'none'}); {HOW_TO_SOLVE}")
    meta, arrays = read_stored(p, ARRAYS, "stride")
    _check_meta(meta, variant, speed, str(p))
    _check_mechanism(meta, mech, str(p))
    check_shapes(arrays, mech, str(p))
    return StoredStride(**arrays, meta=meta, path=str(p))


def stored(folder: Path | None = None) -> list[tuple[str, float]]:
    """``(variant, speed)`` of every stride stored for the 2D human in ``folder``, sorted."""
    from exo_bench.models.mechanism.presets import human

    name = file_stem(human(2).name)
    out = []
    for p in sorted((DATA if folder is None else Path(folder)).glob(f"{name}-*-*.npz")):
        variant, _, speed = p.stem.removeprefix(f"{name}-").rpartition("-")
        if variant in VARIANTS:
            try:
                out.append((variant, int(speed.removeprefix("v")) / 100))
            except ValueError:
                continue
    return sorted(out)


def trials_of(variant: str, speed: float, mech: Mechanism, root: Path) -> list[tuple[str, StoredStride]]:
    """``(name, stride)`` of every trial under ``root`` (a folder per trial, :mod:`~.trials`) that holds a
    stride of ``variant`` at ``speed`` for ``mech``, by name; none when ``root`` is not a folder."""
    found = []
    for d in sorted(p for p in Path(root).glob("*") if p.is_dir()) if Path(root).is_dir() else []:
        try:
            found.append((d.name, load(variant, speed, mech, d)))
        except ValueError:
            continue
    return found


__all__ = [
    "ARRAYS",
    "CONTACTS",
    "DATA",
    "FEET",
    "VARIANTS",
    "StoredStride",
    "check_settings",
    "contact_forces",
    "contact_of",
    "grf_per_foot",
    "load",
    "path_of",
    "save",
    "stored",
    "trials_of",
]
