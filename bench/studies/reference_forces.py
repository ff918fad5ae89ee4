"""The 50-digit reference used wherever the suite reports an error.

``lagrange.reference`` (the sympy Lagrange equations evaluated with mpmath at 50 significant
digits) where the derivation fits a budget; beyond that, ``models.virtual_work`` (d'Alembert's
principle on the point masses in mpmath, any n). The tests check the two against each other.
"""

from __future__ import annotations

import numpy as np

from exo_bench.models.mechanism.mechanism import Mechanism

DPS = 50
LAGRANGE_MAX_LINKS = {2: 6, 3: 5}  # beyond these, deriving costs more than a report should wait


def reference(mech: Mechanism, q, qd, qdd, budget: float = 30.0) -> tuple[np.ndarray, str]:
    """``(tau, label)``: 50-digit generalised forces rounded once to float64, and which reference."""
    if mech.nlinks <= LAGRANGE_MAX_LINKS[mech.dim]:
        try:
            from exo_bench.lagrange import high_precision as lref
            from exo_bench.lagrange import derive

            derive(mech, budget=budget)
            return lref.inverse_dynamics(mech, q, qd, qdd, dps=DPS), "Lagrange, mpmath 50 digits"
        except ImportError:
            pass
        except Exception as e:  # noqa: BLE001 - over budget: fall back, and say so in the label
            if not getattr(e, "skip_reason", None):
                raise
    from exo_bench.models.mechanism import virtual_work

    return virtual_work.inverse_dynamics(mech, q, qd, qdd, dps=DPS), "d'Alembert, mpmath 50 digits"
