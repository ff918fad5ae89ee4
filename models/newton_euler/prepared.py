"""Method ``newton-euler`` as a prepared model: O(n) inverse and forward dynamics from the
constant mass matrix of the rod vectors (``M(q) = J^T M_r J``, docs/paper.md).

Prepare time computes the per-link mass sums and factors ``M_r`` once
(:func:`exo_bench.models.newton_euler.passes.prepare_tree`); a singular ``M_r`` (a link and its subtree carry
no mass where its end point moves) is found there and named by :meth:`forward_dynamics`, while
inverse dynamics stays defined. The option ``kernel`` selects the compiled loops
(``"numba"``, the default; :mod:`exo_bench.models.newton_euler.compiled`) or the numpy reference
(:mod:`exo_bench.models.newton_euler.passes`); with ``"numba"``, batches of inverse dynamics (and bias
forces) of at least :data:`exo_bench.models.newton_euler.simd.MIN_SAMPLES` samples run the kernel
that vectorises across samples (:mod:`exo_bench.models.newton_euler.simd`), smaller ones and forward
dynamics the per-sample kernel. The mass matrix ``J^T (mu (x) I) J`` is native (O(n^2) for
the output only, numpy for both kernels); the bias forces are inverse dynamics at ``qdd = 0``.
"""

from __future__ import annotations

import numpy as np

from exo_bench.models.mechanism.aggregates import coupling
from exo_bench.models.runtime.conditioning import check_conditioning
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import split
from exo_bench.models.runtime.prepared import select
from exo_bench.models.newton_euler import compiled, passes, simd
from exo_bench.models.newton_euler.kernels import NEWTON_EULER_KERNELS
from exo_bench.models.newton_euler.passes import prepare_tree
from exo_bench.models.runtime.conditioning import singular_mass_reason
from exo_bench.models.runtime.prepared import PreparedModel
from exo_bench.models.machine.simd_blocks import ThreadScratch
from exo_bench.models.mechanism.singularity import (
    COS_VERTICAL,
    SingularConfigurationError,
    vertical_reason,
    zero_length_reason,
)


class NewtonEuler(PreparedModel):
    """Method ``newton-euler``: a forward pass of the point masses' accelerations and a backward
    pass of the subtree sums of ``m (a + g up)``, O(n) per sample; forward dynamics by the tree
    factor of ``M_r``, O(n) per sample. Its kernels: :data:`exo_bench.models.newton_euler.kernels.NEWTON_EULER_KERNELS`."""

    method = "newton-euler"
    kernels = NEWTON_EULER_KERNELS
    derivatives_are_its_own = True  # its derivatives differentiate these very passes

    @classmethod
    def sample_bytes(cls, nlinks: int, dim: int) -> float:
        """O(n): the numpy kernel's temporaries peak at 48-51 bytes per coordinate and sample (tracemalloc,
        2D and 3D, n = 20 to 300, validated batches), rounded up to 64. The default bound is O(n^2) (the
        matrix family's), which made chunks of one sample at 3D n = 1000 and cost ``check=True`` 13x
        the kernel there."""
        return 8.0 * 8 * dim * nlinks

    def __init__(self, mechanism: Mechanism, kernel: str = "numba"):
        select(self.method, self.kernels, kernel)  # a bad option is named before any work
        super().__init__(mechanism)
        self.tree = prepare_tree(mechanism)
        self.table = self.tree.table()
        self._g, self._dim = float(mechanism.g), int(mechanism.dim)
        #: The compiled drivers and their arguments before the states, as the matrix family has them:
        #: ``serial_kernel(*kernel_args, q, qd, qdd, out)`` is inverse dynamics on flat C-ordered states.
        self.serial_kernel, self.parallel_kernel = compiled.newton_euler, compiled.newton_euler_parallel
        self.kernel_args = (self.table, float(mechanism.g), int(mechanism.dim), False)
        self._forward_args = (self.table, float(mechanism.g), int(mechanism.dim), True)
        #: The batched inverse dynamics of at least :data:`exo_bench.models.newton_euler.simd.MIN_SAMPLES`
        #: samples: the kernel that vectorises across samples, ``batch_kernel(batch_args, q, qd, qdd, out,
        #: start, stop)`` (:mod:`exo_bench.models.newton_euler.simd`), its block size chosen from the links.
        nlinks = int(self.table.shape[1])
        blocks = simd.blocks_for(nlinks)
        self.batch_kernel = blocks.simd_inverse
        #: Each thread's scratch for :attr:`batch_kernel`, reused from call to call.
        self.batch_scratch = ThreadScratch(blocks.scratch, nlinks, self._dim)
        self.batch_args = (self.table, self._g, self._dim)
        #: Why ``M_r`` is singular (every configuration), or None.
        self.singular_mass = (
            None if self.tree.singular < 0 else singular_mass_reason(mechanism, int(self.tree.singular))
        )
        self._use_kernels(kernel)

    # ------------------------------------------------------------------ the numpy reference
    def numpy_inverse_dynamics(self, q, qd, qdd):
        """The numpy reference of the two passes (:mod:`exo_bench.models.newton_euler.passes`)."""
        return passes.inverse_dynamics(self.tree, self._dim, self._g, q, qd, qdd)

    def numpy_forward_dynamics(self, q, qd, tau):
        """The numpy reference of forward dynamics by the tree factor of ``M_r``."""
        return passes.forward_dynamics(self.tree, self._dim, self._g, q, qd, tau)

    def _mass_matrix(self, q):
        if (c := self.__dict__.get("_coupling")) is None:  # once per model: one call fewer per call
            c = self.__dict__["_coupling"] = coupling(self._mechanism)
        return passes.mass_matrix(self.tree, self._dim, c, q)  # n x n: the output's order

    def _bias_forces(self, q, qd):
        return self._inverse_dynamics(q, qd, np.zeros_like(q))

    def check_regular(self, q: np.ndarray) -> None:
        """O(n) per sample: ``M_r`` singular (found at prepare time), a rod of length zero, or (3D) a
        vertical rod, in the words of :mod:`exo_bench.models.mechanism.singularity`; then the conditioning test
        that every method shares (:func:`exo_bench.models.runtime.conditioning.check_conditioning`, O(n) per
        sample: the cosines computed here, the mechanism's part once)."""
        mech = self._mechanism
        reasons = [] if self.singular_mass is None else [self.singular_mass]
        _, psi, l = split(mech, q)
        bad = l == 0
        cos = None if psi is None else np.abs(np.cos(psi))
        vertical = np.zeros_like(bad) if cos is None else (cos <= COS_VERTICAL) & ~bad
        rows = np.flatnonzero(bad.any(axis=1) | vertical.any(axis=1))
        if rows.size == 0 and not reasons:
            check_conditioning(mech, q, self.coupling_condition, cos)  # the test every method shares
            return
        out = [f"sample 0: {r}" for r in reasons]
        for s in rows[:16]:  # enough to name; the count says the rest
            for i in np.flatnonzero(bad[s] | vertical[s]):  # link by link, as singular_reasons orders them
                out.append(
                    f"sample {s}: "
                    + (
                        zero_length_reason(mech, int(i))
                        if bad[s, i] or psi is None  # 2D: no rod is vertical
                        else vertical_reason(mech, int(i), psi[s, i])
                    )
                )
        raise SingularConfigurationError(out)
