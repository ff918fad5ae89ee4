"""The errata report: its witnesses, its verdicts against an independent derivation
(sympy.physics.mechanics), the file."""

import numpy as np
import pytest
import sympy as sp

from exo_bench.bench.cli import main
from exo_bench.lagrange import BudgetExceeded, extract_matrices
from exo_bench.lagrange.derivation import parameter_values
from exo_bench.lagrange.peer import peer_equations
from exo_bench.bench.studies import errata
from exo_bench.matrix_method import printed
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import random_tree
from exo_bench.models.mechanism.symbols import symbols_for


def _model_scale(mats) -> float:
    return max(float(np.abs(x).max()) for block in mats.values() for x in block.values())


# Error model (tests/conftest.py): two float64 evaluations of the same matrices differ by a few ulps of
# the largest term they sum, so their difference is bounded by k * eps * (largest entry of the model's
# matrices) with k small; 1e-13 leaves k ~ 450 where ~2e-15 is measured on these models.
AGREE = 1e-13


@pytest.mark.parametrize("n,dim,seed", [(1, 2, 1), (4, 2, 2), (1, 3, 3), (4, 3, 4), (6, 3, 5)])
def test_pinocchio_has_exactly_the_papers_matrix_form(n, dim, seed):
    """Eq. (17) rebuilt from the matrices read off Pinocchio reproduces its inverse dynamics for
    random rates: only products of a link's own rates occur."""
    m = random_tree(n, dim, seed)
    q, qd, qdd = random_states(m, 6, seed)
    assert errata.form_residual(m, q, qd, qdd) < AGREE


@pytest.mark.parametrize("n,dim,seed", [(3, 2, 6), (3, 3, 7)])
def test_the_two_witnesses_agree_on_every_matrix(n, dim, seed):
    m = random_tree(n, dim, seed)
    q, _, _ = random_states(m, 6, seed)
    a, b = errata.LagrangeWitness().matrices(m, q), errata.PinocchioWitness().matrices(m, q)
    assert a.keys() == b.keys()
    scale = _model_scale(b)
    for block in a:
        assert a[block].keys() == b[block].keys()
        for name in a[block]:
            assert np.abs(a[block][name] - b[block][name]).max() <= AGREE * scale, (block, name)


@pytest.fixture
def small(monkeypatch):
    """A quick configuration of the report: one model for (18), chains of 1..2 links. The tree of 3
    links (parents -1, 0, -1; signs 1, -1, -1) holds fig2b-3d's pair of links as its subtree, a
    second root and links on no common path: it shows the same misprinted lines of (18) as fig2b-3d
    and as both together (18:g^l, 18:k^l), at half the cost of the independent sympy derivation."""
    monkeypatch.setattr(errata, "spatial_models", lambda: [random_tree(3, 3, 2)])
    monkeypatch.setattr(errata, "CHAIN_LENGTHS", (1, 2))
    monkeypatch.setattr(errata, "SAMPLES", 4)


def _peer_matrices(mech, q):
    """Every matrix of eq. (5)/(17) from an independent derivation: sympy.physics.mechanics'
    LagrangesMethod (lagrange/peer.py, which shares no code with either witness), its equations read
    into the matrix form and evaluated at ``q``; ``{block: {name: (S, n, n)}}``, ``P``: ``(S, n)``."""
    S = symbols_for(mech.nlinks, mech.dim)
    mats = extract_matrices(peer_equations(mech, "lagrange", symbolic_parameters=True), S)
    values = parameter_values(mech, S)
    out = {}
    for block, named in mats.items():
        out[block] = {}
        for name, M in named.items():
            f = sp.lambdify(list(S.q), list(M.xreplace(values)), modules="numpy")
            cols = [np.broadcast_to(np.asarray(v, dtype=float), (q.shape[0],)) for v in f(*q.T)]
            v = np.stack(cols, -1)
            out[block][name] = v if name == "P" else v.reshape(q.shape[0], *M.shape)
    return out


