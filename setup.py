"""The one compiled extension of exo-bench, optional: models/runtime/_lean_call.c, the lean one-sample call of a
compiled kernel (models/runtime/lean_call.py; matrix-factored's and newton-euler's). Everything else is in pyproject.toml.
``optional=True``: where no C compiler works the package installs without it, and the Python lean
path runs instead."""

from setuptools import Extension, setup

setup(
    ext_modules=[
        Extension(
            "exo_bench.models.runtime._lean_call",
            ["models/runtime/_lean_call.c"],
            optional=True,
        )
    ]
)
