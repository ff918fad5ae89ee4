"""``exo-bench equations``: every output (Python, C, LaTeX) agrees with Pinocchio and Lagrange.

Oracles: Pinocchio's RNEA on the generated URDF and our Lagrange II derivation, both independent of
the matrix method the exports are generated from, on seeded random states of seeded random trees
in 2D and 3D (branch signs, several roots) and on the paper's models.

Error model: every output is a sum of products of at most ~10 factors (lengths, rates, sines and
cosines, coefficients rounded once to the nearest double); evaluated in any order its error is at
most ``k * eps * sum |terms|`` with ``k`` of the order of the depth, and on these states ``sum |terms|``
is within a small factor of ``max |tau|``. The references carry the same kind of error. So all
outputs are compared relative to the largest magnitude of the batch, to ``TOL = 1e-13`` (about
450 eps): a wrong sign, a missing term or a misplaced coefficient is off by 1e-3 or more.
"""

from __future__ import annotations

import ctypes
import functools
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import exo_bench
from exo_bench import prepare
from exo_bench.bench.cli import equations as beq
from exo_bench.matrix_method.export import code as export_code, latex as export_latex
from exo_bench.models.gait.motion import random_states
from exo_bench.models.mechanism.presets import exo5, fig2a, fig2b, random_tree

TOL = 1e-13

MODELS = {
    "tree3-2d": lambda: random_tree(3, 2, 5),
    "tree4-3d": lambda: random_tree(4, 3, 7),
    "exo5-3d": lambda: exo5(3),
}
#: Trees whose Lagrange derivation is quick (the 5-link 3D one takes seconds: Pinocchio only there).
LAGRANGE = ("tree3-2d", "tree4-3d")


def _rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.abs(a - b).max() / np.abs(b).max())


def _references(mech, key, q, qd, qdd):
    refs = {"pinocchio": prepare(mech, "pinocchio")}
    if key in LAGRANGE:
        refs["lagrange"] = prepare(mech, "lagrange")
    return {name: (m.inverse_dynamics(q, qd, qdd), m.mass_matrix(q), m.bias_forces(q, qd)) for name, m in refs.items()}


# ------------------------------------------------------------------------------ Python
def _numpy_only_path(tmp: Path) -> Path:
    """A folder holding numpy (a link to the package) and nothing else of site-packages."""
    import numpy

    d = tmp / "only-numpy"
    d.mkdir()
    root = Path(numpy.__file__).resolve().parent
    os.symlink(root, d / "numpy")
    libs = root.parent / "numpy.libs"
    if libs.exists():
        os.symlink(libs, d / "numpy.libs")
    return d


RUNNER = r"""
import sys, importlib
for banned in ("exo_bench", "sympy", "pinocchio"):
    try:
        importlib.import_module(banned)
    except ImportError:
        pass
    else:
        raise SystemExit(f"{banned} is importable: the test would not prove the module standalone")
import numpy
mod = importlib.import_module(sys.argv[1])
z = numpy.load(sys.argv[2])
args = {"q": z["q"], "qd": z["qd"], "qdd": z["qdd"]}
kw = {"params": z["params"]} if "params" in z.files else {}
numpy.savez(sys.argv[3], tau=mod.inverse_dynamics(z["q"], z["qd"], z["qdd"], **kw),
            M=mod.mass_matrix(z["q"], **kw), h=mod.bias_forces(z["q"], z["qd"], **kw),
            tau1=mod.inverse_dynamics(z["q"][0], z["qd"][0], z["qdd"][0], **kw))
print(sorted(m.split(".")[0] for m in sys.modules if not m.startswith("_"))[:0], mod.EXO_BENCH_VERSION, mod.MECHANISM)
"""


