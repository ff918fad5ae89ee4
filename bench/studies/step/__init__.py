"""A predicted walking step of the five-link exoskeleton, by direct collocation (issue 24): one module
per part of the step's study.

* :mod:`exo_bench.bench.studies.step.coordinates` - which rows are the sagittal angles, and the leg swap;
* :mod:`exo_bench.bench.studies.step.problem` - the settings, the Hermite-Simpson collocation problem and its solve;
* :mod:`exo_bench.bench.studies.step.transcription` - the CasADi functions the optimiser calls (inverse dynamics
  from the equations' CasADi export, the point masses' kinematics and the net joint loads) and the problem as
  an NLP with exact derivatives built for one collocation point and mapped over all (IPOPT's ``jac_g``,
  ``grad_f``, ``hess_lag``);
* :mod:`exo_bench.bench.studies.step.data` - the stored step (``bench/studies/step/data/*.npz``), its constraints
  re-evaluated in numpy with the project's own kinematics and joint loads, and the leg swap;
  :mod:`exo_bench.bench.studies.step.identity` - which mechanism a stored step was solved for;
* :mod:`exo_bench.bench.studies.step.scene` - the scene motion ``kind = "step"`` and its kinogram, drawn as it walks;
* :mod:`exo_bench.bench.studies.step.report` - the step's section of its scene report.

Only :mod:`exo_bench.bench.studies.step.transcription` and :func:`exo_bench.bench.studies.step.problem.solve`
import CasADi (the optional extra): the scene reads the stored step with numpy alone.
"""
