"""The predicted full stride of the human-proportioned model with feet (issue 37), a scene of its own,
separate from the paper's step (:mod:`exo_bench.bench.studies.step`).

* :mod:`~exo_bench.bench.studies.stride.actuators` splits the generalised forces of
  :func:`exo_bench.models.mechanism.presets.human` into its actuators (joint motors at hips, knees, ankles and
  arches, and the telescopic rods), their powers, and the work and effort terms;
* :mod:`~exo_bench.bench.studies.stride.coordinates` - the stride's free coordinates, the left/right
  mirror and the full stride from the solved half;
* :mod:`~exo_bench.bench.studies.stride.transcription` and :mod:`~exo_bench.bench.studies.stride.problem` -
  the contact-implicit trapezoidal collocation of half a stride with a symmetry constraint (CasADi, IPOPT),
  its settings, actuator specifications, initial guess and continuation;
* :mod:`~exo_bench.bench.studies.stride.data` - the stored strides (``data/*.npz`` + JSON, no pickle);
  :mod:`~exo_bench.bench.studies.stride.constraints` re-evaluates their constraints in numpy and
  :mod:`~exo_bench.bench.studies.stride.reproduce` says whether a re-solve reproduces one
  (``exo-bench stride``).

Only the transcription and :func:`~exo_bench.bench.studies.stride.problem.solve` import CasADi.
"""
