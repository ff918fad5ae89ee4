"""The checks of every derivative call of :class:`exo_bench.models.derivatives.derivatives.Derivatives`, on the states
and on the answers: shapes and sample counts (always), the values (with ``check``), the singular and
ill-conditioned states that forward dynamics refuses, naming the link, and no NaN or inf returned.

A mixin (:class:`DerivativeChecks`) that needs only ``self.mechanism``; split out of
:mod:`exo_bench.models.derivatives.derivatives` (one responsibility per file: that module computes, this one refuses).
"""

from __future__ import annotations

import numpy as np

from exo_bench.models.runtime.conditioning import (
    CouplingCondition,
    check_conditioning,
    check_finite,
    coupling_condition,
    coupling_reason,
)
from exo_bench.models.mechanism.mechanism import Mechanism, as_states
from exo_bench.models.mechanism.singularity import SingularConfigurationError, mechanism_reasons, singular_reasons
from exo_bench.models.states.states import coordinate_names, is_one_sample


def _real(source: str, name: str, a) -> np.ndarray:
    """``a`` as a float array if it holds real numbers (any layout, lists too); a ValueError naming the
    field otherwise: strings ("0.3"), booleans, Decimals and complex numbers are not read as numbers,
    with or without ``check`` (the main calls with ``check=False`` take float64 arrays only)."""
    raw = a if isinstance(a, np.ndarray) else np.asarray(a)
    if raw.dtype.kind not in "iuf" or isinstance(raw, np.ma.MaskedArray):
        what = "a masked array" if isinstance(raw, np.ma.MaskedArray) else f"dtype {raw.dtype}"
        raise ValueError(f"{source}: field '{name}': expected real numbers, got {what}")
    return np.asarray(raw, dtype=float)


