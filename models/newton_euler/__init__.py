"""Method ``newton-euler``: linear-time, chart-free dynamics from ``M(q) = J^T M_r J``.

One algorithm per file: the rod elements, :mod:`exo_bench.models.mechanism.rod_elements` (one rod's ``q_i -> r_i`` and its derivatives, shared by
both kernels), :mod:`.passes`
(the numpy reference: the per-link mass sums and ``M_r`` factored once, the two passes, forward dynamics, the
mass matrix), :mod:`.compiled` (the
numba kernels), :mod:`.prepared` (the prepared model), :mod:`.chart_free` (simulation in the rod
vectors, where no chart is singular). The derivation is in docs/paper.md.
"""
