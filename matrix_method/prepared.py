"""The matrix family as prepared models: the per-mechanism coefficients computed once.

* ``matrix`` (:class:`MatrixProducts`): the paper's route. Form every matrix of eq. (5)/(17) from
  the closed forms (3D: the corrected transitions (18), nothing divides), then the products with
  the rate vectors. Mass matrix and bias forces are native (the ``A, B, Lambda`` blocks; the
  products with ``qdd = 0``).
* ``matrix-factored`` (:class:`MatrixFactored`): the same equations in factored form, no matrix
  formed (:func:`exo_bench.matrix_method.numpy_kernels.matrix.inverse_dynamics` says how the factorisation follows from
  the closed forms). The fast path.
* ``matrix-paper`` (:class:`MatrixPaper`): eq. (18) exactly as printed, misprints and divisions
  included. **Wrong in 3D by design** (reports/errata.md): kept to expose the misprints.
* ``recurrence`` (:class:`Recurrence`): the matrices grown link by link by eqs. (22)-(26), then
  the products.

**Kernels.** ``matrix``, ``matrix-factored`` and ``recurrence`` take the option ``kernel``:
``"numba"`` (the default) runs the compiled loops of :mod:`exo_bench.matrix_method.numba_kernels.common` (one sample or
a batch, threads for large batches; compiled on first use and cached on disk), ``"numpy"`` the
vectorised numpy reference of :mod:`exo_bench.matrix_method.numpy_kernels.matrix`/:mod:`exo_bench.matrix_method.recurrence`.
Both compute the same arithmetic and agree to rounding (tests/test_compiled.py). With
``check=False`` a numba model's call on one sample is the kernel call writing into ``out`` (or a
new array): nothing else runs.
"""

from __future__ import annotations

import warnings

import numpy as np

from exo_bench.matrix_method.numba_kernels import (
    common as compiled,
    factored as compiled_factored,
    matrix as compiled_matrix,
    recurrence as compiled_recurrence,
)
from exo_bench.matrix_method.numpy_kernels import matrix as numeric
from exo_bench.matrix_method.numba_kernels import lean as compiled_lean, simd as compiled_simd
from exo_bench.models.simd_blocks import ThreadScratch
from exo_bench.matrix_method import recurrence as _recurrence
from exo_bench.matrix_method.closed_forms.coefficients import signed_coupling, signed_gravity
from exo_bench.matrix_method.kernel_choice import KERNEL_CHOICES, kernel_option  # noqa: F401 (KERNEL_CHOICES re-exported)
from exo_bench.models.mechanism import Mechanism, split
from exo_bench.models.prepared import PreparedModel, SerialKernelModel, unchecked_states

_F8 = np.dtype(np.float64)
#: O(1) bounds test of the lean path (the one check_out uses): an out overlapping an input goes to the checked path, which refuses it
_may_overlap = np.may_share_memory


def _tile_option(method: str, tile, block=None) -> int:
    """The option ``tile`` (samples evaluated together); ``block``, its old name, still accepted with a
    DeprecationWarning ("block" also names a coordinate block)."""
    if block is not None:
        warnings.warn(f"{method}: option 'block' is now called 'tile'", DeprecationWarning, stacklevel=4)
        tile = block
    if isinstance(tile, bool) or not isinstance(tile, (int, np.integer)) or tile < 1:
        raise ValueError(f"{method}: option 'tile': expected a number of samples >= 1, got {tile!r}")
    return int(tile)