def _run_python_module(tmp_path, mech, symbolic, q, qd, qdd):
    es = export_code.equation_set(mech, symbolic)
    name = export_code.module_name(es)  # never a standard module's name, nor numpy's
    (tmp_path / f"{name}.py").write_text(export_code.python_module(es, exo_bench.__version__))
    (tmp_path / "run.py").write_text(RUNNER)
    arrays = {"q": q, "qd": qd, "qdd": qdd}
    if symbolic:
        arrays["params"] = np.array(export_code.parameter_values(mech))
    np.savez(tmp_path / "in.npz", **arrays)
    env = {"PYTHONPATH": os.pathsep.join([str(tmp_path), str(_numpy_only_path(tmp_path))]), "PATH": os.environ["PATH"]}
    r = subprocess.run(
        [
            sys.executable,
            "-S",
            "-s",
            str(tmp_path / "run.py"),
            name,
            str(tmp_path / "in.npz"),
            str(tmp_path / "out.npz"),
        ],
        capture_output=True,
        text=True,
        env=env,
        timeout=1800,
        cwd=tmp_path,
    )
    assert r.returncode == 0, r.stderr
    assert exo_bench.__version__ in r.stdout and mech.name in r.stdout
    return np.load(tmp_path / "out.npz")


@pytest.mark.parametrize("key", sorted(MODELS))
def test_python_module_runs_with_numpy_only_and_agrees(key, tmp_path):
    mech = MODELS[key]()
    q, qd, qdd = random_states(mech, 40, 11)
    out = _run_python_module(tmp_path, mech, key == "tree4-3d", q, qd, qdd)
    for name, (tau, M, h) in _references(mech, key, q, qd, qdd).items():
        assert _rel(out["tau"], tau) < TOL, name
        assert _rel(out["M"], M) < TOL, name
        assert _rel(out["h"], h) < TOL, name
    assert _rel(out["tau1"], out["tau"][0]) == 0.0  # a single (dof,) sample: the same numbers


def test_python_module_header_names_mechanism_version_and_coordinate_order():
    es = export_code.equation_set(fig2b(3))
    text = export_code.python_module(es, "9.9.9")
    head = text.split('"""')[1]
    assert "'fig2b-3d'" in head and "exo-bench 9.9.9" in head
    assert "phi1, phi2, psi1, psi2, l1, l2" in head
    assert re.search(r"^import numpy$", text, re.M) and "sympy" not in text.replace("Borisov", "")
    assert "x0 = " in text  # common subexpressions


# ------------------------------------------------------------------------------ C
def _compile(tmp_path, mech, symbolic):
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no system C compiler (cc) on this machine")
    es = export_code.equation_set(mech, symbolic)
    prefix, h, c = export_code.c_sources(es, exo_bench.__version__)
    (tmp_path / f"{prefix}.h").write_text(h)
    (tmp_path / f"{prefix}.c").write_text(c)
    assert f"cc {export_code.C_FLAGS} -c {prefix}.c" in h  # the compile line in the header
    so = tmp_path / f"lib{prefix}.so"
    r = subprocess.run(
        [cc, *export_code.C_FLAGS.split(), "-fPIC", "-shared", "-o", str(so), str(tmp_path / f"{prefix}.c"), "-lm"],
        capture_output=True,
        text=True,
        timeout=1800,
    )
    assert r.returncode == 0 and r.stderr == "", r.stderr  # warning-free at -Wall -Wextra -Werror
    return ctypes.CDLL(str(so)), prefix, c


