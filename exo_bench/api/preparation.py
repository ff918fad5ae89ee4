""":func:`prepare`, the library's entry point, and :class:`PreparedSet`, the prepared models of one run.

``prepare(mechanism, name, **options)`` builds a method's
:class:`~exo_bench.models.runtime.prepared.PreparedModel` once (all per-mechanism work); its
``inverse_dynamics(q, qd, qdd)`` takes batch-first ``(samples, dof)`` (or one ``(dof,)``) arrays in
the block order ``[phi..., psi..., l...]`` and returns ``[M_phi..., M_psi..., F...]``: the
generalised forces of the paper's absolute coordinates. The model is the class's own: calling the
class directly gives the same model (the same chunks, from the class's ``sample_bytes``).
"""

from __future__ import annotations

from typing import Any

from exo_bench.api.methods import method_class, spec
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.runtime.prepared import PreparedModel


def prepare(mechanism: Mechanism, method: str = "matrix-factored", **options: Any) -> PreparedModel:
    """Prepare ``mechanism`` for ``method`` once; call the result's ``inverse_dynamics``,
    ``mass_matrix`` and ``bias_forces`` as often as needed.

    ``options`` are the method's constructor arguments (``threads`` for pinocchio, ``budget`` and
    ``interrupt`` for lagrange, ``tile`` and ``kernel`` for the matrix family); an unknown option is a ValueError.
    A lagrange derivation whose estimated time exceeds its ``budget`` (or whose memory exceeds what
    a run may use) is refused before it starts (:func:`exo_bench.api.cost_model.check`, a ValueError
    naming the estimate and the budget). Pinocchio's ``threads`` is a count from 1 to
    :func:`exo_bench.models.machine.memory.max_count`, and its Data per thread (and the pool's copy)
    are estimated by the same cost model and refused before any is made when they exceed the memory.
    """
    cls = method_class(method)
    _refuse_uncompiled_kernels(method, options)
    if spec(method).derivation_budget or _threads(method, options) > 1:
        # refuse up front a derivation estimated over its budget or the memory, or a Data per thread
        # (and the pool's copy) that would not fit: the cost model's estimate, before any is made
        from exo_bench.api.cost_model import check

        check(mechanism, method, 1, options)
    try:
        model = cls(mechanism, **options)
    except TypeError as e:
        if "unexpected keyword argument" in str(e):
            import inspect

            known = [p for p in inspect.signature(cls.__init__).parameters if p not in ("self", "mechanism")]
            raise ValueError(
                f"{method}: unknown option(s) {sorted(options)}: expected among {known or 'none'}"
            ) from None
        raise
    return model


def _threads(method: str, options: dict[str, Any]) -> int:
    """The option ``threads`` (pinocchio's), checked against its bound (1 for other methods)."""
    if not spec(method).threads_option or "threads" not in options:
        return 1
    from exo_bench.models.machine.memory import check_count

    return check_count(f"{method}: option 'threads'", options["threads"])


def _refuse_uncompiled_kernels(method: str, options: dict[str, Any]) -> None:
    """Under ``NUMBA_DISABLE_JIT``, refuse (one ValueError naming the variable and why) a method's
    compiled kernels: their SIMD tiles are numba intrinsics, which cannot run as Python (a batch raised
    "NotImplementedError: <intrinsic tile_in>"); its numpy kernels (``kernel="numpy"``) still run."""
    from exo_bench.api.methods import METHODS

    method_spec = METHODS.get(method)
    if method_spec is None or not any(k.compiled for k in method_spec.kernels_for(options.get("kernel"))):
        return
    from exo_bench.models.machine.numba_runtime import jit_disabled

    if jit_disabled():
        import os

        raise ValueError(
            f"NUMBA_DISABLE_JIT={os.environ.get('NUMBA_DISABLE_JIT', '')!r}: method {method!r} runs numba's compiled "
            "kernels (option kernel 'numba', the default), whose SIMD tiles are numba intrinsics that cannot run "
            "as Python; expected NUMBA_DISABLE_JIT unset (or 0), or prepare()'s option kernel='numpy'"
        )


class PreparedSet:
    """The prepared models of one run: ``models(mechanism, method)`` prepares on first use, with
    the run's options for that method (``{"lagrange": {"budget": 10.0}}``), and returns the same
    model afterwards. A study creates one per run and passes it down, so nothing is cached
    behind the caller's back and a failure to prepare (over budget) is raised where it is used."""

    def __init__(self, options: dict[str, dict] | None = None) -> None:
        self.options = {k: dict(v) for k, v in (options or {}).items()}
        self._models: dict[tuple, PreparedModel] = {}

    def __call__(self, mechanism: Mechanism, method: str) -> PreparedModel:
        key = (mechanism, method)
        if key not in self._models:
            self._models[key] = prepare(mechanism, method, **self.options.get(method, {}))
        return self._models[key]

    def clear(self) -> None:
        self._models.clear()
