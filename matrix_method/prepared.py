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
``"numba"`` (the default) runs compiled loops (:mod:`exo_bench.matrix_method.numba_kernels`: one sample
or a batch, threads for large batches; compiled on first use and cached on disk), ``"numpy"`` the
vectorised numpy reference of :mod:`exo_bench.matrix_method.numpy_kernels.matrix`/:mod:`exo_bench.matrix_method.recurrence`.
Both compute the same arithmetic and agree to rounding (tests/test_compiled.py). Each kernel is an object
of :mod:`exo_bench.matrix_method.kernels` listed in the class's ``kernels`` (and its MethodSpec); the
public calls are :class:`~exo_bench.models.runtime.prepared.PreparedModel`'s, which run the kernels' entries.
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
from exo_bench.matrix_method.numba_kernels import simd as compiled_simd
from exo_bench.models.machine.simd_blocks import ThreadScratch
from exo_bench.matrix_method import recurrence as _recurrence
from exo_bench.matrix_method.closed_forms.coefficients import signed_coupling, signed_gravity
from exo_bench.matrix_method.kernels import (
    MATRIX_FACTORED_KERNELS,
    MATRIX_KERNELS,
    PRINTED_EQ18_WRONG,
    RECURRENCE_KERNELS,
)
from exo_bench.models.runtime.prepared import select
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import split
from exo_bench.models.runtime.prepared import PreparedModel


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

    #: One sample's temporaries in floats, ``a n^2 + c n``: ``(a in 2D, a in 3D, c)`` (measured).
    _sample_floats: tuple[int, int, int] = (0, 0, 0)

    @classmethod
    def sample_bytes(cls, nlinks: int, dim: int) -> float:
        a2, a3, c = cls._sample_floats
        return 8.0 * ((a2 if dim == 2 else a3) * nlinks * nlinks + c * nlinks)

    def matrices(self, q: np.ndarray) -> dict[str, dict[str, np.ndarray]]:
        """Every matrix of eq. (5)/(17) at ``(S, dof)`` configurations, ``block -> name -> array``."""
        raise NotImplementedError

    def _tiles(self, q, qd, qdd, fn) -> np.ndarray:
        out = np.empty_like(q)
        for s in range(0, q.shape[0], self.tile):
            b = slice(s, s + self.tile)
            out[b] = fn(q[b], qd[b], qdd[b])
        return out

    def numpy_inverse_dynamics(self, q, qd, qdd):
        """The numpy reference: the matrices of :meth:`matrices`, then the products, in tiles."""
        mech = self._mechanism
        return self._tiles(q, qd, qdd, lambda a, b, c: numeric.generalised_forces(mech, self.matrices(a), b, c))

    def _mass_matrix(self, q):
        return numeric.mass_matrix_from_matrices(self._mechanism, self.matrices(q))

    def _bias_forces(self, q, qd):
        return numeric.generalised_forces(self._mechanism, self.matrices(q), qd, np.zeros_like(q))


class _WithKernels(_MatrixFamily):
    """A matrix-family model with the option ``kernel`` (``"numba"`` or ``"numpy"``): the kernel
    objects of :mod:`exo_bench.matrix_method.kernels` listed in :attr:`kernels`, bound to the
    compiled drivers of :attr:`_drivers` (dim -> serial, parallel) and the per-mechanism arguments of
    :meth:`_kernel_extra`."""

    _drivers: dict = {}

    def __init__(
        self, mechanism: Mechanism, tile: int = numeric.TILE, kernel: str = "numba", *, block: int | None = None
    ):
        select(self.method, self.kernels, kernel)  # a bad option is named before any work
        super().__init__(mechanism, _tile_option(self.method, tile, block))
        self.serial_kernel, self.parallel_kernel = self._drivers[mechanism.dim]
        #: the kernel's arguments before the states: ``serial_kernel(*kernel_args, q, qd, qdd, out)``
        #: is the compiled call for flat C-ordered states (what a numba model's one-sample call runs).
        self.kernel_args = (
            compiled.params(self.coupling, self.gravity_coefficients, mechanism.g),
            *self._kernel_extra(mechanism),
        )
        self._prepare_kernels(mechanism)
        self._use_kernels(kernel)

    def _kernel_extra(self, mechanism: Mechanism) -> tuple:
        return ()

    def _prepare_kernels(self, mechanism: Mechanism) -> None:
        """What this method's kernels need besides :attr:`kernel_args` (before they are bound)."""


