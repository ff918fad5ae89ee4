"""The predicted full stride of the human-proportioned model with feet (issue 37), a scene of its own,
separate from the paper's step (:mod:`exo_bench.bench.studies.step`): one module per part of the stride's study.

* :mod:`~exo_bench.bench.studies.stride.actuators` splits the generalised forces of
  :func:`exo_bench.models.mechanism.presets.human` into its actuators (joint motors at hips, knees, ankles and
  arches, and the telescopic rods), their powers, the work and effort terms, and the actuator-sizing table;
  :mod:`~exo_bench.bench.studies.stride.passive` - the passive joint moments the objective does not price;
* :mod:`~exo_bench.bench.studies.stride.coordinates` - the stride's free coordinates, the left/right
  mirror and the full stride from the solved half;
* :mod:`~exo_bench.bench.studies.stride.transcription` and :mod:`~exo_bench.bench.studies.stride.problem` -
  the contact-implicit trapezoidal collocation of half a stride with a symmetry constraint (CasADi, IPOPT),
  its settings, actuator specifications, initial guess and continuation, and its trials (the problem with
  settings changed, solved and stored);
* :mod:`~exo_bench.bench.studies.stride.data` - the stored strides (``data/*.npz`` + JSON, no pickle);
  :mod:`~exo_bench.bench.studies.stride.constraints` re-evaluates their constraints in numpy and measures the
  half-stride join, and :mod:`~exo_bench.bench.studies.stride.reproduce` says whether a re-solve reproduces
  one (``exo-bench stride``);
* against Winter: :mod:`~exo_bench.bench.studies.stride.winter` (his curves),
  :mod:`~exo_bench.bench.studies.stride.cycle` (the cycle cut and resampled),
  :mod:`~exo_bench.bench.studies.stride.evidence` (contact and rod travel) and
  :mod:`~exo_bench.bench.studies.stride.comparison` (the peaks and the done-when checks);
* :mod:`~exo_bench.bench.studies.stride.scene` - the scene motion ``kind = "stride"`` and its figures;
  :mod:`~exo_bench.bench.studies.stride.report` - the stride's section of its scene report.

Only the transcription and :func:`~exo_bench.bench.studies.stride.problem.solve` import CasADi.
"""
