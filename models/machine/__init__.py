"""What runs on this machine: numba's runtime set-up and its on-disk cache keys, the layout of blocks of
samples for SIMD kernels (tiles, angles, branch-free sin/cos), the bounds on thread and process counts, and the
memory a run may use. No physics: a kernel's plumbing, shared by every method's compiled code."""
