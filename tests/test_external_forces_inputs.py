"""``f_ext`` at the edge, probed as a careless user would feed it (issue 34's classes of input, applied
to issue 37's external forces): forces are real numbers, never strings, Decimals, booleans, complex
numbers or masked entries; a ``tau`` given beside ``f_ext`` is read exactly as without it; and forces
whose generalised force overflows float64 are refused naming ``f_ext``, never returned as inf or NaN
nor blamed on ``tau``.

Every call here is one sample or four of fig1 (2D, one link): no solve, no new kernel."""

from __future__ import annotations

from decimal import Decimal

import numpy as np
import pytest

from exo_bench import prepare
from exo_bench.models.runtime import external_forces as xf
from exo_bench.models.simulation import forward_dynamics as xc
from exo_bench.models.mechanism.presets import fig1

MECH = fig1(2)
SHAPE = (4, MECH.nlinks, 3, MECH.dim)
Q = np.tile([0.3, 1.0], (4, 1))
QD = np.tile([0.1, 0.2], (4, 1))
QDD = np.tile([0.5, -0.1], (4, 1))
METHODS = ("newton-euler", "matrix-factored")
MODELS: dict = {}


def _model(method: str):
    if method not in MODELS:
        MODELS[method] = prepare(MECH, method)
    return MODELS[method]


def _masked() -> np.ma.MaskedArray:
    f = np.ma.masked_array(np.ones(SHAPE), mask=np.zeros(SHAPE, bool))
    f.mask[1, 0, 2, 0] = True
    f.data[1, 0, 2, 0] = 1e6  # what a reader by position would use
    return f


NOT_NUMBERS = {
    "str array": lambda: np.full(SHAPE, "1.5"),
    "str list": lambda: np.full(SHAPE, "1.5").tolist(),
    "Decimal": lambda: np.full(SHAPE, Decimal("1.5"), dtype=object),
    "bool": lambda: np.ones(SHAPE, bool),
    "bool list": lambda: np.ones(SHAPE, bool).tolist(),
    "complex": lambda: np.full(SHAPE, 1 + 1j),
    "masked entry": _masked,
}


@pytest.mark.case("P1")
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("kind", sorted(NOT_NUMBERS))
def test_forces_that_are_not_real_numbers_are_refused(method, kind):
    """f_ext of strings, Decimals, booleans, complex numbers or masked entries is refused naming the field
    (it was read as numbers: "1.5" as 1.5, True as 1 N, a masked entry's hidden value used, an
    imaginary part dropped with a warning only), in inverse and forward dynamics."""
    model = _model(method)
    tau = model.inverse_dynamics(Q, QD, QDD)
    with pytest.raises(ValueError, match=r"field 'f_ext'.*expected"):
        model.inverse_dynamics(Q, QD, QDD, f_ext=NOT_NUMBERS[kind]())
    with pytest.raises(ValueError, match=r"field 'f_ext'.*expected"):
        model.forward_dynamics(Q, QD, tau, f_ext=NOT_NUMBERS[kind]())


TAUS = {
    "str array": lambda t: t.astype(str),
    "str list": lambda t: t.astype(str).tolist(),
    "Decimal list": lambda t: [[Decimal(float(x)) for x in row] for row in t],
    "complex": lambda t: t + 0j,
}


@pytest.mark.case("P2")
@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("kind", sorted(TAUS))
def test_tau_beside_f_ext_is_read_as_without_it(method, kind):
    """forward dynamics (and its derivatives) refuse a tau of strings, Decimals or complex numbers with
    f_ext as they do without it (with f_ext it was converted first: "-83.5" read as -83.5)."""
    model = _model(method)
    tau = TAUS[kind](model.inverse_dynamics(Q, QD, QDD))
    f = np.ones(SHAPE)
    with pytest.raises(ValueError, match="field 'tau'"):
        model.forward_dynamics(Q, QD, tau)
    with pytest.raises(ValueError, match="field 'tau'"):
        model.forward_dynamics(Q, QD, tau, f_ext=f)
    with pytest.raises(ValueError, match="field 'tau'"):
        xf.forward_derivatives(model, Q, QD, tau, f)