class MatrixProducts(_WithKernels):
    """Method ``matrix``: form every matrix of eq. (5)/(17) from the closed forms (3D: the planar
    matrices and those of the straightened model, then the corrected eq. (18)), then the products
    with the rate vectors, in tiles of ``tile`` samples."""

    method = "matrix"
    kernels = MATRIX_KERNELS
    _drivers = compiled_matrix.KERNELS

    _sample_floats = (24, 44, 40)

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


class MatrixFactored(_WithKernels):
    """Method ``matrix-factored``: eq. (5)/(17) in factored form, no matrix formed.

    Every element is ``c_ij`` times a dot product of a vector of link i and one of link j, so the
    sum over the matrices of a block is ``r_a,i . sum_j c_ij kappa_j`` (the derivation is in
    :func:`exo_bench.matrix_method.numpy_kernels.matrix.inverse_dynamics`). Samples go on the fast axis in tiles of
    ``tile``. The kernel forms no matrix, so the mass matrix and the bias forces are derived from
    its inverse dynamics (``native_terms`` is False); :meth:`matrices` is the closed forms'.
    ``kernel="numba"`` runs three kernels (:data:`exo_bench.matrix_method.kernels.MATRIX_FACTORED_KERNELS`):
    the SIMD one for batches, the lean one-sample entry (with the per-sample kernel behind it) and
    ``cholesky-forward``, forward dynamics of one sample through the Cholesky factor of the coupling."""

    method = "matrix-factored"
    kernels = MATRIX_FACTORED_KERNELS
    _drivers = compiled_factored.KERNELS

    @classmethod
    def sample_bytes(cls, nlinks: int, dim: int) -> float:
        n, d = nlinks, dim
        return 8.0 * (8 * d * n + 40 * n)

    def _prepare_kernels(self, mechanism: Mechanism) -> None:
        #: the batched path of ``kernel="numba"``: the kernel that vectorises across samples
        #: (:mod:`exo_bench.matrix_method.numba_kernels.simd`); one sample runs :attr:`serial_kernel`
        self.batch_kernel = compiled_simd.KERNELS[mechanism.dim]
        #: Each thread's scratch for :attr:`batch_kernel`, reused from call to call.
        self.batch_scratch = ThreadScratch(compiled_simd.scratch, mechanism.nlinks, mechanism.dim)
        self._kernel = numeric._factored_2d if mechanism.dim == 2 else numeric._factored_3d
        self._nu = self.gravity_coefficients[:, None]
        self._n, self._g = mechanism.nlinks, mechanism.g
        self._products = MatrixProducts(mechanism, self.tile, kernel="numpy")

    def numpy_inverse_dynamics(self, q, qd, qdd):
        """The numpy reference of the factored forms (samples on the fast axis), in tiles."""
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
    known_wrong = PRINTED_EQ18_WRONG

    _sample_floats = (24, 48, 60)

    def matrices(self, q):
        return numeric.paper_matrices(self._mechanism, q)

    def _inverse_dynamics(self, q, qd, qdd):
        return numeric.warn_paper_nan(
            numeric.generalised_forces(self._mechanism, self.matrices(q), qd, qdd), stacklevel=3
        )


class Recurrence(_WithKernels):
    """Method ``recurrence``: the matrices grown link by link by eqs. (22)-(26) (3D: the planar
    recurrence at the configuration and for the straightened model, then eq. (18)), then the
    products with the rate vectors."""

    method = "recurrence"
    kernels = RECURRENCE_KERNELS
    _drivers = compiled_recurrence.KERNELS

    _sample_floats = (40, 80, 60)

    def _kernel_extra(self, mechanism):
        return compiled_recurrence.tables(mechanism)

    def matrices(self, q):
        return _recurrence.matrices(self._mechanism, q)
