"""The derivatives report (bench/perf/reports/derivatives.py) from fake rows, a fake header and a
fake clock: every goal's ratio is computed from the rows it names, judged against its target, and
'not judged' when a row is missing; no wall clock, no benchmark run."""

import datetime as dt

import pandas as pd
import pytest

from exo_bench.bench.perf.reports import derivatives as rep

CLOCK = lambda: dt.datetime(2031, 2, 3, 4, 5, tzinfo=dt.UTC)  # noqa: E731


def _row(group, method, mech, n, median, samples, topology="chain", **extra):
    return dict(group=f"derivatives-{group}", method=method, mechanism=mech, n=n, topology=topology,
                min=median, median=3 * median, samples=samples, **extra)  # fmt: skip


def _frame(
    analytic_exo5=2.0e-4, one=3e-6, fwd=1e-3, c100=4e-4 * 10, chain_ns=(10, 20, 50, 100, 200, 300), p=2.0,
    jvp=1e-4, vjp=1.1e-4,
):  # fmt: skip
    err = dict(max_rel_err=3e-16, err_ratio=0.4, reference="50-digit", prepare_s=0.1)
    r = [
        _row("inverse-batched", "ID (newton-euler batched)", "exo5-3d", 5, 4e-5, 100, "exo5"),
        _row("inverse-batched", "analytic (numba)", "exo5-3d", 5, analytic_exo5, 100, "exo5", **err),
        _row("inverse-batched", "analytic (numpy)", "exo5-3d", 5, 1e-2, 100, "exo5", **err),
        _row("inverse-batched", "casadi AD", "exo5-3d", 5, 4e-3, 100, "exo5", **err),
        _row("inverse-one-sample", "analytic (auto)", "exo5-3d", 5, one, 1, "exo5", **err),
        _row("inverse-one-sample", "pin.rnea (bare)", "exo5-3d", 5, 4e-6, 1, "exo5"),
        _row("forward-batched", "model.derivatives (newton-euler)", "exo5-3d", 5, fwd, 100, "exo5", **err),
        _row("forward-batched", "FD (newton-euler batched)", "exo5-3d", 5, 8e-5, 100, "exo5"),
        _row("products-batched", "JVP (model.derivatives)", "exo5-3d", 5, jvp, 100, "exo5", **err),
        _row("products-batched", "VJP (model.derivatives)", "exo5-3d", 5, vjp, 100, "exo5", **err),
    ]
    for n in chain_ns:  # t = c100 / 10 * (n / 100) ** p seconds per batch of 10
        r.append(_row("inverse-batched", "analytic (numba)", f"chain{n}-3d", n, c100 * (n / 100) ** p, 10, **err))
    return pd.DataFrame(r)


def _goals(df):
    return {g["goal"].split(" ")[0] + str(i): g for i, g in enumerate(rep.goals(df))}


def test_goals_are_ratios_of_the_named_rows_and_judged_against_their_targets():
    """Times are the fastest rounds (``min``); the fake medians are 3x (the chain-100 figure from
    them, 1.2 ms, would not meet its goal)."""
    g = rep.goals(_frame())
    assert [x["target"] for x in g] == [10.0, 1.0, 25.0, 0.5, 2.1, 3.0, 3.0]
    # exo5: 2e-4/100 per sample over 4e-5/100 -> 5x; one sample 3/4; forward 1e-3/8e-5 = 12.5x
    assert [round(x["value"], 6) for x in g[:3]] == [5.0, 0.75, 12.5]
    assert g[3]["value"] == pytest.approx(0.4)  # 4e-3 s / 10 samples = 0.4 ms
    assert g[4]["value"] == pytest.approx(2.0)
    assert [x["value"] for x in g[5:]] == pytest.approx([2.5, 2.75])  # JVP 1e-4, VJP 1.1e-4 over ID's 4e-5
    assert "JVP (model.derivatives)" in g[5]["measured"] and "VJP" in g[6]["goal"]
    assert all(x["verdict"] == "**met**" for x in g)
    assert "CasADi (today's path) 100x" in g[0]["measured"]


def test_goals_not_met_are_said_so():
    g = rep.goals(_frame(analytic_exo5=2e-3, one=5e-6, fwd=3e-3, c100=1e-2, p=2.5, jvp=1.3e-4, vjp=2e-4))
    assert [x["verdict"] for x in g] == ["**not met**"] * 7


def test_a_missing_row_or_range_is_not_judged():
    df = _frame(chain_ns=(10, 20))
    df = df[(df["method"] != "pin.rnea (bare)") & (df["method"] != "VJP (model.derivatives)")]
    g = rep.goals(df)
    assert g[6]["verdict"] == "not judged" and g[5]["verdict"] == "**met**"
    assert g[1]["verdict"] == "not judged" and "pin.rnea" in g[1]["measured"]
    assert g[3]["verdict"] == "not judged" and "--full" in g[3]["measured"]
    assert g[4]["verdict"] == "not judged" and "n = 10..20" in g[4]["measured"]


def test_report_uses_the_injected_header_and_clock_and_lists_rows_and_skips(tmp_path):
    skips = [{"nodeid": "bench/test_derivatives.py::test_inverse_derivatives[x]", "reason": "refused: mimic"}]
    png = tmp_path / "derivatives.png"
    text = rep.derivatives_report(_frame(), skips, "cmd", png, header="HEADER\n", clock=CLOCK, load="busy")
    assert "HEADER" in text and "2031-02-03" in text and "(busy)" in text
    assert "| exo5-3d analytic batched" not in text  # goals are named, not pasted rows
    assert "| chain300-3d | analytic (numba) |" in text
    assert "### Directional derivatives" in text and "| exo5-3d | JVP (model.derivatives) |" in text
    assert "refused: mimic" in text
    assert png.exists() and png.stat().st_size > 0


def test_no_rows_no_figure(tmp_path):
    png = tmp_path / "d.png"
    text = rep.derivatives_report(pd.DataFrame(), [], "cmd", png, header="H\n", clock=CLOCK)
    assert "No derivative rows" in text and not png.exists()