class _MatrixFamily(PreparedModel):
    def __init__(self, mechanism: Mechanism, tile: int = numeric.TILE, *, block: int | None = None):
        tile = _tile_option(self.method, tile, block)
        super().__init__(mechanism, tile=tile)
        self.tile = tile
        self.coupling = np.ascontiguousarray(signed_coupling(mechanism))  # c_ij = mu_ij s_i s_j
        self.gravity_coefficients = np.ascontiguousarray(signed_gravity(mechanism))  # nu_i s_i

    def matrices(self, q: np.ndarray) -> dict[str, dict[str, np.ndarray]]:
        """Every matrix of eq. (5)/(17) at ``(S, dof)`` configurations, ``block -> name -> array``."""
        raise NotImplementedError

    def _tiles(self, q, qd, qdd, fn) -> np.ndarray:
        out = np.empty_like(q)
        for s in range(0, q.shape[0], self.tile):
            b = slice(s, s + self.tile)
            out[b] = fn(q[b], qd[b], qdd[b])
        return out

    def _inverse_dynamics(self, q, qd, qdd):
        mech = self._mechanism
        return self._tiles(q, qd, qdd, lambda a, b, c: numeric.generalised_forces(mech, self.matrices(a), b, c))

    def _mass_matrix(self, q):
        return numeric.mass_matrix_from_matrices(self._mechanism, self.matrices(q))

    def _bias_forces(self, q, qd):
        return numeric.generalised_forces(self._mechanism, self.matrices(q), qd, np.zeros_like(q))


class _WithNumbaKernel(_MatrixFamily, SerialKernelModel):
    """A matrix-family model with the option ``kernel`` (``"numba"`` or ``"numpy"``). Subclasses set
    :attr:`_kernels` (dim -> serial, parallel compiled kernels) and may add per-mechanism kernel
    arguments in :meth:`_kernel_extra`."""

    _kernels: dict = {}

    def __init__(
        self, mechanism: Mechanism, tile: int = numeric.TILE, kernel: str = "numba", *, block: int | None = None
    ):
        kernel = kernel_option(self.method, kernel)
        super().__init__(mechanism, _tile_option(self.method, tile, block))
        self._options["kernel"] = kernel
        self.kernel = kernel
        self._numpy = kernel == "numpy"
        self.serial_kernel, self.parallel_kernel = self._kernels[mechanism.dim]
        #: the kernel's arguments before the states: ``serial_kernel(*kernel_args, q, qd, qdd)``
        #: is the compiled call for flat C-ordered states (what a numba model's call runs).
        self.kernel_args = (
            compiled.params(self.coupling, self.gravity_coefficients, mechanism.g),
            *self._kernel_extra(mechanism),
        )

    def _kernel_extra(self, mechanism: Mechanism) -> tuple:
        return ()

    def inverse_dynamics(self, q, qd, qdd, check: bool = True, out=None) -> np.ndarray:
        if check or self._numpy:
            return PreparedModel.inverse_dynamics(self, q, qd, qdd, check, out)
        unchecked_states(self.method, self._dof, (q, qd, qdd), out)  # memory safety: layout, shapes, out
        if q.ndim == 1:  # one sample: the serial kernel on the arrays as given
            return self._serial(q, qd, qdd, out)
        if out is None:  # a batch: the compiled kernel, no chunks (O(n^2) scratch)
            return self._inverse_dynamics(q, qd, qdd)
        return self._compiled(q, qd, qdd, out)

    inverse_dynamics.__doc__ = PreparedModel.inverse_dynamics.__doc__

    def _compiled(self, q, qd, qdd, out=None):
        """The compiled kernel on ``(samples, dof)`` states (flattened: views when C-ordered), into
        ``out`` (C-ordered) or a new array."""
        o = self._results.empty(q.shape) if out is None else out  # C-ordered whatever q is: reshape(-1) is a view
        compiled.run(
            self.serial_kernel,
            self.parallel_kernel,
            (*self.kernel_args, q.reshape(-1), qd.reshape(-1), qdd.reshape(-1), o.reshape(-1)),
            q.shape[0],
        )
        return o


