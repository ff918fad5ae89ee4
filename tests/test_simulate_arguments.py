"""``simulate()``'s arguments, budgets and what it keeps when a budget stops it (issue 34: H1, U12, D5).

Every argument is validated before any work (a ValueError naming the argument, the expected and the
actual value); there is always a budget (a count of right-hand-side evaluations by default, and a
wall-clock one read from an injected ``clock``, so no test here depends on the machine's speed); and a
run stopped by a budget keeps the steps it accepted, bit for bit those of the same run without the
budget.
"""

import functools
import math

import numpy as np
import pytest
from exo_bench.models.mechanism.presets import fig1
from exo_bench.models.simulation import forward_dynamics as fd
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from exo_bench import prepare

MECH = fig1(2)
Q0 = np.array([[-1.0, 0.5]])
EPS = np.finfo(float).eps


@pytest.fixture(scope="module")
def model():
    return prepare(MECH, "pinocchio")


class Spy:
    """Spring-damper controls that count their calls (no call: no work was done)."""

    def __init__(self, k: float = 1e3):
        self.inner = fd.rod_spring_damper(MECH, k, 0.0, 0.5)
        self.jacobian = self.inner.jacobian
        self.calls = 0

    def __call__(self, t, q, qd):
        self.calls += 1
        return self.inner(t, q, qd)


def _run(model, controls, **kw):
    args = {"t_span": (0.0, 0.2), "integrator": "RK45", "rtol": 1e-6, "max_evaluations": 300, **kw}
    return fd.simulate(model, Q0, np.zeros_like(Q0), controls=controls, **args)


_NAN, _INF = math.nan, math.inf
_not_number = st.one_of(st.text(max_size=5), st.none(), st.booleans(), st.lists(st.floats(), max_size=2))
_times = st.one_of(st.floats(allow_nan=True), st.text(max_size=3), st.booleans(), st.none())
#: argument -> values it must refuse (everything else at a valid value, with a budget so that the call
#: returns even where the argument was not validated).
BAD = {
    "t_span": st.one_of(
        st.sampled_from([(0.0, _NAN), (0.0, _INF), (_NAN, 1.0), (-_INF, 1.0), (1.0, 0.0), (0.5, 0.5), ("0", "1")]),
        st.tuples(st.floats(-10, 10), st.sampled_from([_NAN, _INF, -_INF, "1", None, True])),
        st.tuples(_times, _times).filter(lambda s: not all(isinstance(x, float) and math.isfinite(x) for x in s)),
        st.lists(st.floats(0, 1), max_size=3).filter(lambda s: len(s) != 2),
        st.text(max_size=4),
        st.none(),
    ),
    "rtol": st.one_of(
        st.floats(max_value=2e-14),  # 0, negatives, -inf and values below 100 eps
        st.floats(min_value=1.0),  # a relative error of 100 % or more, and inf
        st.just(_NAN),
        _not_number,
    ),
    "atol": st.one_of(st.floats(max_value=0.0), st.sampled_from([_NAN, _INF]), st.text(max_size=3), st.booleans()),
    "max_evaluations": st.one_of(
        st.integers(max_value=0), st.floats(allow_nan=True), st.text(max_size=3), st.booleans()
    ),
    "max_seconds": st.one_of(st.floats(max_value=0.0), st.sampled_from([_NAN, _INF, -1]), st.text(max_size=3)),
    "first_step": st.one_of(
        st.floats(max_value=0.0), st.floats(min_value=0.21), st.sampled_from([_NAN, _INF]), st.text(max_size=3)
    ),
    "dense": st.one_of(st.text(max_size=3), st.integers(), st.none()),
    "controls": st.one_of(st.none(), st.integers(), st.text(max_size=3)),
}


@pytest.mark.case("H1", "U12")
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_every_bad_argument_is_refused_before_any_work(model, data):
    """Bad arguments of simulate() (a NaN, infinite, reversed or string time span, rtol 0, NaN or below
    100 eps, max_seconds = -1, non-positive budgets, ...) are refused with a ValueError naming the
    argument, the expected and the actual value, before the right-hand side is evaluated once."""
    arg = data.draw(st.sampled_from(sorted(BAD)), label="argument")
    value = data.draw(BAD[arg], label=arg)
    spy = Spy()
    kw = {arg: value}
    controls = value if arg == "controls" else spy
    kw.pop("controls", None)
    with pytest.raises(ValueError) as e:
        _run(model, controls, **kw)
    msg = str(e.value)
    assert f"'{arg}'" in msg and "expected" in msg and "got" in msg, msg
    assert spy.calls == 0


@pytest.mark.case("H1")
@pytest.mark.parametrize("bad", [None, MECH, "pinocchio"], ids=["None", "a Mechanism", "a method name"])
def test_a_model_that_is_not_prepared_is_refused(bad):
    """A model that is not a prepared model (None, a bare Mechanism, a method name) is refused with a
    ValueError naming the argument 'model', not an AttributeError from deep inside."""
    with pytest.raises(ValueError, match="argument 'model': expected a prepared model"):
        fd.simulate(bad, Q0, np.zeros_like(Q0), (0.0, 0.1), Spy(), max_evaluations=10)


