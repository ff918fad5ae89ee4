"""The derivatives of every prepared model's equations of motion (``model.derivatives``): the Jacobians of
inverse and forward dynamics and their directional products, computed for every method by the analytic
Newton-Euler passes (:mod:`exo_bench.models.newton_euler`), with their checks and memory estimate. Above the
method it computes with; CasADi's derivatives of the matrix method stay in ``exo_bench.matrix_method``."""