@pytest.mark.case("P3")
@pytest.mark.parametrize("method", METHODS)
def test_forces_whose_generalised_force_overflows_are_named(method):
    """Finite forces of 1e308 N overflow Q: inverse dynamics returned inf and NaN with check=True, forward
    dynamics blamed 'tau' (which was finite), and the inverse derivatives returned inf. Each now
    refuses naming f_ext and the sample; smaller forces still answer."""
    model = _model(method)
    tau = model.inverse_dynamics(Q, QD, QDD)
    f = np.zeros(SHAPE)
    f[2] = 1e308  # finite, but three points of it sum past float64
    named = r"field 'f_ext': sample 2\b.*finite"
    with pytest.raises(ValueError, match=named):
        model.inverse_dynamics(Q, QD, QDD, f_ext=f)
    with pytest.raises(ValueError, match=named):
        model.forward_dynamics(Q, QD, tau, f_ext=f)
    with pytest.raises(ValueError, match=named):
        xf.inverse_derivatives(model, Q, QD, QDD, f)
    with pytest.raises(ValueError, match=named):
        xf.forward_derivatives(model, Q, QD, tau, f)
    f[2] = 1e3
    assert np.isfinite(model.inverse_dynamics(Q, QD, QDD, f_ext=f)).all()
    assert np.isfinite(model.forward_dynamics(Q, QD, tau, f_ext=f)).all()


@pytest.mark.case("P1")
@pytest.mark.parametrize("kind", ["str", "Decimal", "bool", "complex"])
def test_forces_at_takes_real_numbers_and_a_sample_count(kind):
    """forces_at, the named way to build f_ext, read a force of strings ("700") or Decimals as numbers
    and booleans as 1 N, and took samples=-1 or True (numpy's "negative dimensions", a batch of one):
    each is a ValueError naming the link, the point and the field."""
    name = MECH.names[0]
    value = {"str": ["0", "700"], "Decimal": [Decimal(0), Decimal(700)], "bool": [False, True], "complex": [0, 7j]}
    with pytest.raises(ValueError, match=rf"f_ext: link '{name}', point 'end': expected .*real numbers"):
        xf.forces_at(MECH, {(name, "end"): value[kind]})
    for samples in (-1, True, 2.0):
        with pytest.raises(ValueError, match=r"f_ext: field 'samples': expected"):
            xf.forces_at(MECH, {(name, "end"): [0.0, 700.0]}, samples=samples)
    np.testing.assert_array_equal(xf.forces_at(MECH, {(name, "end"): [0, 700]})[0, 2], [0.0, 700.0])


@pytest.mark.case("P1", "P3")
@pytest.mark.parametrize("kind", ["str", "Decimal", "complex", "huge"])
def test_simulate_reads_the_forces_of_its_f_ext_function_as_the_calls_do(kind):
    """simulate's f_ext(t, q, qd) is read as the calls read f_ext (ControlsWithForces, the right-hand
    side's edge; called here without integrating): its forces of strings or Decimals were read as
    numbers (np.asarray(dtype=float) before the check), a complex force dropped its imaginary part,
    and forces whose Q overflows gave an infinite right-hand side; each is a ValueError naming f_ext."""
    model = _model("newton-euler")
    force = {"str": "700", "Decimal": Decimal(700), "complex": 700j, "huge": 1e308}[kind]  # huge: Q = inf

    def f_ext(t, q, qd):
        f = np.zeros(SHAPE[1:], dtype=object if kind != "huge" else float)
        f[0, :, :] = force
        return f.tolist() if kind == "str" else f

    rhs = xc.ControlsWithForces(model, lambda t, q, qd: np.zeros_like(q), f_ext)
    with pytest.raises(ValueError, match=r"simulate at t = 0 s: field 'f_ext'"):
        rhs(0.0, Q[:1], QD[:1])
    ok = xc.ControlsWithForces(model, lambda t, q, qd: np.zeros_like(q), lambda t, q, qd: np.ones(SHAPE[1:]))
    assert np.isfinite(ok(0.0, Q[:1], QD[:1])).all()


@pytest.mark.case("P2")
def test_a_labelled_tau_beside_f_ext_is_read_by_name():
    """A DataFrame tau whose columns are the coordinate names in another order is read by name with f_ext,
    as without it (with f_ext it was read by position: phi1's moment taken as l1's force)."""
    pd = pytest.importorskip("pandas")
    from exo_bench.models.states.states import coordinate_names

    model = _model("newton-euler")
    tau = model.inverse_dynamics(Q, QD, QDD)
    names = coordinate_names(MECH)
    labelled = pd.DataFrame(tau, columns=names)[names[::-1]]
    f = np.ones(SHAPE)
    np.testing.assert_array_equal(
        model.forward_dynamics(Q, QD, labelled, f_ext=f), model.forward_dynamics(Q, QD, tau, f_ext=f)
    )
