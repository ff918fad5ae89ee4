"""Pinocchio's limits on mimic joints (docs/pinocchio-mimic.md): the reproduction script shows them
with pin 4.1, and the suite calls none of the refused or wrong functions, and resets what it reuses.

Every Pinocchio model of the suite has mimic joints (the middle masses; in 3D the undo joints), so
a call of ``aba``, ``forwardDynamics``, ``computeMinverse``, the RNEA/ABA derivatives,
``computeAllTerms``, the energies or ``computeCoriolisMatrix`` anywhere in the library would be a
call on a mimic model.
"""

import ast
import importlib.util
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from exo_bench.api import prepare
from exo_bench.models.simulation import forward_dynamics as fd
from exo_bench.models.engines import pinocchio_backend as pb
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5, random_tree

ROOT = Path(__file__).resolve().parents[1]
#: Refused on mimic models by pin 4.1 (RuntimeError), or wrong there (computeCoriolisMatrix).
FORBIDDEN = (
    "aba",
    "forwardDynamics",
    "computeMinverse",
    "computeRNEADerivatives",
    "computeABADerivatives",
    "computeAllTerms",
    "computeKineticEnergy",
    "computePotentialEnergy",
    "computeMechanicalEnergy",
    "computeCoriolisMatrix",
    "computeGeneralizedGravity",
    "computeStaticTorque",
    "computeForwardKinematicsDerivatives",
    "constraintDynamics",
    "impulseDynamics",
)
LIBRARY = ("models", "bench", "matrix_method", "lagrange", "exo_bench")


def _repro():
    spec = importlib.util.spec_from_file_location("pinocchio_mimic_limits", ROOT / "docs" / "pinocchio_mimic_limits.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_the_reproduction_shows_each_limit_and_its_control_holds():
    """What docs/pinocchio-mimic.md states, measured again: with mimic joints each function is refused,
    Coriolis is off by more than 1 and a reused Data's CRBA by more than 1; without them every
    function runs, Coriolis holds to rounding and CRBA does not depend on the Data's history."""
    r = _repro()
    with_mimic, without = r.build(True), r.build(False)
    assert all(status.startswith("refused: RuntimeError") and "Mimic" in status for _, status in r.refused(with_mimic))
    assert all(status == "runs" for _, status in r.refused(without))
    assert r.coriolis_residual(with_mimic) > 1.0
    assert r.coriolis_residual(without) < 1e-12
    assert r.crba_reuse_difference(with_mimic) > 1.0
    assert r.crba_reuse_difference(without) == 0.0


def _pinocchio_attributes(path: Path) -> set[str]:
    """Attributes taken of the pinocchio module in a file, under whatever name it is imported."""
    tree = ast.parse(path.read_text(), str(path))
    names = {"pinocchio"}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {a.asname or a.name for a in node.names if a.name == "pinocchio"}
    used = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in names:
            used.add(node.attr)
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] == "pinocchio":
            used |= {a.name for a in node.names}
    return used


#: The one call of a forbidden function that is meant: the derivatives benchmark's Pinocchio row calls it to
#: record Pinocchio's own refusal of mimic joints (issue 36), never to use an answer.
TO_RECORD_THE_REFUSAL = {"bench/perf/derivative_routes.py": {"computeRNEADerivatives"}}


def test_the_library_calls_no_function_refused_or_wrong_on_mimic_models():
    files = [p for d in LIBRARY for p in (ROOT / d).rglob("*.py")]
    assert len(files) > 30
    hits = {
        (rel := str(p.relative_to(ROOT))): sorted(
            _pinocchio_attributes(p) & set(FORBIDDEN) - TO_RECORD_THE_REFUSAL.get(rel, set())
        )
        for p in files
    }
    assert {k: v for k, v in hits.items() if v} == {}
    assert "rnea" in _pinocchio_attributes(
        ROOT / "models" / "engines" / "pinocchio_backend.py"
    )  # the scan sees real uses


def test_the_pinocchio_method_and_forward_dynamics_run_with_the_forbidden_functions_raising(monkeypatch):
    """The same, at run time: every forbidden function raises, and the pinocchio method's inverse
    dynamics, mass matrix, bias forces, and forward dynamics through it, still run."""

    def boom(*a, **k):
        raise AssertionError("a function refused or wrong on mimic models was called")

    for name in FORBIDDEN:
        if hasattr(pin, name):
            monkeypatch.setattr(pin, name, boom)
    mech = exo5(3)
    q, qd, qdd = random_states(mech, 3, 1)
    model = prepare(mech, "pinocchio")
    tau = model.inverse_dynamics(q, qd, qdd)
    M, h = model.mass_matrix(q), model.bias_forces(q, qd)
    assert np.allclose(np.einsum("sij,sj->si", M, qdd) + h, tau, rtol=0, atol=1e-9 * np.abs(tau).max())
    assert np.allclose(fd.accelerations(model, q, qd, tau), qdd, rtol=0, atol=1e-8)


@pytest.mark.parametrize("mech", [exo5(3), random_tree(7, 3, 3), random_tree(7, 2, 4)], ids=lambda m: m.name)
def test_a_reused_data_gives_the_fresh_data_mass_matrix(mech):
    """The suite reuses one Data per thread and resets ``Fcrb`` before each CRBA (models.pinocchio_backend.crba):
    its mass matrices on consecutive states are bit for bit those of a fresh Data each time; pin.crba
    itself on the reused Data is not."""
    q, _, _ = random_states(mech, 6, 2)
    model = prepare(mech, "pinocchio")
    pm = pb.build_model(mech)
    qj = q @ pm.G.T
    fresh = np.stack([pb.crba(pm.model, pin.Data(pm.model), x) for x in qj])
    assert np.array_equal(model.mass_matrix(q), np.stack([pm.G.T @ f @ pm.G for f in fresh]))
    reused = pin.Data(pm.model)
    raw = []
    for x in qj:
        M = pin.crba(pm.model, reused, x)
        raw.append(np.triu(M) + np.triu(M, 1).T)
    if mech.dim == 3:  # the mimic undo joints: pin.crba's history-dependence (docs/pinocchio-mimic.md)
        assert np.abs(np.stack(raw) - fresh).max() > 1e-6
