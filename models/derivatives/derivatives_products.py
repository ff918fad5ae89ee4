"""The directional derivatives of :class:`exo_bench.models.derivatives.derivatives.Derivatives` (a mixin): the JVP and
VJP of inverse and forward dynamics, O(n) per sample, and the choice of their kernel (the option
``products``). Split out of :mod:`exo_bench.models.derivatives.derivatives` (one responsibility per file: that module
computes the full Jacobians, this one the products; :mod:`exo_bench.models.derivatives.derivative_checks` refuses).

The kernels: across SIMD lanes (:mod:`exo_bench.models.newton_euler.products_simd`, the default for
batches and single samples below :data:`PRODUCTS_SIMD_BELOW_LINKS` links), per sample (:mod:`exo_bench.models.newton_euler.products_compiled`), and the
numpy reference of the formulas (:mod:`exo_bench.models.newton_euler.products`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from exo_bench.models.derivatives.derivative_checks import DerivativeChecks

_F8 = np.dtype(np.float64)

#: The option ``products``: the kernel of the directional derivatives (:attr:`DirectionalDerivatives.products_kernel`),
#: each the name of the method that runs it (a table: no branch on a kernel's name): ``"simd"``
#: (:mod:`exo_bench.models.newton_euler.products_simd`, blocks of samples across SIMD lanes), ``"numba"``
#: (:mod:`exo_bench.models.newton_euler.products_compiled`, per sample), ``"numpy"`` (the reference), or
#: ``"auto"`` (:data:`AUTO`).
PRODUCT_KERNELS = {"auto": "", "simd": "_simd_products", "numba": "_compiled_products", "numpy": "_reference_products"}
#: ``products="auto"``: mechanisms of at least this many links run the per-sample products kernel. The SIMD
#: kernel's scratch, 53 rows of 32 samples per link (13.6 kB), leaves the caches as n grows: 3D chains, 64
#: samples, one process, load 2.7-3.1 (provisional), SIMD against per-sample, us per sample: n = 100 JVP 6.0
#: / 20.8, VJP 6.8 / 19.5; n = 300 25 / 65 and 39 / 67; n = 500 66 / 110 and 94 / 111; n = 800 250 / 209 and
#: 211 / 207 (per link, the SIMD JVP's 60 ns at n <= 100 grows to 83, 131 and 312 ns).
PRODUCTS_SIMD_BELOW_LINKS = 500
#: ``products="auto"`` by (the numpy reference runs, at least :data:`PRODUCTS_SIMD_BELOW_LINKS` links): the
#: reference under ``kernel="numpy"``, else the SIMD kernel, and the per-sample kernel for the largest mechanisms.
AUTO = {(True, False): "numpy", (True, True): "numpy", (False, False): "simd", (False, True): "numba"}


def _products_option(option) -> str:
    if option not in PRODUCT_KERNELS:
        raise ValueError(f"derivatives: option 'products': expected one of {tuple(PRODUCT_KERNELS)}, got {option!r}")
    return option


def _samples(q: Any) -> int:
    """The sample count of an array ``(samples, dof)`` (1 for one sample), read from its shape without
    converting it; 0 for what has no shape (a list: estimated once converted)."""
    shape = getattr(q, "shape", None)
    return int(shape[0]) if isinstance(shape, tuple) and len(shape) == 2 else 0 if shape is None else 1


class DirectionalDerivatives(DerivativeChecks):
    """The products of :class:`exo_bench.models.derivatives.derivatives.Derivatives` (module docstring); they use its
    ``table``, ``tree``, ``reference``, the checks and its forward passes (declared here for the type checker)."""

    table: np.ndarray
    tree: Any
    reference: bool
    _products_option: str
    _products_scratch: Any

    if TYPE_CHECKING:

        def _check_memory(self, source: str, samples: int, jacobians: int) -> None: ...

        def _accelerations(self, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> np.ndarray: ...

        def _solve(self, q: np.ndarray, B: np.ndarray, out: np.ndarray | None = None) -> np.ndarray: ...

    @property
    def products_kernel(self) -> str:
        """The kernel that computes the directional derivatives (:data:`PRODUCT_KERNELS`): ``"simd"``,
        ``"numba"`` or ``"numpy"``, the option ``products`` resolved for this mechanism."""
        option = self._products_option
        if option != "auto":
            return option
        return AUTO[(self.reference, self.mechanism.nlinks >= PRODUCTS_SIMD_BELOW_LINKS)]

    @property
    def products_scratch(self):
        """Each thread's scratch of the SIMD products kernel (made at its first use)."""
        if self._products_scratch is None:
            from exo_bench.models.newton_euler import products_simd
            from exo_bench.models.machine.simd_blocks import ThreadScratch

            m = self.mechanism
            self._products_scratch = ThreadScratch(products_simd.scratch, m.nlinks, m.dim)
        return self._products_scratch

    def _products(self, which: str, *arrays):
        """The ``"jvp"`` or ``"vjp"`` of inverse dynamics on validated C-ordered ``(S, dof)`` arrays, O(n)
        per sample, by :attr:`products_kernel` (:data:`PRODUCT_KERNELS`)."""
        return getattr(self, PRODUCT_KERNELS[self.products_kernel])(which, *arrays)

    def _simd_products(self, which: str, *arrays):
        """Across SIMD lanes (:mod:`exo_bench.models.newton_euler.products_simd`)."""
        from exo_bench.models.newton_euler import products_simd

        dim, g = int(self.mechanism.dim), float(self.mechanism.g)
        return getattr(products_simd, which)(self.table, dim, g, *arrays, self.products_scratch)

    def _compiled_products(self, which: str, *arrays, reference: bool = False):
        """Per sample, compiled (:mod:`exo_bench.models.newton_euler.products_compiled`), or its numpy reference."""
        from exo_bench.models.newton_euler import products_compiled as pc

        return getattr(pc, which)(
            self.tree, self.table, self.mechanism.dim, float(self.mechanism.g), *arrays, reference
        )

    def _reference_products(self, which: str, *arrays):
        """The numpy reference (:mod:`exo_bench.models.newton_euler.products`)."""
        return self._compiled_products(which, *arrays, reference=True)

    def _lean_products(self, which: str, source: str, arrays: tuple):
        """The products of ``check=False`` on arrays the general path would pass on unchanged: numpy
        float64 arrays, C-contiguous, all of one shape ``(S, dof)`` with ``S >= 1``, or ``(dof,)``. The
        memory is estimated first, as there; None (having done nothing) for anything else, which the
        general path converts or refuses, naming the field."""
        q = arrays[0]
        if type(q) is not np.ndarray or q.ndim not in (1, 2) or q.shape[-1] != self.mechanism.dof or not q.size:
            return None
        for a in arrays:
            if type(a) is not np.ndarray or a.shape != q.shape or a.dtype != _F8 or not a.flags.c_contiguous:
                return None
        single = q.ndim == 1
        self._check_memory(source, 1 if single else q.shape[0], 0)
        if single:
            out = self._products(which, *(a[None] for a in arrays))
            return out[0] if which == "jvp" else tuple(x[0] for x in out)
        return self._products(which, *arrays)

    def inverse_dynamics_jvp(self, q, qd, qdd, dq, dqd, dqdd, check: bool = True):
        """``dtau = dtau/dq dq + dtau/dqd dqd + M dqdd``, ``(S, dof)``: forward mode through the passes,
        O(n) per sample (:func:`exo_bench.models.newton_euler.products.inverse_jvp`)."""
        arrays = (q, qd, qdd, dq, dqd, dqdd)
        if not check and (out := self._lean_products("jvp", "inverse-dynamics JVP", arrays)) is not None:
            return out
        names = ("q", "qd", "qdd", "dq", "dqd", "dqdd")
        self._check_memory("inverse-dynamics JVP", _samples(q), 0)  # before the states are copied
        arrays, single = self._states("inverse-dynamics JVP", names, (q, qd, qdd, dq, dqd, dqdd), check)
        if check:
            self._refuse_singular_states(arrays[0], "inverse-dynamics JVP")
        out = self._products("jvp", *arrays)
        if check:
            self._finite_inverse("inverse-dynamics JVP", (out,), ("dtau",))
        return out[0] if single else out

    def inverse_dynamics_vjp(self, q, qd, qdd, w, check: bool = True):
        """``(w^T dtau/dq, w^T dtau/dqd, w^T M)``, ``(S, dof)`` each: reverse mode through the passes,
        O(n) per sample (:func:`exo_bench.models.newton_euler.products.inverse_vjp`)."""
        if not check and (out := self._lean_products("vjp", "inverse-dynamics VJP", (q, qd, qdd, w))) is not None:
            return out
        self._check_memory("inverse-dynamics VJP", _samples(q), 0)
        arrays, single = self._states("inverse-dynamics VJP", ("q", "qd", "qdd", "w"), (q, qd, qdd, w), check)
        if check:
            self._refuse_singular_states(arrays[0], "inverse-dynamics VJP")
        out = self._products("vjp", *arrays)
        if check:
            self._finite_inverse("inverse-dynamics VJP", out, ("w_dtau_dq", "w_dtau_dqd", "w_M"))
        return tuple(x[0] for x in out) if single else out

    def forward_dynamics_jvp(self, q, qd, tau, dq, dqd, dtau, check: bool = True):
        """``(qdd, dqdd)`` with ``dqdd = M^-1 (dtau - dID/dq dq - dID/dqd dqd)`` at ``qdd = FD(q, qd, tau)``:
        O(n) per sample; refuses what :meth:`forward_dynamics` refuses."""
        names = ("q", "qd", "tau", "dq", "dqd", "dtau")
        self._check_memory("forward-dynamics JVP", _samples(q), 0)
        (q, qd, tau, dq, dqd, dtau), single = self._states(
            "forward-dynamics JVP", names, (q, qd, tau, dq, dqd, dtau), check
        )
        self._refuse_singular(q, check)
        qdd = self._accelerations(q, qd, tau)
        rhs = dtau - self._products("jvp", q, qd, qdd, dq, dqd, np.zeros_like(q))
        out = (qdd, self._solve(q, rhs[:, :, None])[:, :, 0])
        if check:
            self._finite(out, ("qdd", "dqdd"))
        return tuple(x[0] for x in out) if single else out

    def forward_dynamics_vjp(self, q, qd, tau, w, check: bool = True):
        """``(qdd, w^T dqdd/dq, w^T dqdd/dqd, w^T M^-1)`` at ``qdd = FD(q, qd, tau)``: with ``u = M^-1 w``
        (``M`` symmetric), ``-u^T dID/dq``, ``-u^T dID/dqd`` and ``u``. O(n) per sample."""
        self._check_memory("forward-dynamics VJP", _samples(q), 0)
        (q, qd, tau, w), single = self._states("forward-dynamics VJP", ("q", "qd", "tau", "w"), (q, qd, tau, w), check)
        self._refuse_singular(q, check)
        qdd = self._accelerations(q, qd, tau)
        u = self._solve(q, w[:, :, None])[:, :, 0]
        wq, wqd, _ = self._products("vjp", q, qd, qdd, np.ascontiguousarray(u))
        out = (qdd, -wq, -wqd, u)
        if check:
            self._finite(out, ("qdd", "w_dqdd_dq", "w_dqdd_dqd", "w_Minv"))
        return tuple(x[0] for x in out) if single else out
