"""Benchmark report generation: fits, crossovers, and the README table between its markers."""

import numpy as np
import pandas as pd

from benchmark_rows import exo5_3d_row
from exo_bench.bench.perf.reports.paper_table import (
    PAPER_TABLE,
    README_END,
    README_START,
    paper_table,
    readme_with_table,
)
from exo_bench.bench.perf.reports.scaling import crossover, fit_exponent


def test_growth_exponent_of_a_power_law_is_recovered():
    n = np.array([1, 2, 5, 10, 20, 50, 100], float)
    for p in (0.5, 1.0, 2.0, 3.0):
        assert abs(fit_exponent(n, 3e-7 * n**p) - p) < 1e-12


def test_crossover_is_where_the_faster_method_stays_faster():
    a = pd.Series({1: 1.0, 2: 2.0, 5: 5.0, 10: 10.0})  # grows like n
    b = pd.Series({1: 3.0, 2: 3.0, 5: 3.0, 10: 3.0})  # constant
    assert crossover(a, b) == "n = 5"
    assert crossover(b, a).startswith("none up to")


def _compose_frame():
    rows = []
    for dim, n, topo, *_ in PAPER_TABLE:
        for method, t in (("matrix", 0.005 * n), ("sympy-lagrangesmethod", 1.0 * n**2), ("lagrange", 0.05 * n)):
            rows.append(dict(group=f"compose-{dim}d", method=method, n=n, dim=dim, topology=topo, median=t))
    return pd.DataFrame(rows)


def test_paper_table_puts_the_papers_numbers_beside_ours_and_judges_the_goals():
    text = paper_table(_compose_frame(), [], "test")
    for dim, n, topo, pl, pm, pr in PAPER_TABLE:
        assert f"| {dim}D, {n} link(s) | {pl} | {pm} |" in text
    assert "faster than every Lagrange/Kane peer at every n >= 2: met" in text
    assert "at 3D n=2: 400x (met)" in text


def test_readme_table_is_replaced_between_markers_only():
    readme = f"intro\n{README_START}\nold\n{README_END}\noutro\n"
    out = readme_with_table(readme, paper_table(_compose_frame(), [], "test"), "exo-bench bench")
    assert out.startswith("intro\n") and out.endswith("\noutro\n") and "old" not in out
    assert out.count("| 2D, 1 link(s) | 0.59 |") == 1
    assert readme_with_table("no markers", "x", "y") == "no markers"


def _inverse_frame(fast_us: float, pin_us: float, bare_us: float, pydy_us: float, err: float):
    """exo5-3d rows of one run: matrix-factored (numba) batched and per call, Pinocchio's paths, PyDy."""
    rows = [
        exo5_3d_row("inverse-batched-3d", "matrix-factored (numba)", True, 10_000, fast_us * 1e-6 * 10_000, err=err),
        exo5_3d_row(
            "inverse-batched-3d", "pinocchio-parallel", True, 10_000, pin_us * 1e-6 * 10_000, err=err, threads=2
        ),
        exo5_3d_row("inverse-per-call-3d", "matrix-factored (numba)", False, 1, fast_us * 5e-6, err=err),
        exo5_3d_row("inverse-per-call-3d", "pin.rnea (bare)", False, 1, bare_us * 1e-6, err=err),
        exo5_3d_row("inverse-per-call-3d", "pydy-cython", False, 1, pydy_us * 1e-6, err=err),
    ]
    return pd.DataFrame(rows)


