"""The engines' section of the benchmark reports: their ratio to matrix-factored, and to newton-euler
exactly when a run has that method's rows (another branch adds it)."""

import numpy as np
import pandas as pd

from benchmark_rows import exo5_3d_row
from exo_bench.bench.perf.reports.error_vs_runtime import error_vs_runtime
from exo_bench.bench.perf.reports.scaling import scaling
from exo_bench.bench.perf.peers import engine_section, ratios


def _rows(with_newton: bool):
    us = {
        "matrix-factored (numba)": 0.2,
        "matrix-factored (numpy)": 3.0,
        "mujoco": 40.0,
        "drake": 120.0,
        "pinocchio": 30.0,
    }
    if with_newton:
        us["newton-euler (numba)"] = 0.5
    rows = []
    for m, t in us.items():
        rows.append(exo5_3d_row("inverse-batched-3d", m, True, 1000, t * 1e-3, rel_err=1e-16))
        rows.append(exo5_3d_row("inverse-per-call-3d", m, False, 1, 2 * t * 1e-6, rel_err=1e-16))
    rows.append(exo5_3d_row("inverse-per-call-3d", "mj_rne (bare)", False, 1, 30e-6, rel_err=1e-16))
    df = pd.DataFrame(rows)
    df["us_per_sample"] = df["median"] / df["samples"] * 1e6
    return df


def test_ratios_are_to_the_fastest_row_of_each_reference():
    df = _rows(True)
    assert np.isclose(ratios(df, "mujoco", "matrix-factored", True)["exo5-3d"], 40.0 / 0.2)
    assert np.isclose(ratios(df, "drake", "newton-euler", False)["exo5-3d"], 120.0 / 0.5)
    text = "\n".join(engine_section(df))
    assert "| `mujoco` | exo5-3d | 40 | 200 (`matrix-factored (numba)`) | 80 (`newton-euler (numba)`) |" in text
    # per call: the bare engine's time and the method's overhead over it (drake: no bare row here)
    assert (
        "| `mujoco` | exo5-3d | 80 | 30 | 50 | 200 (`matrix-factored (numba)`) | 80 (`newton-euler (numba)`) |" in text
    )
    assert "| `drake` | exo5-3d | 240 | - | - |" in text
    assert "Python loop over MuJoCo's `mj_kinematics`" in text and "CalcInverseDynamics" in text


def test_newton_euler_column_appears_only_with_its_rows(tmp_path):
    without = "\n".join(engine_section(_rows(False)))
    assert "x newton-euler" not in without and "No `newton-euler` rows in this run." in without
    assert "x matrix-factored" in without
    assert "x newton-euler" in "\n".join(engine_section(_rows(True)))
    for report in (scaling, error_vs_runtime):
        text = report(_rows(True), [], "test", tmp_path / f"{report.__name__}.png")
        assert "## The rigid-body engines as peers" in text and "x newton-euler" in text


def test_no_engine_rows_no_section():
    df = _rows(False)
    assert engine_section(df[~df["method"].isin(["mujoco", "drake", "pinocchio"])]) == []
