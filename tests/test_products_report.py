"""The derivatives report's products goals (bench/perf/reports/derivatives.py) read the rows that
bench/test_derivatives.py now names after the kernel that ran (``"JVP (model.derivatives, simd)"``), from
fake rows (tests/test_derivatives_report.py's): no benchmark run, no wall clock."""

from test_derivatives_report import _frame

from exo_bench.bench.perf.reports import derivatives as rep


def test_the_products_goals_read_the_rows_named_after_their_kernel():
    df = _frame(jvp=1.6e-4, vjp=0.8e-4)
    df["method"] = df["method"].replace(
        {
            "JVP (model.derivatives)": "JVP (model.derivatives, simd)",
            "VJP (model.derivatives)": "VJP (model.derivatives, simd)",
        }
    )
    g = rep.goals(df)
    assert [x["value"] for x in g[5:]] == [4.0, 2.0]  # 1.6e-4 and 0.8e-4 over ID's 4e-5 per batch of 100
    assert "JVP (model.derivatives, simd)" in g[5]["measured"]
    assert [x["verdict"] for x in g[5:]] == ["**not met**", "**met**"]
