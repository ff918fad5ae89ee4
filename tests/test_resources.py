"""Memory and time before the work: Pinocchio's Data size, the cost model, the limits, chunks.

Oracles: the Pinocchio model itself (joint counts), the resident set size measured around
``createData`` (memory, not time), a fresh ``Data`` for CRBA, and the unchunked evaluation for the
chunked one (chunks must not change a single bit).
"""

import numpy as np
import pinocchio as pin
import pytest
from conftest import installed_methods

from exo_bench.api import cost_model as resources
from exo_bench.api import METHODS, prepare
from exo_bench.api.cost_model import Limits, ResourceLimit, check, estimate, parse_size
from exo_bench.models.memory import CHUNK_BYTES
from exo_bench.models import pinocchio_backend as pb
from exo_bench.models.motion import random_states
from exo_bench.models.presets import chain, exo5, random_tree
from exo_bench.models.urdf import data_bytes, pinocchio_model_size


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_model_size_is_the_built_models(dim, seed):
    m = random_tree(7, dim, seed)
    model = pb.build_model(m).model
    assert pinocchio_model_size(m) == (model.nv, model.njoints)


_MEASURE_DATA = """
import json, pinocchio as pin
from exo_bench.models.presets import chain
from exo_bench.models.urdf import to_urdf
def status(key):
    for line in open("/proc/self/status"):
        if line.startswith(key):
            return int(line.split()[1]) * 1024
model = pin.buildModelFromXML(to_urdf(chain({n}, {dim})), mimic=True)
open("/proc/self/clear_refs", "w").write("5")
before = status("VmRSS")
data = pin.Data(model)
print(json.dumps([status("VmHWM") - before, model.nv, model.njoints]))
"""


@pytest.mark.parametrize("dim", [2, 3])
def test_data_bytes_bounds_the_measured_growth_of_a_data(dim):
    """The nv^3 law: pin.Data of a 40-link chain grows the peak RSS of a fresh process by what
    data_bytes predicts (an upper estimate within 25 %), and the nv^3 part is most of it. A fresh
    process: in a long-lived one the allocator may serve the Data from memory freed earlier."""
    import json
    import subprocess
    import sys

    r = subprocess.run(
        [sys.executable, "-c", _MEASURE_DATA.format(n=40, dim=dim)], capture_output=True, text=True, timeout=600
    )
    assert r.returncode == 0, r.stderr
    grown, nv, njoints = json.loads(r.stdout)
    predicted = data_bytes(nv, njoints)
    assert grown <= predicted <= 1.25 * grown, (grown, predicted)
    assert 32 * nv**3 > 0.5 * grown


def test_crba_with_a_reused_data_is_the_fresh_data_result():
    """pin 4.1 reads stale Fcrb on mimic joints; the backend zeroes it instead of a Data per sample."""
    m = random_tree(5, 3, 4)
    pm = pb.build_model(m)
    q, _, _ = random_states(m, 6, 9)
    qj = q @ pm.G.T
    data = pm.model.createData()
    for s in range(q.shape[0]):
        fresh = pin.crba(pm.model, pm.model.createData(), qj[s])
        assert np.array_equal(np.triu(pb.crba(pm.model, data, qj[s])), np.triu(fresh))
    stale = pm.model.createData()
    pin.crba(pm.model, stale, qj[0])
    assert not np.allclose(
        np.triu(pin.crba(pm.model, stale, qj[1])), np.triu(pin.crba(pm.model, pm.model.createData(), qj[1]))
    )


def test_pinocchio_refuses_a_data_that_does_not_fit(monkeypatch):
    monkeypatch.setattr(pb, "usable_memory", lambda: 10_000_000)
    with pytest.raises(pb.PinocchioDataTooLarge) as e:
        pb.PinocchioRNEA(chain(40, 3))
    assert isinstance(e.value, MemoryError)
    msg = str(e.value)
    assert "nv = 120" in msg and "four nv^3 tensors" in msg and "matrix-factored" in msg and "\n" not in msg


def test_estimates_grow_with_n_and_the_batch():
    for method in METHODS:
        for dim in (2, 3):
            a, b = estimate(chain(5, dim), method, 10), estimate(chain(10, dim), method, 10)
            c = estimate(chain(10, dim), method, 10_000)
            assert a.memory < b.memory < c.memory and a.seconds <= b.seconds < c.seconds, method


def test_pinocchio_estimate_is_its_data():
    est = estimate(chain(300, 3), "pinocchio", 1)
    assert est.setup_bytes >= 32 * 900**3
    assert estimate(chain(300, 3), "pinocchio", 1, {"threads": 2}).setup_bytes >= 3 * 32 * 900**3


@pytest.mark.parametrize("method", sorted(METHODS))
def test_a_chunk_keeps_to_its_working_set(method):
    for m in (exo5(3), chain(300, 3), chain(50, 2)):
        k = resources.chunk_samples(m, method)
        per = resources.sample_bytes(m, method)
        assert k >= 1 and (k == 1 or k * per <= CHUNK_BYTES)


