"""The matrix method in numpy, batched over samples (``matrix``): the reference the compiled kernels are
held to."""
