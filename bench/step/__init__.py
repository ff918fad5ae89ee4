"""A predicted walking step of the five-link exoskeleton, by direct collocation (issue 24).

* :mod:`bench.step.symbolic` - the CasADi functions the optimiser calls: inverse dynamics from the
  equations' CasADi export, the point masses' kinematics and the net joint loads;
* :mod:`bench.step.problem` - the settings, the Hermite-Simpson collocation problem and its solve;
* :mod:`bench.step.data` - the stored step (``bench/step/data/*.npz``), its constraints re-evaluated
  in numpy with the project's own kinematics and joint loads, and the leg swap;
* :mod:`bench.step.figures` - the kinogram drawn as it walks.

Only :mod:`bench.step.symbolic` and :mod:`bench.step.problem` import CasADi (the optional extra):
the scene reads the stored step with numpy alone.
"""
