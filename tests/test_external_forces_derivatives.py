"""Derivatives with external forces (issue 37): ``model.derivatives``' calls with ``f_ext`` through
:func:`exo_bench.models.runtime.external_forces.inverse_derivatives` and :func:`~exo_bench.models.runtime.external_forces.forward_derivatives`
(``dtau/dq - dQ/dq``; ``dqdd/dq + M^-1 dQ/dq`` at ``tau + Q``), against central differences of the
public calls with ``f_ext``. Error model of the differences: truncation ``h^2 |f'''| / 6`` and rounding
``eps |f| / h``; with ``h = 1e-6`` and unit-scale states both stay below ``1e-7`` of the largest entry
(measured: at most 1.9e-10), far below a wrong sign of ``dQ/dq`` (2.5 to 2.8 measured)."""

from __future__ import annotations

import numpy as np
import pytest
from test_external_forces import _case

from exo_bench import prepare
from exo_bench.models.runtime import external_forces as xf
from exo_bench.models.mechanism.presets import random_tree


def _central(fn, x, h=1e-6):
    cols = []
    for a in range(x.size):
        e = np.zeros_like(x)
        e[a] = h
        cols.append((fn(x + e) - fn(x - e)) / (2 * h))
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("mech", [random_tree(4, 2, 3), random_tree(4, 3, 3)], ids=lambda m: m.name)
def test_derivatives_with_f_ext_by_central_differences(mech):
    model = prepare(mech, "newton-euler")
    q, qd, qdd, f = (x[0] for x in _case(mech, 13, 1))
    dq, dqd, M = xf.inverse_derivatives(model, q, qd, qdd, f)
    num = _central(lambda x: model.inverse_dynamics(x, qd, qdd, f_ext=f), q)
    assert np.abs(dq - num).max() <= 1e-7 * np.abs(num).max()
    assert np.array_equal(dqd, model.derivatives.inverse_dynamics(q, qd, qdd)[1])
    tau = model.inverse_dynamics(q, qd, qdd, f_ext=f)
    acc, aq, aqd, Minv = xf.forward_derivatives(model, q, qd, tau, f)
    assert np.abs(acc - qdd).max() <= 1e-9 * np.abs(qdd).max()
    num = _central(lambda x: model.forward_dynamics(x, qd, tau, f_ext=f), q)
    assert np.abs(aq - num).max() <= 1e-7 * np.abs(num).max()