def _call_c(lib, prefix, mech, symbolic, q, qd, qdd):
    P = ctypes.POINTER(ctypes.c_double)
    ptr = lambda a: np.ascontiguousarray(a, dtype=float).ctypes.data_as(P)
    dof = mech.dof
    params = [ptr(np.array(export_code.parameter_values(mech)))] if symbolic else []
    tau, M, h = np.zeros((len(q), dof)), np.zeros((len(q), dof * dof)), np.zeros((len(q), dof))
    for s in range(len(q)):
        t, m, b = np.zeros(dof), np.zeros(dof * dof), np.zeros(dof)
        getattr(lib, f"{prefix}_inverse_dynamics")(ptr(q[s]), ptr(qd[s]), ptr(qdd[s]), *params, t.ctypes.data_as(P))
        getattr(lib, f"{prefix}_mass_matrix")(ptr(q[s]), *params, m.ctypes.data_as(P))
        getattr(lib, f"{prefix}_bias_forces")(ptr(q[s]), ptr(qd[s]), *params, b.ctypes.data_as(P))
        tau[s], M[s], h[s] = t, m, b
    return tau, M.reshape(len(q), dof, dof), h


@pytest.mark.parametrize("key", sorted(MODELS))
def test_c_compiles_warning_free_and_agrees(key, tmp_path):
    mech = MODELS[key]()
    symbolic = key == "tree3-2d"
    lib, prefix, src = _compile(tmp_path, mech, symbolic)
    assert "malloc" not in src and "static" not in src  # no allocation, no global state
    q, qd, qdd = random_states(mech, 20, 12)
    tau, M, h = _call_c(lib, prefix, mech, symbolic, q, qd, qdd)
    for name, (rt, rM, rh) in _references(mech, key, q, qd, qdd).items():
        assert _rel(tau, rt) < TOL and _rel(M, rM) < TOL and _rel(h, rh) < TOL, name


def test_the_cli_writes_c_for_exo5_that_agrees_with_exo_bench_inverse(tmp_path):
    """Issue 15, done when: `exo-bench equations exo5-3d --format c -o out/` compiles warning-free
    and agrees with `exo-bench inverse exo5-3d` on the test states."""
    from cli_runs import run_cli

    rc, out, err = run_cli(["equations", "exo5-3d", "--format", "c", "-o", tmp_path / "out"])
    assert rc == 0 and err == "" and sorted(p.name for p in (tmp_path / "out").iterdir()) == ["exo5_3d.c", "exo5_3d.h"]
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no system C compiler (cc)")
    so = tmp_path / "libexo5.so"
    r = subprocess.run(
        [
            cc,
            *export_code.C_FLAGS.split(),
            "-fPIC",
            "-shared",
            "-o",
            str(so),
            str(tmp_path / "out" / "exo5_3d.c"),
            "-lm",
        ],
        capture_output=True,
        text=True,
        timeout=1800,
    )
    assert r.returncode == 0 and r.stderr == "", r.stderr
    mech = exo5(3)
    q, qd, qdd = random_states(mech, 5, 13)
    (tmp_path / "s.json").write_text(json.dumps({"q": q.tolist(), "qd": qd.tolist(), "qdd": qdd.tolist()}))
    rc, out, err = run_cli(["inverse", "exo5-3d", tmp_path / "s.json"])
    assert rc == 0
    ref = np.array(json.loads(out)["tau"])
    tau, _, _ = _call_c(ctypes.CDLL(str(so)), "exo5_3d", mech, False, q, qd, qdd)
    assert _rel(tau, ref) < TOL


# ------------------------------------------------------------------------------ LaTeX
#: The paper's notation -> names sympy's LaTeX parser reads as one symbol each.
_TOKENS = [
    (r"C^{\psi}_{", r"\gamma_{"),
    (r"S^{\psi}_{", r"\sigma_{"),
    (r"\ddot{\varphi}_{", r"\alpha_{"),
    (r"\dot{\varphi}_{", r"\omega_{"),
    (r"\ddot{\psi}_{", r"\beta_{"),
    (r"\dot{\psi}_{", r"\kappa_{"),
    (r"\ddot{l}_{", r"\rho_{"),
    (r"\dot{l}_{", r"\nu_{"),
]


@functools.cache
def parse(text: str):
    """sympy's LaTeX parser (ANTLR; about 0.1 s a call, so each element is parsed once)."""
    from sympy.parsing.latex import parse_latex

    for a, b in _TOKENS:
        text = text.replace(a, b)
    return parse_latex(text)


