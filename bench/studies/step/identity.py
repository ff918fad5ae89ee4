"""Which mechanism a stored step was solved for, and whether a mechanism is that one.

A step solves the dynamics of one mechanism: its dimension, g, tree, signs, masses, middle-mass
fractions and link names (the step problem gives each link a role by its name). Those are the
mechanism's JSON without its own name (:func:`dynamics`); :func:`digest` is the SHA-256 of their
canonical JSON (sorted keys, no white space, floats as Python writes them: exact). A step stores its
mechanism's definition and digest (:func:`stored_identity`), and is reused only for a mechanism of the
same digest (:func:`check_same`). A step stored before the digest is checked against the preset it was
solved for (its ``meta["mechanism"]``, an ``exo5`` preset name).
"""

from __future__ import annotations

import hashlib
import json
from typing import Any

from exo_bench.models.mechanism.mechanism import Mechanism

#: How to get a step for a mechanism that has none: the one line every refusal ends with.
HOW_TO_SOLVE = (
    "solve one with exo-bench gait --solve --store (the presets exo5-2d and exo5-3d), or with "
    "exo_bench.bench.studies.step.problem.solve and exo_bench.bench.studies.step.data.save"
)

__all__ = ["HOW_TO_SOLVE", "check_same", "difference", "digest", "dynamics", "stored_identity"]


def dynamics(mech: Mechanism) -> dict[str, Any]:
    """Everything that defines the mechanism's dynamics and the step's roles: its JSON without its name."""
    d = mech.to_dict()
    d.pop("name", None)
    return d


def _digest_of(definition: dict[str, Any]) -> str:
    text = json.dumps(definition, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()


def digest(mech: Mechanism) -> str:
    """The SHA-256 (hex) of the canonical JSON of :func:`dynamics`."""
    return _digest_of(dynamics(mech))


def stored_identity(mech: Mechanism) -> dict[str, Any]:
    """The entries a stored step's meta carries about its mechanism."""
    return {"mechanism": mech.name, "mechanism_definition": dynamics(mech), "mechanism_digest": digest(mech)}


def difference(stored: dict[str, Any], here: dict[str, Any]) -> str:
    """The first field where two :func:`dynamics` differ, in words (an empty string when equal)."""
    for key in ("dim", "g"):
        if stored.get(key) != here.get(key):
            return f"{key} {stored.get(key)!r} stored, {here.get(key)!r} here"
    a, b = stored.get("links", []), here.get("links", [])
    if len(a) != len(b):
        return f"{len(a)} links stored, {len(b)} here"
    for i, (la, lb) in enumerate(zip(a, b)):
        for key in ("name", "parent", "sign", "masses", "n"):
            if la.get(key) != lb.get(key):
                x, y = (_parent(v) if key == "parent" else repr(v) for v in (la.get(key), lb.get(key)))
                return f"link {i + 1} ({lb.get('name')!r}): {key} {x} stored, {y} here"
    return "" if stored == here else "the definitions differ"


def _parent(p: Any) -> str:
    """A parent index of the JSON (0-based, -1 the support) as messages number links (from 1)."""
    return "O (the support)" if p == -1 else f"link {p + 1}" if isinstance(p, int) else repr(p)


def _solved_for(meta: dict[str, Any], source: str) -> dict[str, Any]:
    """The :func:`dynamics` of the mechanism a stored step was solved for."""
    if "mechanism_digest" in meta:
        definition = meta.get("mechanism_definition")
        if not isinstance(definition, dict) or _digest_of(definition) != meta["mechanism_digest"]:
            raise ValueError(
                f"step: {source}: field 'meta.mechanism_definition': expected the definition of digest "
                f"{str(meta['mechanism_digest'])[:12]}..., got one that does not match it"
            )
        return definition
    from exo_bench.models.mechanism.presets import PRESETS

    name = meta.get("mechanism")
    if not isinstance(name, str) or name not in PRESETS or not name.startswith("exo5-"):
        raise ValueError(
            f"step: {source}: field 'meta.mechanism': expected the preset a step stored without a digest "
            f"was solved for (exo5-2d or exo5-3d), got {name!r}"
        )
    return dynamics(PRESETS[name]())


def check_same(meta: dict[str, Any], mech: Mechanism, source: str) -> None:
    """Nothing when ``mech`` is the mechanism the stored step (``meta``, read from ``source``) was
    solved for; else one line saying it is another one, where they differ, and how to solve one."""
    solved = _solved_for(meta, source)
    if _digest_of(solved) == digest(mech):
        return
    raise ValueError(
        f"step: the stored step {source} was solved for another mechanism than {mech.name!r} "
        f"({difference(solved, dynamics(mech))}); a stored step is reused only for an equal mechanism: " + HOW_TO_SOLVE
    )