class MatrixProducts(_WithNumbaKernel):
    """Method ``matrix``: form every matrix of eq. (5)/(17) from the closed forms (3D: the planar
    matrices and those of the straightened model, then the corrected eq. (18)), then the products
    with the rate vectors, in tiles of ``tile`` samples."""

    method = "matrix"

    @classmethod
    def sample_bytes(cls, nlinks: int, dim: int) -> float:
        n, d = nlinks, dim
        return 8.0 * ((24 if d == 2 else 44) * n * n + 40 * n)

    _kernels = compiled_matrix.KERNELS

    def _inverse_dynamics(self, q, qd, qdd):
        return super()._inverse_dynamics(q, qd, qdd) if self._numpy else self._compiled(q, qd, qdd)

    def matrices(self, q):
        mech = self._mechanism
        phi, _, l = split(mech, q)
        flat = numeric._planar(mech, phi, l, np.cos, np.sin, self.coupling, self.gravity_coefficients)
        if mech.dim == 2:
            return flat
        straight = numeric._planar(
            mech, np.zeros_like(phi), l, np.cos, np.sin, self.coupling, self.gravity_coefficients
        )
        _, psi, _ = split(mech, q)
        return numeric.spatial_from_planar(psi, l, flat, straight, self.gravity_coefficients)


class MatrixFactored(_WithNumbaKernel):
    """Method ``matrix-factored``: eq. (5)/(17) in factored form, no matrix formed.

    Every element is ``c_ij`` times a dot product of a vector of link i and one of link j, so the
    sum over the matrices of a block is ``r_a,i . sum_j c_ij kappa_j`` (the derivation is in
    :func:`exo_bench.matrix_method.numpy_kernels.matrix.inverse_dynamics`). Samples go on the fast axis in tiles of
    ``tile``. The kernel forms no matrix, so the mass matrix and the bias forces are derived from
    its inverse dynamics (``native_terms`` is False); :meth:`matrices` is the closed forms'."""

    method = "matrix-factored"

    @classmethod
    def sample_bytes(cls, nlinks: int, dim: int) -> float:
        n, d = nlinks, dim
        return 8.0 * (8 * d * n + 40 * n)

    _kernels = compiled_factored.KERNELS

    def __init__(
        self, mechanism: Mechanism, tile: int = numeric.TILE, kernel: str = "numba", *, block: int | None = None
    ):
        super().__init__(mechanism, _tile_option(self.method, tile, block), kernel)
        #: the batched path of ``kernel="numba"``: the kernel that vectorises across samples
        #: (:mod:`exo_bench.matrix_method.numba_kernels.simd`); one sample runs :attr:`serial_kernel`
        self.batch_kernel = compiled_simd.KERNELS[mechanism.dim]
        #: Each thread's scratch for :attr:`batch_kernel`, reused from call to call.
        self.batch_scratch = ThreadScratch(compiled_simd.scratch, mechanism.nlinks, mechanism.dim)
        self._lean = None  # the lean one-sample entry, resolved on first use
        n = mechanism.nlinks
        self._kernel = numeric._factored_2d if mechanism.dim == 2 else numeric._factored_3d
        self._nu = self.gravity_coefficients[:, None]
        self._n, self._g = n, mechanism.g
        self._products = MatrixProducts(mechanism, self.tile, kernel="numpy")

    def inverse_dynamics(self, q, qd, qdd, check: bool = True, out=None) -> np.ndarray:
        if not check and out is not None and not self._numpy:
            # the lean path (matrix_method/numba_kernels/lean.py): one sample into out; what unboxing
            # trusts is checked here, the shapes and strides in compiled code
            lean = self._lean or self._resolve_lean()
            try:
                if (
                    q.ndim == 1
                    and qd.ndim == 1
                    and qdd.ndim == 1
                    and out.ndim == 1
                    and q.dtype is _F8
                    and qd.dtype is _F8
                    and qdd.dtype is _F8
                    and out.dtype is _F8
                    and out.flags.writeable
                    and not (_may_overlap(out, q) or _may_overlap(out, qd) or _may_overlap(out, qdd))
                    and lean(self._params, q, qd, qdd, out)
                ):
                    return out
            except AttributeError:
                pass
        return _WithNumbaKernel.inverse_dynamics(self, q, qd, qdd, check, out)

    inverse_dynamics.__doc__ = PreparedModel.inverse_dynamics.__doc__

    def _resolve_lean(self):
        self._params = self.kernel_args[0]
        self._lean = compiled_lean.entry(self._mechanism.dim, self._params)
        # the compiled wrapper, where it was built: from the next call on, model.inverse_dynamics is
        # it, and it passes every call it does not take (check=True, no out, batches) to this method
        fast = compiled_lean.c_call(
            self._mechanism.dim, self._params, type(self).inverse_dynamics.__get__(self, type(self)), self._dof
        )
        if fast is not None:
            self.inverse_dynamics = fast
        return self._lean

    def _compiled(self, q, qd, qdd, out=None):
        """The batched path: :attr:`batch_kernel` over ``(samples, dof)`` states (flat views), into
        ``out`` or a new C-ordered array, split over threads for large batches (:func:`exo_bench.matrix_method.numba_kernels.simd.run`)."""
        o = self._results.empty(q.shape) if out is None else out
        compiled_simd.run(
            self.batch_kernel,
            self.kernel_args[0],
            q.reshape(-1),
            qd.reshape(-1),
            qdd.reshape(-1),
            o.reshape(-1),
            q.shape[0],
            scratch=self.batch_scratch,
        )
        return o

    def _inverse_dynamics(self, q, qd, qdd):
        if not self._numpy:
            return self._compiled(q, qd, qdd)
        kernel, n, g, c, nu = self._kernel, self._n, self._g, self.coupling, self._nu
        if q.shape[0] <= self.tile:
            return kernel(n, g, c, nu, q.T.copy(), qd.T.copy(), qdd.T.copy()).T
        return self._tiles(q, qd, qdd, lambda a, b, d: kernel(n, g, c, nu, a.T.copy(), b.T.copy(), d.T.copy()).T)

    def matrices(self, q):
        return self._products.matrices(q)

    _mass_matrix = PreparedModel._mass_matrix  # derived from the factored inverse dynamics
    _bias_forces = PreparedModel._bias_forces


