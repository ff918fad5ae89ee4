"""Forward dynamics' refusal of singular configurations, the part of every prepared model that decides
it: :class:`Regular`, a base of :class:`~exo_bench.models.runtime.prepared.PreparedModel`.

``M(q)`` is exactly singular where a rod has length zero or (3D) is vertical, or where the mechanism's
mass coupling is (:mod:`exo_bench.models.mechanism.singularity`); it is singular to working precision where the
conditioning test that every method shares says so (:mod:`exo_bench.models.runtime.conditioning`). The common
case, a state clear of every bound, is decided by one compiled pass (:mod:`exo_bench.models.runtime.forward_check`,
resolved on first use with the model's plan); near a bound the exact checks decide and name the sample,
the link and the reason. A method may override :meth:`Regular.check_regular` with its own O(n) test
(newton-euler does), never a public call.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from exo_bench.models.runtime.conditioning import CouplingCondition, check_conditioning, coupling_condition
from exo_bench.models.mechanism.singularity import SingularConfigurationError, singular_reasons

if TYPE_CHECKING:
    from exo_bench.models.mechanism.mechanism import Mechanism


class Regular:
    """The refusal of singular configurations by forward dynamics (module docstring), for a model whose
    mechanism is ``_mechanism``."""

    _mechanism: Mechanism
    #: forward dynamics' compiled checks ``(clear, finite)`` (models/runtime/forward_check.py), resolved on first use
    _forward_checks: tuple[Callable[..., bool], Callable[..., bool]] | None = None
    #: their plan (:func:`exo_bench.models.runtime.forward_check.plan_of`), with them
    forward_plan: Any = None

    def check_regular(self, q: np.ndarray) -> None:
        """Raise :class:`SingularConfigurationError` where ``M(q)`` is exactly singular
        (:func:`exo_bench.models.mechanism.singularity.singular_reasons`), then where it is singular to working
        precision: the conditioning test that every method shares, O(n) per sample
        (:func:`exo_bench.models.runtime.conditioning.check_conditioning`)."""
        if (self._forward_checks or self._resolve_forward_checks())[0](q):  # compiled: the common case
            return
        q = q if q.ndim == 2 else q.reshape(1, -1)
        reasons = [f"sample {s}: {r}" for s, rs in enumerate(singular_reasons(self._mechanism, q)) for r in rs]
        if reasons:
            raise SingularConfigurationError(reasons)
        check_conditioning(self._mechanism, q, self.coupling_condition)

    def _resolve_forward_checks(self) -> tuple[Callable[..., bool], Callable[..., bool]]:
        """``(clear, finite)`` (models/runtime/forward_check.py :func:`checks`) and their plan, kept."""
        from exo_bench.models.runtime.forward_check import checks, plan_of

        self.forward_plan = plan_of(self._mechanism, self.coupling_condition)
        self._forward_checks = checks(self._mechanism.nlinks, self.forward_plan)
        return self._forward_checks

    @property
    def coupling_condition(self) -> CouplingCondition:
        """The mechanism's part of the condition of ``M`` (:func:`exo_bench.models.runtime.conditioning.coupling_condition`),
        O(n), estimated on first use."""
        c = getattr(self, "_coupling_condition", None)
        if c is None:
            c = self._coupling_condition = coupling_condition(self._mechanism)
        return c
