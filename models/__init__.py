"""The physics below every method, by concept (each sub-package's docstring says what belongs in it).

Layers inside, each importing only those below it (no import cycles: pyproject.toml's contracts):

* :mod:`~exo_bench.models.files`: what the package writes and the names in it: one encoder per format, atomic writes.
* :mod:`~exo_bench.models.machine`: what runs on this machine: numba's runtime and cache, the SIMD layout, threads, memory.
* :mod:`~exo_bench.models.states`: state arrays: block order and labels (eqs. 5/17), conversion and validation at the edge.
* :mod:`~exo_bench.models.mechanism`: the mechanism as data, its presets and geometry, and the method-free references.
* :mod:`~exo_bench.models.gait`: motions (eq. 26, random states) and Winter's normative walking.
* :mod:`~exo_bench.models.runtime`: the prepared model and how a public call runs: kernels, chunks, f_ext.
* :mod:`~exo_bench.models.newton_euler`: the method ``newton-euler``, beside the matrix method (``exo_bench.matrix_method``).
* :mod:`~exo_bench.models.derivatives`: ``model.derivatives`` for every method, from newton-euler's analytic passes.
* :mod:`~exo_bench.models.engines`: the peers' models and backends: URDF and Pinocchio, MJCF and MuJoCo, Drake.
* :mod:`~exo_bench.models.simulation`: forward dynamics integrated in time, controls, ground contact.
"""
