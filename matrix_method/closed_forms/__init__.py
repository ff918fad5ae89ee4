"""The closed forms of the matrix method, each written once in any arithmetic (numpy, numba, sympy,
CasADi call them): the mass coefficients (``coefficients``: eq. 6 with the branch signs), every
planar matrix element of eq. 5 (``planar``), the transitions of eq. 18 to 3D (``transitions``) and
the factored form's link elements (``factored``). A numba kernel inlines them: their files key its cache."""