def _values(mech, q, qd, qdd, symbolic: bool) -> dict[str, float]:
    """Parsed symbol name -> value at one state (and the aggregates of eq. (6))."""
    n = mech.nlinks
    phi, l = q[:n], q[-n:]
    psi = q[n : 2 * n] if mech.dim == 3 else None
    v = {"g": mech.g}
    for i in range(n):
        k = str(i + 1)
        v.update(
            {
                f"l_{{{k}}}": l[i],
                f"C_{{{k}}}": np.cos(phi[i]),
                f"S_{{{k}}}": np.sin(phi[i]),
                f"omega_{{{k}}}": qd[i],
                f"alpha_{{{k}}}": qdd[i],
                f"nu_{{{k}}}": qd[-n + i],
                f"rho_{{{k}}}": qdd[-n + i],
            }
        )
        if psi is not None:
            v.update(
                {
                    f"gamma_{{{k}}}": np.cos(psi[i]),
                    f"sigma_{{{k}}}": np.sin(psi[i]),
                    f"kappa_{{{k}}}": qd[n + i],
                    f"beta_{{{k}}}": qdd[n + i],
                }
            )
        for j in range(i + 1, n):
            v[f"C_{{{k}{j + 1}}}"] = np.cos(phi[i] - phi[j])
            v[f"S_{{{k}{j + 1}}}"] = np.sin(phi[i] - phi[j])
        m0, m1, m2 = mech.masses[i]
        v.update(
            {
                f"zeta_{{{k}}}": m1 * mech.n[i] ** 2 + m2,
                f"eta_{{{k}}}": m1 * mech.n[i] + m2,
                f"theta_{{{k}}}": m0 + m1 + m2,
            }
        )
    return v


def _evaluate(text: str, values: dict[str, float]) -> float:
    e = parse(text)
    return float(e.subs({s: values[s.name] for s in e.free_symbols}))


@pytest.mark.parametrize(
    "mech,symbolic",
    [(fig2a(2), False), (fig2b(2), True), (fig2b(3), True)],
    ids=["fig2a-2d-numbers", "fig2b-2d-aggregates", "fig2b-3d-aggregates"],
)
def test_latex_parses_back_to_the_equations_of_pinocchio(mech, symbolic):
    """Every element of every matrix, parsed back from the LaTeX and assembled into eq. (5)/(17),
    gives Pinocchio's and Lagrange's M and tau."""
    from exo_bench.models.states.states import ACCELERATION, RATES, blocks, matrix_names

    els = export_latex.elements(mech, symbolic)
    q, qd, qdd = random_states(mech, 3, 21)
    pin, lag = prepare(mech, "pinocchio"), prepare(mech, "lagrange")
    n, bl = mech.nlinks, blocks(mech.dim)
    coord = {b: slice(k * n, (k + 1) * n) for k, b in enumerate(bl)}
    for s in range(3):
        v = _values(mech, q[s], qd[s], qdd[s], symbolic)
        M = np.zeros((mech.dof, mech.dof))
        tau = np.zeros(mech.dof)
        for a, block in enumerate(bl):
            for i in range(n):
                row = a * n + i
                tau[row] = mech.g * _evaluate(els[block]["P"][(i,)], v)
                for name in matrix_names(mech.dim):
                    factor, rates = RATES[name]
                    for j in range(n):
                        x = _evaluate(els[block][name][(i, j)], v)
                        if len(rates) == 1:
                            rate = qdd[s][coord[rates[0]]][j]
                        else:
                            rate = factor * qd[s][coord[rates[0]]][j] * qd[s][coord[rates[1]]][j]
                        tau[row] += x * rate
                for c, cb in enumerate(bl):
                    for j in range(n):
                        M[row, c * n + j] = _evaluate(els[block][ACCELERATION[cb]][(i, j)], v)
        for ref in (pin, lag):
            assert _rel(M, ref.mass_matrix(q[s])) < TOL, ref.method
            assert _rel(tau, ref.inverse_dynamics(q[s], qd[s], qdd[s])) < TOL, ref.method


