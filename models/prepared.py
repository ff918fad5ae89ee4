"""The prepared model: a method's per-mechanism work done once, then cheap calls.

Like Pinocchio's ``Model``/``Data`` split, :class:`PreparedModel` holds what is fixed for a
mechanism (aggregates, coupling signs, index arrays, lambdified functions, the Pinocchio model);
its calls take states and return forces, with no lookup, no cache and no validation left in the
hot path when ``check=False``.

Every method implements :meth:`PreparedModel._inverse_dynamics` on validated ``(samples, dof)``
float arrays. :meth:`PreparedModel.mass_matrix` and :meth:`PreparedModel.bias_forces` are native
where a method overrides ``_mass_matrix``/``_bias_forces`` (``native_terms`` says which) and are
otherwise derived from inverse dynamics, which is linear in ``qdd``: ``h = ID(q, qd, 0)`` and
``M e_k = ID(q, 0, e_k) - ID(q, 0, 0)`` (:func:`terms_from_inverse_dynamics`).

**Validation.** The mechanism is validated when it is built (:class:`~models.mechanism.Mechanism`
is frozen and checks itself). ``check=True`` (the default) validates the states with
:func:`~models.mechanism.as_states`: shapes, finiteness, non-negative lengths, each with a
message that names the array, the sample and the coordinate. ``check=False`` is the fast path
for trusted hot loops (an ODE right-hand side, a controller): it checks no value, only what
memory safety needs (:func:`unchecked_states`: C-ordered float64 arrays of one shape ``(dof,)``
or ``(samples, dof)``, and ``out`` of that shape), so a wrong layout is a ValueError, never a
read or write past an array.

**Chunks.** A batch is evaluated :attr:`PreparedModel.chunk_samples` samples at a time into a
preallocated result, so that a batch of any length needs the inputs, the result and a fixed
working set (one chunk's temporaries): 10^6 samples take no more scratch memory than one chunk
(bench/test_memory.py measures it). The default chunk keeps the working set near
:data:`CHUNK_BYTES` for the largest per-sample temporaries of any method (``n x n`` matrices);
``exo_bench.prepare`` sets it from the method's calibrated cost model (bench/resources.py).

**Threads and processes.** A prepared model holds no mutable state shared between calls other
than per-thread scratch space, so one model can serve several threads. It pickles by
reconstruction: the pickle holds the mechanism, the method's name and its options, and
unpickling prepares the model again in the receiving process (for ``lagrange`` that derives the
equations again, within the same budget).
"""

from __future__ import annotations

import os
from typing import Any, ClassVar

import numpy as np

from exo_bench.models.mechanism import Mechanism, as_states


class MissingExtra(ValueError):
    """A method's optional engine is not installed (e.g. MuJoCo or Drake, extra ``[peers]``): a
    ValueError whose message names the extra; ``skip_reason`` (the same line) makes studies and
    benchmarks skip the method with it instead of failing."""

    def __init__(self, message: str):
        super().__init__(message)
        self.skip_reason = message


def terms_from_inverse_dynamics(inverse_dynamics, dof: int, q: np.ndarray, qd: np.ndarray):
    """``M (S, dof, dof)`` and ``h (S, dof)`` from any inverse dynamics ``(q, qd, qdd) -> tau`` on
    ``(samples, dof)`` arrays, in ONE batched call.

    Inverse dynamics is linear in ``qdd``: ``ID(q, qd, qdd) = M(q) qdd + h(q, qd)``. Per sample the
    batch holds ``(q, qd, 0)`` (gives ``h``), ``(q, 0, 0)`` (gravity only) and ``(q, 0, e_k)`` for
    every coordinate ``k``; then ``M e_k = ID(q, 0, e_k) - ID(q, 0, 0)``. The subtraction costs at
    most ``eps * |gravity forces| / |M e_k|`` relative, which the tests bound against CRBA.
    """
    S, d = q.shape
    k = dof + 2
    Q = np.repeat(q, k, axis=0)                      # (S*k, d): each sample's q, k times
    QD = np.zeros_like(Q)
    QD[::k] = qd                                     # first row of each block: the real rates
    QDD = np.zeros_like(Q)
    rows = np.arange(S)[:, None] * k + 2 + np.arange(d)[None, :]
    QDD[rows.ravel(), np.tile(np.arange(d), S)] = 1.0
    tau = inverse_dynamics(Q, QD, QDD).reshape(S, k, d)
    h = tau[:, 0]
    M = np.swapaxes(tau[:, 2:] - tau[:, 1:2], 1, 2)  # column k of M is ID(q, 0, e_k) - ID(q, 0, 0)
    return M, h