class DerivativeChecks:
    """The checks of the derivative calls (module docstring), on ``self.mechanism``."""

    mechanism: Mechanism

    def _states(self, source: str, names: tuple[str, ...], arrays, check: bool):
        """The arrays as ``(S, dof)`` float arrays, and whether one ``(dof,)`` sample was given.
        Shapes and sample counts are checked with or without ``check`` (a ValueError naming the field,
        the expected and the actual count: never numpy's reshape error); ``check`` also validates the
        values of the first three (:func:`exo_bench.models.mechanism.mechanism.as_states`) and that the others
        (directions, weights) are finite."""
        single = is_one_sample(arrays[0])
        d = self.mechanism.dof
        shaped: list = []
        for name, a in zip(names, arrays):
            a = _real(source, name, a) if not check or len(shaped) >= 3 else a
            nd = np.ndim(a)
            if nd not in (1, 2) or np.shape(a)[-1] != d or (nd == 1) != single:
                want = f"({d},)" if single else f"(samples, {d})"
                raise ValueError(f"{source}: field '{name}': expected shape {want}, got {np.shape(a)}")
            shaped.append(a)
        counts = [np.shape(a)[0] if not single else 1 for a in shaped]
        for name, c in zip(names[1:], counts[1:]):
            if c != counts[0]:
                raise ValueError(
                    f"{source}: field '{name}': expected {counts[0]} sample{'s' * (counts[0] != 1)} "
                    f"(as {names[0]}), got {c}"
                )
        if check:
            try:
                shaped[:3] = list(as_states(self.mechanism, shaped[0], shaped[1], shaped[2], source=source))
            except ValueError as e:  # the third array of as_states is called qdd
                raise ValueError(str(e).replace("field 'qdd'", f"field '{names[2]}'")) from None
            for name, a in zip(names[3:], shaped[3:]):
                bad = ~np.isfinite(a)
                if bad.any():
                    s, j = (int(x[0]) for x in np.nonzero(np.atleast_2d(bad)))
                    raise ValueError(f"{source}: field '{name}': sample {s}, entry {j}: expected a finite value")
        return [np.ascontiguousarray(np.atleast_2d(np.asarray(a, dtype=float))) for a in shaped], single

    @property
    def coupling_condition(self) -> CouplingCondition:
        """The mechanism's part of the condition of ``M`` (:mod:`exo_bench.models.runtime.conditioning`), on first use."""
        c = getattr(self, "_coupling_condition", None)
        if c is None:
            c = self._coupling_condition = coupling_condition(self.mechanism)
        return c

    def _clear(self, q: np.ndarray) -> bool:
        """Every sample clears the singular and conditioning bounds by a margin: the compiled pass of
        :mod:`exo_bench.models.runtime.forward_check` (False: the exact checks decide and name why)."""
        clear = getattr(self, "_clear_pass", None)
        if clear is None:
            from exo_bench.models.runtime.forward_check import checks, plan_of

            plan = plan_of(self.mechanism, self.coupling_condition)
            clear = self._clear_pass = checks(self.mechanism.nlinks, plan)[0]
        return clear(q)

    def _refuse_singular(self, q: np.ndarray, check: bool) -> None:
        """What forward dynamics refuses: a link that moves no mass (with or without ``check``), and with
        ``check`` a singular state (naming the link) or one beyond the conditioning bound."""
        mech = self.mechanism
        if np.isinf(self.coupling_condition.kappa):
            raise SingularConfigurationError([f"sample 0: {coupling_reason(mech, self.coupling_condition)}"])
        if check and not self._clear(q):
            reasons = [f"sample {s}: {r}" for s, rs in enumerate(singular_reasons(mech, q)) for r in rs]
            if reasons:
                raise SingularConfigurationError(reasons)
            check_conditioning(mech, q, self.coupling_condition)

    def _refuse_singular_states(self, q: np.ndarray, source: str) -> None:
        """The inverse calls' refusal (with ``check``): the states where forward dynamics refuses (a rod of
        length zero, a vertical rod, beyond the conditioning bound), with its reasons prefixed by
        ``source``. Inverse dynamics has no division, but ``M = dtau/dqdd`` is singular there and the
        chart of a vertical rod is. A link that moves no mass is the mechanism's, not the states': there
        the inverse calls stay defined (and the states' conditioning is not estimated)."""
        if self._clear(q):
            return
        mech = self.mechanism
        always = set(mechanism_reasons(mech))
        reasons = [f"sample {s}: {r}" for s, rs in enumerate(singular_reasons(mech, q)) for r in rs if r not in always]
        try:
            if reasons:
                raise SingularConfigurationError(reasons)
            if coupling_reason(mech, self.coupling_condition) is None:
                check_conditioning(mech, q, self.coupling_condition)
        except SingularConfigurationError as e:
            e.args = (f"{source}: {e}",)
            raise

    def _finite_inverse(self, source: str, out: tuple[np.ndarray, ...], names: tuple[str, ...]) -> None:
        """Never NaN or inf from an inverse product (``(S, dof)`` arrays): a ValueError naming the field of
        the result, the sample, the coordinate and its link (inverse dynamics is defined there; the
        inputs are too large for float64). One isfinite pass per array."""
        for x, name in zip(out, names):
            if np.isfinite(x).all():  # not a sum under np.errstate: entering one costs ~5 us
                continue
            s, j = (int(i) for i in np.argwhere(~np.isfinite(x))[0])
            i, mech = j % self.mechanism.nlinks, self.mechanism
            raise ValueError(
                f"{source}: field '{name}' sample {s} coordinate {coordinate_names(mech)[j]} (link {i + 1}, "
                f"{mech.names[i]!r}): expected a finite result, got {x[s, j]!r}: the directions, weights or "
                "states are too large for float64"
            )

    def _finite(self, out: tuple[np.ndarray, ...], names: tuple[str, ...]) -> None:
        """Never NaN or inf: a vector names its coordinate, a Jacobian the row of its coordinate."""
        for x, name in zip(out, names):
            if np.isfinite(x.sum()):  # one pass, no temporary: NaN and inf propagate (a false alarm only on overflow)
                continue
            if x.ndim == 2:
                check_finite(self.mechanism, x, name)
            else:
                check_finite(self.mechanism, np.where(np.isfinite(x).all(axis=2), 0.0, np.inf), name)
