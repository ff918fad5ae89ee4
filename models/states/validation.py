"""Validation of a mechanism's fields at the edge: every message names the link, the field, and the expected
and actual values; the JSON reader that refuses duplicate keys; the force bound that keeps float64 from
overflowing (:func:`force_scale_log10`)."""

from __future__ import annotations

import json
import math
from typing import TYPE_CHECKING, Any

import numpy as np

from exo_bench.models.files import check_name

if TYPE_CHECKING:
    from exo_bench.models.mechanism.mechanism import Mechanism


def _where(i: int, name: str | None) -> str:
    return f"link {i + 1}" + (f" ({name!r})" if name else "")


class DuplicateKey(ValueError):
    pass


def unique_keys(pairs: list[tuple[str, Any]]) -> dict:
    """``object_pairs_hook`` of every JSON the suite reads: a key given twice in one object is an
    error (``json`` would keep the last one silently)."""
    out = {}
    for k, v in pairs:
        if k in out:
            raise DuplicateKey(f"duplicate key {k!r} in one object (JSON readers disagree on which one counts)")
        out[k] = v
    return out


def loads(text: str) -> Any:
    """``json.loads`` refusing duplicate keys (:func:`unique_keys`)."""
    return json.loads(text, object_pairs_hook=unique_keys)


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, (bool, np.bool_))


def _finite(x: Any) -> bool:
    """A number that is a finite float64 (an integer too large for a float is not)."""
    try:
        return math.isfinite(float(x))
    except (OverflowError, TypeError, ValueError):
        return False


#: Why a negative g is refused (the choice is documented in docs/errors.md and tested).
_NEGATIVE_G = (
    "expected g >= 0: g is the magnitude of gravity, which acts along -y in 2D and -z in 3D by convention "
    "(a model that hangs from its support is described by its angles, not by reversing gravity)"
)

#: The largest force scale accepted: a bound on ``|tau|`` of ``1e300`` leaves float64 (largest 1.8e308)
#: a margin of 1e8 for the sums and products inside every method.
MAX_FORCE_SCALE = 1e300


def _lg(x: float) -> float:
    return math.log10(x) if x > 0 else -math.inf


_LOG4 = math.log10(4)


def force_scale_base(mech: Mechanism) -> tuple[float, float]:
    """The mechanism's part of :func:`force_scale_log10`, computed once per mechanism:
    ``log10(total mass bound) + 2 log10(n)`` and ``log10(g)``."""
    n = max(len(mech.masses), 1)
    total_log = _lg(max((max(m) for m in mech.masses), default=0.0)) + math.log10(3 * n)  # >= log10(total mass)
    return total_log + 2 * math.log10(n), _lg(mech.g)


def force_scale_from(base: float, lg_g: float, length: float, rate: float, acceleration: float) -> float:
    """:func:`force_scale_log10` from the mechanism's part (:func:`force_scale_base`). The compiled
    check of states (models/states/validation_pass.py ``_scale``) makes the same operations in the same order."""
    dyn = max(0.0, _lg(acceleration), 2 * _lg(rate), lg_g) + _LOG4
    return base + 2 * _lg(1.0 + length) + dyn


def force_scale_log10(mech: Mechanism, length: float = 1.0, rate: float = 1.0, acceleration: float = 1.0) -> float:
    """``log10`` of a bound on the generalised forces of ``mech`` at rod lengths up to ``length``,
    rates up to ``rate`` and accelerations up to ``acceleration``:
    ``total mass * n^2 * (1 + length)^2 * (1 + acceleration + rate^2 + g)``.

    Every term of the equations of motion is a mass times at most two lengths (summed over at most
    n links along a branch) times an acceleration, a squared rate or g, so ``|tau|`` is below this
    bound. Computed in logarithms, so it is finite for any finite input."""
    return force_scale_from(*force_scale_base(mech), length, rate, acceleration)


def validate(m: Mechanism) -> None:
    """Check every field once; messages name the link, the field, expected and actual. The
    mechanism's own name first (:func:`exo_bench.models.files.check_name`): every message starts
    with it."""
    check_name(m.name, "mechanism: field 'name'")
    if m.dim not in (2, 3) or isinstance(m.dim, bool):
        raise ValueError(f"{m.name}: field 'dim': expected 2 or 3, got {m.dim!r}")
    if not _is_number(m.g) or not _finite(m.g):
        raise ValueError(f"{m.name}: field 'g': expected a finite number, got {m.g!r}")
    if m.g < 0:
        raise ValueError(f"{m.name}: field 'g': {_NEGATIVE_G}, got {m.g!r}")
    n = len(m.parent)
    if n == 0:
        raise ValueError(f"{m.name}: field 'links': expected at least one link, got none")
    for fld in ("sign", "masses", "n", "names"):
        if len(getattr(m, fld)) != n:
            raise ValueError(
                f"{m.name}: field '{fld}': expected {n} entries (one per link), got {len(getattr(m, fld))}"
            )
    for i in range(n):
        where = f"{m.name}: {_where(i, m.names[i])}"
        check_name(m.names[i], f"{where}: field 'name'")  # models/files.py: what every name may hold
        p = m.parent[i]
        if not isinstance(p, (int, np.integer)) or isinstance(p, bool) or not (-1 <= p < i):
            if i == 0:
                expected = "-1 (the support: the first link has no earlier link to hang from)"
            else:
                expected = f"-1 (the support) or the 0-based index of an earlier link, 0..{i - 1} (links 1..{i})"
            raise ValueError(f"{where}: field 'parent': expected {expected}, got {p!r}")
        s = m.sign[i]
        if isinstance(s, bool) or s not in (1, -1):
            raise ValueError(f"{where}: field 'sign': expected +1 or -1, got {s!r}")
        ms = m.masses[i]
        if len(ms) != 3:
            raise ValueError(f"{where}: field 'masses': expected three masses [m0, m1, m2], got {len(ms)}")
        for b, x in enumerate(ms):
            if not _is_number(x) or not _finite(x) or x < 0:
                raise ValueError(f"{where}: field 'masses[{b}]': expected a finite mass >= 0, got {x!r}")
        f = m.n[i]
        if not _is_number(f) or not _finite(f) or not (0.0 < f < 1.0):
            raise ValueError(f"{where}: field 'n': expected a fraction in (0, 1), got {f!r}")
    if all(x == 0 for ms in m.masses for x in ms):
        raise ValueError(f"{m.name}: field 'masses': expected at least one positive mass, got all zero")
    scale = force_scale_log10(m)
    if not scale < math.log10(MAX_FORCE_SCALE):
        big = max(max(ms) for ms in m.masses)
        raise ValueError(
            f"{m.name}: field 'masses': the forces of masses this large overflow float64 even at unit "
            f"lengths and rates (largest mass {big:.3g} kg, force bound 1e{scale:.0f} > "
            f"{MAX_FORCE_SCALE:.0e}); express the model in other units"
        )