def test_a_class_prepared_directly_chunks_as_prepare_does():
    """One chunk size per (mechanism, method): the class's own, whoever builds it."""
    from exo_bench.matrix_method.prepared import MatrixFactored

    m = chain(50, 3)
    assert (
        MatrixFactored(m).chunk_samples
        == prepare(m, "matrix-factored").chunk_samples
        == resources.chunk_samples(m, "matrix-factored")
    )


def test_a_refusal_names_method_estimate_limit_and_a_method_that_fits():
    with pytest.raises(ResourceLimit) as e:
        check(chain(300, 3), "pinocchio", 1, limits=Limits(memory=2e9))
    msg = str(e.value)
    assert msg == e.value.skip_reason and "\n" not in msg
    for needle in (
        "'pinocchio'",
        "23.7 GB",
        "nv = 900",
        "memory limit of 2.0 GB",
        "--max-memory",
        "matrix-factored fits",
    ):
        assert needle in msg, (needle, msg)


def test_lagrange_is_refused_for_its_budget_before_deriving():
    with pytest.raises(ResourceLimit, match=r"'lagrange'.*n=50 links.*budget of 120 s \(raise it with --budget"):
        check(chain(50, 2), "lagrange", 2, limits=Limits(memory=1e15))
    assert check(chain(3, 2), "lagrange", 2, limits=Limits(memory=1e15)).method == "lagrange"
    with pytest.raises(ResourceLimit, match="budget of 1.0 s"):
        check(exo5(3), "lagrange", 2, {"budget": 1.0}, limits=Limits(memory=1e15))


def test_no_method_fits_a_batch_whose_arrays_exceed_the_limit():
    with pytest.raises(ResourceLimit, match="no method fits: the batch's arrays alone take .*split the batch"):
        check(exo5(3), "matrix-factored", 10**8, limits=Limits(memory=1e9))


@pytest.mark.parametrize(
    "text,value",
    [
        ("2G", 2 * 2**30),
        ("512M", 512 * 2**20),
        ("1.5GB", int(1.5 * 2**30)),
        ("2GiB", 2 * 2**30),
        ("1e9", 10**9),
        ("100k", 102400),
    ],
)
def test_sizes(text, value):
    assert parse_size(text) == value


@pytest.mark.parametrize("text", ["", "2X", "-1G", "0", "nan", "G", "1e999"])
def test_bad_sizes(text):
    with pytest.raises(ValueError, match="--max-memory"):
        parse_size(text)


@pytest.mark.parametrize("method", sorted(m for m in METHODS if m in installed_methods()))
@pytest.mark.parametrize("dim", [2, 3])
def test_chunks_do_not_change_a_bit(method, dim):
    m = random_tree(4, dim, 7)
    q, qd, qdd = random_states(m, 23, 5)
    whole = prepare(m, method)
    whole.chunk_samples = 1000
    parts = prepare(m, method)
    parts.chunk_samples = 5
    with np.errstate(all="ignore"):
        for check_ in (True, False):
            assert np.array_equal(
                whole.inverse_dynamics(q, qd, qdd, check=check_),
                parts.inverse_dynamics(q, qd, qdd, check=check_),
                equal_nan=True,
            )
        assert np.array_equal(whole.bias_forces(q, qd), parts.bias_forces(q, qd), equal_nan=True)
        Mw, hw = whole.mass_matrix_and_bias(q, qd)
        Mp, hp = parts.mass_matrix_and_bias(q, qd)
        assert np.array_equal(Mw, Mp, equal_nan=True) and np.array_equal(hw, hp, equal_nan=True)
        assert np.array_equal(whole.mass_matrix(q), parts.mass_matrix(q), equal_nan=True)


def test_prepare_sets_the_calibrated_chunk():
    m = chain(60, 3)
    assert prepare(m, "matrix").chunk_samples == resources.chunk_samples(m, "matrix")
    assert prepare(m, "matrix").chunk_samples < prepare(m, "matrix-factored").chunk_samples


@pytest.mark.parametrize("dim", [2, 3])
def test_newton_euler_chunks_by_its_own_o_n_temporaries(dim):
    """newton-euler keeps O(n) numbers per sample: its ``sample_bytes`` bounds the measured peak of its
    numpy kernel's temporaries (tracemalloc, a validated batch in one chunk) and grows linearly, so
    that a 1000-link chain is not cut into chunks of one sample (the O(n^2) default bound did that)."""
    import tracemalloc

    from exo_bench.models.newton_euler.prepared import NewtonEuler

    mech, S = chain(100, dim), 200
    q, qd, qdd = random_states(mech, S, 0)
    model = prepare(mech, "newton-euler", kernel="numpy")
    model.chunk_samples = S
    model.inverse_dynamics(q[:2], qd[:2], qdd[:2])
    tracemalloc.start()
    try:
        before, _ = tracemalloc.get_traced_memory()
        tau = model.inverse_dynamics(q, qd, qdd)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert tau.shape == (S, mech.dof)
    assert peak - before <= S * NewtonEuler.sample_bytes(100, dim)
    assert NewtonEuler.sample_bytes(1000, dim) == 10 * NewtonEuler.sample_bytes(100, dim)
    assert prepare(chain(1000, dim), "newton-euler").chunk_samples >= 100