def test_speed_goals_are_judged_from_the_rows_of_one_run():
    from exo_bench.bench.perf.reports.loading import _inverse
    from exo_bench.bench.perf.reports.scaling import speed_goals

    good = "\n".join(speed_goals(_inverse(_inverse_frame(0.1, 5.0, 3.0, 1.0, 1e-15)), []))
    # per call 0.5 us against bare 3 us (0.17x) and PyDy 1 us; batched 0.1 us, 50x faster than Pinocchio
    assert "0.17x, goal at most 0.5x: **met**" in good and "0.50x, goal at most 1x: **met**" in good
    assert "0.1 us/sample, goal at most 0.15 us: **met**" in good and "50x slower than" in good
    assert "**not met**" not in good
    bad = "\n".join(speed_goals(_inverse(_inverse_frame(0.2, 5.0, 3.0, 0.5, 3e-14)), []))
    assert bad.count("**not met**") == 4  # PyDy faster, 0.2 us/sample, 25x, error above 1e-14


def _manifest(out, command):
    import json

    files = {n: {"run": "r1"} for n in ("scaling.md", "paper_table.md")}
    (out / "runs.json").write_text(json.dumps({"format": 1, "runs": {"r1": {"command": command}}, "files": files}))


def test_a_quick_run_never_replaces_the_reports_of_a_full_run(tmp_path):
    from exo_bench.bench.perf.reports.benchmark_reports import REPORT_FILES, report_names

    assert report_names(tmp_path, "quick") == {n: n for n in REPORT_FILES}  # nothing there yet
    _manifest(tmp_path, "exo-bench bench")
    assert report_names(tmp_path, "quick")["scaling.md"] == "scaling.md"  # quick over quick
    _manifest(tmp_path, "exo-bench bench --full")
    quick = report_names(tmp_path, "quick")
    assert quick["scaling.md"] == "scaling-quick.md" and quick["scaling.png"] == "scaling-quick.png"
    assert set(quick.values()).isdisjoint(REPORT_FILES)  # every full report kept
    assert report_names(tmp_path, "full") == {n: n for n in REPORT_FILES}  # a full run replaces them


def test_the_verdict_judges_only_the_rows_where_a_peer_finished():
    import numpy as np
    import pandas as pd

    from exo_bench.bench.perf.reports.paper_table import _verdict

    idx = pd.MultiIndex.from_tuples(
        [(3, "chain", 2), (3, "chain", 5), (3, "chain", 50)], names=["dim", "topology", "n"]
    )
    piv = pd.DataFrame({"matrix": [0.01, 0.05, 20.0], "lagrange": [0.1, 0.9, np.nan]}, index=idx)
    lines = _verdict(piv, ["lagrange"])  # n = 50 composed by matrix alone: no peer to compare with
    assert any("every Lagrange/Kane peer at every n >= 2: met" in x for x in lines)
    piv.loc[(3, "chain", 5), "lagrange"] = 0.01
    assert any("**missed**" in x for x in _verdict(piv, ["lagrange"]) if "every Lagrange/Kane peer" in x)


def test_readme_goals_are_replaced_between_markers_only():
    from exo_bench.bench.perf.reports.simd_goals import readme_with_goals

    readme = "intro\n<!-- simd-goals:start -->\nold\n<!-- simd-goals:end -->\noutro\n"
    lines = ["## Issue 23: kernels at the hardware limit", "", "- Batched: 0.05 us per sample: **met**.", ""]
    out = readme_with_goals(readme, lines, "cmd")
    assert out.startswith("intro\n") and out.endswith("\noutro\n") and "old" not in out
    assert "- Batched: 0.05 us per sample: **met**." in out and "## Issue 23" not in out and "`cmd`" in out
    assert readme_with_goals(readme, [], "cmd") == readme  # no figures (the row did not run): unchanged
    assert readme_with_goals("no markers", lines, "cmd") == "no markers"