@pytest.mark.parametrize("mech", [fig2a(2), fig2b(2)], ids=lambda m: m.name)
def test_eq4_with_both_signs_parses_back_to_the_serial_and_branched_models(mech):
    """Eq. (4) on the page: upper signs give Fig. 2a's equations, lower signs Fig. 2b's (Pinocchio and
    Lagrange)."""
    rows = export_latex.eq4_rows(*beq.eq4_pair(mech))
    text = " ".join(rows)
    assert r"\pm" in text and r"\mp" in text
    q, qd, qdd = random_states(mech, 2, 31)
    for model, (pm, mp) in ((fig2a(2), ("+", "-")), (fig2b(2), ("-", "+"))):
        for ref in (prepare(model, "pinocchio"), prepare(model, "lagrange")):
            for s in range(2):
                v = _values(model, q[s], qd[s], qdd[s], True)
                lhs = [_evaluate(r.split("&=")[0].replace(r"\pm", pm).replace(r"\mp", mp), v) for r in rows]
                assert _rel(lhs, ref.inverse_dynamics(q[s], qd[s], qdd[s])) < TOL, (model.name, ref.method)


def test_branch_zeros_and_signs_are_shown():
    """exo5-3d: links 3 and 5 (swing thigh, trunk) are on different branches: 0; link 1 and the
    reversed link 3: a minus sign in front of the coefficient."""
    els = export_latex.elements(exo5(3), True)
    assert els["phi"]["A"][(2, 4)] == "0" and els["psi"]["B"][(4, 3)] == "0"
    assert els["phi"]["A"][(0, 2)].startswith(r"- \left(\eta_{3} + \theta_{4}\right)")
    assert not els["phi"]["A"][(0, 4)].startswith("-")


def test_the_element_factors_recompose_the_matrices_exactly():
    """coefficient x geometry (the page's form) equals matrix_method.symbolic.matrices exactly."""
    import sympy as sp

    from exo_bench.matrix_method.symbolic import matrices

    mech = random_tree(4, 3, 9)
    parts = export_latex.element_parts(mech, False)
    mats = matrices(mech, False)
    for block, mm in mats.items():
        for name, M in mm.items():
            for i in range(mech.nlinks):
                for j in range(M.shape[1]):
                    assert sp.expand(parts.element(block, name, i, j) - M[i, j]) == 0, (block, name, i, j)


def test_pages_compile_with_a_tex_engine_where_installed(tmp_path):
    engine = next((e for e in ("pdflatex", "lualatex", "xelatex", "tectonic") if shutil.which(e)), None)
    files = beq.render(fig2b(2), "latex", True)
    files.update({f"exo5-{k}": v for k, v in beq.render(exo5(3), "latex", True).items()})
    assert all(v.strip() for v in files.values())
    if engine is None:
        print("no TeX engine (pdflatex, lualatex, xelatex, tectonic) installed: the .tex files are not compiled")
        pytest.skip("no TeX engine installed (pdflatex, lualatex, xelatex, tectonic)")
    for name, text in files.items():
        if name.endswith(".tex"):
            (tmp_path / "doc.tex").write_text(text)
            args = (
                [engine, "doc.tex"]
                if engine == "tectonic"
                else [engine, "-interaction=nonstopmode", "-halt-on-error", "doc.tex"]
            )
            r = subprocess.run(args, cwd=tmp_path, capture_output=True, text=True, timeout=1800)
            assert r.returncode == 0, r.stdout[-2000:]


