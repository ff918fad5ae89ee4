import numpy as np
import pytest


def rel_err(a, b) -> float:
    """Largest absolute difference relative to the largest magnitude of the reference."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300))


@pytest.fixture
def rel():
    return rel_err


def power_balance_residual(inverse_dynamics, mech, seed: int) -> float:
    """max |tau . qd - d(T+Pi)/dt| / max |d(T+Pi)/dt| along a seeded smooth motion, with T and Pi
    summed over the point masses (models.kinematics): the power balance every method must satisfy."""
    from exo_bench.models.kinematics import energy_rate
    from exo_bench.models.motion import smooth_random_motion

    f = lambda t: smooth_random_motion(mech, t, seed=seed)
    t = np.linspace(0.0, 3.0, 40)
    mo = f(t)
    power = (inverse_dynamics(mech, mo.q, mo.qd, mo.qdd) * mo.qd).sum(1)
    rate = energy_rate(mech, f, t)
    return float(np.abs(power - rate).max() / np.abs(rate).max())