@pytest.mark.case("H1", "U12")
@pytest.mark.parametrize(
    "kw",
    [
        {"t_span": (0.0, math.nan)},
        {"rtol": 0.0},
        {"rtol": math.nan},
        {"max_seconds": -1},
        {"t_span": ("0", "1")},
        {"atol": 0.0, "rtol": 1e-6},
    ],
    ids=str,
)
def test_the_reported_hanging_arguments_are_refused(model, kw):
    """The issue's cases, t_span=(0, nan), rtol=0, rtol=nan, max_seconds=-1 and string times (and
    atol=0), are refused with a ValueError naming the argument, before any work."""
    spy = Spy()
    arg = next(iter(kw))
    with pytest.raises(ValueError, match=f"argument '{arg}': expected .*, got "):
        _run(model, spy, **kw)
    assert spy.calls == 0


@pytest.mark.parametrize(
    "kw",
    [
        {"rtol": 100 * EPS, "t_span": (0.0, 0.01)},
        {"rtol": np.float32(1e-4), "atol": np.float64(1e-9)},
        {"t_span": np.array([0.0, 0.1])},
        {"t_span": [0, 1]},
        {"max_seconds": 1e9, "first_step": 1e-3},
        {"dense": True},
    ],
    ids=str,
)
def test_valid_edge_arguments_are_accepted(model, kw):
    """The floor of rtol, numpy scalars, lists and arrays of two times are valid."""
    sim = _run(model, Spy(), max_evaluations=100_000, **kw)
    assert sim.ok, sim.status


@pytest.mark.case("H1")
def test_a_run_without_a_budget_has_the_default_one(model, monkeypatch):
    """simulate() without a budget stops at the stated default count of right-hand-side evaluations
    (exo_bench.models.simulation.forward_dynamics.DEFAULT_MAX_EVALUATIONS), recorded in the result."""
    assert isinstance(fd.DEFAULT_MAX_EVALUATIONS, int) and fd.DEFAULT_MAX_EVALUATIONS >= 100_000
    short = _run(model, Spy(), max_evaluations=None)
    assert short.ok and short.max_evaluations == fd.DEFAULT_MAX_EVALUATIONS
    monkeypatch.setattr(fd, "DEFAULT_MAX_EVALUATIONS", 250)
    spy = Spy()
    sim = fd.simulate(model, Q0, np.zeros_like(Q0), (0.0, 10.0), spy, "RK45", 1e-10)
    assert sim.status.startswith("budget exceeded") and "250 right-hand-side evaluations" in sim.status
    assert sim.max_evaluations == 250 and sim.nfev == 251 and spy.calls == 250  # the 251st is refused


class FakeClock:
    """A clock that advances ``tick`` seconds each time it is read."""

    def __init__(self, tick: float):
        self.now, self.tick, self.reads = 0.0, tick, 0

    def __call__(self) -> float:
        self.reads += 1
        self.now += self.tick
        return self.now


@pytest.mark.case("H1", "D5")
@pytest.mark.parametrize("limit", [2.5, 10.5, 40.5])
def test_the_wall_clock_budget_reads_the_injected_clock(model, limit):
    """max_seconds is measured on the injected clock (one tick a read, no real time), and the run
    it stops keeps its accepted steps."""
    clock = FakeClock(1.0)
    sim = _run(model, Spy(), t_span=(0.0, 10.0), rtol=1e-10, max_evaluations=None, max_seconds=limit, clock=clock)
    assert sim.status.startswith(f"budget exceeded: gave up after {limit:g} s"), sim.status
    # read at the start, at each evaluation (it stops at the first past the limit) and at the end
    assert sim.nfev == math.ceil(limit) and clock.reads == sim.nfev + 2
    assert sim.seconds == clock.now - 1.0
    assert len(sim.t) == len(sim.y) >= 1 and f"kept {sim.steps} accepted steps" in sim.status


@functools.cache
def _unbudgeted(model, integrator):
    return _run(model, Spy(), t_span=(0.0, 0.5), integrator=integrator, max_evaluations=10**6, dense=True)


@pytest.mark.case("D5")
@pytest.mark.parametrize("integrator", fd.INTEGRATORS)
@pytest.mark.parametrize("share", [0.15, 0.5, 0.9])
def test_a_run_stopped_by_its_budget_keeps_its_accepted_steps(model, integrator, share):
    """A run stopped by its evaluation budget keeps every step it accepted (bit for bit those of the
    same run with no budget in reach), its dense output over them, and says where and why it stopped."""
    full = _unbudgeted(model, integrator)
    assert full.ok and full.steps > 5
    budget = int(share * full.nfev)  # a share of what the whole run takes
    sim = _run(model, Spy(), t_span=(0.0, 0.5), integrator=integrator, max_evaluations=budget, dense=True)
    assert sim.status.startswith(f"budget exceeded: gave up after {budget} right-hand-side evaluations")
    k = len(sim.t)
    assert 2 <= k < len(full.t), (k, len(full.t))
    assert np.array_equal(sim.t, full.t[:k]) and np.array_equal(sim.y, full.y[:k])
    assert f"kept {k - 1} accepted steps up to t = {sim.t[-1]:.6g} s" in sim.status
    assert sim.t_reached >= sim.t[-1] and sim.t[-1] < 0.5
    end = sim.solution.t_max  # the last step's interpolant may be what the budget stopped (DOP853)
    assert end in (sim.t[-1], sim.t[-2])
    mid = np.linspace(0.0, end, 7)
    assert np.array_equal(sim.solution(mid), full.solution(mid))
    assert budget < sim.nfev <= budget + 2 * MECH.dof  # a finite-difference Jacobian asks for 2 dof at once