def test_a_run_without_inverse_rows_publishes_its_reports_without_the_figures(tmp_path):
    """`exo-bench bench --rows '*test_simd.py*'` (one row, no inverse-dynamics rows) failed after
    measuring: it published the error-against-run-time figure that nothing had drawn."""
    import json

    from exo_bench.bench.perf.reports.benchmark_reports import write_reports

    staging, out = tmp_path / "staging", tmp_path / "out"
    staging.mkdir(), out.mkdir()
    bjson = staging / "benchmarks-full.json"
    bjson.write_text(json.dumps({"benchmarks": [], "machine_info": {}}))
    sjson = staging / "skips.json"
    sjson.write_text("[]")
    published = write_reports(bjson, sjson, staging, out, "full", "exo-bench bench --rows x")
    names = {p.name for p in published}
    assert {"error_vs_runtime.md", "scaling.md", "paper_table.md"} <= names, names
    assert "No numeric inverse-dynamics rows" in (out / "error_vs_runtime.md").read_text()
    assert not any(p.suffix == ".png" and not p.exists() for p in published)


def test_newton_euler_goals_are_judged_against_matrix_factoreds_fastest_kernel():
    """At n = 1000 matrix-factored's numpy kernel (BLAS) beat its numba kernel in the full sweep:
    the 20x goal is judged against the faster of the two, named in the line."""
    import pandas as pd

    from exo_bench.bench.perf.reports.scaling import newton_euler_goals

    base = dict(group="inverse-batched-3d", dim=3, topology="chain", samples=1000, batched=True)
    us = {
        ("newton-euler (numba)", 100): 3.0,
        ("newton-euler (numba)", 1000): 30.0,
        ("matrix-factored (numba)", 100): 7.0,
        ("matrix-factored (numba)", 1000): 700.0,
        ("matrix-factored (numpy)", 100): 20.0,
        ("matrix-factored (numpy)", 1000): 300.0,
    }
    df = pd.DataFrame([dict(base, method=m, n=n, median=t * 1e-6 * 1000) for (m, n), t in us.items()])
    text = "\n".join(newton_euler_goals(df))
    assert "n = 100: `newton-euler (numba)` 3 us" in text and "`matrix-factored (numba)`, 7 us: 2.33x faster" in text
    assert "`matrix-factored (numpy)`, 300 us: 10x faster, goal at least 20x: **not met**" in text
    assert "`matrix-factored (numba)` 700 us, 23.3x" in text  # the slower kernel, stated beside


def test_the_highlights_page_is_rewritten_only_when_a_block_changes(tmp_path, monkeypatch):
    """The generated blocks live in reports/full/highlights.md, which the README links (issue 38: they
    were in the README); the page is written only when a block changes, and never created."""
    from exo_bench.bench.output import provenance
    from exo_bench.bench.perf.reports.readme_blocks import HIGHLIGHTS, replace_block, rewrite_highlights

    monkeypatch.setattr(provenance, "REPO", tmp_path)
    assert rewrite_highlights(lambda r: r + "x") is None  # no page: nothing written
    assert not (tmp_path / HIGHLIGHTS).exists()
    page = tmp_path / HIGHLIGHTS
    page.parent.mkdir(parents=True)
    page.write_text("a\n<!-- b:start -->\nold\n<!-- b:end -->\n")
    assert rewrite_highlights(lambda r: replace_block(r, "b", "old")) is None
    assert rewrite_highlights(lambda r: replace_block(r, "b", "new")) == page
    assert page.read_text() == "a\n<!-- b:start -->\nnew\n<!-- b:end -->\n"
    assert not (tmp_path / "README.md").exists()  # the README is not touched


def test_the_committed_highlights_page_has_both_blocks_and_the_readme_links_it():
    """Both generated blocks are in the committed page, and the README links the page, not the blocks."""
    from exo_bench.bench.output.provenance import REPO
    from exo_bench.bench.perf.reports.readme_blocks import HIGHLIGHTS, markers

    page = (REPO / HIGHLIGHTS).read_text()
    readme = (REPO / "README.md").read_text()
    for name in ("paper-table", "simd-goals"):
        start, end = markers(name)
        assert start in page and end in page and start not in readme
    assert f"]({HIGHLIGHTS.as_posix()})" in readme
