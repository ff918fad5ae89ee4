"""The prepared model and how its public calls run: :class:`~exo_bench.models.runtime.prepared.PreparedModel`
(a method's per-mechanism work done once), the kernels a method supplies and their entries, batches in chunks,
the checks of forward dynamics (regularity, conditioning) and external forces at the point masses (``f_ext``).
A new input check belongs in :mod:`exo_bench.models.states`; the derivatives in :mod:`exo_bench.models.derivatives`."""
