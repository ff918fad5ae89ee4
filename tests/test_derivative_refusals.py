"""Singular states refuse in every derivative call, naming the link (issue 36's done-when item).

The forward-dynamics derivatives refuse where forward dynamics does (tests/test_forward_derivatives.py,
tests/test_forward_conditioning.py). Inverse dynamics has no division, so its derivatives, JVP and VJP
are finite there; but at those states ``M = dtau/dqdd`` is singular (a rod of length zero, a vertical rod
in 3D: its azimuth is undefined and the chart singular) or beyond the conditioning bound, and an optimiser
or an integrator that inverts or factors what it is given gets garbage. So the inverse calls refuse the
same states with the same detector (models/mechanism/singularity.py, conditioning.py, forward_check.py) and the
same reasons, prefixed by the call's name, for one sample and batches. ``check=False`` skips the values'
checks (shapes and sample counts stay checked). A link that moves no mass is a property of the mechanism,
not of the state: there the inverse calls stay defined (tests/test_forward_conditioning.py's T5 test).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from exo_bench import prepare
from exo_bench.models.runtime.conditioning import NumericallySingularError
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5, random_tree
from exo_bench.models.mechanism.singularity import SingularConfigurationError

NAMES = ("inverse-dynamics derivatives", "inverse-dynamics JVP", "inverse-dynamics VJP")


def _inverse_calls(D, q, qd, qdd, check=True):
    """The three inverse calls, named as their messages name them."""
    return {
        NAMES[0]: lambda: D.inverse_dynamics(q, qd, qdd, check=check),
        NAMES[1]: lambda: D.inverse_dynamics_jvp(q, qd, qdd, qd, qdd, q, check=check),
        NAMES[2]: lambda: D.inverse_dynamics_vjp(q, qd, qdd, qdd, check=check),
    }


def _singular(mech, what: str, link: int, samples: int = 3, seed: int = 4):
    """Seeded states (elevations within 1 rad of horizontal), sample 1 made singular: ``"l"`` (rod
    ``link`` of length 0), ``"psi"`` (rod ``link`` vertical) or ``"near"`` (1e-9 rad from vertical)."""
    n = mech.nlinks
    q, qd, qdd = random_states(mech, samples, seed)
    if mech.dim == 3:
        q[:, n : 2 * n] = np.clip(q[:, n : 2 * n], -1.0, 1.0)
    q[:, -n:] = np.maximum(q[:, -n:], 0.3)
    if what == "l":
        q[1, 2 * n + link if mech.dim == 3 else n + link] = 0.0
    else:
        q[1, n + link] = math.pi / 2 - (1e-9 if what == "near" else 0.0)
    return q, qd, qdd


@pytest.mark.case("W4")
@pytest.mark.parametrize(
    "dim, what, link, method",
    [(3, "l", 4, "newton-euler"), (3, "psi", 2, "matrix-factored"), (2, "l", 1, "newton-euler")],
)
def test_inverse_derivatives_jvp_and_vjp_refuse_singular_states_naming_the_link(dim, what, link, method):
    """Every derivative call refuses where forward dynamics does: at a rod of length zero or (3D) a
    vertical rod the inverse-dynamics derivatives, JVP and VJP too, with forward dynamics' reason prefixed
    by the call's name and naming the link, for a batch and one ``(dof,)`` sample (before: the forward
    derivatives gave NaN and inf, the inverse calls answered)."""
    mech = exo5(dim)
    q, qd, qdd = _singular(mech, what, link)
    model = prepare(mech, method)
    with pytest.raises(SingularConfigurationError) as want:
        model.forward_dynamics(q, qd, qdd)
    assert f"sample 1: link {link + 1} ({mech.names[link]})" in str(want.value)
    for states, sample in (((q, qd, qdd), "sample 1"), ((q[1], qd[1], qdd[1]), "sample 0")):
        for name, call in _inverse_calls(model.derivatives, *states).items():
            with pytest.raises(SingularConfigurationError) as got:
                call()
            assert type(got.value) is type(want.value), name
            assert str(got.value).startswith(f"{name}: forward dynamics is not defined: singular mass matrix"), name
            assert f"{sample}: link {link + 1} ({mech.names[link]})" in str(got.value), name
            assert str(got.value).split(": ", 1)[1].replace("sample 0", "sample 1") == str(want.value), name


def test_ill_conditioned_states_refuse_in_the_inverse_calls_naming_the_link():
    """A rod 1e-9 rad from vertical is beyond the conditioning bound (its azimuth moves almost no mass):
    :class:`NumericallySingularError` naming the link, as forward dynamics raises, in the three inverse
    calls."""
    mech = exo5(3)
    q, qd, qdd = _singular(mech, "near", 2)
    model = prepare(mech, "newton-euler")
    with pytest.raises(NumericallySingularError) as want:
        model.forward_dynamics(q, qd, qdd)
    for name, call in _inverse_calls(model.derivatives, q, qd, qdd).items():
        with pytest.raises(NumericallySingularError) as got:
            call()
        assert str(got.value) == f"{name}: {want.value}"
        assert f"link 3 ({mech.names[2]})" in str(got.value), name


def test_check_false_skips_the_values_but_not_the_shapes():
    """With ``check=False`` the inverse calls answer at the singular states (finite: no division), and
    still refuse mismatched shapes and sample counts naming the field."""
    mech = exo5(3)
    q, qd, qdd = _singular(mech, "psi", 2)
    D = prepare(mech, "newton-euler").derivatives
    for name, call in _inverse_calls(D, q, qd, qdd, check=False).items():
        out = call()
        assert all(np.isfinite(x).all() for x in (out if isinstance(out, tuple) else (out,))), name
    for name, call in _inverse_calls(D, q, qd[:2], qdd, check=False).items():
        with pytest.raises(ValueError, match=r"field 'qd': expected 3 samples \(as q\), got 2"):
            call()


def test_regular_states_and_a_massless_link_still_answer():
    """Regular states of a random tree with branch signs answer in every inverse call (nothing refused
    that forward dynamics accepts), and a link that moves no mass (``M`` singular at every configuration,
    a property of the mechanism) leaves the inverse calls defined, with and without ``check``."""
    mech = random_tree(6, 3, 8)
    q, qd, qdd = _singular(mech, "l", 0)
    q[1, -6] = 0.7
    model = prepare(mech, "newton-euler")
    model.forward_dynamics(q, qd, qdd)  # accepted
    for call in _inverse_calls(model.derivatives, q, qd, qdd).values():
        call()
    m = exo5(3)
    masses = list(m.masses)
    masses[3] = (masses[3][0], 0.0, 0.0)
    massless = m.replace(masses=tuple(masses))
    q, qd, qdd = _singular(massless, "l", 0)
    q[1, -5] = 0.7
    D = prepare(massless, "newton-euler").derivatives
    for check in (True, False):
        for call in _inverse_calls(D, q, qd, qdd, check=check).values():
            out = call()
            assert all(np.isfinite(x).all() for x in (out if isinstance(out, tuple) else (out,)))
