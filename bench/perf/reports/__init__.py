"""The benchmark reports, one module each (``paper_table``, ``error_vs_runtime``, ``scaling``,
``derivatives``), what they share (``loading``: frames and figure styles; ``readme_blocks``: the
highlights page's generated blocks), the goals measured in one process (``simd_goals``,
``goals_call_overhead``), and ``benchmark_reports``: the ``exo-bench bench`` job that runs the suite
and writes them."""