def _printed_line_errors(models):
    """Independently of the report and of its witnesses: per line of (18), the largest error of the
    printed right side (fed the peer's planar matrices) against the peer's 3D matrix, relative to
    the largest entry of the model's matrices; the same for the corrected forms."""
    printed_err, corrected_err = {}, {}
    for m in models:
        q, _, _ = random_states(m, 4, 99)
        n = m.nlinks
        q2 = np.concatenate([q[:, :n], q[:, 2 * n :]], axis=1)
        spatial, planar = _peer_matrices(m, q), _peer_matrices(m.replace(dim=2), q2)
        scale = _model_scale(spatial)
        t = printed.transition_namespace(m, q, planar, three_d=spatial)
        for f in printed.TRANSITIONS:
            if f.fn is None:
                continue
            ref = spatial[f.block][f.name]
            err = lambda g: float(np.abs(np.broadcast_to(g(t), ref.shape) - ref).max()) / scale
            printed_err[f.key] = max(printed_err.get(f.key, 0.0), err(f.fn))
            if f.corrected is not None:
                corrected_err[f.key] = max(corrected_err.get(f.key, 0.0), err(f.corrected))
    return printed_err, corrected_err


def test_report_names_exactly_the_misprinted_lines_and_their_verified_corrections(small, tmp_path):
    results = errata.compute()
    text = errata.write_report(tmp_path / "errata.md", results).read_text()
    assert text.startswith("# Errata") and "_Generated by `exo-bench errata`" in text
    for f in printed.ALL:
        assert f"`{f.key}`" in text, f.key
    printed_err, corrected_err = _printed_line_errors(errata.spatial_models())
    # The independent computation is not borderline: a line agrees to rounding or misses by far more
    # than the report's tolerance (a misprint is a wrong term, not a rounding difference).
    borderline = {k: e for k, e in printed_err.items() if AGREE < e <= 1e-3}
    assert not borderline
    misprinted = {k for k, e in printed_err.items() if e > 1e-3}
    assert misprinted  # the paper has misprints in (18): g^l, k^l
    verdicts = results.verdicts
    value_fails = {v.formula.key for v in verdicts if v.formula.kind == "transition" and v.status == "fails"}
    assert value_fails == misprinted
    for v in verdicts:
        if v.status.startswith("fails"):
            assert f"### {v.formula.equation} {v.formula.label} (`{v.formula.key}`): {v.status}" in text
            assert v.formula.corrected is not None and v.largest_corrected <= errata.TOLERANCE, v.formula.key
            if v.formula.key in misprinted:  # the corrected form agrees with the peer to rounding
                assert corrected_err[v.formula.key] <= AGREE, v.formula.key
    label = next(v for v in verdicts if v.formula.key == "18:k^psi")
    assert label.status == "fails (left side)" and not label.label_exists


def test_a_witness_over_budget_is_reported_as_skipped(small, monkeypatch):
    def over(self, mech):
        raise BudgetExceeded("Lagrange II derivation", mech.nlinks, mech.dim, 0.01)

    monkeypatch.setattr(errata.LagrangeWitness, "_compiled", over)
    v = errata.check_transition(printed.TRANSITIONS[0], [errata.LagrangeWitness(), errata.PinocchioWitness()])
    assert {c.witness for c in v.checks if c.skipped} == {"lagrange"} and v.status == "holds"


def test_an_interrupted_run_leaves_no_report(small, monkeypatch, tmp_path):
    def boom(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(errata, "check_all", boom)  # interrupted during the checks
    with pytest.raises(KeyboardInterrupt):
        errata.write_report(tmp_path / "errata.md")
    assert not list(tmp_path.iterdir())


def test_cli_errata_writes_the_report(small, tmp_path, capsys):
    assert main(["errata", "--reports", str(tmp_path)]) == 0
    assert (tmp_path / "errata.md").exists() and "wrote" in capsys.readouterr().out
