"""The one compiled extension of exo-bench, optional: matrix_method/numba_kernels/_lean_call.c, the lean one-sample
call of matrix-factored (numba) (matrix_method/numba_kernels/lean.py). Everything else is in pyproject.toml.
``optional=True``: where no C compiler works the package installs without it, and the Python lean
path runs instead."""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "exo_bench.matrix_method.numba_kernels._lean_call",
            ["matrix_method/numba_kernels/_lean_call.c"],
            optional=True,
        )
    ]
)