class MatrixPaper(_MatrixFamily):
    """Method ``matrix-paper``: eq. (17) with the matrices of eq. (18) **exactly as printed**.

    Wrong in 3D by design: the printed misprints (reports/errata.md) give wrong forces, and where a
    printed line divides by an exact zero (``sin phi_i = 0`` at ``phi_i = 0``) the forces are NaN and
    a :class:`RuntimeWarning` names the samples. In 2D it is the closed forms and correct."""

    method = "matrix-paper"

    @classmethod
    def sample_bytes(cls, nlinks: int, dim: int) -> float:
        n, d = nlinks, dim
        return 8.0 * ((24 if d == 2 else 48) * n * n + 60 * n)

    def matrices(self, q):
        return numeric.paper_matrices(self._mechanism, q)

    def _inverse_dynamics(self, q, qd, qdd):
        return numeric.warn_paper_nan(
            numeric.generalised_forces(self._mechanism, self.matrices(q), qd, qdd), stacklevel=3
        )


class Recurrence(_WithNumbaKernel):
    """Method ``recurrence``: the matrices grown link by link by eqs. (22)-(26) (3D: the planar
    recurrence at the configuration and for the straightened model, then eq. (18)), then the
    products with the rate vectors."""

    method = "recurrence"

    @classmethod
    def sample_bytes(cls, nlinks: int, dim: int) -> float:
        n, d = nlinks, dim
        return 8.0 * ((40 if d == 2 else 80) * n * n + 60 * n)

    _kernels = compiled_recurrence.KERNELS

    def _kernel_extra(self, mechanism):
        return compiled_recurrence.tables(mechanism)

    def _inverse_dynamics(self, q, qd, qdd):
        return super()._inverse_dynamics(q, qd, qdd) if self._numpy else self._compiled(q, qd, qdd)

    def matrices(self, q):
        return _recurrence.matrices(self._mechanism, q)
