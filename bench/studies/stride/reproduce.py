"""Whether a new solve reproduces a stored stride, and a stored stride described in a few lines.

:data:`REPRODUCE_TOL`: a re-solve reproduces the stored stride when every coordinate at every node
agrees to it (rad, m). Error model, the step's (:data:`exo_bench.bench.studies.step.data.REPRODUCE_TOL`):
IPOPT stops at a scaled KKT error ``tol``, not at the optimum, and its distance from the optimum is what
the KKT system's conditioning makes of that error; the step measured ``|x(tol) - x*| ~ 1e-2 sqrt(tol)``.
The strides are solved at ``tol`` 1e-10 (:class:`~.problem.StrideSettings`), so each solve lands about
1e-7 from the optimum, two solves within 2e-7 of each other; the bound 1e-5 leaves a factor of 50 for
this problem's worse conditioning (contact) and other roundings. Measured distances are stated where
the stored strides are (tests/test_stride.py, the report of the commit that stored them).
"""

from __future__ import annotations

import numpy as np

from exo_bench.bench.studies.stride.data import StoredStride
from exo_bench.models.mechanism.mechanism import Mechanism

REPRODUCE_TOL = 1e-5


def distance(a: StoredStride, b: StoredStride) -> float:
    """The largest ``|dq|`` between two strides of the same grid (rad, m); infinite when the grids differ."""
    if a.q.shape != b.q.shape or abs(a.period - b.period) > REPRODUCE_TOL:
        return float("inf")
    return float(np.abs(a.q - b.q).max())


def describe(stride: StoredStride, mech: Mechanism) -> list[str]:
    """Lines describing a stored stride: what it is, how it was solved, its constraints in numpy."""
    from exo_bench.bench.studies.stride.constraints import violations

    sv, prov = stride.solver, stride.meta.get("provenance", {})
    viol = violations(stride, mech)
    worst = max(viol, key=lambda k: viol[k])
    stages = [x for x in sv.get("stages", []) if "iterations" in x]
    its = f"{sum(x['iterations'] for x in stages)} iterations in {len(stages)} stages" if stages else "? iterations"
    return [
        f"{mech.name}, {stride.variant} variant: one stride of {stride.period:.4f} s, {stride.stride_length:.4f} m at "
        f"the prescribed {stride.speed:g} m/s; {len(stride.t) - 1} trapezoidal intervals (half solved, half mirrored)",
        f"  solved at {prov.get('commit', '?')} on {prov.get('date', '?')}: IPOPT {sv.get('status')}, "
        f"{its}, {sv.get('solve_seconds', float('nan')):.1f} s, tol {sv.get('tol')}, "
        f"objective {sv.get('objective', float('nan')):.6g}, constraint violation (CasADi) "
        f"{sv.get('constraint_violation', float('nan')):.1e}",
        f"  constraints re-evaluated in numpy: largest violation {viol[worst]:.1e} ({worst})",
    ]


__all__ = ["REPRODUCE_TOL", "describe", "distance"]
