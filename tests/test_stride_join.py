"""The stride's half-stride join (bench/studies/stride/: the half solved, the other half its mirror).

Only coordinates and rates are mirrored, so the loads may jump where the halves meet; a load that jumps
there is an artefact of the transcription, not of the walk, and the exo sizing table's peaks would carry it.

* The exo variant's stored problem asks for continuous loads (``join_loads``); the human's does not
  (it costs the human stride two of its 17 peaks within 2x: the trial ``human-join-loads``).
* Every stored stride whose problem asks for it has continuous loads across the join, to the solver's
  constraint tolerance. **Error model.** The transcription constrains ``(M_0 - P M_N) / m`` (N·m/kg) and
  ``(F_0 - P F_N) / BW`` to zero; IPOPT stops when the largest violation of its (unscaled) constraints is
  at most ``constr_viol_tol`` (stored with the solver's stats), so a moment jumps by at most
  ``constr_viol_tol x m`` N·m and a rod force by ``constr_viol_tol x BW`` N (5.7e-9 N·m and 5.6e-8 N at
  1e-10); the stored loads are CasADi's evaluation of the same node function at the same nodes, so only
  the final subtraction's rounding adds, ``EPS`` times the loads' size. Measured on the stored
  exo stride: 2.8e-13 N·m, 7.7e-13 N. Solved without it (trial ``exo-join-free``): 49.5 N·m and 669 N.
* The report states each stored stride's jump, computed.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import EPS

from exo_bench.bench.studies.stride import data
from exo_bench.bench.studies.stride.constraints import load_jump
from exo_bench.bench.studies.stride.problem import settings_for
from exo_bench.models.mechanism.presets import human

M = human(2)
STORED = data.stored()


def join_bound(stride) -> tuple[float, float]:
    """``(N·m, N)``: how far the loads may jump across the join of a stride solved with ``join_loads``
    (module docstring)."""
    tol = stride.solver["constr_viol_tol"]
    rounding = 4 * EPS * max(np.abs(stride.moments).max(), np.abs(stride.rod_forces).max())
    return tol * M.total_mass + rounding, tol * stride.body_weight + rounding


def test_the_exo_variants_problem_asks_for_continuous_loads_and_the_humans_does_not():
    assert settings_for(M, "exo", 1.41).join_loads is True
    for speed in (1.0, 1.41, 1.8):
        assert settings_for(M, "human", speed).join_loads is False


@pytest.mark.parametrize("key", [k for k in STORED if k[0] == "exo"], ids=lambda k: f"{k[0]}-{k[1]:g}")
def test_the_stored_exo_strides_loads_are_continuous_across_the_join(key):
    stride = data.load(*key, M)
    moments, forces = load_jump(M, stride.moments, stride.rod_forces)
    bound_m, bound_f = join_bound(stride)
    assert moments <= bound_m, f"moments jump {moments:.3g} N·m at the join (bound {bound_m:.2g})"
    assert forces <= bound_f, f"rod forces jump {forces:.3g} N at the join (bound {bound_f:.2g})"
    assert stride.settings.get("join_loads") is True, stride.settings


def test_the_join_check_catches_a_jump_of_a_micro_newton_metre():
    stride = data.load("exo", 1.41, M)
    N = (len(stride.t) - 1) // 2
    moments = stride.moments.copy()
    moments[N, 4] += 1e-6  # the left knee at the join
    got, _ = load_jump(M, moments, stride.rod_forces)
    assert got >= 1e-6 - join_bound(stride)[0] > join_bound(stride)[0]


def test_load_jump_pairs_each_load_with_its_mirror_image():
    """A hand-made stride: the right knee at t = 0 against the left knee at t = T, not the right one."""
    K, N = 5, 2
    moments, forces = np.zeros((K, 8)), np.zeros((K, 9))
    names = list(data.load("exo", 1.41, M).joint_names)
    moments[0, names.index("right_knee")] = 3.0
    moments[N, names.index("left_knee")] = 3.0
    moments[0, names.index("left_knee")] = 7.0
    moments[N, names.index("right_knee")] = 7.0  # unmirrored, each knee would jump by 4 N·m
    assert load_jump(M, moments, forces) == (0.0, 0.0)
    moments[N, names.index("left_knee")] = 1.0
    assert load_jump(M, moments, forces) == (2.0, 0.0)


def test_a_new_solve_holds_the_constraints_tight_enough_for_1e_8_on_the_full_stride():
    """``CONSTR_VIOL_TOL`` (problem.py): a mirrored node's root-angle residual is at most ``(1 + sqrt(2) d) c BW``
    (``d`` the half stride); with ``c`` the tolerance it is under 1e-8 N·m at every stored speed."""
    from exo_bench.bench.studies.stride.problem import CONSTR_VIOL_TOL

    bw = M.total_mass * M.g
    for variant, speed in STORED:
        s = settings_for(M, variant, speed)
        d = s.speed * s.period[1] / 2
        assert s.constr_viol_tol == CONSTR_VIOL_TOL and (1 + np.sqrt(2) * d) * CONSTR_VIOL_TOL * bw <= 1e-8


@pytest.mark.parametrize("key", ["tol", "constr_viol_tol"])
@pytest.mark.parametrize("bad", [0.0, -1e-10, float("nan"), 1.0, "1e-10", True])
def test_a_bad_solver_tolerance_is_refused_where_the_settings_are_made(key, bad):
    from dataclasses import replace

    with pytest.raises(ValueError, match=rf"stride: field '{key}': expected IPOPT's tolerance in \(0, 1\), got"):
        replace(settings_for(M, "exo", 1.41), **{key: bad})


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    """The stored human and exo strides at 1.41 m/s and their trials solved the other way about the join."""
    import shutil

    root = tmp_path_factory.mktemp("strides")
    for key in (("human", 1.41), ("exo", 1.41)):
        shutil.copy(data.path_of(M.name, *key), root)
    for name in ("human-join-loads", "exo-join-free"):
        shutil.copytree(data.DATA / "trials" / name, root / "trials" / name)
    return root


def test_the_report_states_each_stored_strides_jump_at_the_join(folder):
    from exo_bench.bench.studies.stride import constraints, report
    from exo_bench.models.files import markdown_text

    text = report.markdown(M, data.load("human", 1.41, M, folder), folder=folder)
    assert text.count("### The half-stride join") == 1
    assert text.index("### The half-stride join") < text.index("### Actuator sizing")
    for variant, trial in (("human", "human-join-loads"), ("exo", "exo-join-free")):
        stride = data.load(variant, 1.41, M, folder)
        moments, forces = load_jump(M, stride.moments, stride.rod_forces)
        before = load_jump(
            M, *(lambda t: (t.moments, t.rod_forces))(data.load(variant, 1.41, M, folder / "trials" / trial))
        )
        (group,) = [g for g in constraints.joins(M, [stride], folder / "trials")]
        assert [j.name for j in group] == [constraints.STORED, trial]
        said = constraints.sentence(group)
        assert markdown_text(said) in text
        if variant == "exo":
            assert said.startswith("The exo stride at 1.41 m/s is solved with its loads continuous across the join")
            assert f"at most {moments:.1g} N·m and {forces:.1g} N, within" in said
            assert f"jumped by {before[0]:.3g} N·m and {before[1]:.3g} N" in said
        else:
            assert f"solved without it: its loads jump at the join by {moments:.3g} N·m and {forces:.3g} N" in said
            assert moments > 1.0 and forces > 10.0  # the human's loads do jump: stated, not hidden


def test_a_stride_asked_for_continuous_loads_that_jumps_is_reported_outside_the_tolerance(folder):
    from exo_bench.bench.studies.stride import constraints

    stride = data.load("exo", 1.41, M, folder)
    moments = stride.moments.copy()
    moments[0, 1] += 1e-6  # the right knee at t = 0
    bad = data.StoredStride(**{**stride.__dict__, "moments": moments})
    j = constraints.join_of(M, bad)
    assert j.moments == pytest.approx(1e-6, rel=1e-3) and j.moments > j.bound[0]
    assert "**outside** the solver's constraint tolerance" in constraints.sentence([j])


def test_each_sizing_block_says_whether_its_loads_are_continuous_across_the_join(folder):
    """Beside the numbers a motor is bought from: the exo's block says continuous, the human's the jump."""
    from exo_bench.bench.studies.stride import report
    from exo_bench.models.files import markdown_text

    text = report.markdown(M, data.load("human", 1.41, M, folder), folder=folder)
    sizing = text[text.index("### Actuator sizing") :]
    human, exo = sizing.split("**exo variant at 1.41 m/s**")
    m, f = load_jump(M, *(lambda s: (s.moments, s.rod_forces))(data.load("human", 1.41, M, folder)))
    assert markdown_text(f"Loads at the half-stride join: they jump by {m:.3g} N·m and {f:.3g} N") in human
    assert markdown_text("Loads at the half-stride join: continuous (within the solver's tolerance") in exo
