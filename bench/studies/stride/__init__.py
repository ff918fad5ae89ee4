"""The predicted full stride of the human-proportioned model with feet (issue 37), a scene of its own,
separate from the paper's step (:mod:`exo_bench.bench.studies.step`).

Started, not finished: :mod:`exo_bench.bench.studies.stride.actuators` splits the generalised forces
of :func:`exo_bench.models.presets.human` into its actuators (joint motors at hips, knees, ankles and
arches, and the telescopic rods), their powers, and the objective's terms that price positive and
negative work and effort. The collocation problem (double support, prescribed speed, rod stroke and
rate bounds, the "human" variant), its solve, report and figures are still to come.
"""
