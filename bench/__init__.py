"""exo-bench: the command line, the method registry, scenes, reports and benchmarks."""
