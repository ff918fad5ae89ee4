"""The paper's matrix method (eqs. 5, 17, 18, 22-26) and the methods built on it (``matrix``,
``matrix-factored``, ``recurrence``, ``matrix-paper``): the closed forms written once
(``closed_forms/``), their kernels in numpy (``numpy_kernels/``) and numba (``numba_kernels/``), the
prepared models and kernel objects (``prepared``, ``kernels``), the recurrence (``recurrence``), the
formulas as printed (``printed``), the equations in sympy (``symbolic``), CasADi's derivatives
(``derivatives``) and the exports (``export/``: code, LaTeX, CasADi functions). It imports
``models`` only, never ``lagrange``."""