# ------------------------------------------------------------------------------ scenes and the size study
def test_only_scenes_that_declare_equations_get_the_pages(tmp_path):

    import exo_bench.bench.cli.run as runner
    from exo_bench.bench.studies.options import RunOptions

    base = (
        'mechanism = "fig2a-2d"\nmethods = ["matrix-factored"]\noutputs = [{}]\n[motion]\nkind = "planar-gait"\n'
        "samples_per_period = 20\n"
    )
    (tmp_path / "with.toml").write_text(base.format('"equations"'))
    (tmp_path / "without.toml").write_text(base.format('"table"'))
    rc = runner.run_main_job(
        RunOptions(scenes=[str(tmp_path / "with.toml"), str(tmp_path / "without.toml")], reports=str(tmp_path / "rep"))
    )
    assert rc == 0
    names = sorted(p.name for p in (tmp_path / "rep").iterdir())
    assert names == [
        ".exo-bench.lock",
        "equations-with.md",
        "equations-with.tex",
        "runs.json",
        "summary.md",
        "without.md",
    ]
    page = (tmp_path / "rep" / "equations-with.md").read_text()
    assert "Generated by `exo-bench run with`" in page and "- **run**: `" in page
    assert "Eq. (4)" in page and r"\pm" in page and "upper signs" in page


def test_the_shipped_paper_scenes_declare_equations():
    from exo_bench.bench.studies.scenes import load_scene

    for name in ("fig2a-2d", "fig2b-2d", "exo5-3d"):
        assert load_scene(name).wants("equations")


def test_size_report_is_generated_with_provenance(tmp_path, monkeypatch):

    from exo_bench.bench.studies import equations_size as es
    from exo_bench.bench.studies.options import ReportOptions

    monkeypatch.setattr(es, "QUICK_N", (1, 2))
    monkeypatch.setattr(es, "ROUTES", ("matrix", "lagrange"))  # LagrangesMethod: the test below
    rc = es.size_report(ReportOptions(full=False, reports=tmp_path))
    assert rc == 0
    text = (tmp_path / "equations_size.md").read_text()
    assert "Generated by `exo-bench equations --size-report`" in text
    rows = [ln for ln in text.splitlines() if ln.startswith("| 3D | chain | 2 |")]
    assert {r.split("|")[4].strip() for r in rows} >= {"matrix", "lagrange"}
    assert (tmp_path / "equations_size.png").exists()


def test_size_points_of_the_three_routes_count_the_same_equations():
    """The matrix method's tau is at most as large after CSE as Lagrange's (the same equations, a
    compact form), and each route's C lines and timings are recorded."""
    from exo_bench.bench.studies import equations_size as es
    from exo_bench.models.mechanism.presets import chain

    m = chain(2, 2)
    pts = {r: es.size_point(m, r, 30.0) for r in es.ROUTES}
    for p in pts.values():
        assert p["ops"] > 0 and p["c_lines"] > 20 and p["compose"] >= 0 and p["generate"] > 0
    assert pts["matrix"]["ops"] <= pts["LagrangesMethod"]["ops"]


def test_a_hostile_mechanism_name_cannot_break_the_generated_code(tmp_path):
    """A user's JSON names the mechanism: quotes, comment ends and backslashes stay text."""
    mech = fig2a(2).replace(name='evil */ """ \\ \' x')
    es = export_code.equation_set(mech)
    text = export_code.python_module(es, "0")
    ns: dict = {}
    exec(compile(text, "gen.py", "exec"), ns)  # still valid Python, the name intact
    assert ns["MECHANISM"] == mech.name
    q, qd, qdd = random_states(mech, 3, 1)
    assert _rel(ns["inverse_dynamics"](q, qd, qdd), prepare(mech, "pinocchio").inverse_dynamics(q, qd, qdd)) < TOL
    lib, prefix, _ = _compile(tmp_path, mech, False)  # still compiles, warning-free
    assert prefix.isidentifier()
    tau, _, _ = _call_c(lib, prefix, mech, False, q, qd, qdd)
    assert _rel(tau, ns["inverse_dynamics"](q, qd, qdd)) < TOL