def _rebuild(cls, mechanism: Mechanism, options: dict):
    return cls(mechanism, **options)


#: Target bytes of one chunk's temporaries (see :func:`default_chunk_samples`).
CHUNK_BYTES = 64 * 2**20
#: No chunk is longer than this: past it a longer chunk saves no measurable call overhead.
MAX_CHUNK = 65536


def default_chunk_samples(dof: int, bytes_per_sample: float | None = None) -> int:
    """Samples per chunk so that one chunk's temporaries stay near :data:`CHUNK_BYTES`.

    ``bytes_per_sample`` defaults to a bound for every method: ``8 (dof^2 + 64 dof)`` bytes (the
    matrix family forms ``(samples, n, n)`` matrices, some dozens of them, ``n <= dof / 2``;
    the others keep a few dozen ``(samples, dof)`` arrays)."""
    if bytes_per_sample is None:
        bytes_per_sample = 8.0 * (dof * dof + 64 * dof)
    return int(max(1, min(MAX_CHUNK, CHUNK_BYTES // max(bytes_per_sample, 1.0))))


def available_memory() -> int | None:
    """Bytes that can be allocated without swapping: ``MemAvailable`` of /proc/meminfo, or less
    when a cgroup (container) limit leaves less (``memory.max - memory.current``); elsewhere the
    free physical pages; None where that is unknown."""
    avail = None
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    avail = int(line.split()[1]) * 1024
                    break
    except (OSError, ValueError, IndexError):
        pass
    if avail is None:
        try:
            avail = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (OSError, ValueError, AttributeError):
            return None
    try:
        with open("/sys/fs/cgroup/memory.max") as f:
            cap = f.read().strip()
        with open("/sys/fs/cgroup/memory.current") as f:
            used = int(f.read().strip())
        if cap != "max":
            avail = min(avail, max(int(cap) - used, 0))
    except (OSError, ValueError):
        pass
    return avail


#: The share of :func:`available_memory` a run may plan to use by default: the rest is left to
#: the system and to other processes, so that a run that fits its estimate is not killed by the
#: kernel's out-of-memory killer (a 3D chain of 300 links estimated at 23.7 GB, run with 23.9 GB
#: available, was killed).
USABLE_SHARE = 0.8


def usable_memory() -> int | None:
    """The default memory limit: :data:`USABLE_SHARE` of :func:`available_memory` (None if unknown)."""
    avail = available_memory()
    return None if avail is None else int(USABLE_SHARE * avail)


def _check_out(out, shape: tuple, method: str = "") -> None:
    """``out`` of :meth:`PreparedModel.inverse_dynamics`: a writable C-ordered float64 array of ``shape``."""
    if not (isinstance(out, np.ndarray) and out.dtype == np.float64 and out.shape == tuple(shape)
            and out.flags.c_contiguous and out.flags.writeable):
        got = (f"{type(out).__name__}" if not isinstance(out, np.ndarray) else
               f"{out.dtype} array of shape {out.shape}" + ("" if out.flags.c_contiguous else ", not C-ordered")
               + ("" if out.flags.writeable else ", read-only"))
        raise ValueError(f"{method + ': ' if method else ''}field 'out': expected a writable C-ordered float64 array of shape {tuple(shape)}, got {got}")


_F8 = np.dtype(np.float64)


def _describe(a) -> str:
    if not isinstance(a, np.ndarray):
        return "None" if a is None else type(a).__name__
    return (f"{a.dtype.str if a.dtype.byteorder == '>' else a.dtype} array of shape {a.shape}" + ("" if a.flags.c_contiguous else ", not C-ordered")
            + ("" if a.flags.writeable else ", read-only"))


def unchecked_states(method: str, dof: int, arrays: tuple, out=None) -> None:
    """What ``check=False`` still checks: memory safety, never values.

    The kernels read ``samples * dof`` float64 numbers from each state array and write as many
    into ``out``, through raw pointers (numba does not check bounds). So every array must be a
    C-ordered float64 ndarray of one shape, ``(dof,)`` or ``(samples, dof)``, and ``out`` (if given)
    a writable one of that shape. One comparison per property; a ValueError naming the field,
    the expected and the actual array otherwise (a Fortran-ordered batch from a DataFrame would
    otherwise be read in the wrong order, an ``out`` too small written past its end).
    """
    q = arrays[0]
    try:                                     # straight-line: about 0.15 us on the quiet 2-core machine
        s = q.shape
        ok = len(s) < 3 and s[-1] == dof and q.dtype is _F8 and q.flags.c_contiguous
        for a in arrays[1:]:
            ok = ok and a.shape == s and a.dtype is _F8 and a.flags.c_contiguous
        if ok and out is not None:
            ok = out.shape == s and out.dtype is _F8 and out.flags.c_contiguous and out.flags.writeable
    except (AttributeError, IndexError):
        ok = False
    if ok:
        return
    names = ("q", "qd", "qdd")[:len(arrays)]
    expected = (f"C-ordered float64 arrays of one shape, (dof,) or (samples, dof) with dof = {dof} "
                "(check=False checks memory safety only; check=True converts any layout and dtype)")
    for name, a in zip(names, arrays):
        good = (isinstance(a, np.ndarray) and a.dtype == _F8 and a.flags.c_contiguous and a.ndim in (1, 2)
                and a.shape[-1:] == (dof,) and a.shape == getattr(q, "shape", None))
        if not good:
            raise ValueError(f"{method}: field '{name}': expected {expected}, got {_describe(a)}"
                             + ("" if name == "q" or not isinstance(q, np.ndarray) else f" (q: {q.shape})"))
    if out is not None:
        _check_out(out, q.shape, method)
    # here: safe after all (a float64 dtype object that is not numpy's own, as some libraries make)


def _require_rates(method: str, *rates) -> None:
    """``qd`` (and ``qdd``) are required where the call needs them: None is not "zero"."""
    for name, a in zip(("qd", "qdd"), rates):
        if a is None:
            raise ValueError(f"{method}: field '{name}': expected an array of shape (dof,) or (samples, dof), "
                             "got None (pass zeros for a state at rest)")


def _chunks(S: int, size: int):
    for s0 in range(0, S, size):
        yield slice(s0, min(S, s0 + size))


#: Builds the derivatives of a prepared model's equations, ``provider(mechanism, method)``: registered
#: by ``exo_bench.bench.methods`` (``matrix_method.derivatives.derivatives_of``; this layer cannot
#: import matrix_method). None until then.
derivative_provider = None


class PreparedModel:
    """A mechanism prepared for one method. Subclasses set :attr:`method` and implement
    :meth:`_inverse_dynamics`; they may override ``_mass_matrix`` and ``_bias_forces``."""

    #: The registry name of the method; the algorithm timed under it.
    method: ClassVar[str] = ""

    def __init__(self, mechanism: Mechanism, **options: Any):
        if not isinstance(mechanism, Mechanism):
            raise ValueError(f"{self.method}: expected a Mechanism (exo_bench.Mechanism or exo_bench.load_mechanism), "
                             f"got {type(mechanism).__name__}")
        self._mechanism = mechanism
        self._options = dict(options)
        self._dof = mechanism.dof
        self._chunk = default_chunk_samples(mechanism.dof)

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
    def chunk_samples(self) -> int:
        """Samples evaluated at a time: batches longer than this are split into chunks written
        into one preallocated result (the working set stays that of one chunk)."""
        return self._chunk

    @chunk_samples.setter
    def chunk_samples(self, value: int) -> None:
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"{self.method}: chunk_samples: expected an integer >= 1, got {value!r}")
        self._chunk = int(value)

    def _chunked(self, fn, arrays, out_shape) -> np.ndarray:
        """``fn(*chunks)`` over the rows of ``arrays`` in chunks of :attr:`chunk_samples`, into one
        result of shape ``(S, *out_shape)``; one call when the batch fits in a chunk."""
        S = arrays[0].shape[0]
        if S <= self._chunk:
            return fn(*arrays)
        out = np.empty((S, *out_shape))
        for c in _chunks(S, self._chunk):
            out[c] = fn(*(a[c] for a in arrays))
        return out

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
        -> (qdd, dqdd_dq, dqdd_dqd, Minv)``, batch-first, and ``.source`` (which physics computes
        them): :mod:`matrix_method.derivatives`. Needs the optional extra ``casadi``."""
        if getattr(self, "_derivatives", None) is None:
            if derivative_provider is None:
                raise ValueError(f"{self.method}: derivatives: prepare the model with exo_bench.prepare "
                                 "(it registers the derivative provider)")
            self._derivatives = derivative_provider(self._mechanism, self.method)
        return self._derivatives

    # ------------------------------------------------------------------ calls
    def inverse_dynamics(self, q, qd, qdd, check: bool = True, out=None) -> np.ndarray:
        """Generalised forces ``tau = [M_phi..., M_psi..., F...]`` of the paper's absolute
        coordinates for states in block order ``[phi..., psi..., l...]``: ``(dof,)`` in gives
        ``(dof,)`` out, ``(samples, dof)`` gives ``(samples, dof)``. ``out``: a preallocated
        C-ordered float64 array of the result's shape, written and returned (a loop of calls then
        allocates nothing: the compiled kernels write into it directly)."""
        if check:
            single = np.ndim(q) == 1
            _require_rates(self.method, qd, qdd)
            q, qd, qdd = as_states(self._mechanism, q, qd, qdd)
            if out is not None:
                _check_out(out, q.shape[1:] if single else q.shape, self.method)
            tau = self._chunked(self._inverse_dynamics, (q, qd, qdd), (self._dof,))
            tau = tau[0] if single else tau
        else:
            unchecked_states(self.method, self._dof, (q, qd, qdd), out)
            if q.ndim == 1:
                tau = self._inverse_dynamics(q[None], qd[None], qdd[None])[0]
            elif q.shape[0] <= self._chunk:
                tau = self._inverse_dynamics(q, qd, qdd)
            else:
                tau = self._chunked(self._inverse_dynamics, (q, qd, qdd), (self._dof,))
        if out is None:
            return tau
        out[...] = tau
        return out

    def mass_matrix(self, q, check: bool = True) -> np.ndarray:
        """The mass matrix ``M(q) = d tau / d qdd``, ``(dof, dof)`` or ``(samples, dof, dof)``."""
        single = np.ndim(q) == 1
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
        single = np.ndim(q) == 1
        if check:
            _require_rates(self.method, qd)
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
        if check:
            _require_rates(self.method, qd)
            q, qd, _ = as_states(self._mechanism, q, qd)
        else:
            unchecked_states(self.method, self._dof, (q, qd))
        if q.ndim != 2:
            raise ValueError(f"{self.method}: mass_matrix_and_bias takes a batch: expected q of shape (samples, "
                             f"{self._dof}), got {q.shape}")
        d = self._dof
        if self.native_terms:
            return (self._chunked(self._mass_matrix, (q,), (d, d)), self._chunked(self._bias_forces, (q, qd), (d,)))
        # (dof + 2) inverse-dynamics rows per sample: chunks of fewer samples keep the same working set
        size = max(1, self._chunk // (d + 2))
        S = q.shape[0]
        if S <= size:
            return terms_from_inverse_dynamics(self._inverse_dynamics, d, q, qd)
        M, h = np.empty((S, d, d)), np.empty((S, d))
        for c in _chunks(S, size):
            M[c], h[c] = terms_from_inverse_dynamics(self._inverse_dynamics, d, q[c], qd[c])
        return M, h

    # ------------------------------------------------------------------ per method
    def _inverse_dynamics(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    def _mass_matrix(self, q: np.ndarray) -> np.ndarray:
        d = self._dof
        size = max(1, self._chunk // (d + 2))   # (dof + 2) inverse-dynamics rows per sample
        if q.shape[0] <= size:
            return terms_from_inverse_dynamics(self._inverse_dynamics, d, q, np.zeros_like(q))[0]
        M = np.empty((q.shape[0], d, d))
        for c in _chunks(q.shape[0], size):
            M[c] = terms_from_inverse_dynamics(self._inverse_dynamics, d, q[c], np.zeros_like(q[c]))[0]
        return M

    def _bias_forces(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        return self._inverse_dynamics(q, qd, np.zeros_like(q))
