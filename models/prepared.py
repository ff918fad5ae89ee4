"""The prepared model: a method's per-mechanism work done once, then cheap calls.

Like Pinocchio's ``Model``/``Data`` split, :class:`PreparedModel` holds what is fixed for a
mechanism (aggregates, coupling signs, index arrays, lambdified functions, the Pinocchio model);
its calls take states and return forces, with no lookup, no cache and no validation left in the
hot path when ``check=False``.

The public calls are defined here once; a method supplies kernels (objects of
:mod:`exo_bench.models.kernels`, listed in its MethodSpec, whose entries the calls run) or implements
:meth:`PreparedModel._inverse_dynamics` on validated ``(samples, dof)`` float arrays. :meth:`PreparedModel.mass_matrix` and :meth:`PreparedModel.bias_forces` are native
where a method overrides ``_mass_matrix``/``_bias_forces`` (``native_terms`` says which) and are
otherwise derived from inverse dynamics, which is linear in ``qdd``: ``h = ID(q, qd, 0)`` and
``M e_k = ID(q, 0, e_k) - ID(q, 0, 0)`` (:func:`terms_from_inverse_dynamics`).

**Validation.** The mechanism is validated when it is built (:class:`~exo_bench.models.mechanism.Mechanism`
is frozen and checks itself). ``check=True`` (the default) validates the states with
:func:`~exo_bench.models.mechanism.as_states`: shapes, finiteness, non-negative lengths, each with a
message that names the array, the sample and the coordinate. ``check=False`` is the fast path
for trusted hot loops (an ODE right-hand side, a controller): it checks no value, only what
memory safety needs (:func:`unchecked_states`: C-ordered float64 arrays of one shape ``(dof,)``
or ``(samples, dof)``, and ``out`` of that shape), so a wrong layout is a ValueError, never a
read or write past an array.

**Chunks.** A batch is evaluated :attr:`PreparedModel.chunk_samples` samples at a time into a
preallocated result, so that a batch of any length needs a fixed working set
(:mod:`exo_bench.models.chunked_calls`, the base class that holds the chunks).

**Threads and processes.** A prepared model holds no mutable state shared between calls other
than per-thread scratch space, so one model can serve several threads. It pickles by
reconstruction: the pickle holds the mechanism, the method's name and its options, and
unpickling prepares the model again in the receiving process (for ``lagrange`` that derives the
equations again, within the same budget).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from exo_bench.models.kernels import Entries, Kernel, select
from exo_bench.models.kernels import load as load_kernels
from exo_bench.models.lean_call import public_call
from exo_bench.models.mechanism import Mechanism, as_states
from exo_bench.models.memory import (
    CHUNK_BYTES,
    MAX_CHUNK,
    USABLE_SHARE,
    available_memory,
    check_batch,
    default_chunk_samples,
    usable_memory,
)
from exo_bench.models.derived_terms import cholesky_solve, terms_from_inverse_dynamics, terms_in_chunks
from exo_bench.models import external_forces
from exo_bench.models.chunked_calls import ChunkedCalls
from exo_bench.models.conditioning import check_finite
from exo_bench.models.regularity import Regular
from exo_bench.models.unchecked import apart, check_out, require_rates, unchecked_forward, unchecked_states
from exo_bench.models.states import checked_states, is_one_sample

#: Re-exported: the memory helpers (models/memory.py) and the ``check=False`` checks (models/unchecked.py)
#: were defined here first and are imported from here.
__all__ = [
    "PreparedModel",
    "MissingExtra",
    "terms_from_inverse_dynamics",
    "cholesky_solve",
    "CHUNK_BYTES",
    "MAX_CHUNK",
    "USABLE_SHARE",
    "available_memory",
    "default_chunk_samples",
    "usable_memory",
    "unchecked_states",
    "unchecked_forward",
]


class MissingExtra(ValueError):
    """A method's optional engine is not installed (e.g. MuJoCo or Drake, extra ``[peers]``): a
    ValueError whose message names the extra; ``skip_reason`` (the same line) makes studies and
    benchmarks skip the method with it instead of failing."""

    def __init__(self, message: str):
        super().__init__(message)
        self.skip_reason = message


def _rebuild(cls, mechanism: Mechanism, options: dict):
    return cls(mechanism, **options)


class PreparedModel(ChunkedCalls, Regular):
    """A mechanism prepared for one method. Subclasses set :attr:`method` and either list their
    :attr:`kernels` (and call :meth:`_use_kernels`) or implement :meth:`_inverse_dynamics`; they may
    override ``_mass_matrix``, ``_bias_forces`` and ``check_regular`` (forward dynamics' refusal of
    singular configurations, :class:`~exo_bench.models.regularity.Regular`), never a public call."""

    #: The registry name of the method; the algorithm timed under it.
    method: ClassVar[str] = ""
    #: Every kernel of the method (the tuple its MethodSpec lists; empty: the method's own
    #: :meth:`_inverse_dynamics`). The option ``kernel`` chooses among them (:meth:`_use_kernels`).
    kernels: ClassVar[tuple[Kernel, ...]] = ()
    #: The option ``kernel`` this model runs ("" for a method without the option).
    kernel: str = ""
    #: Its :attr:`derivatives` differentiate the very passes it evaluates (newton-euler), not merely
    #: equations it agrees with to rounding (their ``source`` says which).
    derivatives_are_its_own: ClassVar[bool] = False
    #: Why its results are known to be wrong (None: they are not), in one line; its MethodSpec lists the
    #: same line (exo_bench.api.methods), and its :attr:`derivatives` are then those of the correct equations.
    known_wrong: ClassVar[str | None] = None
    #: The entries of the chosen kernels (:class:`~exo_bench.models.kernels.Entries`, bound by
    #: :meth:`_use_kernels`; each None where none supplies it): what the calls below run. Set on the
    #: instance only: a class-level default (an instance of a mutable class) kept Python 3.11 from
    #: specialising ``self._entries`` in the calls, about 65 ns of a 0.45 us one-sample call. A slot: the
    #: public call reads it in C at its offset (models/_lean_call.c ``slot_read``; by name it cost 60 ns).
    _entries: Entries
    __slots__ = ("_entries",)  # subclasses keep a __dict__ (Regular has one)

    def __init__(self, mechanism: Mechanism, **options: Any):
        if not isinstance(mechanism, Mechanism):
            raise ValueError(
                f"{self.method}: expected a Mechanism (exo_bench.Mechanism or exo_bench.load_mechanism), "
                f"got {type(mechanism).__name__}"
            )
        self._mechanism = mechanism
        self._options = dict(options)
        self._dof = mechanism.dof
        self._start_chunks(mechanism.dof, mechanism.nlinks, mechanism.dim)  # models/chunked_calls.py
        self._entries = Entries()  # no kernel's entries until _use_kernels

    # ------------------------------------------------------------------ what it is
    @property
    def mechanism(self) -> Mechanism:
        return self._mechanism

    @property
    def options(self) -> dict:
        """The constructor options this model was prepared with (a copy)."""
        return dict(self._options)

    @property
    def dof(self) -> int:
        return self._dof

    @property
    def native_terms(self) -> bool:
        """True when :meth:`mass_matrix` and :meth:`bias_forces` are the method's own, False when
        they are derived from its inverse dynamics."""
        return type(self)._mass_matrix is not PreparedModel._mass_matrix

    def __repr__(self) -> str:
        opts = "".join(f", {k}={v!r}" for k, v in self._options.items())
        return f"<{type(self).__name__} {self.method!r} of {self._mechanism.name!r} ({self._dof} dof){opts}>"

    def __reduce__(self):
        return (_rebuild, (type(self), self._mechanism, self._options))

    @property
    def derivatives(self):
        """The derivatives of this model's equations of motion, built on first use:
        ``.inverse_dynamics(q, qd, qdd) -> (dtau_dq, dtau_dqd, M)``, ``.forward_dynamics(q, qd, tau)
        -> (qdd, dqdd_dq, dqdd_dqd, Minv)``, batch-first, their directional derivatives (``*_jvp``,
        ``*_vjp``) and ``.source`` (which physics computes them): the analytic derivatives of the
        Newton-Euler passes for every method, :mod:`exo_bench.models.derivatives` (CasADi's stay in
        :mod:`exo_bench.matrix_method.derivatives`), their ``source`` from this class's facts
        (:attr:`derivatives_are_its_own`, :attr:`known_wrong`)."""
        if getattr(self, "_derivatives", None) is None:
            from exo_bench.models.derivatives import Derivatives, source_text

            cls = type(self)
            source = source_text(self.method, cls.derivatives_are_its_own, cls.known_wrong is not None)
            self._derivatives = Derivatives(self._mechanism, self.method, source)
        return self._derivatives

    # ------------------------------------------------------------------ kernels
    def _use_kernels(self, option: object) -> str:
        """Run the kernels of the option ``kernel`` (``option``; a ValueError naming the values
        otherwise): their entries (:class:`~exo_bench.models.kernels.Entries`), bound to this model, are
        what the calls below run. Called by a method with kernels once its arguments are prepared."""
        chosen = select(self.method, self.kernels, option)
        self._entries = load_kernels(self, chosen)
        self.kernel = self._options["kernel"] = chosen[0].option
        return self.kernel

    # ------------------------------------------------------------------ calls
    @public_call("lean")  # one sample offered to the lean entry in C first (models/lean_call.py)
    def inverse_dynamics(self, q, qd, qdd, check: bool = True, out=None, f_ext=None) -> np.ndarray:
        """Generalised forces ``tau = [M_phi..., M_psi..., F...]`` of the paper's absolute
        coordinates for states in block order ``[phi..., psi..., l...]``: ``(dof,)`` in gives
        ``(dof,)`` out, ``(samples, dof)`` gives ``(samples, dof)``. ``out``: a preallocated
        C-ordered float64 array of the result's shape, written and returned (a loop of calls then
        allocates nothing: the compiled kernels write into it directly). Without ``out``, a result of
        4 MiB or more reuses the memory of one this model returned before, once nothing refers to that
        one any more (:mod:`exo_bench.models.result_pool`: at most two stay allocated after the caller
        dropped them). ``f_ext``: forces at the point masses, ``(samples, links, 3, dim)`` or ``(links, 3,
        dim)`` (:mod:`exo_bench.models.external_forces`): ``tau = ID - Q(q, f_ext)``."""
        if f_ext is not None:
            return external_forces.inverse_dynamics(self, q, qd, qdd, f_ext, check, out)
        e = self._entries
        # one sample, checked (validated first) or not, in C; None (having touched nothing) where it does not take it
        if (lean := e.lean) is not None and (tau := lean(q, qd, qdd, check, out)) is not None:
            return tau
        check_batch("inverse dynamics", q, self._dof, 4 * self._dof)  # a batch: before the states are copied
        if not check:
            unchecked_states(self.method, self._dof, (q, qd, qdd), out)
            if q.ndim == 1:
                if e.inverse_one is not None:
                    return e.inverse_one(q, qd, qdd, np.empty(self._dof) if out is None else out)
                tau = self._inverse_dynamics(q[None], qd[None], qdd[None])[0]
            elif e.inverse_whole is not None:
                return e.inverse_whole(q, qd, qdd, out)
            else:
                tau = self._chunked(self._inverse_dynamics, (q, qd, qdd), (self._dof,))
        else:
            if qd is None or qdd is None:
                require_rates(self.method, qd, qdd)
            single = q.ndim == 1 if type(q) is np.ndarray else is_one_sample(q)
            q, qd, qdd = checked_states(self._mechanism, q, qd, qdd)  # one C-ordered float64 sample stays 1-D
            if out is not None:
                check_out(out, q.shape[-1:] if single else q.shape, self.method)
            if not single and e.inverse_whole is not None:  # the route of check=False: same numbers
                into = None if out is None or not apart(out, (q, qd, qdd)) else out  # overlap: a copy below
                if (tau := e.inverse_whole(q, qd, qdd, into)) is out:
                    return out
            elif not single:
                tau = self._chunked(self._inverse_dynamics, (q, qd, qdd), (self._dof,))
            elif e.inverse_one is not None:  # the kernel of check=False: check never changes the result
                if q.ndim == 2:
                    q, qd, qdd = q[0], qd[0], qdd[0]
                tau = np.empty(self._dof)  # the route of check=False: lean, else one
                if lean is None or lean(q, qd, qdd, False, tau) is None:
                    tau = e.inverse_one(q, qd, qdd, tau)
            else:
                tau = self._inverse_dynamics(q.reshape(1, -1), qd.reshape(1, -1), qdd.reshape(1, -1))[0]
        if out is None:
            return tau
        out[...] = tau
        return out

    def mass_matrix(self, q, check: bool = True) -> np.ndarray:
        """The mass matrix ``M(q) = d tau / d qdd``, ``(dof, dof)`` or ``(samples, dof, dof)``."""
        single = is_one_sample(q)
        check_batch("mass matrix", q, self._dof, self._dof * (self._dof + 1))
        if check:
            q, _, _ = as_states(self._mechanism, q)
        else:
            unchecked_states(self.method, self._dof, (q,))
            if single:
                q = q[None]
        d = self._dof
        M = self._chunked(self._mass_matrix, (q,), (d, d))
        return M[0] if single else M

    def bias_forces(self, q, qd, check: bool = True) -> np.ndarray:
        """``h(q, qd) = tau(q, qd, 0)``: Coriolis, centrifugal and gravity forces."""
        single = is_one_sample(q)
        check_batch("bias forces", q, self._dof, 3 * self._dof)
        if check:
            require_rates(self.method, qd)
            q, qd, _ = as_states(self._mechanism, q, qd)
        else:
            unchecked_states(self.method, self._dof, (q, qd))
            if single:
                q, qd = q[None], qd[None]
        h = self._chunked(self._bias_forces, (q, qd), (self._dof,))
        return h[0] if single else h

    def mass_matrix_and_bias(self, q, qd, check: bool = True) -> tuple[np.ndarray, np.ndarray]:
        """Both terms of ``M qdd + h = tau`` at once, ``(S, dof, dof)`` and ``(S, dof)`` (batch only):
        one batched inverse-dynamics call where the terms are derived."""
        check_batch("mass_matrix_and_bias", q, self._dof, self._dof * (self._dof + 4))
        if check:
            require_rates(self.method, qd)
            q, qd, _ = as_states(self._mechanism, q, qd)
        else:
            unchecked_states(self.method, self._dof, (q, qd))
        if q.ndim != 2:
            raise ValueError(
                f"{self.method}: mass_matrix_and_bias takes a batch: expected q of shape (samples, "
                f"{self._dof}), got {q.shape}"
            )
        d = self._dof
        if self.native_terms:
            return (self._chunked(self._mass_matrix, (q,), (d, d)), self._chunked(self._bias_forces, (q, qd), (d,)))
        return terms_in_chunks(self._inverse_dynamics, d, q, qd, self._chunk)

    @public_call("forward_lean")
    def forward_dynamics(self, q, qd, tau, check: bool = True, out=None, f_ext=None) -> np.ndarray:
        """Forward dynamics: the accelerations ``qdd`` with ``M(q) qdd + h(q, qd) = tau``, same shapes
        and ``out`` as :meth:`inverse_dynamics`. With ``check`` (the default) the states are
        validated and a singular configuration raises
        :class:`~exo_bench.models.singularity.SingularConfigurationError` (a ValueError) naming the sample, the
        link and the reason (zero length, vertical rod, zero mass), never NaN. A method solves
        ``M qdd = tau - h`` by Cholesky on its own ``M`` and ``h`` unless a kernel supplies forward
        dynamics (newton-euler's O(n) passes; its checked one sample: ``tree-forward``, checks and passes
        in one compiled call, models/forward_check.py). ``f_ext``: forces at the point masses, as in
        :meth:`inverse_dynamics`: ``qdd = FD(q, qd, tau + Q(q, f_ext))``."""
        if f_ext is not None:
            return external_forces.forward_dynamics(self, q, qd, tau, f_ext, check, out)
        e = self._entries
        # one sample in C, checked (states validated, the checks' common case) or not; None where it does not take it
        if (lean := e.forward_lean) is not None and (qdd := lean(q, qd, tau, check, out)) is not None:
            return qdd
        check_batch("forward dynamics", q, self._dof, 4 * self._dof)  # a batch: before the states are copied
        single = q.ndim == 1 if type(q) is np.ndarray else is_one_sample(q)
        if check:
            if qd is None or tau is None:
                require_rates(self.method, qd, tau)
            try:
                q, qd, tau = checked_states(self._mechanism, q, qd, tau, source="forward dynamics")
            except ValueError as err:  # the third array of as_states is called qdd: here it is tau
                raise ValueError(
                    str(err).replace("field 'qdd'", "field 'tau'").replace("qdd must", "tau must")
                ) from None
            if out is not None:
                check_out(out, q.shape[-1:] if single else q.shape, self.method)
            if single and (checked := e.forward_checked) is not None:  # checks and passes compiled
                qdd = checked(q, qd, tau) if q.ndim == 1 else checked(q[0], qd[0], tau[0])
                if out is None:
                    return qdd
                out[...] = qdd
                return out
            if q.ndim == 1:
                q, qd, tau = q[None], qd[None], tau[None]
            self.check_regular(q)
        else:
            unchecked_forward(self.method, self._dof, q, qd, tau, out)
            if single and e.forward_one is not None:
                return e.forward_one(q, qd, tau, np.empty(self._dof) if out is None else out)
            if not single and e.forward_whole is not None:
                return e.forward_whole(q, qd, tau, out)
            if single:
                q, qd, tau = q[None], qd[None], tau[None]
        qdd = self._chunked(self._forward_dynamics, (q, qd, tau), (self._dof,))
        if check and not (self._forward_checks or self._resolve_forward_checks())[1](qdd):
            check_finite(self._mechanism, qdd)  # never NaN or inf (forces too large for float64): named
        qdd = qdd[0] if single else qdd
        if out is None:
            return qdd
        out[...] = qdd
        return out

    # ------------------------------------------------------------------ per method
    def _inverse_dynamics(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        """Inverse dynamics of a validated batch of at most :attr:`chunk_samples` samples: the
        kernels' entry, or the method's own code (a method without kernels overrides this)."""
        if (chunk := self._entries.inverse_chunk) is None:
            raise NotImplementedError(f"{self.method}: no inverse dynamics")
        return chunk(q, qd, qdd)

    def _mass_matrix(self, q: np.ndarray) -> np.ndarray:
        return terms_in_chunks(self._inverse_dynamics, self._dof, q, np.zeros_like(q), self._chunk)[0]

    def _bias_forces(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        return self._inverse_dynamics(q, qd, np.zeros_like(q))

    def _external_forces(self, q: np.ndarray, f: np.ndarray) -> np.ndarray:
        """``Q = sum_k J_k^T f_k``, ``(S, dof)``, of forces ``f`` ``(S, links, 3, dim)`` at the point masses
        (:mod:`exo_bench.models.external_forces`); an engine overrides it with its own."""
        from exo_bench.models.external_forces_compiled import bound  # the parameters, bound once on the model

        return external_forces.generalized_forces_compiled(self._mechanism, q, f, bound(self).params)

    def _forward_dynamics(self, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> np.ndarray:
        if (chunk := self._entries.forward_chunk) is not None:
            return chunk(q, qd, tau)
        M, h = self.mass_matrix_and_bias(q, qd, check=False)
        return cholesky_solve(M, tau - h)
