"""The matrix family's compiled (numba) kernels, one algorithm per module (``factored``, ``matrix``,
``recurrence``, ``simd``, ``lean``, ``cholesky_forward``), and what they share (``common``: drivers,
generated call lists, the cache keys of this folder)."""
