"""Eq. (5)/(17) taken out of the package: as numpy and C99 source (``code``), as LaTeX in the paper's
notation (``latex``) and as CasADi functions with their derivatives (``casadi_functions``)."""
