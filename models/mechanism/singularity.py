"""Where forward dynamics is not defined: singular mass matrices, detected exactly and named.

``M = J^T (mu (x) I) J`` (models/simulation/forward_dynamics.py, models/newton_euler/): ``M`` is singular
exactly when the mass distribution ``mu`` is, or when a rod's block of ``J`` is: a rod of length
zero (its angles move no mass) or, in 3D, a vertical rod (``cos psi_i = 0``: the azimuth column
vanishes). The wording of every reason is written here once (:func:`zero_length_reason`,
:func:`vertical_reason`, :func:`massless_reason`), so that every method names a singular
configuration alike. This module imports nothing above :mod:`exo_bench.models.mechanism.mechanism` and
:mod:`exo_bench.models.mechanism.aggregates`, so that :class:`exo_bench.models.runtime.prepared.PreparedModel` can use it.
"""

from __future__ import annotations

import numpy as np

from exo_bench.models.mechanism.aggregates import coupling
from exo_bench.models.mechanism.mechanism import Mechanism
from exo_bench.models.states.states import as_states, split

#: ``|cos psi|`` at or below which a rod counts as vertical to working precision. The float
#: nearest pi/2 has ``cos = 6.1e-17``; angles within two units in the last place of pi/2
#: (ulp = 2.2e-16) stay below 5e-16. 1e-15 covers them with a margin and no more.
COS_VERTICAL = 1e-15


class SingularConfigurationError(ValueError):
    """The mass matrix is singular: forward dynamics is not defined at this state.

    ``reasons`` lists, per offending sample, what makes it singular (link, coordinate, why).
    """

    def __init__(self, reasons: list[str]):
        self.reasons = reasons
        more = f" (and {len(reasons) - 1} more)" if len(reasons) > 1 else ""
        super().__init__(f"forward dynamics is not defined: singular mass matrix: {reasons[0]}{more}")


def massless_reason(mech: Mechanism, i: int) -> str:
    """Link ``i`` (0-based) carries no mass that moves with its coordinates."""
    return (
        f"link {i + 1} ({mech.names[i]}): no mass moves with its coordinates "
        "(no middle or end mass, nothing hanging from it)"
    )


def zero_length_reason(mech: Mechanism, i: int) -> str:
    """Rod ``i`` (0-based) has length zero."""
    return f"link {i + 1} ({mech.names[i]}): rod length l{i + 1} = 0, its angles move no mass"


def vertical_reason(mech: Mechanism, i: int, psi: float) -> str:
    """Rod ``i`` (0-based) is vertical to working precision (``|cos psi| <= COS_VERTICAL``)."""
    return (
        f"link {i + 1} ({mech.names[i]}): vertical rod (psi{i + 1} = {float(psi)!r}, "
        f"|cos psi{i + 1}| = {abs(np.cos(psi)):.2g}): its azimuth phi{i + 1} is undefined "
        "and its column of M vanishes"
    )


def singular_reasons(mech: Mechanism, q: np.ndarray) -> list[list[str]]:
    """Per sample, why the mass matrix is exactly singular there (an empty list: it is not).

    Three causes, each exact (see the module docstring): the mass distribution ``mu`` is
    singular (some rod motion moves no mass), a rod has length zero, or (3D) a rod is vertical
    to working precision (``|cos psi| <= COS_VERTICAL``).
    """
    q, _, _ = as_states(mech, q)
    _, psi, l = split(mech, q)
    always = mechanism_reasons(mech)
    out = []
    for s in range(q.shape[0]):
        r = list(always)
        for i in range(mech.nlinks):
            if l[s, i] == 0:
                r.append(zero_length_reason(mech, i))
            elif psi is not None and abs(np.cos(psi[s, i])) <= COS_VERTICAL:
                r.append(vertical_reason(mech, i, psi[s, i]))
        out.append(r)
    return out


def mechanism_reasons(mech: Mechanism) -> list[str]:
    """Why the mass matrix is singular at every configuration (empty: it is not): a link that moves no
    mass, or a combination of rod motions without inertia (``mu`` singular to working precision)."""
    always: list[str] = []
    mu = coupling(mech)
    for i in range(mech.nlinks):
        if mu[i, i] == 0:
            always.append(massless_reason(mech, i))
    if not always:
        ev = np.linalg.eigvalsh(mu)
        if ev[0] <= mech.nlinks * np.finfo(float).eps * ev[-1]:
            always.append(
                "the mass distribution leaves a combination of rod motions without inertia "
                f"(smallest eigenvalue of mu {ev[0]:.3g} kg, largest {ev[-1]:.3g} kg)"
            )
    return always
